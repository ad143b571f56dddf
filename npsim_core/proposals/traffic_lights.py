"""Traffic lights: each traffic-light component is a housing holding three lamp cells, or two for a
pedestrian signal (docs/proposals.md)."""

from __future__ import annotations

import cv2
import numpy as np

from .core import Context, Group, Light, components, median, pixels

TRAFFIC_LIGHT = 19
INFERRED = 12
TRAFFIC_LIGHT_GROUP = 20
#: Lamp colours of a head in reading order (top to bottom; left to right on a horizontal head),
#: as resources/light_table.json's ``traffic_light.order``.
LAMP_ORDER = ("red", "amber", "green")
#: A pedestrian signal's two lamps (red figure over green figure), as the table's ``order_two``.
PEDESTRIAN_ORDER = ("red", "green")
#: ``meta.traffic_light_direction`` of a pedestrian signal: its state is its own, not the vehicles'.
PEDESTRIAN = "pedestrian"


def _squares(mask: np.ndarray, vertical: bool, frac: float, n: int = 3) -> list[np.ndarray]:
    """``n`` square lamp masks centred in the n equal cells of the housing's long axis (local
    coordinates; not cut to ``mask``)."""
    ys, xs = np.nonzero(mask)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    long0, long1, short0, short1 = (y0, y1, x0, x1) if vertical else (x0, x1, y0, y1)
    cell = (long1 - long0) / float(n)
    side = max(1.0, frac * min(cell, short1 - short0))
    sc = (short0 + short1) / 2.0
    yy, xx = np.mgrid[0:mask.shape[0], 0:mask.shape[1]]
    along, across = (yy + 0.5, xx + 0.5) if vertical else (xx + 0.5, yy + 0.5)
    out = []
    for k in range(n):
        c = long0 + (k + 0.5) * cell
        sq = (np.abs(along - c) <= side / 2 + 1e-6) & (np.abs(across - sc) <= side / 2 + 1e-6)
        if not sq.any():  # sub-pixel lamp: the nearest pixel
            sq = (np.abs(along - c) < 1.0) & (np.abs(across - sc) < 1.0)
        out.append(sq)
    return out


def _cells(mask: np.ndarray, vertical: bool, frac: float, n: int = 3) -> list[np.ndarray]:
    """``n`` square lamp masks centred in the n equal cells of the housing's long axis (local coordinates)."""
    return [sq & mask for sq in _squares(mask, vertical, frac, n)]


def _shift(m: np.ndarray, dy: int, dx: int) -> np.ndarray:
    """``m`` moved by (dy, dx) pixels, what leaves the array dropped."""
    out = np.zeros_like(m)
    h, w = m.shape
    out[max(0, dy):h + min(0, dy), max(0, dx):w + min(0, dx)] = \
        m[max(0, -dy):h - max(0, dy), max(0, -dx):w - max(0, dx)]
    return out


def lens_cells(img: np.ndarray, mask: np.ndarray, squares: list[np.ndarray], reach: int) -> list[np.ndarray]:
    """The lamp squares moved together by the offset (at most ``reach`` px each way) that puts them on
    the lenses, cut to ``mask``.

    A housing's label holds its side and underside too when seen off-axis (the camera is below and
    beside it), which moves the box centre off the front face the lenses are on by a pixel or more.
    The lenses differ in colour from the housing's paint (lit or dark glass in red, amber, green, or
    behind visors, against black or yellow paint): the offset taken is the one whose squares differ
    most, on average, from the housing's median colour (``img``: the housing's box, float RGB; pixels
    of the housing's outline count as paint), a
    move costing 3 % of the score per pixel so that only a clear gain moves them; squares that would
    leave the housing are not moved.
    """
    # The housing's outline pixels blend with the background behind it, which differs from the paint
    # more than a dark lens does: only the pixels inside the outline are scored.
    inner = cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8), borderType=cv2.BORDER_CONSTANT,
                      borderValue=0).astype(bool)
    if not inner.any():
        return [sq & mask for sq in squares]
    paint = median(pixels(img, inner), axis=0)
    d = img - paint  # np.linalg.norm over the channels: the root of their squares' sum, elementwise
    dist = np.where(inner, np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]), 0.0)
    best, best_score = (0, 0), -1.0
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            moved = [_shift(sq, dy, dx) for sq in squares]
            if any(not (m & mask).any() for m in moved):
                continue
            score = sum(float(dist[m].sum()) / max(int(m.sum()), 1) for m in moved)
            score *= 1.0 - 0.03 * (abs(dy) + abs(dx))
            if score > best_score + 1e-9:
                best, best_score = (dy, dx), score
    return [_shift(sq, *best) & mask for sq in squares]


def lit_cell(glow: np.ndarray, cells: list[np.ndarray], ratio: float) -> int | None:
    """Index of the cell the day photo shows lit: its mean ``glow`` (the brightest linear channel: a
    lit red LED is bright in red only, so luminance undersells it) at least ``ratio`` times every
    other cell's; None when no cell stands out (all dark, or glare on all)."""
    means = np.array([float(glow[c].mean()) if c.any() else 0.0 for c in cells])
    k = int(np.argmax(means))
    others = np.delete(means, k)
    if means[k] <= 0 or (others.size and means[k] < ratio * max(float(others.max()), 1e-4)):
        return None
    return k


def _head_height_m(ctx: Context, y0: int, x0: int, mask: np.ndarray) -> float | None:
    """Height (m) of a signal housing from its pixel height and depth (a low percentile: predicted depth
    bleeds the farther background into small objects); None without depth."""
    d = ctx.depths_in(y0, y0 + mask.shape[0], x0, x0 + mask.shape[1], mask)
    if d is None:
        return None
    ys = np.flatnonzero(mask.any(1))
    return float(ys[-1] - ys[0] + 1) * float(np.percentile(d, 20)) / float(ctx.intrinsics.fy)


def propose(ctx: Context) -> list[Group]:
    """One traffic_light_group of three 'inferred' lamps per traffic-light component, two for a
    pedestrian signal.

    With depth, a vertical housing at most ``tl_pedestrian_max_h_m`` tall (a pedestrian head is two
    0.2-0.3 m lenses, 0.6-0.75 m; a vehicle head 0.9-1.1 m) is a pedestrian signal: two lamps, red
    over green (:data:`PEDESTRIAN_ORDER`), its group's ``meta.traffic_light_direction`` is
    ``"pedestrian"`` (its state is its own, npsim_core.render.lights.traffic_light_states). Without
    depth every head gets three lamps.

    Lamps are named red, amber, green in reading order (:data:`LAMP_ORDER`); a cell whose brightest
    channel is much brighter than the other two cells' by day (``tl_lit_ratio``) is the lamp the
    signal shows, kept as the
    group's state, so the night lights that lamp (npsim_core.render.lights.traffic_light_states);
    without one the night's seed picks the state.

    Confidence: 0.9 for a housing elongated like a signal head (aspect >= ``tl_min_aspect``; every one of
    them on the synthetic streets is one, docs/proposals.md), 0.4 for a
    squat one (seen edge-on or merged with something), lowered for components under 4 px across, raised
    slightly when the lamp cells differ in colour from the housing around them (lenses and visors).
    """
    p = ctx.params
    out: list[Group] = []
    for y0, x0, mask, area in components(ctx.labels == TRAFFIC_LIGHT, p.tl_min_area_px):
        h, w = mask.shape
        vertical = h >= w
        aspect = max(h, w) / max(1, min(h, w))
        height_m = _head_height_m(ctx, y0, x0, mask) if vertical else None
        pedestrian = height_m is not None and height_m <= p.tl_pedestrian_max_h_m
        order = PEDESTRIAN_ORDER if pedestrian else LAMP_ORDER
        squares = _squares(mask, vertical, p.tl_lamp_fraction, len(order))
        if any(not (sq & mask).any() for sq in squares):
            continue
        side = int(max(sq.sum(0).max() for sq in squares))
        cells = lens_cells(ctx.image[y0:y0 + h, x0:x0 + w].astype(np.float32) / 255.0, mask, squares,
                           max(1, int(round(p.tl_lens_reach * side))))
        conf = 0.9 if aspect >= p.tl_min_aspect else 0.4
        if min(h, w) < 4:
            conf -= 0.15
        img = ctx.image[y0:y0 + h, x0:x0 + w].astype(np.float32)
        lamps = np.zeros_like(mask)
        for c in cells:
            lamps |= c
        rim = mask & ~lamps
        if rim.sum() >= 3:
            contrast = float(np.abs(img[lamps].mean(0) - img[rim].mean(0)).max()) / 255.0
            conf += 0.15 * min(1.0, contrast / 0.15)
        conf = float(np.clip(conf, 0.0, 1.0))
        lights = [Light(INFERRED, y0, x0, c, conf, colour=order[k]) for k, c in enumerate(cells)]
        lin = (ctx.image[y0:y0 + h, x0:x0 + w].astype(np.float32) / 255.0) ** 2.2
        lit = lit_cell(lin.max(-1), cells, p.tl_lit_ratio)
        out.append(Group(TRAFFIC_LIGHT_GROUP, lights, conf, state=None if lit is None else order[lit],
                         direction=PEDESTRIAN if pedestrian else None))
    return out
