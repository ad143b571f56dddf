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
    """(H, W) float32 multiplicative albedo texture; 1 on sky, lights and untextured classes.

    ``points_w``: (H, W, 3) world hit points (NaN on sky). Factors stay within
    [0.55, 1.35] so textured albedo remains in [0, 1] for the base colours used.
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
    return np.clip(fac, 0.55, 1.35)
