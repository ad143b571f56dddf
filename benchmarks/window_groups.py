"""Window groups against the synthetic street's true windows_groups, with and without the regrouping.

    .venv/bin/python -m benchmarks.window_groups [--size 2048x1024] [--seeds 0,1,2]
                                                 [--variants default,hard,lights]

Per true windows_group (one floor of one building), from the proposed windows that match its panes at
mask IoU >= 0.5 (``benchmarks.annotation_actions.match_lights``, as its oracle column accepts them):
*exact* (all in one proposed group holding no other true group's window), *split* (over two proposed
groups or more), *merged* (a proposed group holding another true group's window too; a group can be
split and merged), *none* (no window matched); *complete*: exact with every pane matched (the only
groups that save the editor benchmark a group action: one held in part costs the double-click that
activates it, as much as grouping it from scratch), *false_in*: its proposed group(s) also hold a
window matching no true one (which keeps the editor's Shift+A review from taking the group). "before"
is the windows proposer's groups per floor of each wall piece, "after" those regrouped per building (:mod:`npsim_core.proposals.window_groups`,
docs/proposals.md "Window groups"); the lights and their confidences are the same.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace


def classify(gt, ann) -> dict[str, int]:
    """Counts of true windows_groups exact / split / merged / none, and of proposed windows_groups."""
    from benchmarks.annotation_actions import match_lights

    match = match_lights(gt, ann)
    pg = {m: gid for gid, g in ann.groups.items() for m in g.members}
    tg = {m: gid for gid, g in gt.groups.items() if gid // 1000 == 13 for m in g.members}
    p2t = {b: tg.get(a) for a, (b, _) in match.items()}
    res = dict(n=0, exact=0, complete=0, split=0, merged=0, false_in=0, none=0)
    for gid, g in gt.groups.items():
        if gid // 1000 != 13:
            continue
        res["n"] += 1
        ps = {pg.get(match[a][0]) for a in g.members if a in match}
        if not ps:
            res["none"] += 1
            continue
        split = len(ps) > 1 or None in ps
        merged = any(p2t.get(m) != gid for p in ps if p is not None for m in ann.groups[p].members if m in p2t)
        res["split"] += split
        res["merged"] += merged
        res["exact"] += not split and not merged
        # exact with every pane matched: the only groups that save the annotator a group action
        res["complete"] += not split and not merged and all(a in match for a in g.members)
        res["false_in"] += any(m not in p2t for p in ps if p is not None for m in ann.groups[p].members)
    res["proposed"] = sum(1 for gid in ann.groups if gid // 1000 == 13)
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="2048x1024")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--variants", default="default,hard,lights")
    args = ap.parse_args(argv)
    from npsim_cli.options import parse_size
    from npsim_core.proposals import core, window_groups, windows
    from npsim_core.proposals.params import ProposalParams
    from npsim_core.synthetic import street_scene

    w, h = parse_size(args.size)
    keys = ("exact", "complete", "split", "merged", "false_in", "none", "proposed")
    print(f"# Window groups against the true ones, synthetic street {w}x{h}\n")
    print("| variant | seed | true groups | " + " | ".join(f"{k} before -> after" for k in keys) + " | regroup s |")
    print("|---" * (4 + len(keys)) + "|")
    total: dict[str, list[dict]] = {}
    regroup = window_groups.regroup_windows
    for variant in [v for v in args.variants.split(",") if v]:
        for seed in [int(s) for s in args.seeds.split(",") if s]:
            sc = street_scene(w, h, seed, variant)
            d = sc.depth if sc.depth is not None else sc.depth_stereo
            ctx = core._check_inputs(sc.image, sc.labels, d, sc.intrinsics, getattr(sc, "instances", None))
            ctx.params = replace(ProposalParams(), camera_height_m=float(sc.camera_height),
                                 camera_pitch_rad=float(sc.camera_pitch))
            window_groups.regroup_windows = lambda ctx, groups, feat=None: groups  # the proposer's own groups
            try:
                before = windows.propose(ctx)
            finally:
                window_groups.regroup_windows = regroup
            t0 = time.perf_counter()
            after = regroup(ctx, before, windows._features(ctx))
            dt = time.perf_counter() - t0
            r0 = classify(sc.lights, core._assemble(ctx.shape, before).annotation)
            r1 = classify(sc.lights, core._assemble(ctx.shape, after).annotation)
            print(f"| {variant} | {seed} | {r0['n']} | " + " | ".join(f"{r0[k]} -> {r1[k]}" for k in keys)
                  + f" | {dt:.2f} |", flush=True)
            total.setdefault(variant, []).append((r0, r1))
    for variant, rows in total.items():
        s0 = {k: sum(r[0][k] for r in rows) for k in ("n",) + keys}
        s1 = {k: sum(r[1][k] for r in rows) for k in keys}
        print(f"| **{variant}** | all | {s0['n']} | " + " | ".join(f"{s0[k]} -> {s1[k]}" for k in keys) + " | |")
    print(f"\n(load {os.getloadavg()[0]:.1f}; regroup s includes the wall features, computed once in the proposer)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
