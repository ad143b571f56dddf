"""Street lamps: a lamp head at the top of each tall pole component (docs/proposals.md)."""

from __future__ import annotations

import numpy as np

from .core import Context, Light, components, median
from .params import ProposalParams

POLE = 17
STREET_LIGHT_HT, STREET_LIGHT_LT = 8, 9
TRAFFIC_LIGHT, TRAFFIC_SIGN = 19, 20


def _pole_depth(ctx: Context, y0: int, x0: int, mask: np.ndarray) -> float | None:
    """Depth of a thin pole (m): a low percentile, because predicted depth bleeds the farther background in."""
    if ctx.depth is None:
        return None
    d = ctx.depth[y0:y0 + mask.shape[0], x0:x0 + mask.shape[1]][mask]
    d = d[np.isfinite(d) & (d > 0)]
    return float(np.percentile(d, 20)) if d.size else None


def _speck_head(specks: list[tuple[int, int, np.ndarray]], taken: set[int], top: int, trunk: int, band: int,
                mpp: float, p: ProposalParams) -> int | None:
    """Index in ``specks`` ((y0, x0, local mask) of pole components smaller than ``pole_min_area_px``
    or under 4 px tall, at least as wide as tall) of the lamp head of the trunk whose top is at global
    row ``top``, column ``trunk``: rows within the head band (``band`` px below the top, or a pixel
    above it), centre ``lamp_min_arm_m`` to ``lamp_max_arm_m`` sideways (``mpp`` metres per pixel at
    the trunk's depth); the nearest one not ``taken``, else None."""
    best, best_d = None, np.inf
    for k, (sy, sx, m) in enumerate(specks):
        if k in taken or sy + m.shape[0] - 1 < top - 1 or sy > top + band:
            continue
        d = abs(sx + (m.shape[1] - 1) / 2.0 - trunk) * mpp
        if p.lamp_min_arm_m <= d <= p.lamp_max_arm_m and d < best_d:
            best, best_d = k, d
    return best


def _lost_top(specks: list[tuple[int, int, np.ndarray]], taken: set[int], top: int, trunk: int, mpp: float,
              p: ProposalParams) -> int | None:
    """Index in ``specks`` of the arm and head of a trunk whose top the labels lost (global row ``top``,
    column ``trunk``): a speck whose bottom row lies 2 px to ``lamp_lost_top_m`` above the top, that
    starts within a pixel of the trunk's column and reaches ``lamp_min_arm_m`` to ``lamp_max_arm_m``
    sideways from it; the lowest one not ``taken``, else None.

    A far pole under a pixel wide shows in the labels only where it covers a pixel's centre, so its
    top stretch can drop out while its arm (longer than wide) stays."""
    best, best_bot = None, -1
    gap = max(3, int(np.ceil(p.lamp_lost_top_m / mpp)))
    for k, (sy, sx, m) in enumerate(specks):
        bot = sy + m.shape[0] - 1
        if k in taken or not top - gap <= bot <= top - 2:
            continue
        near = min(abs(sx - trunk), abs(sx + m.shape[1] - 1 - trunk))
        far = max(abs(sx - trunk), abs(sx + m.shape[1] - 1 - trunk))
        if near <= 1 and p.lamp_min_arm_m <= far * mpp <= p.lamp_max_arm_m and bot > best_bot:
            best, best_bot = k, bot
    return best


def _carries_signal(labels: np.ndarray, r0: int, r1: int, c0: int, c1: int) -> bool:
    """True when a traffic light or traffic sign touches the head box (rows ``r0:r1``, columns
    ``c0..c1``, global) or lies within 2 px of it: the arm is a signal mast or a sign gantry."""
    H, W = labels.shape
    box = labels[max(0, r0 - 2):min(H, r1 + 2), max(0, min(c0, c1) - 2):min(W, max(c0, c1) + 3)]
    return bool(np.isin(box, (TRAFFIC_LIGHT, TRAFFIC_SIGN)).any())


def propose(ctx: Context) -> list[Light]:
    """One street_light_HT/LT per pole component carrying a head.

    The trunk is the component's fullest column (with the arm above it where the labels lost the
    trunk's top, :func:`_lost_top`); the top band (``lamp_head_band_m`` below the component's top) is
    searched for an arm. An arm reaching ``lamp_min_arm_m`` or more puts the head at its far end (the
    lamp: the head's pixels below the arm), confidence ``lamp_arm_conf`` (0.9), 0.5 when a traffic
    light or sign hangs there (a signal mast or a sign gantry, :func:`_carries_signal`); a speck of pole
    beside a trunk's top is the head itself (``lamp_arm_conf``); without an arm, a top band
    ``lamp_lantern_min_widening`` times wider than the trunk (and >= 0.2 m) is a post-top lantern (the
    band is the lamp, 0.65), a plain top gives the band at 0.3. Heads brighter than the trunk
    (diffusers) add up to 0.2. With depth, poles whose top is lower than
    ``lamp_min_height_m`` above the ground (bollards, sign and traffic-light posts) get none,
    and the top's height picks HT (>= ``lamp_high_min_m``) or LT; without depth, the pixel height
    relative to the image decides and confidences drop by 0.15.
    """
    p = ctx.params
    out: list[Light] = []
    fy = float(ctx.intrinsics.fy)
    # Far away the arm is thinner than a pixel and the labels lose it: the head is a separate speck of
    # pole beside the trunk's top (docs/proposals.md).
    # One labelling of the poles serves both the specks and the trunks (each took a full-frame pass).
    poles = list(components(ctx.labels == POLE, min(p.lamp_speck_min_px, p.pole_min_area_px)))
    specks = [(y0, x0, m) for y0, x0, m, a in poles if a >= p.lamp_speck_min_px
              and (a < p.pole_min_area_px or m.shape[0] < 4) and m.shape[1] >= m.shape[0]]
    taken: set[int] = set()
    for y0, x0, mask, area in poles:
        if area < p.pole_min_area_px:
            continue
        h, w = mask.shape
        if h < 4:
            continue
        cols = mask.sum(0)
        trunk = int(np.argmax(cols))
        ys, xs = np.nonzero(mask)
        top = int(ys.min())
        z = _pole_depth(ctx, y0, x0, mask)
        if z is not None:
            mpp = z / fy
            height = float(ctx.height_above_ground(y0 + top, z))
            if height < p.lamp_min_height_m:
                continue
            high = height >= p.lamp_high_min_m
        else:
            # Without depth: a pole must stand tall in pixels; metres per pixel guessed from the image height.
            if h < 0.06 * ctx.shape[0]:
                continue
            mpp = 8.0 / max(h, 1)
            high = True
        if (k := _lost_top(specks, taken, y0 + top, x0 + trunk, mpp, p)) is not None:
            # The labels lost the trunk's top: the pole is the trunk, the gap and the arm above it.
            taken.add(k)
            sy, sx, sm = specks[k]
            ny0, nx0 = min(y0, sy), min(x0, sx)
            ny1, nx1 = max(y0 + h, sy + sm.shape[0]), max(x0 + w, sx + sm.shape[1])
            merged = np.zeros((ny1 - ny0, nx1 - nx0), bool)
            merged[y0 - ny0:y0 - ny0 + h, x0 - nx0:x0 - nx0 + w] |= mask
            merged[sy - ny0:sy - ny0 + sm.shape[0], sx - nx0:sx - nx0 + sm.shape[1]] |= sm
            merged[sy - ny0 + sm.shape[0]:y0 + top - ny0, x0 + trunk - nx0] = True
            y0, x0, mask = ny0, nx0, merged
            h, w = mask.shape
            trunk = int(np.argmax(mask.sum(0)))
            top = int(np.nonzero(mask)[0].min())
        band = max(2, int(round(p.lamp_head_band_m / mpp)))
        in_band = mask & (np.arange(h)[:, None] < top + band)
        by, bx = np.nonzero(in_band)
        dx = bx - trunk
        reach_r, reach_l = int(dx.max()), int(-dx.min())
        reach = max(reach_r, reach_l)
        trunk_w = max(1, int(round(median(mask.sum(1)[mask.any(1)]))))
        if reach * mpp >= p.lamp_min_arm_m and reach > trunk_w + 1:
            sign = 1 if reach_r >= reach_l else -1
            head_w = max(2, int(round(0.8 / mpp)))
            far = trunk + sign * reach
            lo, hi = (far - head_w + 1, far) if sign > 0 else (far, far + head_w - 1)
            arm_h = max(1, int(round(0.12 / mpp)))
            head = in_band & (np.arange(w)[None, :] >= lo) & (np.arange(w)[None, :] <= hi)
            below_arm = head & (np.arange(h)[:, None] >= top + arm_h)
            lamp = below_arm if below_arm.sum() >= max(1, head.sum() // 3) else head
            # A signal or a sign hanging at the arm's end makes it a mast or a gantry, not a luminaire.
            mast = _carries_signal(ctx.labels, y0 + top, y0 + top + band, x0 + lo, x0 + hi)
            conf = 0.5 if mast else p.lamp_arm_conf
        elif (k := _speck_head(specks, taken, y0 + top, x0 + trunk, band, mpp, p)) is not None:
            sy, sx, lamp = specks[k]
            taken.add(k)
            out.append(Light(STREET_LIGHT_HT if high else STREET_LIGHT_LT, sy, sx, lamp,
                             float(np.clip(p.lamp_arm_conf - (0.15 if z is None else 0.0), 0, 1))))
            continue
        else:
            # No arm: a lantern on a post top is wider than the post; a bare pole top is not.
            rows = in_band.sum(1)
            head_w = float(median(rows[rows > 0])) if (rows > 0).any() else 0.0
            lamp = in_band
            conf = 0.65 if head_w >= p.lamp_lantern_min_widening * trunk_w and head_w * mpp >= 0.2 else 0.3
        if not lamp.any():
            continue
        trunk_px = mask & ~in_band
        if trunk_px.sum() >= 3:
            lum = ctx.lum[y0:y0 + h, x0:x0 + w]
            ratio = float(median(lum[lamp])) / max(float(median(lum[trunk_px])), 1e-4)
            conf += 0.2 * float(np.clip((ratio - 1.0) / 0.5, 0.0, 1.0))
        if z is None:
            conf -= 0.15
        out.append(Light(STREET_LIGHT_HT if high else STREET_LIGHT_LT, y0, x0, lamp, float(np.clip(conf, 0, 1))))
    return out
