"""Editor actions to reach a frame's ground-truth light annotation, with and without proposals.

    .venv/bin/python -m benchmarks.annotation_actions [--size 512x256] [--seeds 0,1,2]
                                                      [--variants default,hard] [--thresholds 0.5,0.7,0.9]

Unlike the estimate in ``benchmarks.proposals`` (Table 3), this replays the work in the editor's
own model: an :class:`~npsim_gui.editor.session.EditorSession` holding the annotation, the
proposal layer's :class:`~npsim_gui.editor.proposals.ProposalBook` accepting proposals through
the undo stack, and the same edit commands the editor's keys run; at the end the annotation is
checked against the ground truth (every ground-truth light has a light of its class with mask
IoU >= 0.5, no other light is left, every ground-truth group is a group of exactly those lights).

An **action** is one key press or one mouse gesture (click, drag, rubber band) of the editor:

* draw a light: 1 (one superpixel drag or brush stroke), plus 1 class key the first time a
  light class is drawn (the annotator draws all lights of a class in one go);
* group n lights: n (a click and n-1 Shift+clicks) + 1 (Ctrl+G), plus 1 group-class key when
  the group's class is not the default the editor preselects for its lights' class; complete a
  group that holds k of its n lights already: 2 + (n - k) (click the group, Shift+click the
  others, Ctrl+G joins them to it), + 3 when its class is wrong;
* remove a wrong light: 2 (click, Delete); fix a light's class: 3 (click, class key, C);
  touch up a light whose mask IoU with its ground truth is below 0.7: 1 (one stroke);
  ungroup a group that is not in the ground truth: 2 (click, Ctrl+Shift+G);
* with proposals: "accept all above the slider": 1 (Ctrl+Shift+A), + 1 when the threshold is not
  the slider's default (0.90); "Propose lights" itself: 1.

The ground truth is the synthetic street's exact annotation (docs/synthetic.md); the proposals
get the scene's exact depth and camera (``propose_for_scene``).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

MATCH_IOU = 0.5
TOUCH_UP_IOU = 0.7
#: What the actions are spent on: light classes and group classes -> the category printed in the breakdown.
CATEGORY_OF_CLASS = {1: "windows", 13: "windows", 2: "vehicles", 3: "vehicles", 4: "vehicles", 5: "vehicles",
                     6: "vehicles", 7: "vehicles", 14: "vehicles", 15: "vehicles", 16: "vehicles", 17: "vehicles",
                     18: "vehicles", 19: "vehicles", 8: "street lamps", 9: "street lamps", 12: "signals",
                     20: "signals", 10: "other", 11: "other", 21: "other"}


def match_lights(gt, ann) -> dict[int, tuple[int, float]]:
    """Greedy one-to-one matching (highest mask IoU first) of ground-truth light id -> (light id of
    ``ann``, IoU) at IoU >= :data:`MATCH_IOU`, any class."""
    g_area, p_area = gt.areas(), ann.areas()
    g, p = gt.instance_map.ravel(), ann.instance_map.ravel()
    sel = (g > 0) & (p > 0)
    if not sel.any():
        return {}
    pairs, inter = np.unique(np.stack([g[sel], p[sel]]).astype(np.int64), axis=1, return_counts=True)
    cand = sorted(((n / (g_area[a] + p_area[b] - n), a, b)
                   for (a, b), n in zip(pairs.T.tolist(), inter.tolist())), reverse=True)
    used_p: set[int] = set()
    out: dict[int, tuple[int, float]] = {}
    for iou, a, b in cand:
        if iou >= MATCH_IOU and a not in out and b not in used_p:
            out[a] = (b, iou)
            used_p.add(b)
    return out


def finish_by_hand(session, gt, counts: dict[str, int], by_category: dict[tuple[str, str], int] | None = None
                   ) -> None:
    """Edit ``session``'s annotation into the ground truth with the editor's commands, counting the
    actions of the module doc into ``counts`` and, when given, per (kind, category of the light or
    group class: :data:`CATEGORY_OF_CLASS`) into ``by_category``."""
    from npsim_core.annotation import DEFAULT_GROUP_FOR_LIGHT, class_of
    from npsim_core.annotation_ops import change_class, delete_instance, group_lights, new_instance, paint, ungroup

    if by_category is None:
        by_category = {}

    def count(kind: str, n: int, cls: int) -> None:
        counts[kind] += n
        key = (kind, CATEGORY_OF_CLASS.get(cls, "other"))
        by_category[key] = by_category.get(key, 0) + n

    def do(cmd):
        if isinstance(cmd, tuple):
            cmd = cmd[0]
        session.apply(cmd)

    match = match_lights(gt, session.ann)
    matched_p = {b for b, _ in match.values()}
    for pid in [i for i in session.ann.instance_ids() if i not in matched_p]:
        do(delete_instance(session.ann, pid))
        count("remove", 2, class_of(pid))
    for g, (p, iou) in list(match.items()):
        if class_of(p) != class_of(g):
            cmd, nid = change_class(session.ann, p, class_of(g))
            do(cmd)
            match[g] = (nid, iou)
            count("class fix", 3, class_of(g))
        if iou < TOUCH_UP_IOU:
            count("touch up", 1, class_of(g))
    drawn_classes = set()
    for g in gt.instance_ids():
        if g in match:
            continue
        cmd, nid = new_instance(session.ann, class_of(g))
        do(cmd)
        do(paint(session.ann, gt.instance_map == g, nid, overwrite=True))
        match[g] = (nid, 1.0)
        count("draw", 1, class_of(g))
        drawn_classes.add(class_of(g))
    for c in drawn_classes:
        count("class keys", 1, c)
    wanted = {frozenset(match[m][0] for m in grp.members): grp.class_id for grp in gt.groups.values()}
    have = {gid: (frozenset(g.members), g.class_id) for gid, g in session.ann.groups.items()}
    for members, cls in wanted.items():
        best = max(have.values(), key=lambda h: len(h[0] & members), default=(frozenset(), 0))
        if best == (members, cls):
            continue  # an accepted proposal group is this ground-truth group already
        if best[0] and best[0] <= members:  # a part of it: click the group, Shift+click the rest, Ctrl+G
            count("group", 2 + len(members - best[0]) + (3 if best[1] != cls else 0), cls)
        else:
            first = min(members)
            count("group", len(members) + 1 + (DEFAULT_GROUP_FOR_LIGHT.get(class_of(first)) != cls), cls)
        do(group_lights(session.ann, members, cls))
    for gid, grp in list(session.ann.groups.items()):  # proposal groups left over
        if wanted.get(frozenset(grp.members)) != grp.class_id:
            do(ungroup(session.ann, gid))
            count("ungroup", 2, grp.class_id)


def check_equal(gt, ann) -> None:
    """Raise AssertionError unless ``ann`` reproduces ``gt`` (module doc)."""
    from npsim_core.annotation import class_of

    match = match_lights(gt, ann)
    assert len(match) == len(gt.instance_ids()) == len(ann.instance_ids()), "lights differ"
    assert all(class_of(p) == class_of(g) for g, (p, _) in match.items()), "classes differ"
    want = sorted((g.class_id, sorted(match[m][0] for m in g.members)) for g in gt.groups.values())
    have = sorted((g.class_id, sorted(g.members)) for g in ann.groups.values())
    assert want == have, "groups differ"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", default="512x256")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--variants", default="default,hard")
    ap.add_argument("--thresholds", default="0.5,0.7,0.9")
    args = ap.parse_args(argv)
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from PySide6.QtCore import QCoreApplication

    from npsim_cli.options import parse_size
    from npsim_core.proposals import propose_for_scene
    from npsim_core.synthetic import street_scene
    from npsim_gui.editor.proposals import ProposalBook
    from npsim_gui.editor.session import EditorSession

    _app = QCoreApplication.instance() or QCoreApplication(sys.argv[:1])  # noqa: F841 (Qt objects need it)
    w, h = parse_size(args.size)
    thresholds = [float(t) for t in args.thresholds.split(",") if t]
    kinds = ("draw", "class keys", "group", "accept", "remove", "class fix", "touch up", "ungroup")
    rows = []
    for variant in [v for v in args.variants.split(",") if v]:
        for seed in [int(s) for s in args.seeds.split(",") if s]:
            scene = street_scene(w, h, seed, variant)
            gt = scene.lights
            t0 = time.perf_counter()
            props = propose_for_scene(scene)
            t_prop = time.perf_counter() - t0
            for t in [None] + thresholds:
                s = EditorSession()
                s.load(scene.image, scene.labels, None)
                counts = dict.fromkeys(kinds, 0)
                by_cat: dict[tuple[str, str], int] = {}
                if t is not None:
                    book = ProposalBook(props)
                    book.accept_above(s, t)
                    counts["accept"] = 2 + (abs(t - 0.9) > 1e-9)  # propose, accept above (+ move the slider)
                finish_by_hand(s, gt, counts, by_cat)
                check_equal(gt, s.ann)
                s.shutdown()
                rows.append((variant, seed, t, counts, len(gt.instance_ids()), len(gt.groups), t_prop, by_cat))
    load = os.getloadavg()[0]
    print(f"# Editor actions to the ground truth, synthetic street {w}x{h} (load {load:.1f})\n")
    print("| variant | seed | GT lights | GT groups | proposals accepted ≥ | " + " | ".join(kinds) + " | total |")
    print("|---|---|---|---|---|" + "---|" * (len(kinds) + 1))
    for variant, seed, t, c, n, ng, *_ in rows:
        print(f"| {variant} | {seed} | {n} | {ng} | {'no proposals' if t is None else f'{t:.2f}'} | "
              + " | ".join(str(c[k]) for k in kinds) + f" | {sum(c.values())} |")
    print("\n| variant | without proposals (mean actions) | " +
          " | ".join(f"accept ≥ {t:.2f}" for t in thresholds) + " |")
    print("|---|---|" + "---|" * len(thresholds))
    for variant in dict.fromkeys(r[0] for r in rows):
        tot = {t: np.mean([sum(r[3].values()) for r in rows if r[0] == variant and r[2] == t])
               for t in [None] + thresholds}
        print(f"| {variant} | {tot[None]:.1f} | " + " | ".join(
            f"{tot[t]:.1f} ({100 * (1 - tot[t] / tot[None]):.0f} % fewer)" for t in thresholds) + " |")
    # What the actions are spent on: mean per frame, per kind of action and category of light or group.
    cats = ("windows", "vehicles", "street lamps", "signals", "other")
    spent = ("draw", "group", "remove", "touch up", "class fix", "ungroup")
    print("\nWhat the actions are spent on (mean per frame, each cell windows / vehicles / street lamps / "
          "signals / other; draw = missed lights, group = grouping and completing groups, remove = false "
          "lights, ungroup = proposed groups not kept):\n")
    print("| variant | accepted ≥ | " + " | ".join(spent) + " |")
    print("|---|---|" + "---|" * len(spent))
    for variant in dict.fromkeys(r[0] for r in rows):
        for t in [None] + thresholds:
            sel = [r[7] for r in rows if r[0] == variant and r[2] == t]
            print(f"| {variant} | {'none' if t is None else f'{t:.2f}'} | " + " | ".join(
                " / ".join(f"{np.mean([b.get((k, c), 0) for b in sel]):.0f}" for c in cats) for k in spent) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
