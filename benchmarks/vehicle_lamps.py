"""Where the vehicle lamps go: one frame's missed true lamps and false lamps, printed and drawn.

    .venv/bin/python -m benchmarks.vehicle_lamps [--size 2048x1024] [--variant hard] [--seed 0]
                                                 [--out /tmp/vehicle_lamps.png]
    .venv/bin/python -m benchmarks.vehicle_lamps --causes [--sizes 512x256,2048x1024]
                                                 [--variants default,hard,lights] [--seeds 0,1,2]
    .venv/bin/python -m benchmarks.vehicle_lamps --ceiling [--sizes ...] [--variants ...] [--seeds ...]

``--causes`` prints, per size and variant (seeds pooled), the true lamps by how much of them shows
(under 4 px; a sliver, under 30 % of the whole lamp visible; partly hidden, 30-60 %; the rest) and
how many of each are matched, and the false lamps -- the table of docs/proposals.md "Sixth pass".

``--ceiling`` prints, per size and variant (seeds pooled), how many true lamps an image-based
proposer could see at all: their visible pixels (the truth's mask), how far they depart from the
paint around them on their car (:func:`departure`, 8-bit levels in the day image the proposer sees,
max and median over the lamp's pixels), and the recall if every lamp with >= 2 visible px and a
departure of at least ``CEIL_WEAK`` (the weakest cue the proposer reads: ``_lamp_coloured``'s
10-level lean toward red) or ``CEIL_SNAP`` levels (the snap's and ``_sliver_lamp``'s threshold,
``SLIVER_DIFF``) were found and nothing else -- docs/proposals.md "Fifteenth pass".

Runs the vehicles proposer alone on a synthetic street frame (the scene's depth and Cityscapes
instance ids, as ``benchmarks.proposals``), matches vehicle lamps one-to-one at mask IoU >= 0.3
(``npsim_core.proposals.evaluate``) and writes an overlay: true lamps matched (green outline),
missed (red fill), proposed lamps not matching (yellow fill), matched proposals (cyan outline).
Each missed lamp is printed with its size, depth, the share of the whole lamp (0.30 x 0.15 m
at its depth) that is visible, its car (instance id and pixels: the proposer looks at cars from
``vehicle_min_area_px``) and its mate, the car's other lamp: found (matched), missed, or hidden (no
visible pixel); each false lamp with the IoU of its best true lamp.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

import numpy as np

LAMP_CLASSES = (3, 4, 5, 6)
#: ``--ceiling``'s departures (8-bit levels, the largest channel difference from the paint): the weakest
#: cue the proposer reads (a 10-level lean toward red, ``_lamp_coloured``) and the snap's / the sliver's.
CEIL_WEAK, CEIL_SNAP = 10.0, 40.0


def lamp_matches(gt, pred, iou: float = 0.3) -> tuple[dict[int, int], dict[int, tuple[int, float]]]:
    """(true lamp id -> proposed id) matched greedily at mask IoU >= ``iou``, and per proposed lamp its
    best true lamp and IoU (0 when it overlaps none)."""
    from npsim_core.annotation import class_of

    g_area, p_area = gt.areas(), pred.areas()
    g_ids = [i for i in g_area if class_of(i) in LAMP_CLASSES]
    p_ids = [i for i in p_area if class_of(i) in LAMP_CLASSES]
    g, p = gt.instance_map.ravel(), pred.instance_map.ravel()
    sel = np.isin(g, g_ids) & np.isin(p, p_ids)
    pairs, inter = np.unique(np.stack([g[sel], p[sel]]).astype(np.int64), axis=1, return_counts=True)
    cand = sorted(((n / (g_area[a] + p_area[b] - n), a, b) for (a, b), n in zip(pairs.T.tolist(), inter.tolist())),
                  reverse=True)
    best: dict[int, tuple[int, float]] = {i: (0, 0.0) for i in p_ids}
    for v, a, b in cand:
        if v > best[b][1]:
            best[b] = (a, v)
    out: dict[int, int] = {}
    used: set[int] = set()
    for v, a, b in cand:
        if v >= iou and a not in out and b not in used:
            out[a] = b
            used.add(b)
    return out, best


def _visible(gt, depth, fy: float) -> dict[int, tuple[int, float]]:
    """Per true lamp: its pixels and the share of the whole lamp (0.30 x 0.15 m at its depth) they are."""
    from npsim_core.annotation import class_of

    out = {}
    for gid, a in gt.areas().items():
        if class_of(gid) in LAMP_CLASSES:
            z = float(np.nanmedian(depth[gt.instance_map == gid]))
            out[gid] = (a, a / (0.30 * 0.15 * (fy / z) ** 2))
    return out


def departure(img: np.ndarray, gt_map: np.ndarray, inst: np.ndarray, gid: int) -> tuple[int, float, float]:
    """One true lamp's visible pixels and how far they depart from the paint around it: per pixel the
    largest channel difference (8-bit) between the day image and the median colour of its car's pixels
    (the Cityscapes instance under most of the lamp) 2-4 px from the lamp (not the colour bled a pixel
    around it), no light's pixel among them; (pixels, max, median) over the lamp's pixels, departures 0
    when no such paint shows (the lamp's car hidden around it)."""
    import cv2

    lamp = gt_map == gid
    ys, xs = np.nonzero(lamp)
    n = int(ys.size)
    if n == 0:
        return 0, 0.0, 0.0
    a, b = max(0, int(ys.min()) - 5), max(0, int(xs.min()) - 5)
    sl = (slice(a, int(ys.max()) + 6), slice(b, int(xs.max()) + 6))
    li = lamp[sl].astype(np.uint8)
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    near = cv2.dilate(li, k, iterations=1).astype(bool)
    far = cv2.dilate(li, k, iterations=4).astype(bool)
    v = inst[lamp]
    v = v[v >= 1000]
    car = int(np.bincount(v - v.min()).argmax() + v.min()) if v.size else -1
    ring = far & ~near & (inst[sl] == car) & (gt_map[sl] == 0)
    if not ring.any():
        return n, 0.0, 0.0
    sub = img[sl].astype(np.float32)
    paint = np.median(sub[ring], axis=0)
    dev = np.abs(sub[lamp[sl]] - paint).max(-1)
    return n, float(dev.max()), float(np.median(dev))


def ceiling(sizes: list[str], variants: list[str], seeds: list[int], detail: bool = False) -> None:
    """The ``--ceiling`` table (module doc); with ``detail`` each missed lamp's row too."""
    import os

    from benchmarks.proposals import frame
    from npsim_core.annotation import class_of
    from npsim_core.proposals import ProposalParams, propose_lights

    params = replace(ProposalParams(), categories=("vehicles",))
    print("| size | variant | seeds | true | matched / proposed | >= 2 px | >= 2 px and >= 10 levels (matched) "
          "| >= 2 px and >= 40 levels (matched) | ceiling recall 10 / 40 | matched outside the 10-level set | missed: median max departure |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for size in sizes:
        W, H = (int(v) for v in size.split("x"))
        for variant in variants:
            n_true = n_match = n_prop = n2 = outside = 0
            weak = [0, 0]
            snap = [0, 0]
            missed_dev = []
            for seed in seeds:
                scene, inst = frame(W, H, seed, variant)
                pred = propose_lights(scene.image, scene.labels, scene.depth, scene.intrinsics, inst,
                                      params).above(0.5)
                match, best = lamp_matches(scene.lights, pred)
                n_prop += len(best)
                gmap = scene.lights.instance_map
                for gid in scene.lights.areas():
                    if class_of(gid) not in LAMP_CLASSES:
                        continue
                    n, mx, med = departure(scene.image, gmap, inst, gid)
                    hit = gid in match
                    n_true += 1
                    n_match += hit
                    outside += hit and (n < 2 or mx < CEIL_WEAK)
                    if n < 2:
                        continue
                    n2 += 1
                    if mx >= CEIL_WEAK:
                        weak[0] += 1
                        weak[1] += hit
                    if mx >= CEIL_SNAP:
                        snap[0] += 1
                        snap[1] += hit
                    if not hit:
                        missed_dev.append(mx)
                        if detail:
                            ys, xs = np.nonzero(gmap == gid)
                            print(f"    {size} {variant} seed {seed} missed {gid}: {n} px at x {xs.min()}-{xs.max()} "
                                  f"y {ys.min()}-{ys.max()}, departure max {mx:.0f} median {med:.0f}")
            md = f"{np.median(missed_dev):.0f}" if missed_dev else "-"
            print(f"| {size} | {variant} | {','.join(map(str, seeds))} | {n_true} | {n_match} / {n_prop} | {n2} | "
                  f"{weak[0]} ({weak[1]}) | {snap[0]} ({snap[1]}) | {weak[0] / max(1, n_true):.2f} / "
                  f"{snap[0] / max(1, n_true):.2f} | {outside} | {md} (of {len(missed_dev)}) |")
    print(f"\n(load {os.getloadavg()[0]:.1f})")


def causes(sizes: list[str], variants: list[str], seeds: list[int]) -> None:
    """The ``--causes`` table (module doc)."""
    import os

    from benchmarks.proposals import frame
    from npsim_core.proposals import ProposalParams, propose_lights

    params = replace(ProposalParams(), categories=("vehicles",))
    kinds = ("under 4 px", "sliver < 30 %", "partly hidden 30-60 %", "60 % or more visible")
    print("| size | variant | " + " | ".join(f"{k} (matched / true)" for k in kinds) + " | false lamps |")
    print("|---|---|" + "---|" * (len(kinds) + 1))
    for size in sizes:
        W, H = (int(v) for v in size.split("x"))
        for variant in variants:
            tot = {k: [0, 0] for k in kinds}
            false = 0
            for seed in seeds:
                scene, inst = frame(W, H, seed, variant)
                pred = propose_lights(scene.image, scene.labels, scene.depth, scene.intrinsics, inst,
                                      params).above(0.5)
                match, best = lamp_matches(scene.lights, pred)
                false += len(best) - len(match)
                depth = scene.depth_gt if getattr(scene, "depth_gt", None) is not None else scene.depth
                for gid, (a, vis) in _visible(scene.lights, depth, float(scene.intrinsics.fy)).items():
                    k = kinds[0] if a < 4 else kinds[1] if vis < 0.3 else kinds[2] if vis < 0.6 else kinds[3]
                    tot[k][0] += gid in match
                    tot[k][1] += 1
            print(f"| {size} | {variant} | " + " | ".join(f"{m} / {n}" for m, n in tot.values()) + f" | {false} |")
    print(f"\n(load {os.getloadavg()[0]:.1f})")


def main(argv: list[str] | None = None) -> int:
    import cv2

    from benchmarks.proposals import frame
    from npsim_core.annotation import class_of
    from npsim_core.proposals import ProposalParams, propose_lights

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", default="2048x1024")
    ap.add_argument("--variant", default="hard")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="/tmp/vehicle_lamps.png")
    ap.add_argument("--causes", action="store_true", help="the pooled table of true lamps by visibility")
    ap.add_argument("--ceiling", action="store_true", help="the recall an image-based proposer could reach")
    ap.add_argument("--detail", action="store_true", help="with --ceiling: each missed lamp of >= 2 px")
    ap.add_argument("--sizes", default="512x256,2048x1024")
    ap.add_argument("--variants", default="default,hard,lights")
    ap.add_argument("--seeds", default="0,1,2")
    args = ap.parse_args(argv)
    if args.ceiling:
        ceiling(args.sizes.split(","), args.variants.split(","), [int(v) for v in args.seeds.split(",")],
                args.detail)
        return 0
    if args.causes:
        causes(args.sizes.split(","), args.variants.split(","), [int(v) for v in args.seeds.split(",")])
        return 0
    W, H = (int(v) for v in args.size.split("x"))
    scene, inst = frame(W, H, args.seed, args.variant)
    params = replace(ProposalParams(), categories=("vehicles",))
    pred = propose_lights(scene.image, scene.labels, scene.depth, scene.intrinsics, inst, params).above(0.5)
    gt = scene.lights
    match, best = lamp_matches(gt, pred)
    g_area = gt.areas()
    fy = float(scene.intrinsics.fy)
    depth = scene.depth_gt if getattr(scene, "depth_gt", None) is not None else scene.depth
    img = scene.image[..., ::-1].copy()
    car_of = {}  # true lamp -> the Cityscapes instance (car) under most of its pixels, 0 for none
    for gid in g_area:
        if class_of(gid) in LAMP_CLASSES:
            v = inst[gt.instance_map == gid]
            v = v[v >= 1000]
            car_of[gid] = int(np.bincount(v - v.min()).argmax() + v.min()) if v.size else 0
    print(f"{W}x{H} {args.variant} seed {args.seed}: {sum(class_of(i) in LAMP_CLASSES for i in g_area)} true lamps, "
          f"{len(best)} proposed, {len(match)} matched")
    for gid, a in sorted(g_area.items()):
        if class_of(gid) not in LAMP_CLASSES:
            continue
        m = gt.instance_map == gid
        ys, xs = np.nonzero(m)
        z = float(np.nanmedian(depth[m]))
        whole = 0.30 * 0.15 * (fy / z) ** 2
        if gid in match:
            cv2.drawContours(img, cv2.findContours(m.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)[0],
                             -1, (0, 255, 0), 1)
            continue
        img[m] = (0, 0, 255)
        over = {b: v for b, (a_, v) in best.items() if a_ == gid}
        car = car_of[gid]
        mates = [k for k, c in car_of.items() if c == car and k != gid] if car else []
        mate = ("hidden" if not mates else "found" if any(k in match for k in mates) else "missed")
        print(f"  missed {gid} class {class_of(gid)} at x {xs.min()}-{xs.max()} y {ys.min()}-{ys.max()}: {a} px, "
              f"z {z:.1f} m, visible {a / whole:.2f}, car {car} ({int((inst == car).sum()) if car else 0} px), "
              f"mate {mate}" + (f", overlapped by {over}" if over else ""))
    for pid, (gid, v) in sorted(best.items()):
        m = pred.instance_map == pid
        if pid in match.values():
            cv2.drawContours(img, cv2.findContours(m.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)[0],
                             -1, (255, 255, 0), 1)
            continue
        img[m] = (0, 255, 255)
        ys, xs = np.nonzero(m)
        print(f"  false {pid} class {class_of(pid)} at x {xs.min()}-{xs.max()} y {ys.min()}-{ys.max()}: "
              f"{int(m.sum())} px, best true {gid} IoU {v:.2f}")
    cv2.imwrite(args.out, img)
    print(f"overlay: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
