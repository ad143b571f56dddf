"""Package attributes imported on first use (PEP 562), for packages whose modules pull in heavy
libraries (torch, Mitsuba) that the command line's start must not pay for."""

from __future__ import annotations

from importlib import import_module
from typing import Any, Callable


def lazy_exports(package: str, exports: dict[str, str]) -> Callable[[str], Any]:
    """A module-level ``__getattr__`` for ``package`` that imports ``exports[name]`` (a submodule
    name relative to the package) when ``name`` is first read and returns its attribute."""

    def __getattr__(name: str) -> Any:
        if name in exports:
            return getattr(import_module(f".{exports[name]}", package), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__
