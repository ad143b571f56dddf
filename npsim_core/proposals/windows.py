"""Building windows: façade regions that differ from the local wall and are regular in floors
(docs/proposals.md)."""

from __future__ import annotations

import cv2
import numpy as np

from .core import Context, Group, Light, components

BUILDING, VEGETATION, SKY = 11, 21, 23
GROUND = (6, 7, 8, 9, 22)  # ground, road, sidewalk, parking, terrain
WINDOW_BUILDING, WINDOWS_GROUP = 1, 13


def _masked_mean(val: np.ndarray, w: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Box-filtered mean of ``val`` weighted by ``w`` (k x k), and the weight's box mean."""
    num = cv2.blur(val * w, (k, k), borderType=cv2.BORDER_REPLICATE)
    den = cv2.blur(w, (k, k), borderType=cv2.BORDER_REPLICATE)
    return num / np.maximum(den, 1e-6), den


def wall_reference(feat: np.ndarray, building: np.ndarray, params) -> np.ndarray:
    """Local wall appearance (HxWxC float32) of features ``feat`` (HxWxC: log luminance, Lab a, b).

    Masked box means over building pixels that look like wall, at about 512 px wide: a coarse
    estimate (all building pixels, then those within the window thresholds of it), then a fine one
    over the pixels the coarse estimate calls wall; the coarse one stands where the fine box
    holds too little wall (``window_wall_min_share``).
    """
    H, W = building.shape
    f = max(1, W // 512)  # about 512 px wide: fast at 2048, no detail lost at 512
    h, w = max(1, H // f), max(1, W // f)
    small = cv2.resize(feat, (w, h), interpolation=cv2.INTER_AREA)
    wb = cv2.resize(building.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
    wb = (wb > 0.99).astype(np.float32)
    C = feat.shape[2]

    def mean(mask: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        r = np.stack([_masked_mean(small[..., c], mask, k)[0] for c in range(C)], -1)
        return r, cv2.blur(mask, (k, k), borderType=cv2.BORDER_REPLICATE)

    def wall_like(ref: np.ndarray) -> np.ndarray:
        odd = _differs(small, ref, params)
        if params.window_wall_rim:
            odd = cv2.dilate(odd.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
        return wb * ~odd

    k_fine = max(3, int(round(params.window_wall_kernel_frac * W / f)) | 1)
    k_coarse = max(3, int(round(4 * params.window_wall_kernel_frac * W / f)) | 1)
    # Coarse first (panes are a minority of any large box), then fine over what the coarse estimate
    # calls wall, so a pane larger than the fine box cannot become its own reference.
    r0, _ = mean(wb, k_coarse)
    coarse, den_c = mean(wall_like(r0), k_coarse)
    fine, den_f = mean(wall_like(coarse), k_fine)
    ref = np.where((den_f > params.window_wall_min_share)[..., None], fine, coarse)
    if (den_c <= 1e-3).any():  # nothing nearby looks like wall: the building's overall median
        vals = small[wb > 0]
        ref[den_c <= 1e-3] = np.median(vals, axis=0) if len(vals) else 0.0
    return cv2.resize(ref, (W, H), interpolation=cv2.INTER_LINEAR)


def _differs(feat: np.ndarray, ref: np.ndarray, params) -> np.ndarray:
    """Pixels whose luminance ratio or chromaticity departs from the wall reference."""
    t = -np.log(params.window_dark_ratio)
    d_lum = np.abs(feat[..., 0] - ref[..., 0])
    d_chroma = np.hypot(feat[..., 1] - ref[..., 1], feat[..., 2] - ref[..., 2])
    return (d_lum > t) | (d_chroma > params.window_chroma_delta)


def _features(ctx: Context) -> np.ndarray:
    """HxWx3 float32: log linear luminance, Lab a and b (OpenCV 8-bit Lab, centred)."""
    lab = cv2.cvtColor(ctx.image, cv2.COLOR_RGB2Lab).astype(np.float32)
    return np.dstack([np.log(np.maximum(ctx.lum, 1e-4)), lab[..., 1] - 128.0, lab[..., 2] - 128.0])


def propose(ctx: Context) -> list[Group]:
    """Window instances in one windows_group per floor of each building region.

    Candidates are building pixels whose luminance differs from the local wall
    (:func:`wall_reference`) by more than ``window_dark_ratio`` either way (dark glass, bright
    reflections and frames), or whose chromaticity differs (tinted glass). Each connected blob is
    filled to its convex hull (frames, curtains and mullions split a pane) and kept when its
    height is plausible (``window_height_m`` with depth) and it fills its box
    (``window_min_fill``); a blob failing the fill or size test is eroded, split into its parts
    and each part grown back and tested again (``window_split_steps`` times at most). A darker blob
    with the wall's own colour, or running down to the ground with little tint, is a cast shadow
    (``window_shadow_*``) and dropped. Floors:
    blobs of one building component whose centre heights (with
    depth; else image rows) lie within ``window_floor_tol_m`` (else half a window). Confidence
    0.35 + 0.25 x fill + up to 0.2 for contrast + 0.2 when its floor has >= 3 windows.
    """
    p = ctx.params
    B = ctx.labels == BUILDING
    if not B.any():
        return []
    H, W = ctx.shape
    feat = _features(ctx)
    ref = wall_reference(feat, B, p)
    ratio = feat[..., 0] - ref[..., 0]
    chroma = np.hypot(feat[..., 1] - ref[..., 1], feat[..., 2] - ref[..., 2])
    t = -np.log(p.window_dark_ratio)
    inner = B
    if p.window_skip_border:  # pixels on the building's outline against sky or foliage blend with them
        soft = np.isin(ctx.labels, (SKY, VEGETATION)).astype(np.uint8)
        inner = B & ~(cv2.dilate(soft, np.ones((3, 3), np.uint8)) > 0)
    cand = inner & _differs(feat, ref, p)
    cand = cv2.morphologyEx(cand.astype(np.uint8), cv2.MORPH_OPEN, np.ones((2, 2), np.uint8)).astype(bool) \
        if min(H, W) >= 512 else cand
    bld_n, bld = cv2.connectedComponents(B.astype(np.uint8), connectivity=4)
    fy = float(ctx.intrinsics.fy)
    found = []  # [building id, centre height or row, floor tolerance, Light]

    def accept(y: int, x: int, sub: np.ndarray) -> str | None:
        """Keep the blob ``sub`` at (y, x) as a window, or say why not ("small", "size", "fill")."""
        h, w = sub.shape
        a = int(sub.sum())
        if a < p.window_min_area_px or h < 2:
            return "small"
        z = None
        if ctx.depth is not None:
            d = ctx.depth[y:y + h, x:x + w][sub]
            d = d[np.isfinite(d)]
            if d.size:
                z = float(np.median(d))
        if z is not None:
            # Height, not area: facades recede, so a pane's image width is foreshortened but its height is not.
            height_m = h * z / fy
            if height_m < p.window_height_m[0]:
                return "small"
            if height_m > p.window_height_m[1] or w * z / fy > p.window_height_m[1]:
                return "size"
        elif a > 0.02 * H * W:
            return "size"
        if w < 2:
            filled = sub.copy()
        else:
            hull = cv2.convexHull(cv2.findNonZero(sub.astype(np.uint8)))
            filled = np.zeros((h, w), np.uint8)
            cv2.fillConvexPoly(filled, hull, 1)
            filled = filled.astype(bool) & B[y:y + h, x:x + w]
        fill = filled.sum() / float(w * h)
        if fill < p.window_min_fill:
            return "fill"
        contrast = float(np.median(np.abs(ratio[y:y + h, x:x + w][sub])))
        dark = float(np.median(ratio[y:y + h, x:x + w][sub]))
        if p.window_shadow_chroma > 0 and np.log(p.window_shadow_ratio) < dark < 0:
            tint = float(np.median(chroma[y:y + h, x:x + w][sub]))
            # A pane sits on a sill; a shadow runs down to the facade's foot on the ground.
            below = np.zeros(w, bool)
            rows = h - 1 - np.argmax(sub[::-1], axis=0)               # lowest blob pixel per column
            has = sub.any(0)
            yy = np.minimum(y + rows + 1, H - 1)
            below[has] = np.isin(ctx.labels[yy[has], (x + np.arange(w))[has]], GROUND)
            footed = below[has].mean() > 0.5 if has.any() else False
            if tint < p.window_shadow_chroma or (footed and tint < p.window_shadow_chroma_footed):
                return "shadow"  # the wall's own colour, only darker: a cast shadow, not glass
        ys, xs = np.nonzero(filled)
        cy_ = y + ys.mean()
        b_id = int(np.bincount(bld[y:y + h, x:x + w][filled]).argmax())
        if z is not None:
            level, tol = float(ctx.height_above_ground(cy_, z)), p.window_floor_tol_m
        else:
            level, tol = float(cy_), max(2.0, h / 2.0)
        conf = 0.35 + 0.25 * min(1.0, (fill - p.window_min_fill) / (1 - p.window_min_fill + 1e-6)) \
            + 0.2 * min(1.0, contrast / (3 * t))
        found.append([b_id, level, tol, Light(WINDOW_BUILDING, y, x, filled, conf)])
        return None

    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    stack = [(y0, x0, m, 0) for y0, x0, m, _ in components(cand, p.window_min_area_px, connectivity=4)]
    while stack:
        y0, x0, m, depth_ = stack.pop()
        why = accept(y0, x0, m)
        if why in ("fill", "size") and depth_ < p.window_split_steps:
            # Panes joined by thin bridges (a shadow edge, 1-px gaps far away): erode, split, grow back.
            er = cv2.erode(m.astype(np.uint8), cross) > 0
            parts = list(components(er, 1, connectivity=4))
            if len(parts) > 1 or (parts and depth_ + 1 < p.window_split_steps):
                for py, px, pm, _ in parts:
                    grown = np.zeros(m.shape, np.uint8)
                    grown[py:py + pm.shape[0], px:px + pm.shape[1]] = pm
                    grown = (cv2.dilate(grown, cross) > 0) & m
                    ys, xs = np.nonzero(grown)
                    gy0, gx0 = ys.min(), xs.min()
                    stack.append((y0 + gy0, x0 + gx0, grown[gy0:ys.max() + 1, gx0:xs.max() + 1], depth_ + 1))
    # Floors: sort by building then level, split where the level jumps by more than the tolerance.
    found.sort(key=lambda f: (f[0], f[1]))
    groups: list[list] = []
    for f in found:
        if groups and groups[-1][-1][0] == f[0] and f[1] - groups[-1][-1][1] <= f[2]:
            groups[-1].append(f)
        else:
            groups.append([f])
    out: list[Group] = []
    for g in groups:
        regular = len(g) >= 3
        members = []
        for f in g:
            li = f[3]
            li.confidence = float(np.clip(li.confidence + (0.2 if regular else 0.0), 0, 1))
            members.append(li)
        members.sort(key=lambda li: (li.x0, li.y0))
        out.append(Group(WINDOWS_GROUP, members, float(np.mean([li.confidence for li in members]))))
    return out
