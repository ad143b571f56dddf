"""The ``npsim`` command line.

Sub-commands live in ``npsim_cli/commands/<name>.py``; each module defines
``register(subparsers)`` which adds its parser and sets ``func(args) -> int``.
Errors in the input (:class:`~npsim_core.errors.NpsimInputError`) and in the file
system (a folder that cannot be written, ...) print one line and exit 2.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from npsim_core.errors import NpsimCancelled, NpsimInputError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="npsim", description="NPSim: daytime driving scenes -> labelled nights")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    from . import commands

    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        mod = importlib.import_module(f"{commands.__name__}.{info.name}")
        if hasattr(mod, "register"):
            mod.register(sub)
    return parser


#: Commands whose SIGTERM keeps its default action: a Qt event loop runs Python signal handlers
#: only when Python code runs, so the window would seem to ignore it.
GUI_COMMANDS = ("gui", "annotate", "start")


def _terminate(signum, frame) -> None:
    """SIGTERM ends a command like Ctrl-C: ``finally`` blocks run (an export's staging folder is
    removed, a batch ends its workers), then exit 130."""
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv: list[str] | None = None) -> int:
    import signal
    import threading

    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    catch = args.command not in GUI_COMMANDS and threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if catch else None
    try:
        return _run(args)
    finally:
        if catch:
            signal.signal(signal.SIGTERM, previous)


def _run(args: argparse.Namespace) -> int:
    try:
        return int(args.func(args) or 0)
    except NpsimInputError as exc:
        print(f"npsim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # unwritable output folder, a file where a folder should be, disk full
        where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
        print(f"npsim {args.command}: error: {exc.strerror or exc}{where}; choose another output path or fix "
              "its permissions", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, NpsimCancelled):
        print(f"npsim {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
