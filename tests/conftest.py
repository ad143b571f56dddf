"""Suite-wide set-up: a private scene cache per session, and GUI tests skipped (not crashed) without a display.

GUI tests are the ones that use pytest-qt's ``qtbot``/``qapp`` fixtures or carry the ``gui`` marker.
Qt's xcb platform aborts the whole interpreter ("Fatal Python error") when it cannot open a display,
so whether one is usable is decided once, before any QApplication exists, and GUI items are skipped
with the reason otherwise (the napari / pyvistaqt practice).

Environment:
  ``NPSIM_TEST_SUBSET=headless``  skip the GUI tests even when a display is available.
  ``NPSIM_TEST_CACHE=<folder>``   keep the caches there between sessions (default: a temporary folder
                                  removed at the end of the session). Either way the scene cache
                                  (``NPSIM_CACHE``) and the Mitsuba variant probe's cache (under
                                  ``XDG_CACHE_HOME``) stay out of the user's ``~/.cache/npsim``.

Parallel runs (pytest-xdist: ``bash npsim.sh test -n 2 --dist loadfile``): the workers share
the controller's caches, and ``loadfile`` keeps a file's tests (and its module fixtures) on one worker.
The files are handed out longest first (``SLOW_FIRST``, then the rest in collection order), not by
xdist's count of tests a file holds: a file of a few long tests (the batch runner's, the fuzz test's
one) handed out last kept one worker busy for a minute after the other had finished.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile

import pytest

GUI_FIXTURES = frozenset({"qtbot", "qapp", "qtmodeltester"})
NO_DISPLAY = "no display: GUI tests need X (run 'bash npsim.sh test', which starts Xvfb)"
_tmp_key = pytest.StashKey[str]()
_saved_env_key = pytest.StashKey["dict[str, str | None]"]()
#: The session's cache root, handed to pytest-xdist workers through their environment.
_SHARED_ENV = "NPSIM_TEST_CACHE_ROOT"

# Opening the platform plugin is the only reliable test: a stale DISPLAY aborts Qt just like a missing one.
_PROBE = "from PySide6.QtGui import QGuiApplication; QGuiApplication([]); print('ok')"


def gui_skip_reason() -> str | None:
    """Why GUI tests cannot run in this process, or None when they can. Never creates a QApplication."""
    if os.environ.get("NPSIM_TEST_SUBSET", "").strip().lower() == "headless":
        return "NPSIM_TEST_SUBSET=headless: GUI tests skipped"
    platform = os.environ.get("QT_QPA_PLATFORM", "").split(":")[0].strip().lower()
    if platform in ("offscreen", "minimal"):
        return None  # explicitly chosen, needs no display
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return NO_DISPLAY
    try:
        r = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"cannot check the display ({exc}); {NO_DISPLAY}"
    if r.returncode != 0 or "ok" not in r.stdout:
        if "No module named" in r.stderr:
            return "PySide6 is not importable: GUI tests skipped"
        shown = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
        detail = next((ln.strip() for ln in r.stderr.splitlines() if "could not connect" in ln.lower()),
                      r.stderr.strip().splitlines()[-1] if r.stderr.strip() else f"exit {r.returncode}")
        return f"display {shown!r} cannot be opened by Qt ({detail}); {NO_DISPLAY}"
    return None


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "gui: needs a Qt display (skipped without one, or NPSIM_TEST_SUBSET=headless)")
    if hasattr(config.option, "loadscopereorder"):
        # pytest-xdist's loadfile/loadscope: hand the files out in the collection's order (SLOW_FIRST)
        config.option.loadscopereorder = False
    # Session-wide private caches: npsim_core.synthetic.cache_dir() reads NPSIM_CACHE, and
    # npsim_core.render.variant caches its probe under XDG_CACHE_HOME (read at import, so set it here,
    # before collection imports anything; subprocesses started by tests inherit both).
    keep = os.environ.get("NPSIM_TEST_CACHE")
    shared = os.environ.get(_SHARED_ENV) if os.environ.get("PYTEST_XDIST_WORKER") else None
    if shared:
        # a pytest-xdist worker: the controller's caches (inherited environment), so each scene and
        # the variant probe are made once for all workers (the scene cache is safe for concurrent use)
        root = shared
    elif keep:
        root = os.path.abspath(keep)
    else:
        root = tempfile.mkdtemp(prefix="npsim-test-cache-")
        config.stash[_tmp_key] = root
    env = {"NPSIM_CACHE": os.path.join(root, "scenes"), "XDG_CACHE_HOME": os.path.join(root, "xdg"),
           _SHARED_ENV: root}
    config.stash[_saved_env_key] = {k: os.environ.get(k) for k in env}
    for k, v in env.items():
        os.makedirs(v, exist_ok=True)
        os.environ[k] = v


def pytest_unconfigure(config: pytest.Config) -> None:
    for k, v in config.stash.get(_saved_env_key, {}).items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v
    if _tmp_key in config.stash:
        shutil.rmtree(config.stash[_tmp_key], ignore_errors=True)


#: The test files that take longest (their tests' summed time, waits for subprocesses and GUI events
#: included; session 22 at 2 workers), longest first. Handed out first, so that the last files to
#: finish are short ones and both workers end together. A file not listed runs after these.
SLOW_FIRST = ("test_batch", "test_app", "test_proposals_fuzz", "test_geometry", "test_silent_paths",
              "test_realism", "test_hard_inputs", "test_lights_source", "test_render", "test_synthetic",
              "test_gui_responsiveness", "test_gui_layout", "test_denoisers", "test_night_artefacts",
              "test_editor", "test_gui_annotation_files")


#: The files with GUI tests. Both workers share one X display (xvfb-run), so a window one worker
#: shows can take the pointer from under the other's (a leave event cleared the editor's hover while
#: a test waited for it): loadfile hands these files to one worker as one unit, one after the other.
GUI_FILES = ("test_app", "test_gui_responsiveness", "test_gui_layout", "test_denoisers", "test_editor",
             "test_gui_annotation_files", "test_gui_keymap", "test_gui_proposals", "test_proposals",
             "test_vehicle_groups")


def _file_stem(nodeid: str) -> str:
    return nodeid.split("::", 1)[0].rsplit("/", 1)[-1].removesuffix(".py")


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadfile`` with the GUI files (``GUI_FILES``) as one scope."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class GuiFilesTogether(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return "GUI files" if _file_stem(nodeid) in GUI_FILES else super()._split_scope(nodeid)

    return GuiFilesTogether(config, log)


def _slow_rank(item: pytest.Item) -> int:
    name = _file_stem(item.nodeid)
    return SLOW_FIRST.index(name) if name in SLOW_FIRST else len(SLOW_FIRST)


def _is_gui(item: pytest.Item) -> bool:
    return bool(GUI_FIXTURES.intersection(getattr(item, "fixturenames", ()))) or \
        item.get_closest_marker("gui") is not None


@pytest.hookimpl(tryfirst=True)  # before --lf/--ff's reordering, which then still applies
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    items.sort(key=_slow_rank)  # stable: each file's tests keep their order, the other files theirs
    gui = [it for it in items if _is_gui(it)]
    if not gui:
        return  # no probe when no GUI test was selected
    reason = gui_skip_reason()
    if reason is None:
        return
    skip = pytest.mark.skip(reason=reason)
    for it in gui:
        it.add_marker(skip)


@pytest.fixture(scope="session")
def cityscapes_layout(tmp_path_factory):
    """A factory of Cityscapes-layout datasets from the synthetic street (stereo, no ground truth):
    ``cityscapes_layout(frames=, size=, corrupt=)`` -> (root, frame stems), a new folder each call
    (a test may write into it). The fixture writer is deterministic (tests/test_cityscapes_fixture.py,
    same arguments same bytes), so each set of arguments is written once per process and copied
    after that (the stereo matching is most of the cost)."""
    written: dict[tuple, tuple] = {}

    def make(*, frames: int, size: tuple[int, int], corrupt: int):
        from npsim_core.synthetic.cityscapes import write_cityscapes_fixture

        key = (frames, tuple(size), corrupt)
        if key not in written:
            src = tmp_path_factory.mktemp("cityscapes-written")
            written[key] = (src, list(write_cityscapes_fixture(src, frames=frames, size=size, corrupt=corrupt)))
        src, stems = written[key]
        root = tmp_path_factory.mktemp("cityscapes")
        shutil.copytree(src, root, dirs_exist_ok=True)
        return root, list(stems)

    return make


@pytest.fixture(scope="session")
def sgm_frame(tmp_path_factory):
    """One 256x128 Cityscapes-layout frame with SGM stereo (the fixture's default) and its exact
    depth, written outside the dataset: (scene, exact depth in metres)."""
    import numpy as np

    from npsim_core.datasets import open_dataset
    from npsim_core.synthetic.cityscapes import write_cityscapes_fixture

    root = tmp_path_factory.mktemp("sgm")
    truth = tmp_path_factory.mktemp("truth")
    stem = write_cityscapes_fixture(root, frames=1, size=(256, 128), corrupt=0, truth=truth)[0]
    return open_dataset(root)[0].load(), np.load(truth / f"{stem}_depth.npy")


@pytest.fixture
def settings(tmp_path, monkeypatch):
    """Every QSettings of a GUI test and the annotations folder in a temporary folder: the
    user's window layout and saved annotations are never touched. Returns the settings folder."""
    from PySide6.QtCore import QSettings

    for fmt in (QSettings.Format.NativeFormat, QSettings.Format.IniFormat):
        QSettings.setPath(fmt, QSettings.Scope.UserScope, str(tmp_path / "settings"))
    monkeypatch.setenv("NPSIM_ANNOTATIONS", str(tmp_path / "annotations"))
    return tmp_path / "settings"


@pytest.fixture(scope="module")
def street():
    """A 64x32 synthetic street (a module's CLI and hard-input tests share it)."""
    from npsim_core.synthetic import street_scene

    return street_scene(64, 32)


@pytest.fixture(scope="module")
def scene_dir(street, tmp_path_factory):
    """``street`` saved as a scene folder."""
    from npsim_core.scene import save_scene

    return save_scene(street, tmp_path_factory.mktemp("scene") / "street")

