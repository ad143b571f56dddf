"""A proposed window's confidence: how sure the proposer is that it is a window the annotator
keeps (docs/proposals.md, "Seventh pass: confidence").

Kept apart from :mod:`.windows` (which finds the panes) so the score can be refitted without
touching the detection: :func:`rescore_windows` runs on the final window groups.
"""

from __future__ import annotations

import numpy as np

from .core import Context, Group, Light
from .windows import _median_depth, _ring_contrast


def confidence_features(ctx: Context, feat: np.ndarray, B: np.ndarray, li: Light, n_group: int) -> dict:
    """What a window's final confidence is judged on (:func:`window_confidence`): the contrast to
    the building pixels in a ring around it (:func:`windows._ring_contrast`, 0 without a ring), its area and
    box (px), height (m; NaN without depth), the size of its windows_group; kind, cut and position
    are there to be logged beside it (docs/proposals.md "Seventh pass" was fitted on them)."""
    d = _ring_contrast(feat, B, li.y0, li.x0, li.mask, max(2, ctx.params.window_ring_px), ctx.params)
    z = _median_depth(ctx, li)
    h, w = li.mask.shape
    return {"ring_lum": d[0] if d else 0.0, "ring_chroma": d[1] if d else 0.0, "area_px": float(li.mask.sum()),
            "h_px": float(h), "w_px": float(w),
            "h_m": h * z / float(ctx.intrinsics.fy) if z is not None else float("nan"),
            "n_group": float(n_group), "kind": li.kind or "window", "cut": bool(li.cut),
            "y0": li.y0, "x0": li.x0}


def window_confidence(p, conf: float, x: dict) -> float:
    """A window's final confidence from its first one ``conf`` and its features ``x``
    (:func:`confidence_features`; docs/proposals.md "Seventh pass").

    The first confidence (fill, contrast to the wall reference, a floor of three) hardly told a
    true window from a false one (most false windows cover no true light at all: flecks of wall,
    balcony slabs, edges between wall colours). What does is how much the window differs from the
    wall right around it, how tall it is, and how many pixels it has (a small one is rarely traced
    within the editor's touch-up IoU, 0.7): a logistic score ``window_conf_bias + w . (conf, ring
    log-luminance contrast, ring chroma contrast, height m, ln pixels)`` (``window_conf_weights``;
    contrasts over the window thresholds, clipped at 3; height clipped at 2.5 m, 1 m without depth)
    mapped to 0.5 + 0.5 sigmoid(score). Only windows at least 0.5
    confident are rescored, into [0.5, 1): the set kept at 0.5 does not change, only its order.
    A window of fewer than ``window_tiny_px`` pixels stays at most ``window_tiny_max_confidence``.
    """
    wts = p.window_conf_weights
    if conf < 0.5 or not any(wts):
        return conf
    h = x["h_m"] if np.isfinite(x["h_m"]) else 1.0
    v = (conf, min(x["ring_lum"], 3.0), min(x["ring_chroma"], 3.0), min(h, 2.5), np.log(max(x["area_px"], 1.0)))
    z = p.window_conf_bias + float(np.dot(wts, v))
    out = 0.5 + 0.5 / (1.0 + np.exp(-z))
    if x["area_px"] < p.window_tiny_px:
        out = min(out, p.window_tiny_max_confidence)
    return float(out)


def rescore_windows(ctx: Context, groups: list[Group], feat: np.ndarray, B: np.ndarray) -> list[Group]:
    """Set every window's final confidence (:func:`window_confidence`) and each group's as the mean
    of its members'. ``feat``: the windows proposer's per-pixel features; ``B``: its building mask."""
    p = ctx.params
    for g in groups:
        for li in g.members:
            li.confidence = window_confidence(p, li.confidence, confidence_features(ctx, feat, B, li, len(g.members)))
        g.confidence = float(np.mean([li.confidence for li in g.members])) if g.members else g.confidence
    return groups
