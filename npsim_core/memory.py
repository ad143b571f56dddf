"""Hand the pages of freed arrays back to the system after each job or stage.

A 2048x1024 frame passes hundreds of arrays of 1-50 MB through the chain (in the app, through
its worker threads).
glibc's malloc raises its mmap threshold after such an array is freed (up to 32 MB), so later
ones come from the heap and the per-thread arenas, where freed memory stays resident: after
the pipeline job the app held ~0.4 GB it no longer used, on top of which the night render
reached its peak (2.83 GB; with :func:`release_free_memory` after each job 2.43 GB, the same
as a fixed 1-4 MB mmap threshold without its page-fault cost on every large temporary).
"""

from __future__ import annotations

import ctypes
import sys

_state: dict[str, object] = {}


def _glibc():
    """glibc's C library (None elsewhere: other allocators keep their own policy)."""
    if "lib" not in _state:
        lib = None
        if sys.platform.startswith("linux"):
            try:
                cand = ctypes.CDLL("libc.so.6")
                lib = cand if hasattr(cand, "malloc_trim") else None
            except OSError:
                lib = None
        _state["lib"] = lib
    return _state["lib"]


def release_free_memory() -> bool:
    """Return the free pages of every malloc arena to the system (``malloc_trim(0)``).

    Call it when a job or a stage has ended (its temporaries are gone) -- in the app off the GUI
    thread: it walks every arena, a few ms with a large heap.

    Returns
    -------
    bool
        True when memory was released, False when there was none to release or the C
        library is not glibc.
    """
    lib = _glibc()
    return bool(lib is not None and lib.malloc_trim(0))
