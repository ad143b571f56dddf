"""Street lamps: a lamp head at the top of each tall pole component (docs/proposals.md)."""

from __future__ import annotations

import numpy as np

from .core import Context, Light, components
from .params import ProposalParams

POLE = 17
STREET_LIGHT_HT, STREET_LIGHT_LT = 8, 9


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


def _lens(in_band: np.ndarray, top: float, far: int, sign: int, mpp: float, p: ProposalParams) -> np.ndarray:
    """An arm head's lens (local mask): the pole pixels of the head band (``in_band``) whose centres lie
    ``lamp_lens_top_m`` or more below the pole's top edge (``top``, rows: under the arm) and between
    ``lamp_lens_inset_m`` and ``lamp_lens_inset_m + lamp_lens_len_m`` back from the head's far edge
    (the outer edge of column ``far``, the arm reaching toward ``sign``); ``mpp`` metres per pixel.

    Pixel centres, not pixel counts: a lens 5.6 px long covers 5 or 6 pixels depending on where its
    ends fall, as the annotator's mask (or a label map sampled at pixel centres) does."""
    h, w = in_band.shape
    cx = np.arange(w) + 0.5
    edge = far + 1.0 if sign > 0 else float(far)
    back = (edge - cx) * sign  # metres-per-pixel units back from the far edge
    cols = (back >= p.lamp_lens_inset_m / mpp) & (back <= (p.lamp_lens_inset_m + p.lamp_lens_len_m) / mpp)
    rows = np.arange(h) + 0.5 >= top + p.lamp_lens_top_m / mpp
    return in_band & cols[None, :] & rows[:, None]


def _glass(in_band: np.ndarray, top: int, mpp: float, p: ProposalParams) -> np.ndarray:
    """A lantern's glass (local mask): the head band's pixels (``in_band``) whose centres lie under a cap
    ``lamp_lantern_cap_m`` tall below the top edge (row ``top``), within ``lamp_lantern_glass_m`` below
    it, and ``lamp_lantern_frame_m`` or more inside their row's left and right edges."""
    h, w = in_band.shape
    cy = np.arange(h) + 0.5 - top
    rows = (cy >= p.lamp_lantern_cap_m / mpp) & (cy <= (p.lamp_lantern_cap_m + p.lamp_lantern_glass_m) / mpp)
    m = in_band & rows[:, None]
    if not m.any():
        return m
    cx = np.arange(w)[None, :] + 0.5
    has = m.any(1)
    left = np.where(has, np.argmax(m, 1), 0).astype(np.float64)[:, None]
    right = np.where(has, w - np.argmax(m[:, ::-1], 1), 0).astype(np.float64)[:, None]
    inset = p.lamp_lantern_frame_m / mpp
    return m & (cx - left >= inset) & (right - cx >= inset)


def propose(ctx: Context) -> list[Light]:
    """One street_light_HT/LT per pole component carrying a head.

    The trunk is the component's fullest column; the top band (``lamp_head_band_m`` below the
    component's top) is searched for an arm. An arm reaching ``lamp_min_arm_m`` or more puts the
    head at its far end (the lamp: the head's lens, :func:`_lens`), confidence 0.85; without an arm,
    a top band ``lamp_lantern_min_widening`` times wider than the trunk (and >= 0.2 m) is a post-top
    lantern (the lamp: its glass, :func:`_glass`; 0.75), a plain top gives the band at 0.3; a speck
    of pole beside a trunk's top is the head itself (0.75). Heads brighter than the trunk (diffusers)
    add up to 0.2. (Seeds 0-2 of the synthetic streets, both sizes: of the arm heads and lanterns
    at 0.8-0.9 before the +0.1, 91-97 % matched their lamp at IoU >= 0.5; docs/proposals.md.) With depth, poles whose top is lower than
    ``lamp_min_height_m`` above the ground (bollards, sign and traffic-light posts) get none,
    and the top's height picks HT (>= ``lamp_high_min_m``) or LT; without depth, the pixel height
    relative to the image decides and confidences drop by 0.15.
    """
    p = ctx.params
    out: list[Light] = []
    fy = float(ctx.intrinsics.fy)
    # Far away the arm is thinner than a pixel and the labels lose it: the head is a separate speck of
    # pole beside the trunk's top (docs/proposals.md).
    specks = [(y0, x0, m) for y0, x0, m, a in components(ctx.labels == POLE, p.lamp_speck_min_px)
              if (a < p.pole_min_area_px or m.shape[0] < 4) and m.shape[1] >= m.shape[0]]
    taken: set[int] = set()
    for y0, x0, mask, area in components(ctx.labels == POLE, p.pole_min_area_px):
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
        band = max(2, int(round(p.lamp_head_band_m / mpp)))
        in_band = mask & (np.arange(h)[:, None] < top + band)
        by, bx = np.nonzero(in_band)
        dx = bx - trunk
        reach_r, reach_l = int(dx.max()), int(-dx.min())
        reach = max(reach_r, reach_l)
        trunk_w = max(1, int(round(np.median(mask.sum(1)[mask.any(1)]))))
        if reach * mpp >= p.lamp_min_arm_m and reach > trunk_w + 1:
            sign = 1 if reach_r >= reach_l else -1
            head_w = max(2, int(round(0.8 / mpp)))
            far = trunk + sign * reach
            lo, hi = (far - head_w + 1, far) if sign > 0 else (far, far + head_w - 1)
            head = in_band & (np.arange(w)[None, :] >= lo) & (np.arange(w)[None, :] <= hi)
            if y0 + top == 0:
                # The frame cuts the pole: its top is not seen. The lens hangs under the arm, whose rows
                # are those the pole holds halfway between the trunk and the head.
                arm_rows = np.flatnonzero(in_band[:, (trunk + (lo if sign > 0 else hi)) // 2])
                lens_top = (int(arm_rows.max()) + 1) - p.lamp_lens_top_m / mpp if arm_rows.size else -np.inf
            else:
                lens_top = float(top)
            lens = _lens(in_band, lens_top, far, sign, mpp, p)
            lamp = lens if lens.sum() >= max(1, head.sum() // 3) else head
            conf = 0.85
        elif (k := _speck_head(specks, taken, y0 + top, x0 + trunk, band, mpp, p)) is not None:
            sy, sx, lamp = specks[k]
            taken.add(k)
            out.append(Light(STREET_LIGHT_HT if high else STREET_LIGHT_LT, sy, sx, lamp,
                             float(np.clip(0.75 - (0.15 if z is None else 0.0), 0, 1))))
            continue
        else:
            # No arm: a lantern on a post top is wider than the post; a bare pole top is not.
            rows = in_band.sum(1)
            head_w = float(np.median(rows[rows > 0])) if (rows > 0).any() else 0.0
            lantern = head_w >= p.lamp_lantern_min_widening * trunk_w and head_w * mpp >= 0.2
            glass = _glass(in_band, top, mpp, p) if lantern else in_band
            lamp = glass if glass.any() else in_band
            conf = 0.75 if lantern else 0.3
        if not lamp.any():
            continue
        trunk_px = mask & ~in_band
        if trunk_px.sum() >= 3:
            lum = ctx.lum[y0:y0 + h, x0:x0 + w]
            ratio = float(np.median(lum[lamp])) / max(float(np.median(lum[trunk_px])), 1e-4)
            conf += 0.2 * float(np.clip((ratio - 1.0) / 0.5, 0.0, 1.0))
        if z is None:
            conf -= 0.15
        out.append(Light(STREET_LIGHT_HT if high else STREET_LIGHT_LT, y0, x0, lamp, float(np.clip(conf, 0, 1))))
    return out
