"""The main window on small screens, its remembered layout, the Cancel of long jobs and
annotation edits that leave the depth/3D views alone. Runs under Xvfb (1600x900)."""

from __future__ import annotations

import numpy as np
import pytest

from npsim_core.chain import ChainParams
from npsim_core.synthetic import street_scene
from npsim_core.synthetic.cityscapes import fixture_image

W, H = 128, 64


def _window(qtbot, *, with_3d: bool = False):
    from npsim_gui.main_window import MainWindow

    win = MainWindow(with_3d=with_3d)
    win.ask = lambda *a: "Discard"
    qtbot.addWidget(win)
    return win


def _long_job(chain=None, release=None):
    """A pipeline job that runs until cancelled (or ``release`` is set), holding the chain's lock
    as a running stage does (the real stages' length depends on the machine and the optimiser's
    stopping rule)."""
    from npsim_core.errors import NpsimCancelled

    def hold(cancel):
        while not cancel.wait(0.05):
            if release is not None and release.is_set():
                return

    def job(cancel, progress):
        progress({"stage": "refine"})
        if chain is not None:
            with chain._lock:
                hold(cancel)
        else:
            hold(cancel)
        raise NpsimCancelled("cancelled during stage 'refine'")
    return job


def _global_rect(w):
    from PySide6.QtCore import QRect

    return QRect(w.mapToGlobal(w.rect().topLeft()), w.size())


@pytest.mark.parametrize("size", [(1366, 768), (1600, 900)])
def test_every_panel_fits_the_screen(qtbot, settings, size):
    from PySide6.QtCore import QRect
    from PySide6.QtWidgets import QDockWidget

    win = _window(qtbot, with_3d=True)
    avail = QRect(0, 0, *size)
    win.fit_to(avail)
    win.move(0, 0)
    win.show()
    qtbot.waitExposed(win)
    qtbot.wait(50)
    hint = win.minimumSizeHint()
    assert hint.width() <= size[0] and hint.height() <= size[1]
    assert win.width() <= size[0] and win.height() <= size[1]
    shown = {}
    for d in win.findChildren(QDockWidget):
        if d.isVisible() and not d.visibleRegion().isEmpty():  # a dock behind a tab is off-screen
            r = _global_rect(d)
            assert avail.contains(r), (d.objectName(), r)
            shown[d.objectName()] = r
    assert avail.contains(_global_rect(win.centralWidget()))
    # parameters, the night preview and the log are always on screen; the 3D view shares a tab on
    # the small screen and has its own place on the larger one
    assert {"Parameters", "Night_preview", "Loss_and_log"} <= set(shown)
    assert ("3D_mesh" in shown) == (size[0] >= win.NARROW_SCREEN)
    assert win.night_preview_shown()
    win.close()


def test_layout_is_remembered_between_sessions(qtbot, settings):
    first = _window(qtbot)
    first.show()
    qtbot.waitExposed(first)
    first.log_dock.hide()
    avail = first.screen().availableGeometry()
    first.resize(avail.width() - 30, 700)  # fits whatever screen the tests run on
    qtbot.wait(50)
    size = (first.width(), first.height())
    assert size[1] == 700
    first.close()
    assert any(settings.rglob("*.conf")), "the layout was not written to the test's settings folder"
    second = _window(qtbot)  # the next session
    second.show()
    qtbot.waitExposed(second)
    assert second.log_dock.isHidden() and not second.params_dock.isHidden()
    assert (second.width(), second.height()) == size
    second.close()


def test_cancel_stops_a_running_job_and_returns_to_idle(qtbot, settings):
    from PySide6.QtCore import Qt

    win = _window(qtbot)
    win.show()
    qtbot.waitExposed(win)
    assert not win.act_cancel.isEnabled() and win.cancel_btn.isVisible()
    win.render_dock.hide()  # (the pipeline's jobs are cancelled here: no night preview needed first)
    win.set_scene(street_scene(W, H), ChainParams().with_value("refine", "steps", 20))
    qtbot.waitUntil(lambda: win.results is not None and win.results_final and not win.jobs_busy, timeout=120_000)
    win.pipeline_jobs.submit(_long_job(win.chain))  # a job only the cancel can end
    qtbot.waitUntil(lambda: "refine" in win.busy_label.text(), timeout=10_000)
    assert win.pipeline_jobs.is_busy and win.act_cancel.isEnabled()
    # Esc in the editor with nothing selected cancels (with a selection it clears it first)
    qtbot.keyClick(win.editor.canvas, Qt.Key.Key_Escape)
    qtbot.waitUntil(lambda: not win.jobs_busy, timeout=30_000)
    assert not win.act_cancel.isEnabled()
    assert "cancelled" in win.busy_label.text()
    # the button does the same for a new job
    win.pipeline_jobs.submit(_long_job())
    qtbot.waitUntil(lambda: win.act_cancel.isEnabled(), timeout=10_000)
    win.cancel_btn.click()
    qtbot.waitUntil(lambda: not win.jobs_busy, timeout=30_000)
    assert not win.act_cancel.isEnabled()
    win.close()


def test_annotation_edit_rebuilds_the_night_scene_only_for_a_shown_night_preview(qtbot, settings):
    from npsim_core.annotation_ops import new_instance, paint

    win = _window(qtbot)
    win.show()
    qtbot.waitExposed(win)
    params = ChainParams().with_value("refine", "steps", 20).with_value("night", "spp", 2) \
        .with_value("night", "preview_scale", 1.0)
    win.set_scene(street_scene(W, H), params)
    qtbot.waitUntil(lambda: win.results is not None and win.results_final and win.render_panel.night is not None
                    and not win.jobs_busy, timeout=120_000)
    results, night = win.results, win.render_panel.night
    runs = []
    orig = win.chain.engine.run

    def spy(until, params, **kw):
        run = orig(until, params, **kw)
        runs.append(list(run.recomputed))
        return run
    win.chain.engine.run = spy
    win.render_dock.hide()  # no lighting view on screen
    assert not win.night_preview_shown()
    s = win.editor.session
    cmd, iid = new_instance(s.ann, 8)
    s.apply(cmd)
    mask = np.zeros((H, W), bool)
    mask[5:9, 60:64] = True
    s.apply(paint(s.ann, mask, iid))
    qtbot.wait(800)  # longer than every debounce
    assert runs == [] and not win.jobs_busy  # nothing recomputed: no mesh, no views
    assert win.results is results and win.render_panel.night is night
    win.render_dock.show()  # the night preview comes back: the mesh and night scene follow the edit
    qtbot.waitUntil(lambda: win.render_panel.night is not night and not win.jobs_busy, timeout=120_000)
    assert iid in win.chain.annotation.instance_ids()  # the night used the edit
    done = [st for r in runs for st in r]
    assert "night_scene" in done and "mesh" not in done  # the lights never rebuild the mesh
    assert not {"geometry", "filter", "uncertain", "refine"} & set(done)
    assert win.results is results  # the depth, normal and 3D views stay as they were
    win.close()


def test_a_large_real_layout_frame_opens_with_its_proxy(qtbot, settings, cityscapes_layout, monkeypatch):
    """A Cityscapes-layout frame wider than the proxy width (its instanceIds included) opens and
    answers from the proxy chain. (A 128-px proxy width: a 192x96 frame is proxied as a 768x384 one
    is at the app's 512, without the fixture's stereo matching at 768x384.)"""
    from npsim_gui.main_window import MainWindow

    monkeypatch.setattr(MainWindow, "PROXY_WIDTH", 128)
    root, stems = cityscapes_layout(frames=1, size=(192, 96), corrupt=0)
    win = _window(qtbot)
    win.open_scene(fixture_image(root, stems[0]))
    assert getattr(win, "last_error", None) is None
    assert win.chain.scene.width == 192 and win.proxy_chain.scene.width == win.PROXY_WIDTH == 128
    assert win.editor.canvas.base.array.shape[:2] == (96, 192)
    win.cancel_jobs()
    qtbot.waitUntil(lambda: not win.jobs_busy, timeout=60_000)
    win.close()


def test_an_edit_during_a_long_job_does_not_wait_for_it(qtbot, settings):
    """The chain's lock is held by a running job: an annotation edit must not take it on the GUI thread.
    A guard releases the lock after 60 s so that a blocking edit fails the test instead of hanging it."""
    import threading

    from npsim_core.annotation_ops import new_instance

    win = _window(qtbot)
    win.show()
    qtbot.waitExposed(win)
    win.set_scene(street_scene(W, H), ChainParams().with_value("refine", "steps", 20))
    qtbot.waitUntil(lambda: win.results is not None and win.results_final and not win.jobs_busy, timeout=120_000)
    release = threading.Event()
    guard = threading.Timer(60.0, release.set)
    guard.start()
    win.pipeline_jobs.submit(_long_job(win.chain, release))  # holds the chain's lock until cancelled
    qtbot.waitUntil(lambda: "refine" in win.busy_label.text(), timeout=10_000)
    assert win.pipeline_jobs.is_busy
    s = win.editor.session
    s.apply(new_instance(s.ann, 8)[0])
    qtbot.wait(400)  # the edit's debounced night request included
    # the edit and its follow-ups ran while the job still held the lock
    assert not release.is_set() and win.pipeline_jobs.is_busy and len(s.ann.instance_ids()) > 0
    guard.cancel()
    win.cancel_jobs()
    qtbot.waitUntil(lambda: not win.jobs_busy, timeout=30_000)
    win.close()


def test_at_1600x900_the_canvas_is_the_largest_panel_and_the_side_panel_needs_no_scrolling(qtbot, settings):
    """The annotator's workspace gets the room: wider and larger than any dock, the editor's tabs
    (classes, instances, proposals, view) on screen without scrolling."""
    from PySide6.QtCore import QRect
    from PySide6.QtWidgets import QDockWidget

    win = _window(qtbot, with_3d=True)
    win.fit_to(QRect(0, 0, 1600, 900))
    win.move(0, 0)
    win.show()
    qtbot.waitExposed(win)
    big = np.zeros((1024, 2048, 3), np.uint8)  # a full-size frame in every view (no computation needed)
    win.editor.show_image(big)
    win.render_panel.set_day(big)
    win.render_panel.set_night(big, "16 spp · 11.31 s · llvm_ad_rgb · " + "a long render status " * 20)
    win.frames_dock.show()
    qtbot.wait(50)
    c = win.editor.canvas
    docks = [d for d in win.findChildren(QDockWidget) if d.isVisible() and not d.visibleRegion().isEmpty()]
    assert c.width() > 700
    for d in docks:
        assert c.width() * c.height() > d.width() * d.height(), d.objectName()
        if d is not win.log_dock:
            assert c.width() > d.width(), d.objectName()
    side = win.editor.side_panel
    tabs = win.editor.side_tabs
    for k in range(tabs.count()):
        tabs.setCurrentIndex(k)
        qtbot.wait(10)
        assert side.widget().minimumSizeHint().height() <= side.viewport().height(), tabs.tabText(k)
    win.close()


def test_superpixel_borders_are_hidden_at_fit_zoom_on_a_large_frame(qtbot):
    from npsim_gui.editor.editor import AnnotationEditor

    ed = AnnotationEditor()
    qtbot.addWidget(ed)
    ed.resize(1100, 700)
    ed.show()
    qtbot.waitExposed(ed)
    ed.load(np.zeros((1024, 2048, 3), np.uint8))
    ed.shutdown()  # the superpixels themselves are not needed here
    ed.canvas.fit()
    assert ed.layer_boxes["superpixels"].isChecked() and not ed.superpixel_borders_shown()
    assert not ed.canvas.layers["superpixels"].isVisible()
    ed.canvas.set_zoom(1.0)
    assert ed.superpixel_borders_shown() and ed.canvas.layers["superpixels"].isVisible()
