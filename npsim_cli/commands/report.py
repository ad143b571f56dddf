"""``npsim report OUT``: an HTML page of a batch or sweep output folder (``OUT/report.html``)."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("report", help="write OUT/report.html for a batch or sweep output folder")
    p.add_argument("out", help="the output folder of 'npsim batch' or 'npsim sweep'")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from npsim_core.report import write_report

    print(f"wrote {write_report(args.out)}")
    return 0
