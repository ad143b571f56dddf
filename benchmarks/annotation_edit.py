"""What one light-annotation edit costs before the night preview shows it, on Cityscapes-layout frames.

    .venv/bin/python -m benchmarks.annotation_edit [--sizes 512x256,2048x1024] [--edits 3]

For each size a one-frame Cityscapes-layout fixture (``npsim_core.synthetic.cityscapes``: image,
labelIds, stereo disparity, camera JSON; lights proposed by the chain) is written to a temporary
folder; the frame's chain is run to its night inputs (mesh, materials, Mitsuba scene, OIDN guides)
and then, ``--edits`` times, one light of the annotation is removed and a new window painted on a
facade (what an annotator does with one stroke), and the night inputs are brought up to date as the
app's night preview does:

* **incremental** (the chain's default): the mesh is not rebuilt; the night scene rebuilds only the
  64-row bands and the lights whose faces changed (``build_scene(previous=...)``);
* **from scratch**: the same edit with the night scene built anew (what every edit cost before the
  incremental stage), for comparison.

Error: the largest absolute difference between a 16-spp render of the incrementally updated scene
and of a scene built from scratch for the same annotation (same seed): 0 means the same night.
Printed: per-stage seconds, shapes rebuilt, peak RSS, the machine's load.
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time

import numpy as np


def _edit(ann, k: int):
    """``ann`` with its k-th ungrouped light removed and a 6x8-pixel-per-256 window painted."""
    ann = ann.copy()
    grouped = {m for g in ann.groups.values() for m in g.members}
    lone = [i for i in ann.instance_ids() if i not in grouped]
    if lone:
        ann.instance_map[ann.instance_map == lone[k % len(lone)]] = 0
    H, W = ann.shape
    s = max(1, W // 256)
    y, x = H // 5 + 9 * s * k, W // 3 + 11 * s * k
    ann.instance_map[y:y + 6 * s, x:x + 8 * s] = 4900 + k  # class 4: a window
    return ann


def run_size(W: int, H: int, edits: int, log) -> list[dict]:
    from npsim_core.chain import Chain, ChainParams
    from npsim_core.chain.session import load_frame
    from npsim_core.render.render import render_final
    from npsim_core.synthetic.cityscapes import fixture_image, fixture_stem, write_cityscapes_fixture

    rows = []
    with tempfile.TemporaryDirectory() as d:
        write_cityscapes_fixture(d, frames=1, size=(W, H), corrupt=0)
        scene = load_frame(fixture_image(d, fixture_stem("synthcity", 0)))
    chain = Chain(scene)
    params = ChainParams()
    t = time.perf_counter()
    chain.compute(params)
    chain.night_inputs(params)
    log(f"{W}x{H}: first mesh and night inputs {time.perf_counter() - t:.1f} s "
        f"({len(chain.lights(params).annotation.instance_ids())} proposed lights)")
    ann = chain.lights(params).annotation
    p = params.with_value("lights", "source", "annotation")
    for k in range(edits):
        ann = _edit(ann, k)
        for mode in ("incremental", "from scratch"):
            if mode == "from scratch":
                chain.engine.clear_cache("night_scene")  # no previous scene to update
            chain.set_annotation(ann)
            load = os.getloadavg()[0]
            t0 = time.perf_counter()
            res = chain.compute(p)
            built, _, _, run = chain.night_inputs(p)
            total = time.perf_counter() - t0
            rows.append({"size": f"{W}x{H}", "edit": k + 1, "mode": mode, "total": total,
                         "recomputed": {**{s: res.timings[s] for s in res.recomputed},
                                        **{s: run.timings[s] for s in run.recomputed}},
                         "rebuilt": built.info.get("rebuilt", ""), "load": load,
                         "rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6})
            if mode == "incremental":
                built.apply_lights(chain.activate(p))
                inc = render_final(built, spp=16, seed=5)
        built.apply_lights(chain.activate(p))
        ref = render_final(built, spp=16, seed=5)
        rows[-2]["error"] = rows[-1]["error"] = float(np.abs(inc - ref).max())
        log(f"  edit {k + 1}: incremental {rows[-2]['total']:.2f} s, from scratch {rows[-1]['total']:.2f} s, "
            f"max |difference| {rows[-1]['error']:.3g}")
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="512x256,2048x1024")
    ap.add_argument("--edits", type=int, default=3)
    a = ap.parse_args(argv)

    def log(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    rows = []
    for size in a.sizes.split(","):
        W, H = (int(v) for v in size.lower().split("x"))
        rows += run_size(W, H, a.edits, log)
    print(f"\nannotation edit -> night inputs up to date ({os.cpu_count()} cores)\n")
    print("| size | edit | night scene | total (s) | stages recomputed (s) | shapes rebuilt | max render "
          "difference | load | peak RSS (GB) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        st = ", ".join(f"{k} {v:.2f}" for k, v in r["recomputed"].items())
        print(f"| {r['size']} | {r['edit']} | {r['mode']} | {r['total']:.2f} | {st} | {r['rebuilt']} | "
              f"{r['error']:.3g} | {r['load']:.1f} | {r['rss_gb']:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
