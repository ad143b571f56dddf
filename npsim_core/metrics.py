"""Depth and normal error metrics (docs/method.md §9.2), masked to pixels valid in both maps."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .camera import valid_depth_mask


@dataclass(frozen=True)
class DepthMetrics:
    """AbsRel = mean |d - g| / g; RMSE in metres; delta1 = fraction with max(d/g, g/d) < 1.25;
    RMSElog = sqrt(mean (ln d - ln g)^2); n = pixels compared."""

    abs_rel: float
    rmse: float
    delta1: float
    n: int
    rmse_log: float = float("nan")

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class NormalMetrics:
    """Angular errors in degrees: RMSE, mean, median, and fractions within 5, 11.25, 22.5, 30 degrees."""

    rmse_deg: float
    mean_deg: float
    median_deg: float
    within_5: float
    within_11_25: float
    within_22_5: float
    within_30: float
    n: int

    def as_dict(self) -> dict:
        return asdict(self)


def depth_metrics(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray | None = None) -> DepthMetrics:
    """Depth errors of ``pred`` against ``gt`` (both HxW metres) where both are valid (and ``mask``)."""
    pred = np.asarray(pred, dtype=np.float64)
    gt = np.asarray(gt, dtype=np.float64)
    m = valid_depth_mask(pred) & valid_depth_mask(gt)
    if mask is not None:
        m &= mask.astype(bool)
    n = int(m.sum())
    if n == 0:
        return DepthMetrics(float("nan"), float("nan"), float("nan"), 0)
    p, g = pred[m], gt[m]
    ratio = np.maximum(p / g, g / p)
    return DepthMetrics(abs_rel=float(np.mean(np.abs(p - g) / g)), rmse=float(np.sqrt(np.mean((p - g) ** 2))),
                        delta1=float(np.mean(ratio < 1.25)), n=n,
                        rmse_log=float(np.sqrt(np.mean((np.log(p) - np.log(g)) ** 2))))


def angular_error_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-pixel angle in degrees between two HxWx3 normal maps (NaN where either is invalid)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    na = np.linalg.norm(a, axis=-1)
    nb = np.linalg.norm(b, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.sum(a * b, axis=-1) / (na * nb)
    ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    ang[~((na > 0) & (nb > 0) & np.isfinite(cos))] = np.nan
    return ang


def normal_metrics(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray | None = None) -> NormalMetrics:
    """Angular error statistics of ``pred`` against ``gt`` over pixels valid in both (and ``mask``)."""
    ang = angular_error_deg(pred, gt)
    m = np.isfinite(ang)
    if mask is not None:
        m &= mask.astype(bool)
    e = ang[m]
    if e.size == 0:
        nan = float("nan")
        return NormalMetrics(nan, nan, nan, nan, nan, nan, nan, 0)
    return NormalMetrics(rmse_deg=float(np.sqrt(np.mean(e ** 2))), mean_deg=float(e.mean()),
                         median_deg=float(np.median(e)), within_5=float(np.mean(e < 5)),
                         within_11_25=float(np.mean(e < 11.25)), within_22_5=float(np.mean(e < 22.5)),
                         within_30=float(np.mean(e < 30)), n=int(e.size))
