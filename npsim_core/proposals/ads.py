"""Advertisements: saturated, uniform panels on facades (docs/proposals.md)."""

from __future__ import annotations

import cv2
import numpy as np

from .core import Context, Light, components, median, pixels

BUILDING = 11
SKY = 23
ADVERTISEMENT = 10


class _Linear:
    """An 8-bit sRGB image's linear RGB (``(x / 255) ** 2.2`` as float32), computed on the slices read:
    over the whole frame it took a fifth of the proposer's time for a few signs."""

    _LUT = (np.arange(256, dtype=np.float32) / 255.0) ** 2.2  # the same floats as the power per pixel

    def __init__(self, image: np.ndarray):
        self.image = image

    def __getitem__(self, key) -> np.ndarray:
        return self._LUT[self.image[key]]


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
    za, zb = (float(median(d[:, c][~np.isnan(d[:, c])])) for c in (cols[0], cols[-1]))  # np.nanmedian
    xa, xb = (x0 + cols[0] - 0.5 - cx) * za / fx, (x0 + cols[-1] + 0.5 - cx) * zb / fx
    return float(np.hypot(xb - xa, zb - za))


def _with_edge(lin: np.ndarray, wall: np.ndarray, y0: int, x0: int, m: np.ndarray) -> tuple[int, int, np.ndarray]:
    """Blob ``m`` (box at ``y0, x0``) with the pixels of its one-pixel rim that the panel covers at least
    half of, as (y0, x0, mask).

    A rim pixel's colour mixes the panel's and the wall's by coverage (in linear light): its share of
    the way from the wall's colour (median of the ``wall`` pixels -- building, not panel -- 2-3 px
    outside the blob) to the panel's (the blob's median) is its coverage; an annotator's mask, like a
    label map sampled at pixel centres, holds the pixels at least half covered. The saturation
    threshold alone drops them: a rim pixel is paler than the panel.
    """
    H, W = wall.shape
    h, w = m.shape
    b0, b1 = max(0, y0 - 3), min(H, y0 + h + 3)
    a0, a1 = max(0, x0 - 3), min(W, x0 + w + 3)
    big = np.zeros((b1 - b0, a1 - a0), np.uint8)
    big[y0 - b0:y0 - b0 + h, x0 - a0:x0 - a0 + w] = m
    k = np.ones((3, 3), np.uint8)
    rim1 = cv2.dilate(big, k).astype(bool)
    near = cv2.dilate(big, k, iterations=3).astype(bool) & ~rim1
    box = lin[b0:b1, a0:a1]
    wall_px = near & wall[b0:b1, a0:a1]
    if wall_px.sum() < 3:
        return y0, x0, m
    panel = median(pixels(box, big.astype(bool)), axis=0)
    base = median(pixels(box, wall_px), axis=0)
    step = panel - base
    if float(step @ step) < 0.02 ** 2:
        return y0, x0, m
    cover = ((box - base) @ step) / float(step @ step)
    grown = big.astype(bool) | (rim1 & wall[b0:b1, a0:a1] & (cover >= 0.5))
    ys, xs = np.nonzero(grown)
    return b0 + int(ys.min()), a0 + int(xs.min()), grown[ys.min():ys.max() + 1, xs.min():xs.max() + 1]


def _hidden_edge(labels: np.ndarray, y0: int, x0: int, m: np.ndarray) -> bool:
    """True when the row just above blob ``m``'s top pixels, or just below its bottom ones, is mostly
    (>= half its columns) something other than building or sky: an object in front hides the
    panel's top or bottom, so the panel is taller than it shows."""
    H = labels.shape[0]
    h, w = m.shape
    cols = np.flatnonzero(m.any(0))
    top = y0 + np.argmax(m[:, cols], 0)
    bot = y0 + h - 1 - np.argmax(m[::-1, cols], 0)
    for rows in (top - 1, bot + 1):
        ok = (rows >= 0) & (rows < H)
        if not ok.any():
            continue
        lab = labels[rows[ok], x0 + cols[ok]]
        if np.mean((lab != BUILDING) & (lab != SKY)) >= 0.5 and ok.sum() >= 0.5 * cols.size:
            return True
    return False


def _union(a: tuple[int, int, np.ndarray], b: tuple[int, int, np.ndarray]) -> tuple[int, int, np.ndarray]:
    """The union of two local masks given as (y0, x0, mask), as (y0, x0, mask) over their joint box."""
    y0, x0 = min(a[0], b[0]), min(a[1], b[1])
    y1 = max(a[0] + a[2].shape[0], b[0] + b[2].shape[0])
    x1 = max(a[1] + a[2].shape[1], b[1] + b[2].shape[1])
    m = np.zeros((y1 - y0, x1 - x0), bool)
    for yy, xx, mm in (a, b):
        m[yy - y0:yy - y0 + mm.shape[0], xx - x0:xx - x0 + mm.shape[1]] |= mm
    return y0, x0, m


def _across_occluder(labels: np.ndarray, lin: np.ndarray, a: tuple[int, int, np.ndarray],
                     b: tuple[int, int, np.ndarray]) -> bool:
    """True when blobs ``a`` and ``b`` ((y0, x0, mask), ``a`` left of ``b``) are one panel that
    something in front (a pole, a sign, a tree) cuts in two: their rows overlap over at least 70 % of
    the shorter one's, every column between them is at least 80 % something other than building or
    sky over those rows, and their colours (median, linear RGB) differ by under a fifth of the
    brighter one's."""
    ay, ax, am = a
    by, bx, bm = b
    g0, g1 = ax + am.shape[1], bx            # the gap's columns
    if g1 <= g0:
        return False
    r0, r1 = max(ay, by), min(ay + am.shape[0], by + bm.shape[0])
    if r1 - r0 < 0.7 * min(am.shape[0], bm.shape[0]):
        return False
    gap = labels[r0:r1, g0:g1]
    if ((gap != BUILDING) & (gap != SKY)).mean(0).min() < 0.8:
        return False
    ca = median(pixels(lin[ay:ay + am.shape[0], ax:ax + am.shape[1]], am), axis=0)
    cb = median(pixels(lin[by:by + bm.shape[0], bx:bx + bm.shape[1]], bm), axis=0)
    return float(np.abs(ca - cb).max()) < 0.2 * float(max(ca.max(), cb.max()))


def propose(ctx: Context) -> list[Light]:
    """One advertisement per saturated panel on a building.

    Candidates: building pixels with HSV saturation >= ``ad_min_saturation`` and value >= 0.3
    (painted or printed panels; glass, plaster and brick are far less saturated). A blob takes the
    rim pixels the panel covers at least half of (:func:`_with_edge`) and is kept when it fills
    >= ``ad_min_hull_fill`` of its convex hull and, with depth, is at least ``ad_min_height_m`` tall
    and, unless the frame cuts it, ``ad_min_area_m2`` large (its box's height times its width along
    the wall, :func:`_width_on_wall`: a sign on a facade receding along the street is foreshortened);
    one whose top or bottom runs along an object in front (:func:`_hidden_edge`) is held to half the
    height alone; one under these rules is proposed at 0.4, under the render's and the editor's
    thresholds, so that the windows proposer does not take a small sign for a window -- unless its
    bottom edge lies in a shop's fascia band (``ad_fascia_m`` above the ground) and it is at least half
    ``ad_min_height_m`` tall or along an object in front: a shop sign, as sure as a panel that meets the
    rules (docs/proposals.md, fifteenth pass). Two blobs that something in front cuts apart are one
    panel (:func:`_across_occluder`).
    Confidence 0.7, +0.25 x how uniform the hue of its saturated core is, -0.2 when it is kept only by
    the half height (seeds 0-5 of the synthetic streets, 512x256: all 44 proposed at >= 0.9 match their
    sign at IoU >= 0.7; docs/proposals.md, eleventh pass).
    """
    p = ctx.params
    B = ctx.labels == BUILDING
    if not B.any():
        return []
    hsv = cv2.cvtColor(ctx.image, cv2.COLOR_RGB2HSV_FULL)
    # The tests on saturation and value (x / 255 as float32) looked up per 8-bit level: the same floats.
    level = np.arange(256, dtype=np.float32) / 255.0
    cand = B & (level >= p.ad_min_saturation)[hsv[..., 1]] & (level >= 0.3)[hsv[..., 2]]
    out: list[Light] = []
    fy = float(ctx.intrinsics.fy)
    lin = _Linear(ctx.image)
    wall = B & ~cand
    blobs = []
    for cy, cx, core, a in components(cand, 6, connectivity=4):
        y0, x0, m = _with_edge(lin, wall, cy, cx, core)
        h, w = m.shape
        # A flat panel is a quadrilateral in the image (a trapezoid on a receding facade): it fills
        # most of its convex hull, not necessarily of its box.
        pts = np.stack(np.nonzero(m)[::-1], 1).astype(np.int32)
        hull = cv2.fillConvexPoly(np.zeros((h, w), np.uint8), cv2.convexHull(pts), 1)
        if int(m.sum()) / float(max(int(hull.sum()), 1)) >= p.ad_min_hull_fill:
            blobs.append(((y0, x0, m), (cy, cx, core)))
    # A pole, a sign or a tree in front cuts a shop sign in two: the parts are one light.
    blobs.sort(key=lambda t: t[0][1])
    k = 0
    while k < len(blobs):
        j = next((j for j in range(k + 1, len(blobs)) if _across_occluder(ctx.labels, lin, blobs[k][0], blobs[j][0])),
                 None)
        if j is None:
            k += 1
            continue
        blobs[k] = (_union(blobs[k][0], blobs[j][0]), _union(blobs[k][1], blobs[j][1]))
        del blobs[j]
    for (y0, x0, m), (cy, cx, core) in blobs:
        h, w = m.shape
        relaxed = under = False
        if ctx.depth is not None:
            d = ctx.depth[y0:y0 + h, x0:x0 + w][m]
            d = d[np.isfinite(d)]
            if d.size:
                z = float(median(d))
                # A panel cut by the frame shows only part of its area: it is held to its height alone.
                # One whose top or bottom edge runs along something in front (a tree, a pole's sign) shows
                # only part of its height too: it is held to half the height, and is less sure.
                cut = x0 == 0 or y0 == 0 or x0 + w == ctx.shape[1] or y0 + h == ctx.shape[0]
                hidden = _hidden_edge(ctx.labels, y0, x0, m)
                height_m = h * z / fy
                small = height_m < p.ad_min_height_m or (
                    not cut and height_m * _width_on_wall(ctx, y0, x0, m, z) < p.ad_min_area_m2)
                # A panel under the size rules is still a panel, not a window: proposed under the render's
                # and the editor's thresholds, it keeps its pixels from the windows proposer.
                under = small and not (hidden and height_m >= 0.5 * p.ad_min_height_m)
                # Kept only because something in front may hide the rest of it: less sure. A panel that
                # meets the full rules anyway is as sure as any (its mask is what shows, as an annotator's).
                relaxed = small
                # A small panel whose bottom edge lies in a shop's fascia band (over the glazing and the
                # awning, under the first floor) is a shop sign: a one-bay shop's sign far away, or the
                # strip of one that shows over an awning. As sure as one that meets the size rules -- if
                # it is at least half the height, or something in front hides the rest of it: a fleck
                # thinner than that on open wall is a letter or a piece of a sign, not a sign.
                if (small and (hidden or height_m >= 0.5 * p.ad_min_height_m)
                        and p.ad_fascia_m[0] <= float(ctx.height_above_ground(y0 + h - 0.5, z)) <= p.ad_fascia_m[1]):
                    under = relaxed = False
        # The hue of the saturated core: the rim's pixels mix in the wall's.
        hue = hsv[cy:cy + core.shape[0], cx:cx + core.shape[1], 0][core].astype(np.float32) * (2 * np.pi / 256.0)
        spread = 1.0 - float(np.hypot(np.cos(hue).mean(), np.sin(hue).mean()))  # circular variance
        conf = 0.7 + 0.25 * float(np.clip(1.0 - spread / 0.1, 0.0, 1.0))
        if relaxed:
            conf -= 0.2
        if under:
            conf = 0.4
        out.append(Light(ADVERTISEMENT, y0, x0, m, conf))
    return out
