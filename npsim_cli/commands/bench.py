"""``npsim bench TARGET [ARGS...]``: run a speed-against-error benchmark.

Each target is a module ``benchmarks/<target>.py`` of the source checkout with a
``main(argv) -> int`` function (e.g. ``refine``, ``mesh``, ``render``); adding a
benchmark means adding such a module, nothing here. Everything after TARGET is
passed to its ``main`` (``npsim bench refine --help`` shows the target's options).
The same runs as ``python -m benchmarks.<target>`` from the repository.
"""

from __future__ import annotations

import argparse
import importlib

from npsim_core.errors import NpsimInputError


def available() -> list[str]:
    try:
        import benchmarks
    except ImportError:
        return []
    return benchmarks.available()


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="run a benchmark (benchmarks/<target>.py)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("target", help="benchmark name: " + (", ".join(available()) or "none found"))
    p.add_argument("args", nargs=argparse.REMAINDER, help="arguments for the benchmark's main()")
    p.set_defaults(func=run)


def load_benchmark(target: str):
    """Import ``benchmarks.<target>``."""
    names = available()
    if target not in names:
        raise NpsimInputError(f"unknown benchmark {target!r}; available: {', '.join(names) or 'none'} (the "
                              "benchmarks ship with the source checkout: install it with 'bash npsim.sh setup')")
    mod = importlib.import_module(f"benchmarks.{target}")
    if not hasattr(mod, "main"):
        raise NpsimInputError(f"benchmark {target} has no main(argv) function")
    return mod


def run(args: argparse.Namespace) -> int:
    return int(load_benchmark(args.target).main(list(args.args)) or 0)
