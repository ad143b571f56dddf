"""``npsim report OUT``: an HTML page of a batch or sweep output folder (``OUT/report.html``)."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("report", help="write OUT/report.html for a batch or sweep output folder")
    p.add_argument("out", help="the output folder of 'npsim batch' or 'npsim sweep'")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from npsim_core.report import frame_check, write_report

    page = write_report(args.out)
    out = Path(args.out)
    batch = out / "batch.json"
    if batch.is_file():  # the frames' state in words as well (the page has the details)
        import json

        frames = json.loads(batch.read_text()).get("frames", {})
        counts: dict[str, int] = {}
        for name, f in frames.items():
            status, why = f.get("status", "?"), f.get("error", "")
            if status in ("done", "skipped"):
                status, why, _ = frame_check(out / name)
            counts[status] = counts.get(status, 0) + 1
            if status != "done":
                print(f"  {name}: {status}" + (f": {why}" if why else ""))
        print(f"{len(frames)} frames: " + ", ".join(f"{n} {k}" for k, n in sorted(counts.items())))
    print(f"wrote {page}")
    return 0
