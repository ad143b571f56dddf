"""The desktop app driven as a person would: open the sample scene, move sliders, wait for the
mesh and the night preview, toggle lights, export, and check the files on disk.

Runs under Xvfb (the README's test command starts it) so the pyvista view really renders.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np
import pytest

os.environ.setdefault("XDG_CONFIG_HOME", tempfile.mkdtemp(prefix="npsim-test-config-"))


from npsim_core.synthetic import street_scene  # noqa: E402
from npsim_core.chain import ChainParams  # noqa: E402
from npsim_core.synthetic.cityscapes import fixture_image

W, H = 128, 64


@pytest.fixture(scope="module")
def scene():
    return street_scene(W, H)


#: Tests of the pipeline, the views, the project and the night-less exports never read the night preview:
#: they run with its dock closed (as a person may close it), so no preview is rendered when the scene
#: opens or after each change (~1-2 s of Mitsuba per window and per change). (The export with a night
#: keeps the preview: without it the export builds the night scene itself, no quicker.)
preview_closed = pytest.mark.parametrize("window", ["preview closed"], indirect=True)


@pytest.fixture
def window(qtbot, scene, request):
    from npsim_gui.main_window import MainWindow

    night = getattr(request, "param", None) != "preview closed"
    win = MainWindow()
    win.ask = lambda title, text, buttons: "Discard"
    qtbot.addWidget(win)
    win.show()
    if not night:
        win.save_layout = lambda: None  # (the closed dock is not remembered for the next test's window)
        win.render_dock.hide()
        assert not win.night_preview_shown()
    # keep the test quick: a short refinement and a tiny preview
    params = ChainParams().with_value("refine", "steps", 40).with_value("night", "spp", 4) \
                             .with_value("night", "preview_scale", 1.0).with_value("night", "final_spp", 4)
    win.set_scene(scene, params)
    qtbot.waitUntil(lambda: win.results is not None and win.results.mesh is not None, timeout=120_000)
    if night:
        qtbot.waitUntil(lambda: win.render_panel.night is not None, timeout=120_000)
    yield win
    if not night:
        assert win.render_panel.night is None  # no preview was rendered behind the test's back
    win.close()


def test_opens_scene_builds_mesh_and_renders(window, scene):
    r = window.results
    assert r.mesh.n_faces > 1000
    assert set(r.recomputed) <= {"filter", "uncertain", "refine", "lights", "mesh"}
    night = window.render_panel.night
    assert night.shape == (H, W, 3)
    # a night: far darker than the day photo but not black (lights and ego headlights)
    assert 2 < night.mean() < 0.6 * scene.image.mean()
    # the 3D view rendered something (not a blank background)
    shot = window.viewer.screenshot()
    assert shot.std() > 5
    assert "street" in window.windowTitle()
    # The walls closing depth steps are their own layer in the 3D view, and can be hidden.
    d = window.viewer.display
    assert d.walls is not None and d.walls.n_cells > 0
    assert d.walls.n_cells + d.background.n_cells + d.foreground.n_cells == window.viewer.mesh.n_faces
    window.viewer.show_walls.setChecked(False)
    window.viewer.show_walls.setChecked(True)


def _record_results(window):
    """Wrap the window's result display to record (recomputed stages, final?) per update."""
    seen = []
    orig = window._show_results

    def spy(res, t0, *, final, **kw):
        seen.append((list(res.recomputed), final))
        return orig(res, t0, final=final, **kw)
    window._show_results = spy
    return seen


@preview_closed
def test_lambda_slider_recomputes_only_refine_and_mesh(window, qtbot):
    seen = _record_results(window)
    slider = window.params_panel.sliders[("refine", "lambda2")]
    slider.slider.setValue(slider.slider.value() + 40)  # as a drag would
    qtbot.waitUntil(lambda: bool(seen) and seen[-1][1] and not window.pipeline_jobs.is_busy, timeout=120_000)
    # first a quick refinement (time budget) for the 2D views, then the full one with its mesh
    assert seen[0] == (["refine"], False)
    assert seen[-1] == (["refine", "mesh"], True)
    assert window.params.refine.lambdas[1] == pytest.approx(slider.value())
    assert window.loss_plot.series.get("total")


@preview_closed
def test_filter_slider_recomputes_from_filter(window, qtbot):
    seen = _record_results(window)
    s = window.params_panel.sliders[("filter", "sigma_s")]
    s.spin.setValue(6.0)
    qtbot.waitUntil(lambda: bool(seen) and seen[-1][1] and not window.pipeline_jobs.is_busy, timeout=120_000)
    assert seen[0] == (["filter", "uncertain", "refine"], False)
    assert seen[-1] == (["refine", "mesh"], True)  # filter and U come from the quick pass's cache
    assert window.params.filter.sigma_s == 6.0


@preview_closed
def test_view_modes_show_in_the_canvas(window, qtbot):
    from npsim_core.views import view_image

    for mode in ("refined depth", "uncertain map", "normal error vs GT"):
        window.view_mode.setCurrentText(mode)
        want = view_image(window.chain.scene, window.results, mode)
        qtbot.waitUntil(lambda: np.array_equal(window.editor.canvas.base.array[..., :3], want), timeout=30_000)


def test_light_toggle_rerenders_with_that_light_off(window, qtbot):
    tree = window.render_panel.lights
    assert tree.topLevelItemCount() > 0
    state = window.render_panel.light_state()
    on = [i for i, v in state.items() if v]
    assert on, "the sample scene has lights on at seed 0"
    before = window.render_panel.night
    forced = {i: False for i in state}  # switch everything off
    window.on_lights_toggled(forced)
    qtbot.waitUntil(lambda: window.render_panel.night is not before and window.render_jobs.is_busy is False,
                    timeout=120_000)
    assert window.render_panel.night.mean() < before.mean()


def test_export_writes_all_outputs(window, qtbot, tmp_path):
    window.export(tmp_path, nights=1, show_progress=False)
    qtbot.waitUntil(lambda: hasattr(window, "last_export"), timeout=180_000)
    names = {p.name for p in window.last_export}
    n = window.chain.scene.name
    for expected in (f"{n}_labelIds.png", f"{n}_depth_refined.png", f"{n}_normals_refined_vis.png",
                     f"{n}_mesh.glb", f"{n}_night_0.png", f"{n}_night_0_labelIds.png",
                     f"{n}_lights_instanceIds.png", f"{n}_export.json"):
        assert expected in names
        assert (tmp_path / expected).stat().st_size > 0
    from npsim_core.io import read_label_image

    assert np.array_equal(read_label_image(tmp_path / f"{n}_night_0_labelIds.png"), window.chain.scene.labels)


def test_bad_scene_path_is_a_message_not_a_crash(qtbot, tmp_path, scene):
    from npsim_gui.main_window import MainWindow

    window = MainWindow(with_3d=False)  # (no mesh or night needed: the open fails before any work)
    qtbot.addWidget(window)
    window.set_scene(scene, ChainParams().with_value("refine", "steps", 5))
    window.open_scene(tmp_path / "does-not-exist")
    assert "not found" in window.last_error
    assert window.chain is not None and window.chain.scene is scene  # the old scene stays open
    window.cancel_jobs()
    qtbot.waitUntil(lambda: not window.jobs_busy, timeout=60_000)
    window.close()


@preview_closed
def test_project_round_trip(window, qtbot, tmp_path):
    from npsim_core.chain.project import load_project

    window.params_panel.sliders[("refine", "lambda3")].spin.setValue(2.5)
    qtbot.waitUntil(lambda: window.params.refine.lambdas[2] == 2.5, timeout=10_000)
    window.save_project(tmp_path / "proj")
    scene, params = load_project(tmp_path / "proj")
    assert params.refine.lambdas[2] == 2.5
    assert params.refine.steps == 40
    assert np.array_equal(scene.labels, window.chain.scene.labels)
    assert scene.lights is not None and scene.lights.instance_ids() == window.chain.scene.lights.instance_ids()


def test_window_filter_passes_events_of_objects_pyside_cannot_treat_as_qobjects(qtbot, settings):
    """The window's application-wide event filter sees events of watched objects that PySide hands
    over as a non-QObject (the 3D view's QSurface with a timer event, seen in CI): it lets them
    pass instead of raising in the Qt event loop (which failed a test's setup)."""
    from PySide6.QtCore import QTimerEvent

    from npsim_gui.main_window import MainWindow

    window = MainWindow()  # with its 3D view; no scene needed to call the filter
    qtbot.addWidget(window)
    window.show()
    assert window.eventFilter(object(), QTimerEvent(1)) is False
    window.close()


def test_a_closed_3d_view_lets_go_of_its_gl_surface_wrapper(qtbot, settings):
    """The 3D view's GL surface is no QObject: PySide never learns of its deletion, and while a
    closed window's Python object lived on, the stale wrapper claimed the address, so the next Qt
    object allocated there came back as a ``QSurface`` (a dock's toggle action in CI: a failed
    window construction). Closing the window must drop and invalidate that wrapper."""
    import shiboken6

    from npsim_gui.main_window import MainWindow

    window = MainWindow()
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    window.viewer_dock.show()
    window.viewer_dock.raise_()
    window.viewer.request_render()
    interactor = window.viewer.plotter.interactor
    qtbot.waitUntil(lambda: getattr(interactor, "_surface", None) is not None, timeout=10_000)
    surface = interactor._surface  # initializeGL ran: the wrapper exists
    assert shiboken6.isValid(surface)
    window.close()
    assert interactor._surface is None
    assert not shiboken6.isValid(surface)  # its address no longer maps to a QSurface


@preview_closed
def test_fov_slider_shows_scene_fov_and_changes_intrinsics(window, qtbot, scene):
    fov = window.params_panel.sliders[("camera", "hfov_deg")]
    assert fov.value() == pytest.approx(scene.intrinsics.hfov_deg, abs=0.1)
    seen = _record_results(window)
    fov.spin.setValue(70.0)
    qtbot.waitUntil(lambda: bool(seen) and seen[-1][1] and not window.pipeline_jobs.is_busy, timeout=120_000)
    assert window.results.intrinsics.hfov_deg == pytest.approx(70.0)
    assert seen[0][0] == ["geometry", "filter", "uncertain", "refine"]  # new camera: everything is recomputed


def test_unsaved_annotation_is_recovered_after_a_crash(qtbot, tmp_path, scene):
    """Edits autosaved by a session that died are offered back when the scene is opened again."""
    from npsim_core.annotation import write_recovery
    from npsim_core.scene import load_scene, save_scene
    from npsim_gui.main_window import MainWindow

    folder = save_scene(scene, tmp_path / "s")
    edited = scene.lights.copy()
    victim = edited.instance_ids()[0]
    edited.instance_map[edited.instance_map == victim] = 0  # the crashed session erased one light
    edited.groups = {g: type(x)(x.id, tuple(m for m in x.members if m != victim))
                     for g, x in edited.groups.items() if any(m != victim for m in x.members)}
    write_recovery(edited, folder, scene.name)
    win = MainWindow(with_3d=False)
    qtbot.addWidget(win)
    asked = []
    win.ask = lambda title, text, buttons: asked.append(title) or "Restore"
    win.set_scene(load_scene(folder), ChainParams().with_value("refine", "steps", 5))
    assert asked == ["Recover unsaved edits"]
    assert victim not in win.editor.session.ann.instance_ids()
    assert win.editor.session.is_dirty and win.windowTitle().endswith("*")
    assert victim not in win.chain.annotation.instance_ids()
    win.confirm_close = lambda: True
    win.close()


@pytest.mark.parametrize("cmd", [["gui"], ["annotate", "."]])
def test_gui_commands_without_display_say_so(cmd, tmp_path):
    """Without a display the GUI commands explain what to do instead of letting Qt abort."""
    import subprocess
    import sys

    from npsim_core.scene import save_scene

    save_scene(street_scene(W, H), tmp_path)
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    r = subprocess.run([sys.executable, "-m", "npsim_cli", *cmd], cwd=tmp_path, env=env, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 2, r.stderr[-800:]
    assert "no display" in r.stderr


def test_last_scene_is_remembered_between_runs(qtbot, tmp_path, scene):
    from npsim_core.scene import save_scene
    from npsim_gui.main_window import MainWindow

    folder = save_scene(scene.with_(name="remembered"), tmp_path / "r")
    first = MainWindow(with_3d=False)
    qtbot.addWidget(first)
    first.open_scene(folder)
    assert first.chain.scene.name == "remembered"
    first.close()
    second = MainWindow(with_3d=False)  # a new run of the app
    qtbot.addWidget(second)
    second.reopen_last()
    assert second.chain is not None and second.chain.scene.name == "remembered"
    second.close()


@preview_closed
def test_export_twice_reports_once_each(window, qtbot, tmp_path):
    logged = []
    window.log.log = lambda text, _orig=window.log.log: (logged.append(text), _orig(text))
    for k in (1, 2):
        before = getattr(window, "export_reports", 0)
        window.export(tmp_path / f"e{k}", nights=0, show_progress=False)
        qtbot.waitUntil(lambda: getattr(window, "export_reports", 0) == before + 1, timeout=120_000)
        qtbot.wait(200)
    exported = [t for t in logged if t.startswith("exported")]
    assert len(exported) == 2 and str(tmp_path / "e1") in exported[0] and str(tmp_path / "e2") in exported[1]


@pytest.fixture(scope="module")
def real_layout(cityscapes_layout):
    return cityscapes_layout(frames=2, size=(W, H), corrupt=0)


def test_opens_a_real_layout_frame_by_image_and_by_dataset_root(qtbot, real_layout):
    from npsim_gui.main_window import MainWindow

    root, stems = real_layout
    win = MainWindow(with_3d=False)
    win.ask = lambda *a: "Discard"
    qtbot.addWidget(win)
    win.params = ChainParams().with_value("refine", "steps", 5).with_value("night", "spp", 2)
    win.open_scene(fixture_image(root, stems[0]))
    qtbot.waitUntil(lambda: win.results is not None and win.results.mesh is not None, timeout=120_000)
    assert win.chain.scene.name == stems[0] and win.results.depth_source.startswith("stereo")
    win.open_dataset(root)
    assert win.frame_list.count() == 2 and not win.frames_dock.isHidden()
    assert win.chain.scene.name == stems[0]
    win.step_frame(+1)
    assert win.chain.scene.name == stems[1] and win.frame_list.currentRow() == 1
    win.step_frame(+1)  # past the end: stays on the last frame
    assert win.chain.scene.name == stems[1]
    qtbot.waitUntil(lambda: win.results is not None and win.results.scene is win.chain.scene, timeout=120_000)
    win.close()


def test_large_frames_answer_sliders_from_a_proxy(qtbot, monkeypatch):
    from npsim_gui.main_window import MainWindow

    # the proxy rule does not depend on the size: a 128-px proxy width keeps the frames small
    # (a 192x96 frame is proxied as a 768x384 one is at the app's 512; the sliders answer the same way)
    monkeypatch.setattr(MainWindow, "PROXY_WIDTH", 128)
    big = street_scene(192, 96)
    win = MainWindow(with_3d=False)
    win.ask = lambda *a: "Discard"
    qtbot.addWidget(win)
    win.FULL_RES_SETTLE_S = 0.3
    win.set_scene(big, ChainParams().with_value("night", "spp", 1))
    qtbot.waitUntil(lambda: win.results is not None and win.results_final, timeout=180_000)
    assert win.proxy_chain is not None and win.proxy_chain.scene.width == MainWindow.PROXY_WIDTH
    full = win.results
    logged = []
    win.log.log = lambda text, _orig=win.log.log: (logged.append(text), _orig(text))
    win.on_param_changed("refine", "lambda2", 3.0)
    qtbot.waitUntil(lambda: any("proxy" in t for t in logged), timeout=60_000)
    assert win.results is full  # the proxy result is shown, never kept
    assert win.editor.canvas.base.array.shape[:2] == (96, 192)
    qtbot.waitUntil(lambda: win.results is not full and win.results_final, timeout=180_000)
    assert win.results.depth.shape == (96, 192)
    win.close()


@preview_closed
def test_export_of_an_unchanged_frame_reuses_the_last_one_and_asks_before_overwriting(window, qtbot, tmp_path):
    logged, asked = [], []
    window.log.log = lambda text, _orig=window.log.log: (logged.append(text), _orig(text))
    window.ask = lambda title, text, buttons: asked.append(title) or "Cancel"
    calls = []
    import npsim_core.chain as chain_mod

    real = chain_mod.export_frame
    chain_mod.export_frame = lambda *a, **k: calls.append(1) or real(*a, **k)
    try:
        for k in (1, 2):
            before = getattr(window, "export_reports", 0)
            window.export(tmp_path / f"e{k}", nights=0, show_progress=False)
            qtbot.waitUntil(lambda: getattr(window, "export_reports", 0) == before + 1, timeout=120_000)
        assert len(calls) == 1 and "nothing recomputed" in logged[-1]  # the second was copied
        n = window.chain.scene.name
        a, b = (tmp_path / "e1" / f"{n}_depth_refined.png"), (tmp_path / "e2" / f"{n}_depth_refined.png")
        assert a.read_bytes() == b.read_bytes()
        before = getattr(window, "export_reports", 0)
        window.export(tmp_path / "e1", nights=0, show_progress=False)  # already an export there: Cancel
        assert asked == ["Overwrite the export?"] and not window.export_jobs.is_busy
        assert getattr(window, "export_reports", 0) == before
    finally:
        chain_mod.export_frame = real


def test_an_unattended_screenshot_shows_the_night_preview_whatever_the_saved_layout(qtbot, settings, monkeypatch):
    """`npsim gui --screenshot` grabs the window after the first night render; the render runs only while
    the preview is on screen, so with a saved layout that put the 3D view's tab in front it never came
    and the shot waited for the 600 s fallback."""
    from PySide6.QtWidgets import QApplication

    from npsim_gui import app as app_mod
    from npsim_gui.main_window import MainWindow

    first = MainWindow()
    qtbot.addWidget(first)
    first.show()
    qtbot.waitExposed(first)
    first.viewer_dock.show()
    first.viewer_dock.raise_()  # the 3D view's tab in front of the night preview's
    qtbot.waitUntil(lambda: not first.night_preview_shown(), timeout=5_000)
    first.close()  # saves the layout

    shown = []
    real_show = MainWindow.show

    def show(self):
        shown.append(self)
        real_show(self)

    monkeypatch.setattr(MainWindow, "show", show)
    monkeypatch.setattr(QApplication, "exec", lambda self: 0)  # the test drives the event loop itself
    assert app_mod.main(None, sample_size=(128, 64), screenshot=str(settings / "shot.png")) == 0
    win = shown[-1]
    qtbot.addWidget(win)
    win.ask = lambda *a: "Discard"
    qtbot.waitUntil(win.night_preview_shown, timeout=5_000)
    win.close()
