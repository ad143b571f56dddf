"""Procedural albedo textures in world space (value noise, paving joints, facade courses).

The texture is a per-pixel multiplicative *albedo factor* evaluated at the exact
pixel-centre hit points. Because the day render is linear in albedo (sun
direct light plus an ambient term), multiplying the rendered radiance by the
same factor equals rendering the textured albedo; the returned ``albedo`` map
stays exactly consistent with the image.
"""

from __future__ import annotations

import numpy as np

from .street import BUILDING, CAR, ROAD, SIDEWALK, VEGETATION


def _hash3(ix: np.ndarray, iy: np.ndarray, iz: np.ndarray, seed: int) -> np.ndarray:
    """Deterministic lattice hash -> float32 in [0, 1)."""
    h = (ix.astype(np.uint32) * np.uint32(73856093)) ^ (iy.astype(np.uint32) * np.uint32(19349663)) \
        ^ (iz.astype(np.uint32) * np.uint32(83492791)) ^ np.uint32((seed * 2654435761) & 0xFFFFFFFF)
    h ^= h >> np.uint32(13)
    h *= np.uint32(1274126177)
    h ^= h >> np.uint32(16)
    return (h & np.uint32(0xFFFFFF)).astype(np.float32) / np.float32(0x1000000)


def value_noise(p: np.ndarray, scale: float, seed: int) -> np.ndarray:
    """Trilinear value noise in [-1, 1] of world points ``p`` (N, 3) with lattice spacing ``scale`` metres."""
    q = p / scale
    f = np.floor(q)
    t = (q - f).astype(np.float32)
    t = t * t * (3 - 2 * t)  # smoothstep: no visible lattice creases
    i = f.astype(np.int64)
    out = np.zeros(len(p), dtype=np.float32)
    for dx in (0, 1):
        wx = t[:, 0] if dx else 1 - t[:, 0]
        for dy in (0, 1):
            wy = t[:, 1] if dy else 1 - t[:, 1]
            for dz in (0, 1):
                wz = t[:, 2] if dz else 1 - t[:, 2]
                out += wx * wy * wz * _hash3(i[:, 0] + dx, i[:, 1] + dy, i[:, 2] + dz, seed)
    return out * 2 - 1


def albedo_factor(points_w: np.ndarray, labels: np.ndarray, light: np.ndarray, seed: int) -> np.ndarray:
    """(H, W) float32 multiplicative albedo texture; 1 on sky and untextured classes.

    ``points_w``: (H, W, 3) world hit points (NaN on sky). Surface factors stay within
    [0.55, 1.35] so textured albedo remains in [0, 1] for the base colours used; light
    pixels get :func:`light_factor` (dark glass may brighten up to ~7x for frames and
    curtains; the caller clips albedo to [0, 1]).
    """
    H, W = labels.shape
    fac = np.ones((H, W), dtype=np.float32)
    plain = light == 0

    def apply(mask: np.ndarray, fn) -> None:
        if mask.any():
            fac[mask] = fn(points_w[mask].astype(np.float64))

    def asphalt(p):
        return 1 + 0.12 * value_noise(p, 0.04, seed) + 0.10 * value_noise(p, 2.5, seed + 1)

    def paving(p):
        # 0.5 m square slabs with dark joints, slight per-slab tone.
        gx, gz = p[:, 0] / 0.5, p[:, 2] / 0.5
        joint = (np.abs(gx - np.round(gx)) < 0.04) | (np.abs(gz - np.round(gz)) < 0.04)
        slab = value_noise(np.stack([np.floor(gx) * 7.1, np.zeros_like(gx), np.floor(gz) * 3.3], -1), 1.0, seed + 2)
        top = p[:, 1] > 0.14  # the kerb face stays plain concrete
        return np.where(top & joint, 0.62, 1 + 0.07 * slab + 0.05 * value_noise(p, 0.05, seed + 3))

    def facade(p):
        # Plaster/brick: faint horizontal courses every 0.25 m plus blotchy weathering.
        course = np.abs(p[:, 1] / 0.25 - np.round(p[:, 1] / 0.25)) < 0.08
        return (1 + 0.10 * value_noise(p, 0.8, seed + 4) + 0.05 * value_noise(p, 0.07, seed + 5)) * \
            np.where(course, 0.9, 1.0)

    def foliage(p):
        return 1 + 0.30 * value_noise(p, 0.12, seed + 6) + 0.12 * value_noise(p, 0.6, seed + 7)

    def paint(p):
        return 1 + 0.03 * value_noise(p, 0.3, seed + 8)

    apply(plain & (labels == ROAD), asphalt)
    apply(plain & (labels == SIDEWALK), paving)
    apply(plain & (labels == BUILDING), facade)
    apply(plain & (labels == VEGETATION), foliage)
    apply(plain & (labels == CAR), paint)
    fac = np.clip(fac, 0.55, 1.35)
    lit = ~plain & np.isfinite(points_w).all(-1)
    if lit.any():
        fac[lit] = light_factor(points_w[lit].astype(np.float64), light[lit], seed)
    return fac


def _per_light(ids: np.ndarray, seed: int, salt: int) -> np.ndarray:
    """A uniform [0, 1) number per light id (stable across image sizes: a hash of the id, not of the pixel)."""
    return _hash3(ids, np.full_like(ids, salt), np.full_like(ids, 7), seed)


def light_factor(p: np.ndarray, ids: np.ndarray, seed: int) -> np.ndarray:
    """Albedo factor of light pixels (N,) at world points ``p`` (N, 3) owned by light ids ``ids`` (N,).

    Makes the lights look like the real thing rather than uniform patches, so light proposals
    cannot find them by colour alone (docs/proposals.md "The synthetic street's lights"): building
    panes vary in brightness (dark interiors to sky-bright
    reflections, 0.45-2.5x the glass colour) with a vertical reflection gradient; 40 % have a
    light frame 6-10 cm wide (half of those with a central mullion) and 30 % a curtain (a
    pale, folded band over the top or one side). Car panes vary 0.6-2x, lamps and street-lamp
    diffusers 0.55-1.15x (some are no brighter than their housing). The frame and curtain lie
    inside the pane, so the light masks (ground truth) are unchanged. Pane-relative positions come
    from the visible pixels' world extent per light.
    """
    ids = ids.astype(np.int64)
    cls = ids // 1000
    out = np.ones(len(ids), np.float64)
    uniq, inv = np.unique(ids, return_inverse=True)
    r = [_per_light(uniq, seed, salt)[inv].astype(np.float64) for salt in range(6)]
    # Pane coordinates: v = height, u = the horizontal axis along which the pane extends.
    lo = np.full((len(uniq), 3), np.inf)
    hi = np.full((len(uniq), 3), -np.inf)
    np.minimum.at(lo, inv, p)
    np.maximum.at(hi, inv, p)
    ext = hi - lo
    u_axis = np.where(ext[:, 0] >= ext[:, 2], 0, 2)[inv]
    pu = np.where(u_axis == 0, p[:, 0], p[:, 2])
    lo_u = np.where(u_axis == 0, lo[inv, 0], lo[inv, 2])
    ext_u = np.maximum(np.where(u_axis == 0, ext[inv, 0], ext[inv, 2]), 1e-6)
    ext_v = np.maximum(ext[inv, 1], 1e-6)
    du = pu - lo_u                      # metres from the pane's left/near edge
    dv = p[:, 1] - lo[inv, 1]           # metres above the pane's bottom
    fu, fv = du / ext_u, dv / ext_v

    win = cls == 1
    if win.any():
        bright = np.exp(np.log(0.45) + (np.log(2.5) - np.log(0.45)) * r[0])
        grad = 1.0 + (r[1] - 0.5) * 1.2 * (fv - 0.5)
        f = bright * grad
        framed = r[2] < 0.4
        fw = 0.06 + 0.04 * r[3]
        edge = np.minimum(np.minimum(du, ext_u - du), np.minimum(dv, ext_v - dv)) < fw
        mullion = framed & (r[3] < 0.5) & (np.abs(fu - 0.5) * ext_u < fw / 2)
        frame = framed & (edge | mullion)
        curtain = (r[4] < 0.3) & ~frame
        top = r[5] < 0.6
        side = np.where(r[5] < 0.8, fu < 0.3 + 0.2 * r[1], fu > 0.7 - 0.2 * r[1])
        band = np.where(top, fv > 0.55 + 0.25 * r[3], side)
        folds = 1.0 + 0.15 * np.sin(du * 2 * np.pi / 0.12)
        f = np.where(curtain & band, (3.0 + 3.0 * r[2]) * folds, f)
        f = np.where(frame, 3.0 + 3.0 * r[1], f)
        out = np.where(win, f, out)
    car_pane = cls == 2
    out = np.where(car_pane, 0.6 + 1.4 * r[0], out)
    lamp = (cls >= 3) & (cls <= 6) | (cls == 8) | (cls == 9)
    out = np.where(lamp, 0.55 + 0.6 * r[0], out)
    return out.astype(np.float32)
