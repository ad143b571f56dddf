"""Traffic lights: each traffic-light component is a housing holding three lamp cells, or two for a
pedestrian signal (docs/proposals.md)."""

from __future__ import annotations

import numpy as np

from .core import Context, Group, Light, components

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


def _cells(mask: np.ndarray, vertical: bool, frac: float, n: int = 3) -> list[np.ndarray]:
    """``n`` square lamp masks centred in the n equal cells of the housing's long axis (local coordinates)."""
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
        out.append(sq & mask)
    return out


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
    if ctx.depth is None:
        return None
    d = ctx.depth[y0:y0 + mask.shape[0], x0:x0 + mask.shape[1]][mask]
    d = d[np.isfinite(d)]
    if d.size == 0:
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
        cells = _cells(mask, vertical, p.tl_lamp_fraction, len(order))
        if any(not c.any() for c in cells):
            continue
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
