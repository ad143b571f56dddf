"""``npsim gui``: start the desktop app (on the built-in synthetic scene by default)."""

from __future__ import annotations

import os
import sys
from pathlib import Path


def has_display() -> bool:
    """True when Qt can open windows here (an X or Wayland display, or an explicit Qt platform)."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
                or os.environ.get("QT_QPA_PLATFORM"))


def _is_dataset_root(path) -> bool:
    """True for a folder of several frames (a dataset root), not one frame's or one scene's folder."""
    p = Path(path)
    if (p / "project.json").exists() or (p / "scene.json").exists() or (p / "intrinsics.json").exists():
        return False
    from npsim_core.chain import iter_frames
    from npsim_core.errors import NpsimInputError

    try:
        return len(iter_frames(p)) > 1
    except NpsimInputError:
        return False


def main(path: str | None = None, *, sample_size: tuple[int, int] = (512, 256), screenshot: str | None = None,
         quit_after: float | None = None) -> int:
    """Open the main window on ``path`` (scene folder, project folder, dataset image, or a dataset root whose
    frames go to the Frames dock) or the sample scene.

    ``screenshot``/``quit_after`` (seconds) support unattended runs: after the first
    render the window is grabbed to a PNG and the app exits.
    """
    from PySide6.QtCore import QTimer
    from PySide6.QtWidgets import QApplication

    from npsim_core.errors import NpsimInputError
    from npsim_core.chain import load_frame
    from npsim_core.chain.project import load_project

    from .main_window import MainWindow

    params = None
    dataset = None
    try:  # read the input before any window exists, so a bad path is a message, not a dialog
        if path is not None and Path(path).is_dir() and _is_dataset_root(path):
            dataset, scene = path, None  # a dataset root: its frames in the Frames dock, the first one opened
        elif path is None:
            from npsim_core.synthetic import street_scene

            scene = street_scene(*sample_size)
        elif (Path(path) / "project.json").exists():
            scene, params = load_project(path)
        else:
            scene = load_frame(path)
    except NpsimInputError as exc:
        print(f"npsim gui: error: {exc}", file=sys.stderr)
        return 2
    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("NPSim")
    win = MainWindow()
    win.show()
    if screenshot:  # the shot waits for the night: a saved layout may have its tab behind the 3D view's
        win.render_dock.show()
        win.render_dock.raise_()
    if dataset is not None:
        win.open_dataset(dataset)
    else:
        win.set_scene(scene, params)
    if screenshot or quit_after:
        def finish() -> None:
            if screenshot:
                win.grab().save(screenshot)
                print(f"npsim gui: screenshot -> {screenshot}", file=sys.stderr)
            win.confirm_close = lambda: True  # unattended: never block on a dialog
            win.close()
            app.quit()
        # timers with the window as context: they die with it instead of firing on a deleted window
        if screenshot:
            win.render_jobs.finished.connect(lambda *_: QTimer.singleShot(500, win, finish))
        QTimer.singleShot(int((quit_after or 600) * 1000), win, finish)
    return app.exec()
