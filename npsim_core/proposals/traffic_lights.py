"""Traffic lights: each traffic-light component is a housing holding three lamp cells (docs/proposals.md)."""

from __future__ import annotations

import numpy as np

from .core import Context, Group, Light, components

TRAFFIC_LIGHT = 19
INFERRED = 12
TRAFFIC_LIGHT_GROUP = 20
#: Lamp colours of a head in reading order (top to bottom; left to right on a horizontal head),
#: as resources/light_table.json's ``traffic_light.order``.
LAMP_ORDER = ("red", "amber", "green")


def _cells(mask: np.ndarray, vertical: bool, frac: float) -> list[np.ndarray]:
    """Three square lamp masks centred in the thirds of the housing's long axis (local coordinates)."""
    ys, xs = np.nonzero(mask)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    long0, long1, short0, short1 = (y0, y1, x0, x1) if vertical else (x0, x1, y0, y1)
    cell = (long1 - long0) / 3.0
    side = max(1.0, frac * min(cell, short1 - short0))
    sc = (short0 + short1) / 2.0
    yy, xx = np.mgrid[0:mask.shape[0], 0:mask.shape[1]]
    along, across = (yy + 0.5, xx + 0.5) if vertical else (xx + 0.5, yy + 0.5)
    out = []
    for k in range(3):
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


def propose(ctx: Context) -> list[Group]:
    """One traffic_light_group of three 'inferred' lamps per traffic-light component.

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
        cells = _cells(mask, vertical, p.tl_lamp_fraction)
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
        lights = [Light(INFERRED, y0, x0, c, conf, colour=LAMP_ORDER[k]) for k, c in enumerate(cells)]
        lin = (ctx.image[y0:y0 + h, x0:x0 + w].astype(np.float32) / 255.0) ** 2.2
        lit = lit_cell(lin.max(-1), cells, p.tl_lit_ratio)
        out.append(Group(TRAFFIC_LIGHT_GROUP, lights, conf, state=None if lit is None else LAMP_ORDER[lit]))
    return out
