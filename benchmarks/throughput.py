"""Batch throughput: frames through geometry + one night per minute, 1 worker against 2 (README
"Throughput").

Usage::

    python -m benchmarks.throughput [--root DATASET] [--frames 4] [--size 2048x1024]
                                    [--workers 1,2] [--nights 1] [--set SECTION.FIELD=VALUE ...]
                                    [--out FILE.md]

Without ``--root`` it writes the real-layout fixture (``python -m npsim_core.synthetic.cityscapes``:
the synthetic street with SGM stereo, ego vehicle, Cityscapes folders) of ``--frames`` frames at
``--size`` into a temporary folder. For each worker count it runs :func:`npsim_core.chain.batch.run_batch`
on the same frames with the defaults (plus ``--set``) into a fresh folder and prints one row:

* ``img/min``: frames done per minute of wall clock (what a user waits for),
* ``CPU s/img``: user + system CPU seconds per frame of this process and its workers -- far less
  sensitive to other jobs on the machine than the wall clock,
* ``peak GiB/worker``: the largest peak resident memory of a worker,
* ``MB/img``: bytes written per frame (the frame folders),
* ``stages``: mean seconds per frame of geometry (the chain up to the mesh), night inputs (scene
  build, materials, guides), render and denoise, from the export manifests,
* the 1-minute load average at the start and the end (``os.getloadavg``).

On a shared machine the wall clock is inflated by the load; the CPU seconds are not (much).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script from the checkout
    sys.path.insert(0, str(ROOT))


def _cpu_seconds() -> float:
    """User + system CPU of this process and its reaped children."""
    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime


def _folder_bytes(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def run_one(sources, params, out: Path, workers: int, nights: int, log) -> dict:
    """One batch of ``sources`` with ``workers`` processes; the row of the table."""
    from npsim_core.chain.batch import run_batch

    load0, c0, t0 = os.getloadavg()[0], _cpu_seconds(), time.perf_counter()
    res = run_batch(sources, params, out, nights=nights, workers=workers, skip_existing=False, log=log)
    wall, cpu = time.perf_counter() - t0, _cpu_seconds() - c0
    done = [o for o in res.outcomes if o.status == "done"]
    stages = {"geometry": 0.0, "night inputs": 0.0, "render": 0.0, "denoise": 0.0}
    frame_bytes = []
    for o in done:
        man = json.loads(next((out / o.name).glob("*_export.json")).read_text())
        t = man["timings"]
        stages["geometry"] += sum(t.get(k, 0.0) for k in ("geometry", "filter", "uncertain", "refine", "mesh", "lights"))
        for night in man["nights"]:
            stages["night inputs"] += night["timings"].get("night_inputs", 0.0)
            stages["render"] += night["timings"].get("render", 0.0)
            stages["denoise"] += night["timings"].get("denoise", 0.0)
        frame_bytes.append(_folder_bytes(out / o.name))
    n = max(1, len(done))
    return {"workers": workers, "frames": len(sources), "done": len(done), "wall_s": wall,
            "img_per_min": 60.0 * len(done) / wall, "cpu_s_per_img": cpu / n,
            "peak_gb": max((o.peak_rss_mb for o in done), default=0.0) / 1024.0,
            "mb_per_img": sum(frame_bytes) / n / 1e6, "max_mb_img": max(frame_bytes, default=0) / 1e6,
            "stages": {k: v / n for k, v in stages.items()}, "load_start": load0, "load_end": os.getloadavg()[0],
            "failed": [f"{o.name}: {o.error}" for o in res.outcomes if o.status == "failed"]}


def format_table(rows: list[dict], size: str, what: str) -> str:
    lines = [f"Throughput, {size}, {what}; load = 1-minute average at the start -> end",
             "", "| workers | frames | img/min | s/img (wall) | CPU s/img | peak GiB/worker | MB/img (max) | "
                 "geometry s | night inputs s | render s | denoise s | load |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        st = r["stages"]
        lines.append(f"| {r['workers']} | {r['done']}/{r['frames']} | {r['img_per_min']:.2f} | "
                     f"{r['wall_s'] / max(1, r['done']):.1f} | {r['cpu_s_per_img']:.1f} | {r['peak_gb']:.2f} | "
                     f"{r['mb_per_img']:.1f} ({r['max_mb_img']:.1f}) | {st['geometry']:.1f} | "
                     f"{st['night inputs']:.1f} | {st['render']:.1f} | {st['denoise']:.1f} | "
                     f"{r['load_start']:.1f} -> {r['load_end']:.1f} |")
    fails = [f for r in rows for f in r["failed"]]
    if fails:
        lines += ["", "Failed: " + "; ".join(fails)]
    lines += ["", "Stage columns: mean seconds per frame inside one worker (with 2 workers each has about "
                  "one core, so they are longer while the frames per minute are higher)."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.throughput", description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", default=None, help="dataset folder (default: a fresh real-layout fixture)")
    ap.add_argument("--frames", type=int, default=4, help="frames (default 4)")
    ap.add_argument("--size", default="2048x1024", help="fixture size WxH (default 2048x1024)")
    ap.add_argument("--workers", default="1,2", help="comma list of worker counts (default 1,2)")
    ap.add_argument("--nights", type=int, default=1, help="nights per frame (default 1)")
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.FIELD=VALUE",
                    help="override a parameter (value as JSON), as on the command line")
    ap.add_argument("--out", default=None, help="also write the table (markdown) to this file")
    ap.add_argument("--keep", default=None, help="write the outputs here (default: a temporary folder)")
    args = ap.parse_args(argv)

    from npsim_core.chain.params import ChainParams
    from npsim_core.chain.session import iter_frames

    params = ChainParams()
    for item in args.set:
        key, _, value = item.partition("=")
        section, _, field = key.partition(".")
        params = params.with_value(section, field, json.loads(value))
    tmp = tempfile.TemporaryDirectory(prefix="npsim-throughput-")
    work = Path(args.keep) if args.keep else Path(tmp.name)
    log = lambda m: print(f"  [{time.strftime('%H:%M:%S')}] {m}", file=sys.stderr, flush=True)  # noqa: E731
    if args.root:
        root = Path(args.root)
    else:
        from npsim_core.synthetic.cityscapes import write_cityscapes_fixture

        w, h = (int(v) for v in args.size.lower().split("x"))
        root = work / "dataset"
        log(f"writing the {args.frames}-frame {w}x{h} real-layout fixture to {root}")
        write_cityscapes_fixture(root, frames=args.frames, size=(w, h), corrupt=0)
    sources = iter_frames(root)[: args.frames]
    rows = []
    for workers in (int(v) for v in args.workers.split(",")):
        log(f"{workers} worker(s), {len(sources)} frames, load {os.getloadavg()[0]:.1f}")
        rows.append(run_one(sources, params, work / f"out_{workers}w", workers, args.nights, log))
    what = (f"{len(sources)} real-layout frames (synthetic street, SGM stereo), geometry + {args.nights} "
            f"night(s) at the defaults" + (f" with {' '.join(args.set)}" if args.set else "")
            + f", {os.cpu_count()} cores")
    table = format_table(rows, args.size if not args.root else str(root), what)
    print(table)
    if args.out:
        Path(args.out).write_text(table + "\n")
        Path(args.out).with_suffix(".json").write_text(json.dumps(rows, indent=1))
    tmp.cleanup()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
