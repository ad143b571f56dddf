"""Geometry estimators on the synthetic street scene: speed against error.

    .venv/bin/python -m benchmarks.geometry [--size 512x256] [--seed 0] [--checkpoint DIR]
    .venv/bin/python -m benchmarks.geometry --variants [--sizes 512x256,2048x1024] [--seed 0]
    .venv/bin/python -m benchmarks.geometry --chain [--size 512x256] [--seeds 0] [--which canopy,hard2]

Rows: the semantic pop-up prior, a constant-depth baseline (median of the
ground truth, fronto-parallel normals), the scene's simulated network
prediction (ground truth with realistic errors, see npsim_core.synthetic) and,
with ``--checkpoint``, a local depth network aligned on the pop-up prior.
Errors over all pixels with valid ground truth (sky excluded), docs/method.md §9.2.

``--variants``: the pop-up prior on the hard street layouts (docs/synthetic.md),
AbsRel per class and per variant and seed (``--seeds 0,1,2``), the share of pixels
placed at the far limit (``far``) and of those the ones with a visible ground contact
below them (``far|contact``, should be 0), the share of pixels the prior's confidence
map puts below 0.5 and the AbsRel there and elsewhere, and the prior's time (best of
``--repeat``). ``--priors flat,default``: rows for
``PopupParams(facades="flat", sidewalk_height=0)`` (the first prior) and the default (``street_line``:
the default without ``under_canopy``, the prior before the bus-shelter fix).
The scenes are the exact ground truth and labels of ``make_street_scene`` without the
render (the prior reads only labels and camera).

``--chain``: :func:`chain_table`, what the prior's confidence changes through the chain.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np


def _row(name, seconds, depth, normals, scene):
    from npsim_core.metrics import depth_metrics, normal_metrics

    dm = depth_metrics(depth, scene.depth_gt)
    nm = normal_metrics(normals, scene.normals_gt)
    cover = dm.n / max(int(np.isfinite(scene.depth_gt).sum()), 1)
    t = f"{seconds:8.3f}" if seconds is not None else "       -"
    return (f"| {name:<24} | {t} | {dm.abs_rel:6.3f} | {dm.rmse:7.2f} | {dm.delta1:5.3f} | {nm.rmse_deg:6.1f} | "
            f"{nm.median_deg:6.1f} | {nm.within_11_25:5.3f} | {nm.within_30:5.3f} | {cover:5.3f} |")


VARIANT_CLASSES = (("road", 7), ("sidewalk", 8), ("building", 11), ("vegetation", 21), ("car", 26))
BEFORE = {"facades": "flat", "sidewalk_height": 0.0}
PRIORS = {"flat": BEFORE, "segment": {"crowns": "segment"}, "columns": {"crowns": "columns"},
          "street_line": {"under_canopy": False}, "default": {}}
ALL_VARIANTS = "default,receding,occluded_base,corner,clutter,hard,busy,canopy,square,shopfront,hard2"


def far_limit_shares(depth: np.ndarray, scene, max_depth: float) -> tuple[float, float]:
    """Share of the pixels with ground truth placed at ``max_depth``, and share of them standing on visible ground.

    The second counts far-limit pixels of non-ground classes whose vertical run of their own
    label ends on a ground pixel (a visible ground contact right below them).
    """
    from npsim_core.labels import cityscapes

    valid = np.isfinite(scene.depth_gt)
    at_far = valid & np.isfinite(depth) & (depth >= 0.999 * max_depth)
    ground = cityscapes().lut("ground").astype(bool)[scene.labels]
    H = scene.labels.shape[0]
    # Row where each pixel's run of its own label ends (first row below with another label).
    change = np.ones(scene.labels.shape, dtype=bool)
    change[:-1] = scene.labels[1:] != scene.labels[:-1]
    rows = np.where(change, np.arange(H)[:, None], H)
    end = np.minimum.accumulate(rows[::-1], axis=0)[::-1]
    below = np.minimum(end + 1, H - 1)
    on_ground = ground[below, np.arange(scene.labels.shape[1])[None, :]] & (end < H - 1)
    contact = at_far & ~ground & on_ground
    n = max(int(valid.sum()), 1)
    return at_far.sum() / n, contact.sum() / n


def variant_scene(W: int, H: int, seed: int, variant: str):
    """Labels, camera and exact ground truth of a street variant, without the render (what the prior reads)."""
    from npsim_core.scene import Scene
    from npsim_core.synthetic import street_ground_truth
    from npsim_core.synthetic.street import SKY

    layout, intr, pose, gt = street_ground_truth(W, H, seed, variant=variant)
    hit = gt.prim >= 0
    labels = np.where(hit, layout.prims.label[np.maximum(gt.prim, 0)], SKY).astype(np.uint8)
    return Scene(name=f"street_{variant}_s{seed}", image=np.zeros((H, W, 3), np.uint8), labels=labels,
                 intrinsics=intr, depth_gt=gt.depth, normals_gt=gt.normals, camera_height=pose.height,
                 camera_pitch=pose.pitch)


def class_abs_rel(depth: np.ndarray, scene) -> dict[str, float]:
    """AbsRel of ``depth`` per class of :data:`VARIANT_CLASSES`, and over every pixel with ground truth ("all")."""
    from npsim_core.metrics import depth_metrics

    out = {name: depth_metrics(depth, scene.depth_gt, scene.labels == cid).abs_rel for name, cid in VARIANT_CLASSES}
    out["all"] = depth_metrics(depth, scene.depth_gt).abs_rel
    return out


def confidence_split(est, scene, threshold: float | None = None) -> tuple[float, float, float]:
    """Share of the pixels with ground truth whose confidence is below ``threshold``, and AbsRel below / at or above it.

    NaN when the estimate has no confidence map.
    """
    from npsim_core.geometry import LOW_CONFIDENCE
    from npsim_core.metrics import depth_metrics

    threshold = LOW_CONFIDENCE if threshold is None else threshold
    conf = est.confidence
    if conf is None:
        return float("nan"), float("nan"), float("nan")
    valid = np.isfinite(scene.depth_gt)
    low = valid & (conf < threshold)
    share = low.sum() / max(int(valid.sum()), 1)
    a = depth_metrics(est.depth, scene.depth_gt, low).abs_rel if low.any() else float("nan")
    high = valid & (conf >= threshold)
    b = depth_metrics(est.depth, scene.depth_gt, high).abs_rel if high.any() else float("nan")
    return float(share), float(a), float(b)


def variants_table(sizes: list[tuple[int, int]], seeds: list[int], repeat: int, variants: list[str],
                   priors: list[str] = ("flat", "default")) -> list[dict]:
    """Print (and return) the pop-up prior's table on the street variants (see the module docstring)."""
    from npsim_core.geometry.popup import PopupParams, estimate_popup

    rows = []
    print(f"pop-up prior on the street variants, seeds {','.join(map(str, seeds))}; load "
          f"{os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)")
    names = [n for n, _ in VARIANT_CLASSES] + ["all"]
    print("| size | variant | seed | prior | " + " | ".join(names)
          + " | far | far\\|contact | low conf share | AbsRel low | AbsRel high | time s |")
    print("|---|---|---|---|" + "---|" * len(names) + "---|---|---|---|---|---|")
    for W, H in sizes:
        for variant in variants:
            for seed in seeds:
                scene = variant_scene(W, H, seed, variant)
                for label in priors:
                    params = PopupParams(**PRIORS[label])
                    times, est = [], None
                    for _ in range(max(1, repeat)):
                        t0 = time.perf_counter()
                        est = estimate_popup(scene, params)
                        times.append(time.perf_counter() - t0)
                    err = class_abs_rel(est.depth, scene)
                    far, far_contact = far_limit_shares(est.depth, scene, params.max_depth)
                    low_share, low, high = confidence_split(est, scene)
                    rows.append({"size": f"{W}x{H}", "variant": variant, "seed": seed, "prior": label, **err,
                                 "far": far, "far_contact": far_contact, "low_confidence_share": low_share,
                                 "abs_rel_low": low, "abs_rel_high": high, "seconds": min(times)})
                    print(f"| {W}x{H} | {variant} | {seed} | {label} | "
                          + " | ".join(f"{err[n]:.3f}" for n in names)
                          + f" | {far:.4f} | {far_contact:.4f} | {low_share:.2f} | {low:.3f} | {high:.3f} "
                          f"| {min(times):.2f} |", flush=True)
    print(f"load after: {os.getloadavg()[0]:.2f}")
    return rows


def chain_table(size: tuple[int, int], seeds: list[int], variants: list[str]) -> list[dict]:
    """Print (and return) what wiring the prior's confidence into the chain changes, per variant and seed.

    ``Chain.compute`` with ``depth.source=prior`` on the variant's exact labels (a label-colour image
    for the filter), ``uncertainty.confidence_below`` 0 (off, "before") and the default (on, "after"):
    the uncertain map's share of the pixels with ground truth, AbsRel of the input, of the refined depth
    (``refine.keep_input`` on and off) and of the ray-cast mesh, the share of pixels below
    ``LOW_CONFIDENCE``, and the share of pixels where the mesh is within 1 % of the true depth and within
    its :func:`~npsim_core.mesh.quality.depth_error_bound` (docs/geometry.md, "Confidence in the chain").
    """
    from dataclasses import replace

    from npsim_core.chain.chain import Chain
    from npsim_core.chain.params import ChainParams
    from npsim_core.geometry import LOW_CONFIDENCE
    from npsim_core.mesh.quality import depth_error_bound, rasterize, reprojection_error
    from npsim_core.metrics import depth_metrics

    W, H = size
    palette = np.random.default_rng(0).integers(30, 230, (256, 3)).astype(np.uint8)
    print(f"the prior's confidence in the chain, {W}x{H}; load {os.getloadavg()[0]:.2f} (1-min average, "
          f"{os.cpu_count()} cores)")
    print("| variant | seed | U share | input AbsRel | refined | refined, keep_input off | mesh (ray-cast) "
          "| low-conf share | mesh within 1 % / within bound of the truth |")
    print("|---|---|---|---|---|---|---|---|---|")
    rows = []
    for variant in variants:
        for seed in seeds:
            scene = variant_scene(W, H, seed, variant)
            scene = scene.with_(image=palette[scene.labels])
            valid = np.isfinite(scene.depth_gt)
            r: dict = {}
            for tag, below in (("before", 0.0), ("after", LOW_CONFIDENCE)):
                for keep in (True, False):
                    p = ChainParams()
                    p = replace(p, depth=replace(p.depth, source="prior"),
                                uncertainty=replace(p.uncertainty, confidence_below=below),
                                refine=replace(p.refine, keep_input=keep))
                    chain = Chain(scene)
                    res = chain.compute(p, until="mesh" if keep else "refine")
                    r[tag, keep] = depth_metrics(res.depth, scene.depth_gt).abs_rel
                    if keep:
                        ras = rasterize(res.mesh, res.intrinsics)
                        conf = chain.engine.run(("geometry",), p).results["geometry"].confidence
                        r[tag, "U"] = float(res.uncertain[valid].mean())
                        r[tag, "mesh"] = depth_metrics(ras.depth, scene.depth_gt).abs_rel
                        r["input"] = depth_metrics(res.depth_in, scene.depth_gt).abs_rel
                        r["low"] = float(np.mean(conf[np.isfinite(conf)] < LOW_CONFIDENCE))
                        r["within"] = (reprojection_error(ras, scene.depth_gt, scene.labels)["within_tol"],
                                       reprojection_error(ras, scene.depth_gt, scene.labels,
                                                          tol=depth_error_bound(conf))["within_tol"])
            rows.append({"variant": variant, "seed": seed, **{str(k): v for k, v in r.items()}})
            print(f"| {variant} | {seed} | {r['before', 'U']:.3f} -> {r['after', 'U']:.3f} | {r['input']:.4f} "
                  f"| {r['before', True]:.4f} -> {r['after', True]:.4f} | {r['before', False]:.4f} -> "
                  f"{r['after', False]:.4f} | {r['before', 'mesh']:.4f} -> {r['after', 'mesh']:.4f} | {r['low']:.2f} "
                  f"| {r['within'][0]:.3f} / {r['within'][1]:.3f} |", flush=True)
    print(f"load after: {os.getloadavg()[0]:.2f}")
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", default="512x256", help="WxH of the synthetic scene")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per estimator (best is shown)")
    ap.add_argument("--checkpoint", help="local transformers depth checkpoint folder (optional)")
    ap.add_argument("--variants", action="store_true",
                    help="the pop-up prior before/after on the hard street variants, AbsRel per class")
    ap.add_argument("--sizes", default="512x256,2048x1024", help="WxH list for --variants")
    ap.add_argument("--seeds", help="seed list for --variants (default: --seed)")
    ap.add_argument("--which", default=ALL_VARIANTS, help="street variants for --variants")
    ap.add_argument("--priors", default="flat,default",
                    help="prior settings for --variants: flat, segment (crowns as one segment), "
                         "columns (crowns per column, no canopy slab), street_line (no under_canopy: a "
                         "footless facade under the crowns on its street line), default")
    ap.add_argument("--chain", action="store_true",
                    help="the prior's confidence in the chain (uncertain map, refinement, mesh) before/after, "
                         "per variant at --size")
    args = ap.parse_args(argv)
    if args.chain:
        seeds = [int(s) for s in args.seeds.split(",")] if args.seeds else [args.seed]
        chain_table(tuple(int(x) for x in args.size.lower().split("x")), seeds, args.which.split(","))
        return 0
    if args.variants:
        sizes = [tuple(int(x) for x in sz.lower().split("x")) for sz in args.sizes.split(",")]
        seeds = [int(s) for s in args.seeds.split(",")] if args.seeds else [args.seed]
        variants_table(sizes, seeds, args.repeat, args.which.split(","), args.priors.split(","))
        return 0
    W, H = (int(x) for x in args.size.lower().split("x"))

    from npsim_core.camera import normals_from_depth
    from npsim_core.geometry import estimate_geometry
    from npsim_core.geometry.network import NetworkParams, align_to_prior
    from npsim_core.synthetic import street_scene

    scene = street_scene(W, H, seed=args.seed)

    def best(fn):
        times, out = [], None
        for _ in range(max(1, args.repeat)):
            t0 = time.perf_counter()
            out = fn()
            times.append(time.perf_counter() - t0)
        return min(times), out

    print(f"synthetic street scene {W}x{H}, seed {args.seed}; load {os.getloadavg()[0]:.2f} "
          f"(1-min average, {os.cpu_count()} cores)")
    print("| estimator                |   time s | AbsRel | RMSE m |   δ1  | n RMSE° | n med° | <11.25° | <30° | cover |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    t, est = best(lambda: estimate_geometry(scene, "popup"))
    print(_row("semantic pop-up", t, est.depth, est.normals, scene))
    valid = np.isfinite(scene.depth_gt)
    const = np.where(valid, np.nanmedian(scene.depth_gt), np.nan).astype(np.float32)
    print(_row("constant (GT median)", None, const, normals_from_depth(const, scene.intrinsics), scene))
    if scene.depth is not None and scene.normals is not None:
        print(_row("simulated prediction", None, scene.depth, scene.normals, scene))
    # The alignment alone: a relative network that were perfect up to an unknown affine map of
    # inverse depth (oracle), and the simulated prediction handed over as relative inverse depth.
    params = NetworkParams(checkpoint="-")
    with np.errstate(divide="ignore"):
        oracle = 2.7 / scene.depth_gt.astype(np.float64) + 0.05
    t, (d, _) = best(lambda: align_to_prior(scene, oracle, params))
    print(_row("oracle relative, aligned", t, d, normals_from_depth(d, scene.intrinsics), scene))
    if scene.depth is not None:
        with np.errstate(divide="ignore"):
            rel = 0.5 / scene.depth.astype(np.float64) + 0.1
        _, (d, _) = best(lambda: align_to_prior(scene, rel, params))
        print(_row("sim. pred. as relative", None, d, normals_from_depth(d, scene.intrinsics), scene))
    if args.checkpoint:
        t, est = best(lambda: estimate_geometry(scene, "network", NetworkParams(checkpoint=args.checkpoint)))
        print(_row("network (aligned)", t, est.depth, est.normals, scene))
    return 0


if __name__ == "__main__":
    sys.exit(main())
