"""Window groups against the synthetic street's true windows_groups, with and without the regrouping.

    .venv/bin/python -m benchmarks.window_groups [--size 2048x1024] [--seeds 0,1,2]
                                                 [--variants default,hard,lights] [--slider [--ceiling] [--detail]]

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

``--slider``: what the editor benchmark pays for at its slider instead (docs/proposals.md "Fourteenth pass:
why the true floors cost a group action at the slider"): every proposal (``propose_for_scene``) accepted
as ``benchmarks.annotation_actions`` does at the slider's default (0.9, then the Shift+A review and the
stroke accept), and per true windows_group why it costs a group action (:func:`slider_causes`).
``--detail`` lists the grouping errors proper (every pane accepted, the floor merged or split:
:func:`grouping_errors`) with the proposed groups that hold them. ``--ceiling`` adds the mean actions a
frame at the slider with the proposals as they are and with the windows matched at IoU >= 0.5 regrouped by
their true floor (the rest kept in their proposed groups): what any grouping of these windows could save.
"""

from __future__ import annotations

import argparse
import os

import numpy as np
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


#: Why a true windows_group costs a group action at the slider (:func:`slider_causes`), in the order tested.
SLIDER_CAUSES = ("exact", "not proposed", "not proposed, rest broken", "pending", "merged", "split", "class")


def slider_causes(gt, ann, proposals) -> dict[str, int]:
    """Per true windows_group (class 13) of ``gt``, why the annotation ``ann`` (what the editor holds after
    accepting proposals: the slider, the review) does not hold it as a group already, the first that holds:

    * ``exact``: it does (every light matched at mask IoU >= 0.5, all in one group whose other lights
      match no true light -- they are removed, each by its own action -- and of its class): no group action;
    * ``not proposed``: a light no proposal (``proposals``: the proposals' annotation) matches at IoU >= 0.5:
      it is drawn, and the group costs the double-click that activates its accepted part or the Ctrl+G of
      one drawn whole -- as from scratch; ``not proposed, rest broken``: the same, its accepted lights
      split over groups (or left single) or sharing one with another true group's light (more than one
      action);
    * ``pending``: every light proposed, one not accepted (under the slider, not worth a review);
    * ``merged``: all accepted, in a group with another true group's light;
    * ``split``: all accepted, over two groups or more (or left single);
    * ``class``: one group of the wrong class.

    Returns the counts per :data:`SLIDER_CAUSES` and ``n``."""
    from benchmarks.annotation_actions import match_lights

    match = match_lights(gt, ann)
    owner = {b: a for a, (b, _) in match.items()}
    pmatch = match_lights(gt, proposals)
    tg = {m: gid for gid, g in gt.groups.items() for m in g.members}
    gof = ann.group_index()
    res = dict.fromkeys(SLIDER_CAUSES, 0)
    res["n"] = 0
    for gid, g in gt.groups.items():
        if gid // 1000 != 13:
            continue
        res["n"] += 1
        have = {match[a][0] for a in g.members if a in match}
        groups = {gof.get(p) for p in have}
        # the lights of those groups that match a true light (the others are removed before grouping)
        held = {q for k in groups - {None} for q in ann.groups[k].members if q in owner}
        merged = any(tg.get(owner[q]) != gid for q in held)
        split = len(groups) > 1 or None in groups
        if len(have) == len(g.members) and not split and not merged:
            res["exact" if ann.groups[groups.pop()].class_id == g.class_id else "class"] += 1
        elif any(a not in pmatch for a in g.members):
            res["not proposed, rest broken" if have and (split or merged) else "not proposed"] += 1
        elif len(have) < len(g.members):
            res["pending"] += 1
        else:
            res["merged" if merged else "split"] += 1
    return res


def grouping_errors(gt, ann, proposals, depth=None) -> list[dict]:
    """The grouping errors proper of :func:`slider_causes` (every pane of a true windows_group accepted, the
    group ``merged`` or ``split``), one dict each: the true group id, its kind, its panes' box (x0, x1, y0, y1),
    their median depth (``depth``: m, optional), and per proposed group (``proposals``) holding one of its matched
    panes: its id, its members' box, how many of them match this floor and which other true floors the rest
    match (with their boxes). For ``--detail``: sorting the errors by cause."""
    from benchmarks.annotation_actions import match_lights

    match = match_lights(gt, ann)
    owner = {b: a for a, (b, _) in match.items()}
    pmatch = match_lights(gt, proposals)
    powner = {b: a for a, (b, _) in pmatch.items()}
    tg = {m: gid for gid, g in gt.groups.items() for m in g.members}
    gof = ann.group_index()
    pgof = proposals.group_index()

    def box(amap, ids):
        m = np.isin(amap, list(ids))
        ys, xs = np.nonzero(m)
        return (int(xs.min()), int(xs.max()) + 1, int(ys.min()), int(ys.max()) + 1) if ys.size else None

    out = []
    for gid, g in gt.groups.items():
        if gid // 1000 != 13:
            continue
        have = {match[a][0] for a in g.members if a in match}
        groups = {gof.get(p) for p in have}
        held = {q for k in groups - {None} for q in ann.groups[k].members if q in owner}
        merged = any(tg.get(owner[q]) != gid for q in held)
        split = len(groups) > 1 or None in groups
        if len(have) < len(g.members) or not (split or merged):
            continue
        row = dict(gid=gid, kind=("merged+split" if merged and split else "merged" if merged else "split"),
                   n=len(g.members), box=box(gt.instance_map, g.members), parts=[])
        if depth is not None:
            m = np.isin(gt.instance_map, list(g.members)) & np.isfinite(depth)
            row["z"] = float(np.median(depth[m])) if m.any() else float("nan")
        held_by = {pgof.get(pmatch[a][0]) for a in g.members if a in pmatch}
        for k in sorted(held_by, key=lambda k: -1 if k is None else k):
            if k is None:
                row["parts"].append(dict(pid=None, n=sum(pgof.get(pmatch[a][0]) is None for a in g.members)))
                continue
            mem = proposals.groups[k].members
            others = sorted({tg.get(powner[q]) for q in mem if q in powner} - {gid}, key=lambda x: x or 0)
            row["parts"].append(dict(pid=k, box=box(proposals.instance_map, mem), n=len(mem),
                                     mine=sum(tg.get(powner.get(q)) == gid for q in mem),
                                     false=sum(q not in powner for q in mem),
                                     others=[(o, box(gt.instance_map, gt.groups[o].members) if o in gt.groups else None)
                                             for o in others]))
        out.append(row)
    return out


def regrouped_by_truth(gt, props):
    """``props`` with its windows matched at IoU >= 0.5 regrouped by their true windows_group (one group each),
    the other windows left in their proposed groups (restricted to them); for the ceiling of ``--slider``."""
    from benchmarks.annotation_actions import match_lights
    from npsim_core.annotation import GroupInstance
    from npsim_core.proposals import LightProposals

    ann = props.annotation
    owner = {b: a for a, (b, _) in match_lights(gt, ann).items()}
    tg = {m: gid for gid, g in gt.groups.items() if gid // 1000 == 13 for m in g.members}
    truth = {q: tg[owner[q]] for q in ann.instance_ids() if q in owner and owner[q] in tg}
    groups = {k: g for k, g in ann.groups.items() if k // 1000 != 13}
    conf = {k: v for k, v in props.confidence.items() if k // 1000 != 13}
    parts = [[m for m in g.members if m not in truth] for k, g in ann.groups.items() if k // 1000 == 13]
    by_truth: dict[int, list[int]] = {}
    for q, t in truth.items():
        by_truth.setdefault(t, []).append(q)
    used = set(ann.groups)
    k = 0
    for members in parts + list(by_truth.values()):
        if not members:
            continue
        k += 1
        while 13000 + k in used:
            k += 1
        gid = 13000 + k
        groups[gid] = GroupInstance(gid, tuple(sorted(members)))
        conf[gid] = float(sum(props.confidence[m] for m in members) / len(members))
    return LightProposals(replace(ann, groups=groups), conf)


def slider_actions(scene, props, causes: dict[str, int] | None = None, errors: list | None = None) -> int:
    """The editor benchmark's actions at the slider's default on ``scene`` with ``props`` (its default model:
    ``benchmarks.annotation_actions.main``); ``causes``: when given, :func:`slider_causes` of the state before
    the finish by hand are added to it."""
    from benchmarks import annotation_actions as aa
    from npsim_gui.editor.proposals import DEFAULT_ACCEPT_THRESHOLD, ProposalBook
    from npsim_gui.editor.session import EditorSession

    gt = scene.lights
    s = EditorSession(superpixels=False)
    s.load(scene.image, scene.labels, None)
    s.set_vehicle_instances(scene.instances)
    counts = dict.fromkeys(("draw", "class keys", "group", "tool", "accept", "review", "remove", "class fix",
                            "touch up", "ungroup"), 0)
    book = ProposalBook(props)
    book.accept_above(s, DEFAULT_ACCEPT_THRESHOLD)
    counts["accept"] = aa.accept_actions(DEFAULT_ACCEPT_THRESHOLD)
    aa.review_pending(s, book, gt, counts, {})
    aa.stroke_accept_pending(s, book, gt, counts, {})
    if causes is not None:
        for key, v in slider_causes(gt, s.ann, props.annotation).items():
            causes[key] = causes.get(key, 0) + v
    if errors is not None:
        errors.extend(grouping_errors(gt, s.ann, props.annotation, getattr(scene, "depth_gt", None)))
    aa.finish_by_hand(s, gt, counts, {})
    aa.check_equal(gt, s.ann)
    s.shutdown()
    return sum(counts.values())


def _main_slider(args) -> int:
    import sys

    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from PySide6.QtCore import QCoreApplication, QThreadPool

    from npsim_cli.options import parse_size
    from npsim_core.proposals import propose_for_scene
    from npsim_core.synthetic import street_scene

    _app = QCoreApplication.instance() or QCoreApplication(sys.argv[:1])  # noqa: F841 (Qt objects need it)
    w, h = parse_size(args.size)
    rows = []
    for variant in [v for v in args.variants.split(",") if v]:
        causes: dict[str, int] = {}
        acts, ceil = [], []
        for seed in [int(s) for s in args.seeds.split(",") if s]:
            sc = street_scene(w, h, seed, variant)
            props = propose_for_scene(sc)
            errs: list = []
            acts.append(slider_actions(sc, props, causes, errs if args.detail else None))
            for e in errs:
                print(f"{variant} s{seed} floor {e['gid']} {e['kind']} panes {e['n']} box {e['box']} "
                      f"z {e.get('z', float('nan')):.0f}", flush=True)
                for p in e["parts"]:
                    print(f"    proposed {p}", flush=True)
            if args.ceiling:
                ceil.append(slider_actions(sc, regrouped_by_truth(sc.lights, props)))
        rows.append((variant, causes, acts, ceil))
    QThreadPool.globalInstance().waitForDone()
    print(f"# Why the true window groups cost a group action at the slider (0.9), synthetic street {w}x{h}, "
          f"seeds {args.seeds} (load {os.getloadavg()[0]:.1f})\n")
    print("| variant | true groups | " + " | ".join(SLIDER_CAUSES) + " |" + (
        " actions a frame | regrouped by truth |" if args.ceiling else ""))
    print("|---" * (2 + len(SLIDER_CAUSES) + (2 if args.ceiling else 0)) + "|")
    for variant, c, acts, ceil in rows:
        print(f"| {variant} | {c.get('n', 0)} | " + " | ".join(str(c.get(k, 0)) for k in SLIDER_CAUSES) + " |" + (
            f" {sum(acts) / len(acts):.1f} | {sum(ceil) / len(ceil):.1f} |" if args.ceiling and acts else ""))
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="2048x1024")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--variants", default="default,hard,lights")
    ap.add_argument("--slider", action="store_true",
                    help="why each true window group costs a group action at the editor's slider (module doc)")
    ap.add_argument("--ceiling", action="store_true",
                    help="with --slider: also the actions with the matched windows regrouped by their true floor")
    ap.add_argument("--detail", action="store_true",
                    help="with --slider: list the grouping errors proper (every pane accepted, merged or split)")
    args = ap.parse_args(argv)
    if args.slider:
        return _main_slider(args)
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
