"""Depth refinement kernel benchmark: accuracy against time (docs/refine.md, docs/method.md §9).

For each synthetic-street size it prints markdown tables of

* the cross-bilateral filter: the default (inverse depth, σs scaled with the image width), the
  thesis setting (depth domain, 10 px at every size), the exact brute-force reference (small
  sizes only) and OpenCV's ximgproc.jointBilateralFilter (the peer) -- time, error against the
  reference and depth AbsRel against ground truth;
* the variance filter (uncertain map);
* the refinement *accuracy against time* of every solver -- the thesis-faithful Adam (1000 steps,
  lr 1e-4, the reference), L-BFGS (the previous default) and the default damped Gauss-Newton/PCG
  solver -- at several iteration counts: normal RMSE / median / fraction within 11.25° (normals
  from depth against ground truth), depth AbsRel, the 99.9th percentile and max of |Δd|/d outside
  the uncertain set, max |Δd| in metres. Each solver runs once; its iterates are scored through
  ``refine_depth(on_iterate=...)`` (scoring time excluded). Times are seconds since the call
  began (set-up included);
* the time each solver needs to reach Adam-1000's final *accuracy* (normal RMSE and AbsRel);
* the whole kernel (filter + variance + refinement at their defaults): stage times, peak RSS,
  AbsRel input -> output.

Then the same solvers on a Cityscapes-layout fixture (stereo only, scored against stereo within
80 m, :mod:`npsim_core.scoring`), and a plot of accuracy against time (``--plot``).

Adam-1000's curve is cached (``--cache``, keyed by a hash of its inputs): at 2048x1024 it takes
1.5-3 minutes. Run: ``python -m benchmarks.refine [--sizes 512x256,2048x1024]`` or
``npsim bench refine``. Timings on a shared machine are noisy: the load average is printed with them.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from npsim_core.camera import Intrinsics, normals_from_depth  # noqa: E402
from npsim_core.metrics import depth_metrics, normal_metrics  # noqa: E402
from npsim_core.refine import (FilterParams, RefineParams, UncertaintyParams, cross_bilateral,  # noqa: E402
                               cross_bilateral_reference, refine_depth, uncertain_map)

#: Solvers compared, with the iterates scored: (key, label, params, steps scored).
ADAM_MARKS = (0, 25, 50, 100, 200, 300, 500, 700, 1000)
LBFGS_MARKS = (0, 1, 2, 5, 10, 20, 30, 50, 70, 100)
#: Gauss-Newton iterates shown in the table (every one is scored and plotted).
FAST_MARKS = (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 25, 30)


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


def load_str() -> str:
    a = os.getloadavg()
    return f"{a[0]:.2f} {a[1]:.2f} {a[2]:.2f}"


# --------------------------------------------------------------------------- accuracy
def accuracy(depth, depth_in, U, intr, depth_ref, normals_ref) -> dict:
    """Accuracy of ``depth`` against a reference and its move from ``depth_in`` (the refinement's input)."""
    valid = np.isfinite(depth_in) & (depth_in > 0)
    d = np.where(valid, depth, np.nan).astype(np.float32)
    dm = depth_metrics(d, depth_ref)
    out = {"abs_rel": dm.abs_rel, "rmse_m": dm.rmse}
    if normals_ref is not None:
        nm = normal_metrics(normals_from_depth(d, intr), normals_ref)
        out.update(n_rmse=nm.rmse_deg, n_median=nm.median_deg, n_11=nm.within_11_25)
    out_u = valid & ~U
    if out_u.any():
        rel = np.abs(d[out_u].astype(np.float64) - depth_in[out_u]) / depth_in[out_u]
        out.update(p999=float(np.percentile(rel, 99.9)), rel_max=float(rel.max()))
    else:
        out.update(p999=0.0, rel_max=0.0)
    out["max_m"] = float(np.nanmax(np.abs(d[valid].astype(np.float64) - depth_in[valid]))) if valid.any() else 0.0
    return out


def run_curve(filtered, normals, intr, U, params: RefineParams, marks, score) -> dict:
    """Run one solver once, scoring the iterates in ``marks`` (all when None); returns its curve."""
    pts = []

    def on_iterate(step, t, d):
        if marks is None or step in marks:
            pts.append({"step": int(step), "t_opt": float(t), **score(d)})

    with PeakRSS() as m:
        r = refine_depth(filtered, normals, intr, U, params, on_iterate=on_iterate)
    setup = r.timings["setup_s"]
    for p in pts:
        p["t"] = setup + p["t_opt"]
    # the optimiser's own clock (observer time excluded, as for the points), set-up included
    t_final = setup + (float(r.history["time_s"][-1]) if len(r.history["time_s"]) else 0.0)
    final = {"step": r.steps, "t": t_final, **score(r.depth)}
    return {"points": pts, "final": final, "wall_s": m.seconds, "rss_mb": m.peak, "message": r.message,
            "steps": r.steps}


def _hash(*arrays, extra: str = "") -> str:
    h = hashlib.sha1(extra.encode())
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.shape, a.dtype)).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


def adam_curve(filtered, normals, intr, U, steps, score, cache: Path | None, tag: str) -> dict:
    """Adam's curve, from the cache when the same inputs were benchmarked before."""
    p = RefineParams(optimizer="adam_faithful", steps=steps)
    marks = tuple(m for m in ADAM_MARKS if m < steps) + (steps,)
    key = _hash(filtered, normals, U, extra=f"{tag}|{intr}|{p}|{marks}|v2")
    path = cache / f"adam_{key}.json" if cache is not None else None
    if path is not None and path.exists():
        out = json.loads(path.read_text())
        out["cached"] = True
        return out
    out = run_curve(filtered, normals, intr, U, p, set(marks), score)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(out))
    out["cached"] = False
    return out


def fmt_point(label, p, extra=""):
    n = lambda k, f: (f.format(p[k]) if k in p and np.isfinite(p[k]) else "n/a")  # noqa: E731
    return [label, f"{p['t']:.2f}", n("n_rmse", "{:.2f}"), n("n_median", "{:.2f}"), n("n_11", "{:.3f}"),
            n("abs_rel", "{:.4f}"), n("p999", "{:.4f}"), n("rel_max", "{:.3f}"), n("max_m", "{:.3f}"), extra]


ACC_HEADER = ["solver, iterate", "time (s)", "normal RMSE (°)", "normal median (°)", "within 11.25°", "AbsRel",
              "p99.9 |Δd|/d (outside U)", "max |Δd|/d (outside U)", "max |Δd| (m)", "note"]


def reach(curve: dict, target: dict, tol_abs_rel: float) -> dict | None:
    """First scored iterate at least as accurate as ``target`` in normal RMSE and AbsRel."""
    for p in sorted(curve["points"] + [curve["final"]], key=lambda q: q["t"]):
        if p.get("n_rmse", np.inf) <= target["n_rmse"] and p["abs_rel"] <= target["abs_rel"] + tol_abs_rel:
            return p
    return None


def solver_configs(args) -> list[tuple[str, str, RefineParams, object]]:
    fast_default = RefineParams()
    return [
        ("lbfgs", "L-BFGS (previous default)", RefineParams(optimizer="lbfgs", steps=args.lbfgs_steps),
         set(LBFGS_MARKS)),
        ("fast", f"Gauss-Newton/PCG (default: {fast_default.n_steps} steps x {fast_default.cg_iters} CG)",
         RefineParams(steps=args.fast_steps), None),
    ]


def bench_refine(scene_like, filtered, U, size_label, args, cache):
    """Accuracy-against-time table of every solver on one frame with ground truth."""
    intr, normals = scene_like.intrinsics, scene_like.normals

    def score(d):
        return accuracy(d, filtered, U, intr, scene_like.depth_gt, scene_like.normals_gt)

    h, w = filtered.shape
    warm = (slice(0, min(h, 32)), slice(0, min(w, 64)))  # first-call costs of torch kernels, not the method's
    small = Intrinsics(intr.fx, intr.fy, intr.cx, intr.cy, min(w, 64), min(h, 32))
    for opt in ("fast", "lbfgs", "adam_faithful"):
        refine_depth(filtered[warm], normals[warm], small, U[warm], RefineParams(optimizer=opt, steps=2))
    curves = {"adam": adam_curve(filtered, normals, intr, U, args.adam_steps, score, cache, size_label)}
    print(f"  [{size_label}] Adam: {curves['adam']['message']}{' (cached)' if curves['adam']['cached'] else ''}",
          file=sys.stderr, flush=True)
    labels = {"adam": f"Adam faithful ({args.adam_steps} steps, lr 1e-4; reference)"}
    for key, label, p, marks in solver_configs(args):
        curves[key] = run_curve(filtered, normals, intr, U, p, marks, score)
        labels[key] = label
        print(f"  [{size_label}] {label}: {curves[key]['message']}", file=sys.stderr, flush=True)
    target = curves["adam"]["final"]
    rows = [fmt_point("input: predicted depth", {"t": 0.0, **accuracy(scene_like.depth, filtered, U, intr,
                                                                        scene_like.depth_gt, scene_like.normals_gt)}),
            fmt_point("refinement input: filtered depth", {"t": 0.0, **score(filtered)})]
    default_steps = RefineParams().n_steps
    for key, c in curves.items():
        for p in c["points"]:
            if p["step"] == 0 or (key == "fast" and p["step"] not in FAST_MARKS):
                continue
            note = ""
            if key == "fast" and p["step"] == default_steps:
                note = "**default**"
            if key == "adam" and p["step"] == args.adam_steps:
                note = "reference"
            rows.append(fmt_point(f"{labels[key]}, {p['step']}", p, note))
    print(f"\n#### Refinement accuracy against time, {size_label} (λ = appendix_b (1, 5, 1); load {load_str()})\n")
    print(md_table(ACC_HEADER, rows))
    lines = []
    t_adam = target["t"]
    for key, c in curves.items():
        if key == "adam":
            continue
        hit = reach(c, target, args.abs_rel_tol)
        if hit is None:
            lines.append(f"- {labels[key]}: does not reach Adam-{args.adam_steps}'s accuracy (normal RMSE "
                         f"{target['n_rmse']:.2f}°, AbsRel {target['abs_rel']:.4f}) within its run")
        else:
            lines.append(f"- {labels[key]}: reaches Adam-{args.adam_steps}'s accuracy (normal RMSE "
                         f"{target['n_rmse']:.2f}° and AbsRel {target['abs_rel']:.4f}, tolerance "
                         f"{args.abs_rel_tol:g}) at iterate {hit['step']} after {hit['t']:.2f} s -- "
                         f"{t_adam / max(hit['t'], 1e-9):.0f}x sooner than Adam's {t_adam:.1f} s")
    print("\n" + "\n".join(lines))
    peak = {k: f"{c['rss_mb']:.0f}" for k, c in curves.items() if "rss_mb" in c}
    print(f"\npeak RSS during each run (MB, scoring copies included): {peak}")
    return curves, labels


def bench_filter(scene, size_label, reference: bool):
    rows = []
    d, img, lab = scene.depth, scene.image, scene.labels
    rng = float(np.nanmax(d) - np.nanmin(d))
    default = FilterParams()
    thesis = FilterParams(domain="depth", scale_width=0)
    ref = None
    t_ref = None
    if reference:
        with PeakRSS() as m:
            ref = cross_bilateral_reference(d, img, lab, default)
        t_ref = m.seconds
        rows.append(["reference (exact, brute force), default parameters", f"{m.seconds:.2f}", "1x", "0", "0",
                     f"{depth_metrics(ref, scene.depth_gt).abs_rel:.4f}", f"{m.peak:.0f}"])
    cross_bilateral(d, img, lab, default)  # warm-up (OpenCV/numpy first-call costs)
    out = {}
    for name, fp in (("default", default), ("thesis", thesis)):
        with PeakRSS() as m:
            fast = cross_bilateral(d, img, lab, fp)
        out[name] = fast
        err = (f"{np.nanmean(np.abs(fast - ref)) / rng * 100:.3f}", f"{np.nanmean(np.abs(fast - ref)):.4f}") \
            if ref is not None and name == "default" else ("n/a", "n/a")
        label = (f"fast, default (inverse depth, σs = 10 px at 2048 wide = {fp.at_width(d.shape[1]).sigma_s:.2f} px)"
                 if name == "default" else "fast, thesis setting (depth domain, σs = 10 px at every size)")
        rows.append([label, f"{m.seconds:.3f}", f"{t_ref / m.seconds:.0f}x" if t_ref and name == "default" else "-",
                     *err, f"{depth_metrics(fast, scene.depth_gt).abs_rel:.4f}", f"{m.peak:.0f}"])
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
                     f"{t_ref / m.seconds:.0f}x" if t_ref else "-", *err,
                     f"{depth_metrics(peer, scene.depth_gt).abs_rel:.4f}", f"{m.peak:.0f}"])
    except (ImportError, AttributeError) as exc:  # pragma: no cover
        rows.append([f"OpenCV peer unavailable: {exc}", "-", "-", "-", "-", "-", "-"])
    print(f"\n#### Cross-bilateral filter, {size_label} (depth range {rng:.1f} m; input AbsRel "
          f"{depth_metrics(d, scene.depth_gt).abs_rel:.4f}; load {load_str()})\n")
    print(md_table(["method", "time (s)", "speed-up vs reference", "MAE vs reference (% of range)",
                    "MAE vs reference (m)", "AbsRel vs ground truth", "peak RSS (MB)"], rows))
    return out["default"]


def bench_variance(filtered, labels, size_label):
    rows = []
    uncertain_map(filtered, labels)  # warm-up
    res = {}
    for name, up in (("relative, τ=1e-3 (default)", UncertaintyParams()),
                     ("absolute, μ_v=1e-3 m² (thesis)", UncertaintyParams(mode="absolute"))):
        with PeakRSS() as m:
            U = uncertain_map(filtered, labels, up)
        res[name] = U
        rows.append([name, f"{m.seconds:.3f}", f"{U.mean():.3f}", f"{m.peak:.0f}"])
    print(f"\n#### Variance filter, {size_label} (load {load_str()})\n")
    print(md_table(["mode", "time (s)", "uncertain fraction", "peak RSS (MB)"], rows))
    return res["relative, τ=1e-3 (default)"]


def bench_kernel(scene, size_label):
    """Filter + variance + refinement at their defaults, as the chain runs them."""
    with PeakRSS() as m:
        t0 = time.perf_counter()
        f = cross_bilateral(scene.depth, scene.image, scene.labels)
        t1 = time.perf_counter()
        U = uncertain_map(f, scene.labels)
        t2 = time.perf_counter()
        r = refine_depth(f, scene.normals, scene.intrinsics, U)
        t3 = time.perf_counter()
    a_in = depth_metrics(scene.depth, scene.depth_gt).abs_rel
    a_out = depth_metrics(r.depth, scene.depth_gt).abs_rel
    nm = normal_metrics(normals_from_depth(r.depth, scene.intrinsics), scene.normals_gt)
    return [size_label, f"{t1 - t0:.3f}", f"{t2 - t1:.3f}", f"{t3 - t2:.2f} ({r.steps} steps)", f"{t3 - t0:.2f}",
            f"{m.peak:.0f}", f"{a_in:.4f} -> {a_out:.4f} ({'not worse' if a_out <= a_in else 'WORSE'})",
            f"{nm.rmse_deg:.2f}", load_str()]


# --------------------------------------------------------------------------- stereo-only fixture
def bench_fixture(size, frames, args, cache):
    """The solvers on a Cityscapes-layout fixture scored against its stereo (no ground truth)."""
    from npsim_core.chain import Chain
    from npsim_core.chain.params import ChainParams
    from npsim_core.chain.session import iter_frames
    from npsim_core.scoring import reference_of
    from npsim_core.synthetic.cityscapes import write_cityscapes_fixture

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        write_cityscapes_fixture(tmp, frames=frames, size=size, corrupt=0)
        for src in iter_frames(tmp):
            res = Chain(src.load()).compute(ChainParams(), until="uncertain")
            sc = res.scene
            ref = reference_of(sc)
            if ref is None:
                continue
            f, U, intr = res.filtered, res.uncertain, res.intrinsics

            def score(d):
                return accuracy(d, f, U, intr, ref.depth, ref.normals)

            name = src.name[:24]
            rows.append(fmt_point(f"{name}: input ({res.depth_source.split(':')[0]})", {"t": 0.0, **accuracy(
                res.depth_in, f, U, intr, ref.depth, ref.normals)}))
            rows.append(fmt_point(f"{name}: filtered", {"t": 0.0, **score(f)}))
            adam = adam_curve(f, res.normals_in, intr, U, args.adam_steps, score, cache, f"fixture-{name}")
            rows.append(fmt_point(f"{name}: Adam faithful, {args.adam_steps}", adam["final"], "reference"))
            for key, label, p, _ in solver_configs(args):
                if key == "fast":
                    p = RefineParams()
                r = run_curve(f, res.normals_in, intr, U, p, set(), score)
                rows.append(fmt_point(f"{name}: {label.split(' (')[0]}, {r['steps']}", r["final"],
                                      "**default**" if key == "fast" else ""))
    w, h = size
    print(f"\n#### Stereo-only Cityscapes-layout fixture, {w}x{h}, {frames} frames (scored against stereo "
          f"within 80 m; load {load_str()})\n")
    print(md_table(ACC_HEADER, rows))


# --------------------------------------------------------------------------- plot
def plot(all_curves: dict, path: Path) -> None:
    """Normal RMSE and AbsRel against time, one line per solver and size (log time axis)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    styles = {"adam": "-", "lbfgs": "--", "fast": "-"}
    colours = {"adam": "tab:gray", "lbfgs": "tab:blue", "fast": "tab:red"}
    for (size, key), (curve, label) in all_curves.items():
        pts = sorted([p for p in curve["points"] if p["step"] > 0], key=lambda q: q["t"])
        if not pts:
            continue
        t = [p["t"] for p in pts]
        big = size.startswith("2048")
        kw = dict(ls=styles[key], color=colours[key], marker="o" if big else ".", ms=3,
                  alpha=1.0 if big else 0.55, label=f"{label.split(' (')[0]}, {size}")
        axes[0].plot(t, [p["n_rmse"] for p in pts], **kw)
        axes[1].plot(t, [p["abs_rel"] for p in pts], **kw)
        default = [p for p in pts if key == "fast" and p["step"] == RefineParams().n_steps]
        if default:  # the default's stopping point
            for ax, m in zip(axes, ("n_rmse", "abs_rel")):
                ax.plot([default[0]["t"]], [default[0][m]], marker="*", ms=13 if big else 9, color="black",
                        zorder=5, label="default (10 steps)" if big and ax is axes[0] else None)
    for ax, name in zip(axes, ("normal RMSE (°)", "depth AbsRel")):
        ax.set_xscale("log")
        ax.set_xlabel("time since the call began (s, log)")
        ax.set_ylabel(name)
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    axes[1].legend(handles, labels, fontsize=7, loc="upper right")  # the AbsRel panel's empty corner
    fig.suptitle("Depth refinement on the synthetic street: accuracy against time (benchmarks/refine.py)",
                 fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="512x256,2048x1024", help="comma-separated WxH list")
    ap.add_argument("--adam-steps", type=int, default=1000, help="faithful Adam steps (thesis: 1000)")
    ap.add_argument("--lbfgs-steps", type=int, default=100, help="L-BFGS iterations (scored along the way)")
    ap.add_argument("--fast-steps", type=int, default=30,
                    help="Gauss-Newton steps of the curve (every one scored; the default stops at 10)")
    ap.add_argument("--abs-rel-tol", type=float, default=1e-4,
                    help="AbsRel tolerance when comparing with Adam's accuracy")
    ap.add_argument("--reference-max-pixels", type=int, default=512 * 256,
                    help="run the brute-force reference filter only up to this many pixels")
    ap.add_argument("--fixture", default="512x256", help="WxH of the stereo-only fixture ('' = skip)")
    ap.add_argument("--fixture-frames", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cache", default=None,
                    help="folder caching Adam's curves (default: $NPSIM_CACHE/bench_refine; 'none' = no cache)")
    ap.add_argument("--plot", default=str(Path(__file__).resolve().parents[1] / "docs" / "img"
                                          / "refine_accuracy_vs_time.png"),
                    help="PNG of accuracy against time ('none' = no plot)")
    args = ap.parse_args(argv)
    from npsim_core.synthetic import cache_dir, street_scene

    if args.cache is None:
        cache = cache_dir() / "bench_refine"
    else:
        cache = None if args.cache.lower() == "none" else Path(args.cache)
    sizes = [tuple(int(v) for v in s.lower().split("x")) for s in args.sizes.split(",") if s]
    print(f"## Depth refinement kernel benchmark\n\nmachine: {os.cpu_count()} cores, load average "
          f"{load_str()} at start; torch threads 1 (RefineParams.threads)")
    kernel_rows = []
    all_curves = {}
    for w, h in sizes:
        label = f"{w}x{h}"
        scene = street_scene(w, h, args.seed)
        filtered = bench_filter(scene, label, reference=w * h <= args.reference_max_pixels)
        U = bench_variance(filtered, scene.labels, label)
        curves, labels = bench_refine(scene, filtered, U, label, args, cache)
        for k, c in curves.items():
            all_curves[(label, k)] = (c, labels[k])
        kernel_rows.append(bench_kernel(scene, label))
    print("\n#### Whole kernel (fast filter + variance filter + refinement, all at their defaults)\n")
    print(md_table(["size", "filter (s)", "variance (s)", "refine (s)", "total (s)", "peak RSS (MB)",
                    "AbsRel input -> output", "normal RMSE (°)", "load"], kernel_rows))
    if args.fixture:
        fw, fh = (int(v) for v in args.fixture.lower().split("x"))
        bench_fixture((fw, fh), args.fixture_frames, args, cache)
    if str(args.plot).lower() != "none" and all_curves:
        plot(all_curves, Path(args.plot))
        print(f"\nplot: {args.plot}")
    print(f"\nload average at end: {load_str()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
