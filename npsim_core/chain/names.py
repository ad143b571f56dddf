"""The chain's named choices, importable without numpy (the command line's parser is built from
them; ``npsim --help`` must start in well under a second). :mod:`.params` uses them."""

from __future__ import annotations

__all__ = ["DEPTH_SOURCES", "LIGHT_SOURCES"]

#: Where the input depth comes from (docs/method.md §2.2); ``auto`` picks per frame.
DEPTH_SOURCES = ("auto", "files", "stereo", "network", "prior")

#: Where a frame's light annotation comes from (``lights.source``; docs/method.md §7.5).
LIGHT_SOURCES = ("auto", "annotation", "proposed", "none", "file")
