"""Documentation screenshots of the app on real-layout frames (run under Xvfb).

``xvfb-run -a -s "-screen 0 1600x900x24" .venv/bin/python -m npsim_gui.app_screenshot docs/img``
writes ``app.png``: the main window at the screen's size on frame 0 of a
Cityscapes-layout dataset (``npsim_core.synthetic.cityscapes``, 2048x1024: image, labelIds,
stereo disparity, camera JSON) opened as a dataset root, once its full-resolution mesh and night
preview are shown, with its light proposals (Ctrl+P) and those at or above the slider's default
(``npsim_gui.editor.proposals.DEFAULT_ACCEPT_THRESHOLD``) accepted; and
``editor_proposals.png``: the stand-alone editor on the synthetic street
(1024x512) with light proposals, the sure ones (at or above that default) accepted, zoomed on a street
corner. ``--dataset ROOT`` uses an existing dataset instead of writing the fixture.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from PySide6.QtWidgets import QApplication

from .editor.proposals import DEFAULT_ACCEPT_THRESHOLD


def _wait(app: QApplication, cond, timeout: float = 1800.0) -> None:
    t0 = time.perf_counter()
    while not cond():
        app.processEvents()
        time.sleep(0.01)
        if time.perf_counter() - t0 > timeout:
            raise TimeoutError("the app did not get there in time")


def app_real_frame(app: QApplication, out: Path, dataset: Path | None, size: tuple[int, int]) -> None:
    from npsim_core.synthetic.cityscapes import write_cityscapes_fixture

    from .main_window import MainWindow

    if dataset is None:
        dataset = Path(tempfile.mkdtemp(prefix="npsim-shot-")) / "cityscapes"
        write_cityscapes_fixture(dataset, frames=3, size=size, corrupt=0)
    win = MainWindow()
    win.ask = lambda *a: "Discard"
    win.show()
    win.move(0, 0)
    _wait(app, win.isVisible)
    win.open_dataset(dataset)
    _wait(app, lambda: win.results is not None and win.results_final and not win.pipeline_jobs.is_busy)
    _wait(app, lambda: win.render_panel.night is not None and not win.render_jobs.is_busy)
    win.render_panel.split.setValue(35)  # the day / night split shows both
    win.editor.auto_display()
    ed = win.editor
    ed.actions_by_name["propose"].trigger()  # Ctrl+P: the proposals as a dashed layer, their tab shown
    _wait(app, lambda: ed.proposal_book is not None and not ed.proposal_jobs.is_busy)
    ed.confidence_slider.setValue(int(round(DEFAULT_ACCEPT_THRESHOLD * 100)))
    ed.accept_proposals_above()
    t0 = time.perf_counter()
    _wait(app, lambda: time.perf_counter() - t0 > 1.0 and not win.jobs_busy)  # the night with those lights
    t0 = time.perf_counter()
    _wait(app, lambda: time.perf_counter() - t0 > 1.5)
    if win.viewer is not None:
        win.viewer.plotter.render()
    app.processEvents()
    shot = win.screen().grabWindow(0)  # the whole X screen: the VTK view's GL content included
    shot.save(str(out))
    print(f"app screenshot -> {out} ({shot.width()}x{shot.height()})", file=sys.stderr)
    win.confirm_close = lambda: True
    win.close()


def editor_proposals(app: QApplication, out: Path) -> None:
    from npsim_core.proposals import propose_for_scene
    from npsim_core.scene import save_scene
    from npsim_core.synthetic import street_scene

    from .editor.screenshot import _open, _settle

    scene = street_scene(1024, 512)
    folder = save_scene(scene.with_(lights=None), Path(tempfile.mkdtemp(prefix="npsim-shot-")) / "street")
    win = _open(folder)
    win.resize(1500, 860)
    win.move(0, 0)
    _settle(app, win)
    ed = win.editor
    ed.set_proposals(propose_for_scene(scene))
    ed.accept_proposals_above(DEFAULT_ACCEPT_THRESHOLD)
    ed.canvas.set_zoom(2.2)
    ed.canvas.centerOn(330, 190)
    ed.side_tabs.setCurrentWidget(ed.proposals_box)  # the Proposals tab and its list
    t0 = time.perf_counter()
    _wait(app, lambda: time.perf_counter() - t0 > 0.5)
    win.grab().save(str(out))
    print(f"editor screenshot -> {out}", file=sys.stderr)
    ed.session.discard_recovery()
    win.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out_dir")
    ap.add_argument("names", nargs="*", default=["app", "proposals"])
    ap.add_argument("--dataset", default="")
    ap.add_argument("--size", default="2048x1024")
    args = ap.parse_args(argv)
    app = QApplication.instance() or QApplication(sys.argv[:1])
    from PySide6.QtCore import QSettings

    for fmt in (QSettings.Format.NativeFormat, QSettings.Format.IniFormat):  # fresh layout, user's settings untouched
        QSettings.setPath(fmt, QSettings.Scope.UserScope, tempfile.mkdtemp(prefix="npsim-settings-"))
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    w, h = (int(v) for v in args.size.split("x"))
    if "app" in args.names:
        app_real_frame(app, out / "app.png", Path(args.dataset) if args.dataset else None, (w, h))
    if "proposals" in args.names:
        editor_proposals(app, out / "editor_proposals.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
