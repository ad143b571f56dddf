"""Depth refinement kernel benchmark: speed against error on the synthetic street (docs/method.md §9).

For each size it prints markdown tables of

* the cross-bilateral filter: exact reference (512x256 only) vs the fast filter
  vs OpenCV's ximgproc.jointBilateralFilter (d=61, colour term only, the peer);
* the variance filter (uncertain map);
* the refinement: faithful Adam (1000 steps, lr 1e-4) vs the fast L-BFGS at
  several iteration budgets and both loss variants -- wall time, peak RSS,
  final loss, max depth change, depth AbsRel/RMSE and normal angular RMSE
  (normals from depth) against ground truth, and the time the fast optimiser
  needs to reach Adam's final loss;
* the whole kernel (filter + variance + fast refinement at its default budget).

Run: ``python benchmarks/refine.py [--sizes 512x256,2048x1024]`` or ``npsim bench refine``.
Timings on a shared machine are noisy: the load average is printed with them.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from npsim_core.camera import normals_from_depth  # noqa: E402
from npsim_core.metrics import depth_metrics, normal_metrics  # noqa: E402
from npsim_core.refine import (FilterParams, RefineParams, UncertaintyParams, cross_bilateral,  # noqa: E402
                               cross_bilateral_reference, refine_depth, uncertain_map)


class PeakRSS:
    """Peak resident set size (MB) of this process while the block runs (sampled every 5 ms)."""

    def __enter__(self):
        self.peak = self._rss()
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._poll, daemon=True)
        self._t.start()
        self.t0 = time.perf_counter()
        return self

    def _poll(self):
        while not self._stop.wait(0.005):
            self.peak = max(self.peak, self._rss())

    @staticmethod
    def _rss() -> float:
        try:
            with open("/proc/self/status") as f:
                for line in f:
                    if line.startswith("VmRSS:"):
                        return int(line.split()[1]) / 1024.0
        except OSError:
            pass
        import resource
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0

    def __exit__(self, *exc):
        self.seconds = time.perf_counter() - self.t0
        self._stop.set()
        self._t.join()
        self.peak = max(self.peak, self._rss())
        return False


def md_table(header, rows) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def scores(scene, depth):
    dm = depth_metrics(depth, scene.depth_gt)
    nm = normal_metrics(normals_from_depth(depth, scene.intrinsics), scene.normals_gt)
    return dm, nm


def bench_filter(scene, size_label, reference: bool, fp: FilterParams):
    rows = []
    d, img, lab = scene.depth, scene.image, scene.labels
    rng = float(np.nanmax(d) - np.nanmin(d))
    ref = None
    if reference:
        with PeakRSS() as m:
            ref = cross_bilateral_reference(d, img, lab, fp)
        rows.append(["reference (exact, brute force)", f"{m.seconds:.2f}", "1x", "0", "0", f"{m.peak:.0f}"])
        t_ref = m.seconds
    cross_bilateral(d, img, lab, fp)  # warm-up (OpenCV/numpy first-call costs)
    with PeakRSS() as m:
        fast = cross_bilateral(d, img, lab, fp)
    err = (f"{np.nanmean(np.abs(fast - ref)) / rng * 100:.3f}", f"{np.nanmean(np.abs(fast - ref)):.4f}") \
        if ref is not None else ("n/a", "n/a")
    rows.append([f"fast (K={FilterParams().clusters}, M={FilterParams().neighbours})", f"{m.seconds:.3f}",
                 f"{t_ref / m.seconds:.0f}x" if ref is not None else "-", *err, f"{m.peak:.0f}"])
    t_fast = m.seconds
    try:
        import cv2

        valid = np.isfinite(d) & (d > 0)
        lab_img = cv2.cvtColor(img.astype(np.float32) / 255.0, cv2.COLOR_RGB2Lab)
        src = np.where(valid, d, 0).astype(np.float32)
        with PeakRSS() as m:
            peer = cv2.ximgproc.jointBilateralFilter(lab_img, src, 61, 5.0, 10.0)
        peer = np.where(valid, peer, np.nan)
        err = (f"{np.nanmean(np.abs(peer - ref)) / rng * 100:.3f}", f"{np.nanmean(np.abs(peer - ref)):.4f}") \
            if ref is not None else ("n/a", "n/a")
        rows.append(["OpenCV jointBilateralFilter d=61 (colour only, peer)", f"{m.seconds:.2f}",
                     f"{t_ref / m.seconds:.0f}x" if ref is not None else "-", *err, f"{m.peak:.0f}"])
    except (ImportError, AttributeError) as exc:  # pragma: no cover
        rows.append([f"OpenCV peer unavailable: {exc}", "-", "-", "-", "-", "-"])
    print(f"\n#### Cross-bilateral filter, {size_label} (depth range {rng:.1f} m, domain '{fp.domain}')\n")
    print(md_table(["method", "time (s)", "speed-up vs reference", "MAE vs reference (% of range)",
                    "MAE vs reference (m)", "peak RSS (MB)"], rows))
    return fast, t_fast


def bench_refine(scene, filtered, U, size_label, budgets, adam_steps, adam_scale_aware: bool):
    rows = []
    dm, nm = scores(scene, scene.depth)
    rows.append(["input: predicted depth", "-", "-", "-", "-", f"{dm.abs_rel:.4f}", f"{dm.rmse:.3f}",
                 f"{nm.rmse_deg:.2f}", f"{nm.median_deg:.2f}"])
    dm, nm = scores(scene, filtered)
    rows.append(["after cross-bilateral filter", "-", "-", "-", "-", f"{dm.abs_rel:.4f}", f"{dm.rmse:.3f}",
                 f"{nm.rmse_deg:.2f}", f"{nm.median_deg:.2f}"])
    runs = {}
    configs = [("adam_faithful", f"Adam faithful, {adam_steps} steps, lr 1e-4",
                RefineParams(optimizer="adam_faithful", steps=adam_steps))]
    for b in budgets:
        configs.append((f"fast{b}", f"fast L-BFGS, {b} iterations", RefineParams(steps=b)))
    configs.append(("fast_sa", f"fast L-BFGS, {budgets[-1]} it., scale_aware loss",
                    RefineParams(steps=budgets[-1], loss="scale_aware")))
    if adam_scale_aware:
        configs.append(("adam_sa", f"Adam faithful, {adam_steps} steps, scale_aware loss",
                        RefineParams(optimizer="adam_faithful", steps=adam_steps, loss="scale_aware")))
    h, w = filtered.shape
    warm = (slice(0, min(h, 32)), slice(0, min(w, 64)))  # first-call costs of torch kernels, not the method's
    refine_depth(filtered[warm], scene.normals[warm], _crop_intr(scene.intrinsics, min(w, 64), min(h, 32)), U[warm],
                 RefineParams(steps=2))
    for key, label, p in configs:
        with PeakRSS() as m:
            r = refine_depth(filtered, scene.normals, scene.intrinsics, U, p)
        runs[key] = r
        dm, nm = scores(scene, r.depth)
        rows.append([label, f"{m.seconds:.2f}", f"{m.peak:.0f}", f"{r.final_loss:.5g}", f"{r.max_change_m:.3f}",
                     f"{dm.abs_rel:.4f}", f"{dm.rmse:.3f}", f"{nm.rmse_deg:.2f}", f"{nm.median_deg:.2f}"])
        print(f"  [{size_label}] {label}: {r.message}", file=sys.stderr, flush=True)
    print(f"\n#### Refinement, {size_label} (λ = appendix_b (1, 5, 1); losses in each variant's own units)\n")
    print(md_table(["method", "time (s)", "peak RSS (MB)", "final loss", "max |Δd| (m)", "AbsRel", "RMSE (m)",
                    "normal RMSE (°)", "normal median (°)"], rows))
    adam = runs["adam_faithful"]
    target = adam.final_loss
    t_adam = adam.history["time_s"][-1]
    lines = []
    for key, r in runs.items():
        if not key.startswith("fast") or key == "fast_sa":
            continue
        h = r.history
        hit = np.flatnonzero(h["total"] <= target)
        reach = f"{h['time_s'][hit[0]]:.2f} s (iteration {hit[0]})" if hit.size else "not reached"
        ratio = f", {t_adam / h['time_s'][hit[0]]:.0f}x sooner" if hit.size and h["time_s"][hit[0]] > 0 else ""
        lines.append(f"- {key}: reaches Adam's final loss {target:.5g} (Adam: {t_adam:.1f} s) after {reach}{ratio}; "
                     f"ends at {r.final_loss:.5g} ({'lower' if r.final_loss < target else 'NOT lower'})")
    print("\n" + "\n".join(lines))
    return runs


def _crop_intr(intr, w, h):
    from npsim_core.camera import Intrinsics

    return Intrinsics(intr.fx, intr.fy, intr.cx, intr.cy, w, h)


def bench_kernel(scene, size_label, refine_params: RefineParams, fp: FilterParams):
    with PeakRSS() as m:
        t0 = time.perf_counter()
        f = cross_bilateral(scene.depth, scene.image, scene.labels, fp)
        t1 = time.perf_counter()
        U = uncertain_map(f, scene.labels)
        t2 = time.perf_counter()
        r = refine_depth(f, scene.normals, scene.intrinsics, U, refine_params)
        t3 = time.perf_counter()
    dm, nm = scores(scene, r.depth)
    return [size_label, f"{t1 - t0:.3f}", f"{t2 - t1:.3f}", f"{t3 - t2:.2f} ({r.steps} it.)", f"{t3 - t0:.2f}",
            f"{m.peak:.0f}", f"{dm.abs_rel:.4f}", f"{nm.rmse_deg:.2f}"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="512x256,2048x1024", help="comma-separated WxH list")
    ap.add_argument("--adam-steps", type=int, default=1000, help="faithful Adam steps (thesis: 1000)")
    ap.add_argument("--budgets", default="10,30,100", help="fast optimiser iteration budgets")
    ap.add_argument("--reference-max-pixels", type=int, default=512 * 256,
                    help="run the brute-force reference filter only up to this many pixels")
    ap.add_argument("--kernel-budget", type=int, default=10, help="fast iterations in the whole-kernel row")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--filter-domain", choices=("depth", "inverse"), default="depth",
                    help="FilterParams.domain used by every row (default: the formula's 'depth')")
    args = ap.parse_args(argv)
    from npsim_core.synthetic import street_scene

    sizes = [tuple(int(v) for v in s.lower().split("x")) for s in args.sizes.split(",") if s]
    budgets = [int(b) for b in args.budgets.split(",") if b]
    load = os.getloadavg()
    print(f"## Depth refinement kernel benchmark\n\nmachine: {os.cpu_count()} cores, load average "
          f"{load[0]:.2f} {load[1]:.2f} {load[2]:.2f} at start; torch threads 1 (RefineParams.threads)")
    kernel_rows = []
    for w, h in sizes:
        label = f"{w}x{h}"
        scene = street_scene(w, h, args.seed)
        fp = FilterParams(domain=args.filter_domain)
        fast, _ = bench_filter(scene, label, reference=w * h <= args.reference_max_pixels, fp=fp)
        with PeakRSS() as m:
            U = uncertain_map(fast, scene.labels)
        with PeakRSS() as m_abs:
            U_abs = uncertain_map(fast, scene.labels, UncertaintyParams(mode="absolute"))
        print(f"\n#### Variance filter, {label}\n")
        print(md_table(["mode", "time (s)", "uncertain fraction", "peak RSS (MB)"],
                       [["relative, τ=1e-3 (default)", f"{m.seconds:.3f}", f"{U.mean():.3f}", f"{m.peak:.0f}"],
                        ["absolute, μ_v=1e-3 m² (thesis)", f"{m_abs.seconds:.3f}", f"{U_abs.mean():.3f}",
                         f"{m_abs.peak:.0f}"]]))
        bench_refine(scene, fast, U, label, budgets, args.adam_steps, w * h <= args.reference_max_pixels)
        kernel_rows.append(bench_kernel(scene, label, RefineParams(steps=args.kernel_budget), fp))
    print(f"\n#### Whole kernel (fast filter + variance filter + fast refinement, {args.kernel_budget} iterations)\n")
    print(md_table(["size", "filter (s)", "variance (s)", "refine (s)", "total (s)", "peak RSS (MB)", "AbsRel",
                    "normal RMSE (°)"], kernel_rows))
    load = os.getloadavg()
    print(f"\nload average at end: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
