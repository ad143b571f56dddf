"""Exceptions raised at NPSim's boundaries (files, CLI, GUI)."""

from __future__ import annotations


class NpsimInputError(ValueError):
    """Bad user input: a file, array or parameter that cannot be used.

    The message always names the offending file or field and says how to fix it.
    """


class NpsimCancelled(RuntimeError):
    """A long computation was cancelled by its caller (e.g. a GUI slider moved)."""
