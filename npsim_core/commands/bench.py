"""``npsim bench TARGET [ARGS...]``: run a speed-against-error benchmark.

Each target is a script ``benchmarks/<target>.py`` in the source tree with a
``main(argv) -> int`` function (e.g. ``refine``, ``mesh``, ``render``); adding a
benchmark means adding such a file, nothing here. Everything after TARGET is
passed to its ``main`` (``npsim bench refine --help`` shows the target's options).
"""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

from ..errors import NpsimInputError


def benchmarks_dir() -> Path:
    """``benchmarks/`` next to the ``npsim_core`` package (source checkout / editable install)."""
    return Path(__file__).resolve().parents[2] / "benchmarks"


def available() -> list[str]:
    d = benchmarks_dir()
    return sorted(p.stem for p in d.glob("*.py") if not p.stem.startswith("_")) if d.is_dir() else []


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="run a benchmark script (benchmarks/<target>.py)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("target", help="benchmark name: " + (", ".join(available()) or "none found"))
    p.add_argument("args", nargs=argparse.REMAINDER, help="arguments for the benchmark's main()")
    p.set_defaults(func=run)


def load_benchmark(target: str):
    """Import ``benchmarks/<target>.py`` as a module."""
    path = benchmarks_dir() / f"{target}.py"
    if not target.isidentifier() or not path.is_file():
        raise NpsimInputError(f"unknown benchmark {target!r}; available: {', '.join(available()) or 'none'} "
                              f"(scripts in {benchmarks_dir()})")
    spec = importlib.util.spec_from_file_location(f"npsim_benchmark_{target}", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    if not hasattr(mod, "main"):
        raise NpsimInputError(f"benchmark {path} has no main(argv) function")
    return mod


def run(args: argparse.Namespace) -> int:
    return int(load_benchmark(args.target).main(list(args.args)) or 0)
