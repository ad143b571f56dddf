"""Geometry estimators on the synthetic street scene: speed against error.

    .venv/bin/python benchmarks/geometry.py [--size 512x256] [--seed 0] [--checkpoint DIR]

Rows: the semantic pop-up prior, a constant-depth baseline (median of the
ground truth, fronto-parallel normals), the scene's simulated network
prediction (ground truth with realistic errors, see npsim_core.synthetic) and,
with ``--checkpoint``, a local depth network aligned on the pop-up prior.
Errors over all pixels with valid ground truth (sky excluded), docs/method.md §9.2.
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", default="512x256", help="WxH of the synthetic scene")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per estimator (best is shown)")
    ap.add_argument("--checkpoint", help="local transformers depth checkpoint folder (optional)")
    args = ap.parse_args(argv)
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
