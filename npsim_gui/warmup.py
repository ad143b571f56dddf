"""Import at start-up what the first pipeline and night would import in a worker thread.

Importing an extension module (dlopen and its initialisation: Mitsuba's variant and Dr.Jit's
libraries, ~0.1-0.2 s) or compiling a module holds the GIL for the whole call, so the GUI thread,
which needs the GIL for every paint and slot, froze for 150-310 ms after a frame was opened
while a worker imported them. Done before the window is shown, they only lengthen the start-up.
pyoidn (cffi, ~1 s of mostly pure-Python parsing that yields the GIL) is imported in a thread.
"""

from __future__ import annotations

import importlib
import threading

#: npsim_core modules the chain's stages import lazily (found by comparing ``sys.modules`` before
#: and after the first pipeline and night of a 2048x1024 frame).
CORE_MODULES = (
    "npsim_core.datasets", "npsim_core.geometry", "npsim_core.geometry.files", "npsim_core.geometry.network",
    "npsim_core.geometry.popup", "npsim_core.geometry.stereo", "npsim_core.refine.optimize",
    "npsim_core.refine.gauss_newton",
    "npsim_core.mesh.reduce", "npsim_core.mesh.postprocess", "npsim_core.proposals", "npsim_core.render.ego",
    "npsim_core.render.render", "npsim_core.render.scene_builder", "npsim_core.render.denoise",
    "npsim_core.render.camera_post",
)
#: Imported in a background thread (slow, but yield the GIL).
THREADED_MODULES = ("pyoidn",)

_done: dict[str, object] = {}


def _try_import(name: str) -> bool:
    try:
        importlib.import_module(name)
        return True
    except Exception:  # noqa: BLE001 -- an optimisation only: the stage reports a missing module itself
        return False


def warm_up() -> list[str]:
    """Import the chain's lazily imported modules and the Mitsuba variant the night will use (once
    per process; call before the first window is shown).

    Returns
    -------
    list of str
        The modules imported on this thread (empty after the first call).
    """
    if _done:
        return []
    _done["started"] = True
    loaded = [m for m in CORE_MODULES if _try_import(m)]
    try:
        from npsim_core.render.variant import resolve_variant

        # the variant's module only: the active variant (a process-wide setting) is left as it is
        variant = f"mitsuba.{resolve_variant().name}"
        if _try_import(variant):
            loaded.append(variant)
    except Exception:  # noqa: BLE001 -- no Mitsuba: the night preview says so when asked
        pass
    t = threading.Thread(target=lambda: [_try_import(m) for m in THREADED_MODULES], name="npsim-warmup",
                         daemon=True)
    t.start()
    _done["thread"] = t
    return loaded
