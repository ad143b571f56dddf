"""Realism measures of a rendered night (docs/relight.md "Realism measures"): what the manifest,
the batch report and the app's night panel show for every night.

* **Structure ratio** -- mean |band-pass| (Gaussian σ 2 px minus σ 8 px) of log grey level of the
  night over the same of the day photo, where the night is not black (> 8 grey levels), the
  whole frame and per class (each class mask eroded 2 px, at least 200 pixels). Both images are
  compared at 1024 px wide. Streaks, speckle, broken geometry and hard-edged lit blobs raise it;
  published day->night pairs give SOLO 0.75, CycleGAN 0.89, ControlNet 1.45. Identical to
  ``../shared/tools/night_artefacts.py`` (checked on the benchmark's 2048x1024 nights: the same digits).
* **Global statistics** -- grey mean, median, 99th percentile, % of pixels > 240, R/B of the
  brightest 10 % (grey), at 1024 px wide; identical to ``../shared/tools/night_stats.py``.
  :data:`REAL_NIGHT` holds the values of 5 real ACDC night photos (docs/relight.md, "Realism measures").

Images are sRGB uint8 (H, W, 3) in RGB order; labels are Cityscapes labelIds.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["CLASSES", "REAL_NIGHT", "WIDTH", "structure_ratio", "global_stats", "night_realism",
           "stats_within", "format_realism"]

#: Classes measured (name -> labelIds), as the shared tool.
CLASSES: dict[str, tuple[int, ...]] = {"road": (7,), "sidewalk": (8,), "building": (11,), "vegetation": (21,),
                                       "car": (26,), "person+rider": (24, 25), "bicycle": (33, 32)}
#: Every image is compared at this width.
WIDTH = 1024
#: Global statistics of 5 real ACDC night photos (docs/relight.md, "Realism measures").
REAL_NIGHT = {"mean": 43.8, "median": 35.8, "p99": 170.0, "pct_over_240": 0.24, "lit_rb": 1.61}


def _grey(rgb: np.ndarray) -> np.ndarray:
    g = cv2.cvtColor(np.ascontiguousarray(rgb, np.uint8), cv2.COLOR_RGB2GRAY)
    return cv2.resize(g, (WIDTH, round(g.shape[0] * WIDTH / g.shape[1])), interpolation=cv2.INTER_AREA)


def _bandpass(g: np.ndarray) -> np.ndarray:
    lg = np.log(g.astype(np.float64) + 4.0)
    return np.abs(cv2.GaussianBlur(lg, (0, 0), 2.0) - cv2.GaussianBlur(lg, (0, 0), 8.0))


def structure_ratio(day: np.ndarray, labels: np.ndarray, night: np.ndarray) -> dict:
    """Structure ratio of ``night`` against ``day`` (module docstring).

    Returns
    -------
    dict
        ``whole`` (float), ``classes`` {name: ratio or None when the class has < 200 lit pixels},
        ``hot`` {name: % of the class's pixels >= 250 grey or None}.
    """
    gd, gn = _grey(day), _grey(night)
    lab = cv2.resize(np.asarray(labels, np.uint8), (gd.shape[1], gd.shape[0]), interpolation=cv2.INTER_NEAREST)
    hd, hn = _bandpass(gd), _bandpass(gn)
    lit = gn > 8
    whole = float(hn[lit].mean() / max(hd[lit].mean(), 1e-6)) if lit.any() else float("nan")
    classes: dict = {}
    hot: dict = {}
    kernel = np.ones((5, 5), np.uint8)
    for name, ids in CLASSES.items():
        m = cv2.erode(np.isin(lab, ids).astype(np.uint8), kernel).astype(bool) & lit
        if m.sum() < 200:
            classes[name] = hot[name] = None
            continue
        classes[name] = float(hn[m].mean() / max(hd[m].mean(), 1e-6))
        hot[name] = float(100.0 * (gn[m] >= 250).mean())
    return {"whole": whole, "classes": classes, "hot": hot}


def global_stats(night: np.ndarray) -> dict:
    """Grey ``mean``, ``median``, ``p99``, ``pct_over_240`` (%) and ``lit_rb`` (R/B of the brightest
    10 % by grey) of an sRGB night at 1024 px wide (module docstring)."""
    im = np.ascontiguousarray(night, np.uint8)
    h, w = im.shape[:2]
    im = cv2.resize(im, (WIDTH, round(h * WIDTH / w)), interpolation=cv2.INTER_AREA)
    g = cv2.cvtColor(im, cv2.COLOR_RGB2GRAY).astype(np.float64)
    f = im.astype(np.float64)
    lit = g >= np.percentile(g, 90)
    r, b = f[..., 0][lit].mean(), f[..., 2][lit].mean()
    return {"mean": float(g.mean()), "median": float(np.median(g)), "p99": float(np.percentile(g, 99)),
            "pct_over_240": float(100.0 * (g > 240).mean()), "lit_rb": float(r / max(b, 1e-6))}


def stats_within(stats: dict, tolerance: float = 0.15) -> dict:
    """Per statistic: whether it is within ``tolerance`` (relative) of :data:`REAL_NIGHT`."""
    return {k: bool(abs(stats[k] - v) <= tolerance * abs(v)) for k, v in REAL_NIGHT.items()}


def night_realism(day: np.ndarray, labels: np.ndarray, night: np.ndarray) -> dict:
    """Both measures of one night, rounded for a manifest: ``structure`` (:func:`structure_ratio`),
    ``stats`` (:func:`global_stats`) and ``real_night`` (:data:`REAL_NIGHT`, for comparison)."""
    def rnd(x):
        if isinstance(x, dict):
            return {k: rnd(v) for k, v in x.items()}
        return None if x is None or not np.isfinite(x) else round(float(x), 3)

    return {"structure": rnd(structure_ratio(day, labels, night)), "stats": rnd(global_stats(night)),
            "real_night": dict(REAL_NIGHT)}


def format_realism(r: dict) -> str:
    """One or two lines of text for a panel or a report: structure ratio (whole, per class) and stats."""
    s = r.get("structure") or {}
    cls = " ".join(f"{k} {v:.2f}" for k, v in (s.get("classes") or {}).items() if v is not None)
    st = r.get("stats") or {}
    line2 = ""
    if st:
        line2 = (f"mean {st['mean']:.1f} median {st['median']:.1f} p99 {st['p99']:.0f} >240 {st['pct_over_240']:.2f} % "
                 f"R/B {st['lit_rb']:.2f} (real nights 43.8 / 35.8 / 170 / 0.24 % / 1.61)")
    whole = s.get("whole")
    return (f"structure {whole:.2f} ({cls})" if whole is not None else "structure -") + ("\n" + line2 if line2 else "")
