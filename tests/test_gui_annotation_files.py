"""The annotator's work on dataset frames is never lost: the app saves a frame's light annotation
where the command line reads it (``X_lights.json`` beside the image, ``--lights auto``), keeps a
recovery file within 2 s of an edit, offers it back after the process was killed, asks before
leaving a frame with unsaved edits, and marks saved frames ✓ in the Frames dock.

Cityscapes-layout fixture (``npsim_core.synthetic.cityscapes``, 128x64, two frames). Driven by
signals and ``qtbot.waitUntil``; no sleeps, no wall-clock assertions.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from npsim_core.synthetic.cityscapes import fixture_image

SIZE = (128, 64)


@pytest.fixture
def dataset(cityscapes_layout):
    """A fresh copy for each test (tests write annotations and recovery files beside the images)."""
    return cityscapes_layout(frames=2, size=SIZE, corrupt=0)


def _window(qtbot, answers: list[str] | None = None):
    from npsim_core.chain import ChainParams
    from npsim_gui.main_window import MainWindow

    win = MainWindow(with_3d=False)
    win.asked = []

    def ask(title, text, buttons):
        win.asked.append(title)
        return answers.pop(0) if answers else "Discard"
    win.ask = ask
    win.params = ChainParams().with_value("refine", "steps", 5).with_value("night", "spp", 1)
    qtbot.addWidget(win)
    return win


def _edit(win, n: int = 1, class_id: int = 8) -> list[int]:
    """``n`` new lights of a few pixels each, one undo step each (as brush strokes make them)."""
    from npsim_core.annotation_ops import new_instance, paint

    s = win.editor.session
    W = s.ann.shape[1]
    ids = []
    for k in range(n):
        cmd, iid = new_instance(s.ann, class_id)
        s.begin_stroke("test stroke")
        s.apply(cmd)
        s.apply(paint(s.ann, np.arange(6) + (10 + 4 * k) * W + 20 + 10 * k, iid))
        s.end_stroke()
        ids.append(iid)
    return ids


def _close(win):
    win.confirm_close = lambda: True
    win.close()


def test_a_dataset_image_is_saved_beside_it_where_the_cli_reads_it(qtbot, settings, dataset):
    from npsim_core.annotation import annotation_paths, autosave_path
    from npsim_core.chain import load_frame

    root, stems = dataset
    image = fixture_image(root, stems[0])
    win = _window(qtbot)
    win.open_scene(image)
    ids = _edit(win, 2)
    assert win.windowTitle().endswith("*")
    # the recovery file within 2 s of the edit
    rec = autosave_path(image.parent, stems[0])
    qtbot.waitUntil(rec.exists, timeout=2000)
    with qtbot.waitSignal(win.editor.session.saved, timeout=10_000):
        win.save_annotation()
    assert not win.windowTitle().endswith("*") and not win.editor.session.is_dirty
    assert annotation_paths(image.parent, stems[0])["json"].exists()
    qtbot.waitUntil(lambda: not rec.exists(), timeout=5000)  # saved: the recovery file goes
    # what `npsim run IMAGE --lights auto` and `npsim batch ROOT` read
    scene = load_frame(image)
    assert sorted(scene.lights.instance_ids()) == sorted(ids)
    assert np.array_equal(scene.lights.instance_map, win.editor.session.ann.instance_map)
    _close(win)


def test_a_read_only_dataset_saves_into_the_annotations_folder_the_cli_reads(qtbot, settings, dataset, tmp_path,
                                                                                 monkeypatch):
    import npsim_core.chain.session as session_mod
    from npsim_core.annotation import annotation_paths
    from npsim_core.chain import iter_frames

    root, stems = dataset
    image = fixture_image(root, stems[0])
    monkeypatch.setattr(session_mod, "_writable", lambda folder: False)  # root ignores file modes
    win = _window(qtbot)
    win.open_scene(image)
    ids = _edit(win)
    with qtbot.waitSignal(win.editor.session.saved, timeout=10_000):
        win.save_annotation()
    folder = win.editor.session.folder
    assert str(folder).startswith(str(tmp_path / "annotations")) and not any(image.parent.glob("*_lights*"))
    assert annotation_paths(folder, stems[0])["json"].exists()
    assert iter_frames(root)[0].load().lights.instance_ids() == ids  # the batch finds it there
    _close(win)


def test_leaving_a_dataset_frame_with_unsaved_edits_asks_and_marks_it_done(qtbot, settings, dataset):
    from npsim_core.chain import iter_frames

    root, stems = dataset
    win = _window(qtbot, answers=["Cancel", "Save"])
    win.open_dataset(root)
    assert win.frame_list.item(0).text().startswith("   ")  # not annotated yet
    ids = _edit(win, 3)
    win.step_frame(+1)  # Cancel: stay, edits kept
    assert win.asked == ["Unsaved annotation"]
    assert win.chain.scene.name == stems[0] and win.editor.session.is_dirty
    assert win.frame_list.currentRow() == 0
    win.step_frame(+1)  # Save: written, then the next frame
    assert win.asked == ["Unsaved annotation"] * 2
    assert win.chain.scene.name == stems[1] and not win.editor.session.is_dirty
    assert win.frame_list.item(0).text() == f"✓ {stems[0]}"
    assert sorted(iter_frames(root)[0].load().lights.instance_ids()) == sorted(ids)
    # and the ✓ is found again when the dataset is reopened
    win.open_dataset(root)
    assert win.frame_list.item(0).text().startswith("✓") and not win.frame_list.item(1).text().startswith("✓")
    _close(win)


def test_saving_a_frame_without_a_folder_says_so_in_the_window(qtbot, settings):
    from npsim_core.synthetic import street_scene

    win = _window(qtbot)
    win.set_scene(street_scene(128, 64).with_(provenance={}), win.params)
    _edit(win)
    win.save_annotation()  # the generated street exists only in memory
    assert "Annotation not saved" in win.asked
    assert "Save project" in win.last_error and win.editor.session.is_dirty
    _close(win)


CHILD = textwrap.dedent("""
    import sys
    from PySide6.QtWidgets import QApplication
    app = QApplication([])
    from npsim_core.chain import ChainParams
    from npsim_gui.main_window import MainWindow
    import npsim_gui.main_window as main_window
    import tests.test_gui_annotation_files as t
    MainWindow.AUTOSAVE_MS = 100   # the recovery file's delay is not what is tested: no need to wait 1 s
    main_window.warm_up = lambda: []  # nor the start-up's imports for the workers (torch, Mitsuba: ~3 s)
    win = MainWindow(with_3d=False)
    win.ask = lambda *a: "Discard"
    win.params = ChainParams().with_value("refine", "steps", 5)
    win.show()
    win.open_scene(sys.argv[1])
    win.editor.session.autosaved.connect(lambda p: print("autosaved", flush=True))
    print(*t._edit(win, 6), flush=True)
    app.exec()
""")


def test_edits_survive_the_app_being_killed(qtbot, settings, dataset, tmp_path):
    """Six edits, then SIGKILL once the recovery file is written: reopening offers all six back."""
    root, stems = dataset
    image = fixture_image(root, stems[0])
    env = {**os.environ, "XDG_CONFIG_HOME": str(tmp_path / "child-config")}
    child = subprocess.Popen([sys.executable, "-c", CHILD, str(image)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=env,
                             cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    try:
        ids = [int(i) for i in child.stdout.readline().split()]
        assert len(ids) == 6, child.stderr.read() if child.poll() is not None else ids
        assert child.stdout.readline().strip() == "autosaved"
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait(30)
    assert child.returncode == -signal.SIGKILL
    win = _window(qtbot, answers=["Restore"])
    win.open_scene(image)
    assert win.asked == ["Recover unsaved edits"]
    assert sorted(win.editor.session.ann.instance_ids()) == sorted(ids)
    assert win.editor.session.is_dirty and win.windowTitle().endswith("*")
    _close(win)


def test_a_save_ending_after_the_next_image_opened_leaves_that_image_alone(qtbot, tmp_path):
    """Ctrl+S, then straight to another (restored, so unsaved) image: the late save of the first must not
    mark the second saved or delete its recovery file."""
    from npsim_core.annotation import LightAnnotation, write_recovery
    from npsim_core.annotation_ops import new_instance, paint
    from npsim_gui.editor.session import EditorSession

    s = EditorSession()
    img = np.zeros((64, 128, 3), np.uint8)
    s.load(img, None, None, tmp_path / "a", "a")
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    cmd, iid = new_instance(s.ann, 1)
    s.apply(cmd)
    s.apply(paint(s.ann, np.arange(5), iid))
    rec_b = write_recovery(LightAnnotation.empty(64, 128), tmp_path / "b", "b")
    s.save_in_background()
    s.load(img, None, LightAnnotation.empty(64, 128), tmp_path / "b", "b", dirty=True)  # restored: unsaved
    with qtbot.waitSignal(s.saved, timeout=10_000):
        pass
    s.wait_for_writes()
    qtbot.wait(20)
    assert s.is_dirty and rec_b.exists()
    assert (tmp_path / "a" / "a_lights.json").exists()
