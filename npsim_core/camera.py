"""Pinhole camera: intrinsics, back-projection and normals from depth (docs/method.md §1).

Conventions: OpenCV camera frame (x right, y down, z forward); pixel (u, v) =
(column, row) with centres at integer coordinates; depth is z-depth in metres;
normals are unit vectors pointing toward the camera (n·P < 0 on visible surfaces).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import NpsimInputError


#: Confidence below which a pixel of an estimate's confidence map counts as guessed: the pop-up
#: prior's hidden feet, crowns over occluders, nearest fills and far-limit placements fall below it,
#: its visible contacts and the ground above (docs/geometry.md, "Confidence"). The uncertain map's
#: default (``UncertaintyParams.confidence_below``) and the manifest's share use it.
LOW_CONFIDENCE = 0.5


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels for an image of ``width`` x ``height``.

    ``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``; pixel centres are at integer
    coordinates, so the image centre is ``((W-1)/2, (H-1)/2)``.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def __post_init__(self) -> None:
        vals = (self.fx, self.fy, self.cx, self.cy)
        if not all(math.isfinite(float(v)) for v in vals):
            raise NpsimInputError(f"intrinsics must be finite, got fx,fy,cx,cy = {vals}")
        if self.fx <= 0 or self.fy <= 0:
            raise NpsimInputError(f"focal lengths must be > 0, got fx={self.fx}, fy={self.fy}")
        if int(self.width) < 1 or int(self.height) < 1:
            raise NpsimInputError(f"image size must be >= 1x1, got {self.width}x{self.height}")

    @classmethod
    def from_fov(cls, width: int, height: int, hfov_deg: float) -> "Intrinsics":
        """Square pixels from a horizontal field of view in degrees (docs/method.md §1.2)."""
        if not (0.0 < hfov_deg < 180.0):
            raise NpsimInputError(f"horizontal field of view must be in (0, 180) degrees, got {hfov_deg}")
        f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        return cls(f, f, (width - 1) / 2.0, (height - 1) / 2.0, int(width), int(height))

    @classmethod
    def from_matrix(cls, K: np.ndarray, width: int, height: int) -> "Intrinsics":
        """From a 3x3 camera matrix."""
        K = np.asarray(K, dtype=np.float64)
        if K.shape != (3, 3):
            raise NpsimInputError(f"camera matrix must be 3x3, got shape {K.shape}")
        return cls(float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]), int(width), int(height))

    @classmethod
    def cityscapes(cls, width: int = 2048, height: int = 1024) -> "Intrinsics":
        """Cityscapes' typical intrinsics (docs/method.md §1.2), rescaled to ``width`` x ``height``."""
        return cls(2262.52, 2265.30, 1096.98, 513.14, 2048, 1024).resized(width, height)

    @property
    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1]], dtype=np.float64)

    @property
    def hfov_deg(self) -> float:
        return math.degrees(2.0 * math.atan((self.width / 2.0) / self.fx))

    def resized(self, width: int, height: int) -> "Intrinsics":
        """Intrinsics of the same camera for an image resampled to ``width`` x ``height``.

        Pixel centres map as ``u' = (u + 0.5) * sx - 0.5`` (OpenCV INTER_AREA/LINEAR
        convention), so ``cx' = (cx + 0.5) * sx - 0.5``.
        """
        sx, sy = width / self.width, height / self.height
        return Intrinsics(self.fx * sx, self.fy * sy, (self.cx + 0.5) * sx - 0.5, (self.cy + 0.5) * sy - 0.5,
                          int(width), int(height))

    def to_dict(self) -> dict:
        return {"fx": self.fx, "fy": self.fy, "cx": self.cx, "cy": self.cy,
                "width": self.width, "height": self.height}

    @classmethod
    def from_dict(cls, d: dict) -> "Intrinsics":
        try:
            return cls(float(d["fx"]), float(d["fy"]), float(d["cx"]), float(d["cy"]),
                       int(d["width"]), int(d["height"]))
        except KeyError as exc:
            raise NpsimInputError(f"intrinsics need fx, fy, cx, cy, width, height; missing {exc}") from None

    def pixel_rays(self, dtype=np.float32) -> np.ndarray:
        """HxWx3 rays ``K^-1 (u, v, 1)`` (z = 1) for every pixel centre."""
        u = (np.arange(self.width, dtype=np.float64) - self.cx) / self.fx
        v = (np.arange(self.height, dtype=np.float64) - self.cy) / self.fy
        rays = np.empty((self.height, self.width, 3), dtype=np.float64)
        rays[..., 0] = u[None, :]
        rays[..., 1] = v[:, None]
        rays[..., 2] = 1.0
        return rays.astype(dtype, copy=False)

    def rays_at(self, uv: np.ndarray, dtype=np.float32) -> np.ndarray:
        """(N, 3) rays ``K^-1 (u, v, 1)`` (z = 1) through image positions ``uv`` (N, 2), pixels."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        out = np.empty((len(uv), 3), dtype=np.float64)
        out[:, 0] = (uv[:, 0] - self.cx) / self.fx
        out[:, 1] = (uv[:, 1] - self.cy) / self.fy
        out[:, 2] = 1.0
        return out.astype(dtype, copy=False)


def valid_depth_mask(depth: np.ndarray) -> np.ndarray:
    """True where depth is a usable z-depth: finite and > 0."""
    d = np.asarray(depth)
    with np.errstate(invalid="ignore"):
        return np.isfinite(d) & (d > 0)


def backproject(depth: np.ndarray, intr: Intrinsics) -> np.ndarray:
    """HxW z-depth (m) -> HxWx3 camera-frame points ``P = d K^-1 (u, v, 1)``.

    Invalid depth (NaN, inf, <= 0) yields NaN points, so it cannot leak into
    downstream sums unnoticed.
    """
    d = np.asarray(depth, dtype=np.float32)
    _check_hw(d, intr, "depth")
    valid = valid_depth_mask(d)
    pts = intr.pixel_rays(np.float32) * np.where(valid, d, np.nan)[..., None]
    return pts


def normals_from_depth(depth: np.ndarray, intr: Intrinsics) -> np.ndarray:
    """Unit normals (HxWx3, camera frame, toward the camera) from z-depth.

    ``T_u = P(u+1,v) - P(u,v)``, ``T_v = P(u,v+1) - P(u,v)``, ``n = normalize(T_v x T_u)``
    (docs/method.md §1.3). Where the forward neighbour is invalid (last column/row, depth
    edge into sky) the backward difference is used; pixels with neither are NaN.
    """
    # Per (H, W) component plane rather than (H, W, 3) arrays: the same float64 operations in the
    # same order (bit for bit the result of np.cross / np.linalg.norm on the stacked points), ~5x
    # less CPU at 2048x1024 (0.9 -> 0.17 s; it runs ~14 times per frame).
    d = np.asarray(depth, dtype=np.float32)
    _check_hw(d, intr, "depth")
    ok = valid_depth_mask(d)
    dn = np.where(ok, d, np.float32(np.nan))
    rays = intr.pixel_rays(np.float32)
    planes = [(rays[..., k] * dn).astype(np.float64) for k in range(3)]  # P = d K^-1 (u, v, 1)
    u0, u1, u2 = _one_sided_diff(planes, ok, axis=1)
    v0, v1, v2 = _one_sided_diff(planes, ok, axis=0)
    n0 = v1 * u2 - v2 * u1  # T_v x T_u
    n1 = v2 * u0 - v0 * u2
    n2 = v0 * u1 - v1 * u0
    norm = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    bad = ~(norm > 0)
    out = np.empty(d.shape + (3,), np.float32)
    with np.errstate(invalid="ignore", divide="ignore"):
        for k, c in enumerate((n0, n1, n2)):
            c = c / norm
            c[bad] = np.nan
            out[..., k] = c
    return out


def _one_sided_diff(planes: list[np.ndarray], ok: np.ndarray, axis: int) -> list[np.ndarray]:
    """Forward difference of each (H, W) float64 plane along ``axis`` where both pixels are valid
    (``ok``), else the backward difference where that pair is valid, else NaN."""
    H, W = ok.shape
    n = ok.shape[axis]
    out = [np.full((H, W), np.nan) for _ in planes]
    if n < 2:
        return out
    a = (slice(None), slice(0, n - 1)) if axis == 1 else (slice(0, n - 1), slice(None))
    b = (slice(None), slice(1, n)) if axis == 1 else (slice(1, n), slice(None))
    pair = ok[b] & ok[a]  # the forward difference of the pixels in ``a`` is finite
    fwd_ok = np.zeros((H, W), bool)
    fwd_ok[a] = pair
    use_bwd = np.zeros((H, W), bool)
    use_bwd[b] = pair
    use_bwd &= ~fwd_ok
    sel = use_bwd[b]
    for o, p in zip(out, planes):
        diff = p[b] - p[a]
        o[a] = np.where(pair, diff, np.nan)
        o[b][sel] = diff[sel]
    return out


def _check_hw(arr: np.ndarray, intr: Intrinsics, what: str) -> None:
    if arr.ndim < 2 or arr.shape[:2] != (intr.height, intr.width):
        raise NpsimInputError(
            f"{what} has shape {arr.shape[:2]} but the intrinsics are for {intr.height}x{intr.width} (HxW); "
            "resize the array or use Intrinsics.resized()")
