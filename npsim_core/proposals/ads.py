"""Advertisements: saturated, uniform panels on facades (docs/proposals.md)."""

from __future__ import annotations

import cv2
import numpy as np

from .core import Context, Light, components

BUILDING = 11
ADVERTISEMENT = 10


def _width_on_wall(ctx: Context, y0: int, x0: int, m: np.ndarray, z: float) -> float:
    """Width (m) of a blob along the surface it lies on: the distance between the points its first and
    last columns show (median depth of each column, back-projected); its image width at depth ``z``
    when a column has no depth."""
    h, w = m.shape
    d = np.where(m, ctx.depth[y0:y0 + h, x0:x0 + w], np.nan)
    ok = np.isfinite(d).any(0)
    fx, cx = float(ctx.intrinsics.fx), float(ctx.intrinsics.cx)
    if ok.sum() < 2:
        return w * z / fx
    cols = np.flatnonzero(ok)
    za, zb = (float(np.nanmedian(d[:, c])) for c in (cols[0], cols[-1]))
    xa, xb = (x0 + cols[0] - 0.5 - cx) * za / fx, (x0 + cols[-1] + 0.5 - cx) * zb / fx
    return float(np.hypot(xb - xa, zb - za))


def propose(ctx: Context) -> list[Light]:
    """One advertisement per saturated panel on a building.

    Candidates: building pixels with HSV saturation >= ``ad_min_saturation`` and value >= 0.3
    (painted or printed panels; glass, plaster and brick are far less saturated). A blob is kept
    when it fills >= 70 % of its box and, with depth, is at least ``ad_min_height_m`` tall and
    ``ad_min_area_m2`` large (its box's height times its width along the wall, :func:`_width_on_wall`:
    a sign on a facade receding along the street is foreshortened). Confidence 0.55, +0.25 x how
    uniform its hue is.
    """
    p = ctx.params
    B = ctx.labels == BUILDING
    if not B.any():
        return []
    hsv = cv2.cvtColor(ctx.image, cv2.COLOR_RGB2HSV_FULL)
    sat = hsv[..., 1].astype(np.float32) / 255.0
    val = hsv[..., 2].astype(np.float32) / 255.0
    cand = B & (sat >= p.ad_min_saturation) & (val >= 0.3)
    out: list[Light] = []
    fy = float(ctx.intrinsics.fy)
    for y0, x0, m, a in components(cand, 6, connectivity=4):
        h, w = m.shape
        if a / float(h * w) < 0.7:
            continue
        if ctx.depth is not None:
            d = ctx.depth[y0:y0 + h, x0:x0 + w][m]
            d = d[np.isfinite(d)]
            if d.size:
                z = float(np.median(d))
                if h * z / fy < p.ad_min_height_m or (h * z / fy) * _width_on_wall(ctx, y0, x0, m, z) < p.ad_min_area_m2:
                    continue
        hue = hsv[y0:y0 + h, x0:x0 + w, 0][m].astype(np.float32) * (2 * np.pi / 256.0)
        spread = 1.0 - float(np.hypot(np.cos(hue).mean(), np.sin(hue).mean()))  # circular variance
        conf = 0.55 + 0.25 * float(np.clip(1.0 - spread / 0.1, 0.0, 1.0))
        out.append(Light(ADVERTISEMENT, y0, x0, m, conf))
    return out
