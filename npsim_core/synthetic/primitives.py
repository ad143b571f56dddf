"""Axis-aligned primitives, the street camera pose, and exact pixel-centre ray casting.

The synthetic scene is a list of axis-aligned boxes and rectangles in a *world*
frame: x right, y up, z along the street (forward), ground at y = 0, metres.
(That frame is left-handed; nothing here depends on handedness because every
quantity is converted to the right-handed OpenCV camera frame explicitly.)

The camera sits at ``(0, camera_height, 0)`` looking along +z, pitched down by
``camera_pitch`` radians. Its axes expressed in the world frame are::

    x_c = (1, 0, 0)                 image right
    y_c = (0, -cos p, -sin p)       image down
    z_c = (0, -sin p,  cos p)       optical axis

so a world direction ``d`` has camera coordinates ``R_cw d`` with the rows of
``R_cw`` = (x_c, y_c, z_c), and the horizon row is ``cy - fy tan p`` (docs/method.md §1.2).

Ground truth is computed by casting one ray per pixel centre ``K^-1 (u, v, 1)``
(z = 1 in the camera frame, so the ray parameter *is* the z-depth) against every
primitive's slab bounds, restricted to the primitive's projected screen box,
and keeping the nearest hit. This is exact at pixel centres and needs no
renderer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..camera import Intrinsics

#: Material kinds: index into this tuple is stored per primitive.
MATERIALS = ("diffuse", "glass", "paint", "lamp", "metal", "foliage")
#: Linear roughness per material kind (the Scene's ``roughness`` map).
ROUGHNESS = {"diffuse": 0.9, "glass": 0.05, "paint": 0.3, "lamp": 0.2, "metal": 0.45, "foliage": 0.8}


@dataclass
class PrimitiveList:
    """Growable list of axis-aligned boxes / rectangles (a rectangle has ``lo[a] == hi[a]`` on one axis).

    Attributes per primitive: world bounds ``lo``/``hi`` (m), Cityscapes ``label``,
    light instance id ``light`` (0 = none), linear RGB base ``color`` in [0, 1],
    material index into :data:`MATERIALS`, and for rectangles lying on a host face
    ``out`` = +-1, the host's outward side along the rectangle's axis (0 = none).
    """

    lo: list
    hi: list
    label: list
    light: list
    color: list
    material: list
    out: list

    @classmethod
    def new(cls) -> "PrimitiveList":
        return cls([], [], [], [], [], [], [])

    def box(self, lo, hi, label: int, color, material: str = "diffuse", light: int = 0, out: int = 0) -> None:
        lo = np.asarray(lo, dtype=np.float64)
        hi = np.asarray(hi, dtype=np.float64)
        a, b = np.minimum(lo, hi), np.maximum(lo, hi)
        self.lo.append(a)
        self.hi.append(b)
        self.label.append(int(label))
        self.light.append(int(light))
        self.color.append(np.asarray(color, dtype=np.float64))
        self.material.append(MATERIALS.index(material))
        self.out.append(int(out))

    def rect(self, axis: int, at: float, lo2, hi2, label: int, color, material: str = "diffuse",
             light: int = 0, out: int = 0) -> None:
        """Rectangle in the plane ``world[axis] == at``; ``lo2``/``hi2`` bound the other two axes in order."""
        others = [i for i in range(3) if i != axis]
        lo = np.zeros(3)
        hi = np.zeros(3)
        lo[axis] = hi[axis] = at
        lo[others[0]], lo[others[1]] = lo2
        hi[others[0]], hi[others[1]] = hi2
        self.box(lo, hi, label, color, material, light, out)

    def arrays(self) -> "Primitives":
        return Primitives(lo=np.array(self.lo).reshape(-1, 3), hi=np.array(self.hi).reshape(-1, 3),
                          label=np.array(self.label, dtype=np.int32), light=np.array(self.light, dtype=np.int32),
                          color=np.array(self.color).reshape(-1, 3), material=np.array(self.material, dtype=np.int32),
                          out=np.array(self.out, dtype=np.int32))


@dataclass(frozen=True)
class Primitives:
    """Frozen array form of :class:`PrimitiveList` (N primitives)."""

    lo: np.ndarray
    hi: np.ndarray
    label: np.ndarray
    light: np.ndarray
    color: np.ndarray
    material: np.ndarray
    out: np.ndarray

    def __len__(self) -> int:
        return int(self.lo.shape[0])

    def subset(self, keep: np.ndarray) -> "Primitives":
        return Primitives(self.lo[keep], self.hi[keep], self.label[keep], self.light[keep], self.color[keep],
                          self.material[keep], self.out[keep])


@dataclass(frozen=True)
class CameraPose:
    """Camera height above the ground (m) and downward pitch (rad); camera at world (0, h, 0)."""

    height: float = 1.22
    pitch: float = 0.038

    @property
    def center(self) -> np.ndarray:
        return np.array([0.0, self.height, 0.0])

    @property
    def R_cw(self) -> np.ndarray:
        """Rows = camera axes in world coordinates (world -> camera rotation)."""
        s, c = math.sin(self.pitch), math.cos(self.pitch)
        return np.array([[1.0, 0.0, 0.0], [0.0, -c, -s], [0.0, -s, c]])

    def world_to_camera(self, pw: np.ndarray) -> np.ndarray:
        return (np.asarray(pw, dtype=np.float64) - self.center) @ self.R_cw.T


@dataclass(frozen=True)
class GroundTruth:
    """Exact pixel-centre buffers. ``prim`` is the primitive index per pixel (-1 = sky)."""

    depth: np.ndarray      # (H, W) float32 z-depth m, NaN = sky
    normals: np.ndarray    # (H, W, 3) float32 camera frame, toward camera, NaN = sky
    prim: np.ndarray       # (H, W) int32


def _screen_box(prims: Primitives, i: int, intr: Intrinsics, pose: CameraPose) -> tuple[int, int, int, int] | None:
    """Pixel bbox [x0, x1) x [y0, y1) that can see primitive ``i``; None when it is fully behind the camera."""
    lo, hi = prims.lo[i], prims.hi[i]
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    pc = pose.world_to_camera(corners)
    z = pc[:, 2]
    if np.all(z <= 0):
        return None
    W, H = intr.width, intr.height
    if np.any(z < 1e-3):
        # Straddles the camera plane: projection of corners is meaningless; test the whole image.
        return 0, W, 0, H
    u = intr.fx * pc[:, 0] / z + intr.cx
    v = intr.fy * pc[:, 1] / z + intr.cy
    x0 = max(int(math.floor(u.min())) - 1, 0)
    x1 = min(int(math.ceil(u.max())) + 2, W)
    y0 = max(int(math.floor(v.min())) - 1, 0)
    y1 = min(int(math.ceil(v.max())) + 2, H)
    if x0 >= x1 or y0 >= y1:
        return None
    return x0, x1, y0, y1


def raycast(prims: Primitives, intr: Intrinsics, pose: CameraPose) -> GroundTruth:
    """Nearest hit of every pixel-centre ray (exact; vectorised per primitive over its screen box).

    Ties (coplanar primitives) go to the primitive listed first, except that light
    primitives win ties: they lie flush on their host face, and the plane
    parameter of a rectangle and of the coplanar box face is computed with the
    same float32 operations, so the tie is exact. Depth relative error ~1e-7;
    rectangles take a cheaper single-plane path.
    """
    H, W = intr.height, intr.width
    rays_c = intr.pixel_rays(np.float64)                     # z = 1 -> ray parameter = z-depth
    dirs = (rays_c @ pose.R_cw).astype(np.float32)           # world directions, (H, W, 3)
    o = pose.center.astype(np.float32)
    zbuf = np.full((H, W), np.inf, dtype=np.float32)
    prim = np.full((H, W), -1, dtype=np.int32)
    axis_map = np.zeros((H, W), dtype=np.int8)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
    lo_all = prims.lo.astype(np.float32)
    hi_all = prims.hi.astype(np.float32)
    for i in range(len(prims)):
        box = _screen_box(prims, i, intr, pose)
        if box is None:
            continue
        x0, x1, y0, y1 = box
        lo, hi = lo_all[i], hi_all[i]
        zb = zbuf[y0:y1, x0:x1]
        flat = prims.lo[i] == prims.hi[i]
        if flat.any():
            a = int(np.argmax(flat))
            b, c = [k for k in range(3) if k != a]
            d = dirs[y0:y1, x0:x1]
            t = (lo[a] - o[a]) * inv[y0:y1, x0:x1, a]
            pb = o[b] + t * d[..., b]
            pc = o[c] + t * d[..., c]
            closer = (t <= zb) if prims.light[i] else (t < zb)
            hit = (t > 1e-6) & closer & (pb >= lo[b]) & (pb <= hi[b]) & (pc >= lo[c]) & (pc <= hi[c])
            if not hit.any():
                continue
            zb[hit] = t[hit]
            axis_map[y0:y1, x0:x1][hit] = a
        else:
            iv = inv[y0:y1, x0:x1]
            with np.errstate(invalid="ignore"):
                t1 = (lo - o) * iv
                t2 = (hi - o) * iv
            tmin = np.minimum(t1, t2)
            tnear = tmin.max(axis=-1)
            tfar = np.maximum(t1, t2).min(axis=-1)
            hit = (tnear <= tfar) & (tnear > 1e-6) & (tnear < zb)
            if not hit.any():
                continue
            zb[hit] = tnear[hit]
            axis_map[y0:y1, x0:x1][hit] = np.argmax(tmin[hit], axis=-1)
        prim[y0:y1, x0:x1][hit] = i
    sky = prim < 0
    # Normal: unit world axis of the hit face, signed against the ray, then rotated into the camera frame.
    ax = axis_map[..., None].astype(np.intp)
    d_axis = np.take_along_axis(dirs, ax, axis=-1)[..., 0]
    n_w = np.zeros((H, W, 3), dtype=np.float64)
    np.put_along_axis(n_w, ax, -np.sign(d_axis).astype(np.float64)[..., None], axis=-1)
    normals = (n_w @ pose.R_cw.T).astype(np.float32)
    normals[sky] = np.nan
    depth = zbuf
    depth[sky] = np.nan
    return GroundTruth(depth=depth, normals=normals, prim=prim)
