"""Light proposals on a brick-textured street, with and without depth: time against image size.

    .venv/bin/python -m benchmarks.proposals_textured [--sizes 512x256,1024x512,2048x1024]
                                                      [--seeds 0] [--depth none,scene]

The editor opened on a bare image (``npsim annotate IMAGE``) proposes without depth; on a strongly
textured facade the window proposer then finds hundreds to thousands of candidates, and its
stages that compare candidates pairwise set the time (docs/proposals.md "Eleventh pass: one pass
over the occluder joins"). The frame: the default fixture street, its walls textured twice by
tests/test_proposals_fuzz.py's ``_expose(..., "texture")`` (rng = seed). Per size, seed and depth:
the time of ``propose_lights`` (the scene's intrinsics; no instance ids; wall clock, and the process's CPU
time: on the 2 shared cores the wall clock also counts the waits for a core), the parts of it in the
windows' occluder joins, in the window groups and confidences (``regroup_windows``,
``rescore_windows``) and in the groups alone, the window candidates entering the joins, the windows proposed
and their recall / precision against the scene's true lights (the proposals of confidence >= 0.5, IoU >= 0.3:
``npsim_core.proposals.evaluate.score``, as ``benchmarks.proposals``). Target:
<= 2 s at 2048x1024 (README). Prints the 1-min load average with each row (2 cores shared).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np


def textured(W: int, H: int, seed: int):
    """The default street at WxH, its walls textured twice (rng ``seed``)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_proposals_fuzz import _expose  # the fuzz test's texture: one generator

    from npsim_core.synthetic import street_scene

    s = street_scene(W, H, seed, "default")
    rng = np.random.default_rng(seed)
    img = _expose(_expose(s.image, s.labels, "texture", rng), s.labels, "texture", rng)
    return s, img


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="512x256,1024x512,2048x1024")
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--depth", default="none,scene", help="none (a bare image) and/or scene")
    a = ap.parse_args(argv)
    import npsim_core.proposals.window_confidence as cmod
    import npsim_core.proposals.window_groups as gmod
    import npsim_core.proposals.windows as wmod
    from npsim_core.proposals import propose_lights
    from npsim_core.proposals.evaluate import score_category

    join, regroup, rescore = wmod._join_across_occluders, gmod.regroup_windows, cmod.rescore_windows
    spent = {"join": 0.0, "n": 0, "after": 0.0, "groups": 0.0}

    def after(fn, part=None):
        def run(*args, **kw):
            t = time.perf_counter()
            out = fn(*args, **kw)
            spent["after"] += time.perf_counter() - t
            if part:
                spent[part] += time.perf_counter() - t
            return out
        return run

    def timed(ctx, found, p):
        spent["n"] = len(found)
        t = time.perf_counter()
        out = join(ctx, found, p)
        spent["join"] += time.perf_counter() - t
        return out

    wmod._join_across_occluders = timed
    gmod.regroup_windows, cmod.rescore_windows = after(regroup, "groups"), after(rescore)
    print(f"{'size':>10} {'seed':>4} {'depth':>5} {'total s':>8} {'cpu s':>6} {'joins s':>8} {'groups+conf s':>13} {'groups s':>8} {'cands':>6} "
          f"{'windows':>7} {'recall':>6} {'prec':>6} {'load':>5}")
    try:
        for size in a.sizes.split(","):
            W, H = (int(v) for v in size.split("x"))
            for seed in (int(v) for v in a.seeds.split(",")):
                s, img = textured(W, H, seed)
                for dmode in a.depth.split(","):
                    spent.update(join=0.0, n=0, after=0.0, groups=0.0)
                    depth = None if dmode == "none" else s.depth
                    t, c = time.perf_counter(), time.process_time()
                    props = propose_lights(img, s.labels, depth, s.intrinsics, None)
                    total, cpu = time.perf_counter() - t, time.process_time() - c
                    nwin = len(props.category_ids("windows"))
                    sc = score_category(s.lights, props.above(0.5), "windows")
                    print(f"{size:>10} {seed:>4} {dmode:>5} {total:8.2f} {cpu:6.2f} {spent['join']:8.2f} {spent['after']:13.2f} {spent['groups']:8.2f} {spent['n']:6d} "
                          f"{nwin:7d} {sc.recall:6.2f} {sc.precision:6.2f} {os.getloadavg()[0]:5.2f}", flush=True)
    finally:
        wmod._join_across_occluders = join
        gmod.regroup_windows, cmod.rescore_windows = regroup, rescore
    return 0


if __name__ == "__main__":
    sys.exit(main())
