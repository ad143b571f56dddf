"""``npsim gui [PATH]`` and ``npsim start``: the desktop app, or a headless run without a display."""

from __future__ import annotations

import argparse
import sys


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("gui", help="open the desktop app (default: the built-in sample scene)")
    p.add_argument("path", nargs="?", help="scene folder, project folder, image with *_labelIds.png beside it "
                                           "(or a Cityscapes/ACDC image), or a dataset root (its frames listed)")
    p.add_argument("--size", default="512x256", help="sample scene size when no PATH is given (default 512x256)")
    p.add_argument("--screenshot", help="save a window screenshot after the first render, then quit")
    p.add_argument("--quit-after", type=float, help="quit after this many seconds")
    p.set_defaults(func=run_gui)
    s = sub.add_parser("start", help="the main job: the app on the sample scene, or (no display) a headless "
                                     "run of the whole pipeline on it")
    s.add_argument("-o", "--out", default="out/sample", help="output folder of the headless run (default out/sample)")
    s.add_argument("--size", default="512x256", help="sample scene size (default 512x256)")
    s.set_defaults(func=run_start)


def run_gui(args: argparse.Namespace) -> int:
    from npsim_core.errors import NpsimInputError

    from ..options import parse_size

    size = parse_size(args.size)
    try:
        from npsim_gui.app import has_display, main
    except ImportError as exc:  # e.g. Qt's system libraries missing
        raise NpsimInputError(f"the GUI cannot start ({exc}); run 'bash npsim.sh setup' to install its "
                              "system packages") from None
    if not has_display():
        raise NpsimInputError("no display to open a window on (DISPLAY is not set): run it on a desktop, under "
                              "'xvfb-run -a npsim gui …', or use 'npsim start' / 'npsim run' for a headless run")
    return main(args.path, sample_size=size, screenshot=args.screenshot, quit_after=args.quit_after)


def run_start(args: argparse.Namespace) -> int:
    from ..options import parse_size
    from .run import run_sample_headless

    try:
        from npsim_gui.app import has_display
    except ImportError:
        def has_display() -> bool:
            return False
    if has_display():
        return run_gui(argparse.Namespace(path=None, size=args.size, screenshot=None, quit_after=None))
    print("npsim start: no display here, so running the whole pipeline headless on the sample scene "
          "(open the app with 'npsim gui' on a desktop)", file=sys.stderr)
    return run_sample_headless(args.out, parse_size(args.size))
