"""Worldsheet grid mesh from a depth map (docs/method.md §4, thesis §3.3).

One vertex per pixel (or per ``stride`` pixels) at ``P(u, v) = d(u, v) K^-1 (u, v, 1)^T``,
two triangles per 2x2 quad of vertices. Conventions (docs/method.md §1):

* winding: the geometric normal ``(v1 - v0) x (v2 - v0)`` points toward the
  camera (``n . P < 0``). With corners ``a=(u,v)``, ``b=(u+1,v)``, ``c=(u,v+1)``,
  ``d=(u+1,v+1)`` the triangles are ``(a,c,b)``, ``(b,c,d)`` (diagonal b-c) or
  ``(a,c,d)``, ``(a,d,b)`` (diagonal a-d).
* quad diagonal: the *shorter 3D diagonal* (ties -> b-c). On a plane both
  diagonals give the same surface; across a crease the shorter one follows the
  crease better and never spans the larger depth jump.
* a quad with exactly three usable corners gets the one triangle on them, so
  silhouettes follow the pixel staircase to half a pixel.
* no vertex for invalid depth (NaN, <= 0, inf), for excluded labels (sky by
  default) or beyond ``far_limit``.
* per-vertex ``uv = ((u + 0.5) / W, 1 - (v + 0.5) / H)``, ``pixel = (u, v)``,
  label and light instance id.

:func:`quad_faces` is the shared triangulation used by the post-processing
kernel as well: it only connects corners that carry the same ``group`` id, so
one call triangulates many disjoint sheets at once.
"""

from __future__ import annotations

import time
from collections.abc import Iterable

import numpy as np

from ..camera import Intrinsics, _check_hw, valid_depth_mask
from ..errors import NpsimInputError
from ..labels import cityscapes
from .types import MeshPart, SceneMesh

__all__ = ["grid_mesh", "quad_faces", "grid_axes", "pixel_uv", "check_mesh_inputs"]


def grid_axes(width: int, height: int, stride: int) -> tuple[np.ndarray, np.ndarray]:
    """Sampled columns and rows for a stride: ``0, s, 2s, ...`` plus the last pixel.

    Including the last row/column keeps the mesh covering the whole image at any stride.
    """
    if int(stride) < 1:
        raise NpsimInputError(f"stride must be an integer >= 1, got {stride}")
    s = int(stride)
    cols = np.arange(0, width, s)
    rows = np.arange(0, height, s)
    if cols[-1] != width - 1:
        cols = np.append(cols, width - 1)
    if rows[-1] != height - 1:
        rows = np.append(rows, height - 1)
    return cols, rows


def pixel_uv(u: np.ndarray, v: np.ndarray, width: int, height: int) -> np.ndarray:
    """(N, 2) float32 texture coordinates ``((u + 0.5) / W, 1 - (v + 0.5) / H)`` (docs/method.md §4)."""
    uv = np.empty((len(u), 2), dtype=np.float32)
    uv[:, 0] = (np.asarray(u, dtype=np.float64) + 0.5) / width
    uv[:, 1] = 1.0 - (np.asarray(v, dtype=np.float64) + 0.5) / height
    return uv


def check_mesh_inputs(depth, intrinsics: Intrinsics, labels, light_ids=None):
    """Validate and normalise depth/labels/light ids (raises :class:`NpsimInputError`)."""
    if not isinstance(intrinsics, Intrinsics):
        raise NpsimInputError(f"intrinsics must be an npsim_core.camera.Intrinsics, got {type(intrinsics).__name__}")
    depth = np.asarray(depth)
    if depth.ndim != 2 or not np.issubdtype(depth.dtype, np.floating):
        raise NpsimInputError(f"depth must be an HxW float array (metres, NaN invalid), got {depth.dtype} {depth.shape}")
    _check_hw(depth, intrinsics, "depth")
    labels = np.asarray(labels)
    if labels.shape != depth.shape or not np.issubdtype(labels.dtype, np.integer):
        raise NpsimInputError(f"labels must be an HxW integer labelId map of shape {depth.shape}, "
                              f"got {labels.dtype} {labels.shape}")
    return depth.astype(np.float32, copy=False), labels.astype(np.uint8, copy=False), light_id_map(light_ids,
                                                                                                   depth.shape)


def light_id_map(light_ids, shape: tuple[int, int]) -> np.ndarray:
    """The light instance map ``light_ids`` as (H, W) int32 (None: all 0); raises
    :class:`NpsimInputError` on another shape or a non-integer dtype."""
    if light_ids is None:
        return np.zeros(shape, dtype=np.int32)
    light_ids = np.asarray(light_ids)
    if light_ids.shape != tuple(shape) or not np.issubdtype(light_ids.dtype, np.integer):
        raise NpsimInputError(f"light_ids (light instance map) must be HxW integers of shape {tuple(shape)}, "
                              f"got {light_ids.dtype} {light_ids.shape}")
    return light_ids.astype(np.int32, copy=False)


def usable_mask(depth: np.ndarray, labels: np.ndarray, exclude: Iterable[int] | None,
                far_limit: float | None) -> np.ndarray:
    """Pixels that may carry a vertex: valid depth, label not excluded, not beyond ``far_limit``."""
    ok = valid_depth_mask(depth)
    if exclude is None:
        exclude = (cityscapes().sky_id,)
    ex = list(exclude)
    if ex:
        lut = np.zeros(256, dtype=bool)
        lut[np.asarray(ex, dtype=np.intp)] = True
        ok &= ~lut[labels]
    if far_limit is not None:
        if not far_limit > 0:
            raise NpsimInputError(f"far_limit must be > 0 metres or None, got {far_limit}")
        with np.errstate(invalid="ignore"):
            ok &= depth <= far_limit
    return ok


def quad_faces(index: np.ndarray, points: np.ndarray, group: np.ndarray | None = None,
               cells: np.ndarray | None = None) -> np.ndarray:
    """Triangulate a grid of vertices, two triangles per quad, front face toward the camera.

    Parameters
    ----------
    index : (h, w) int64
        Vertex index of each grid node, -1 where there is no vertex.
    points : (h, w, 3) float
        Camera-frame positions of the grid nodes (used to pick the shorter diagonal;
        values at nodes without a vertex are ignored).
    group : (h, w) int, optional
        Sheet id per node; a triangle is only made from three nodes of the same group.
    cells : (h-1, w-1) bool, optional
        Only these quads are triangulated (the reducer passes the quads no larger cell covers).

    Returns
    -------
    (F, 3) int64 faces. Full quads come first in row-major order, then the
    single triangles of three-corner quads.
    """
    has = index >= 0
    rows = np.flatnonzero(has.any(1))
    cols = np.flatnonzero(has.any(0))
    if len(rows) < 2 or len(cols) < 2:
        return np.zeros((0, 3), dtype=np.int64)
    # Work on the bounding box of the vertices (sparse layers, e.g. foreground objects, are small).
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    index, points, has = index[r0:r1, c0:c1], points[r0:r1, c0:c1], has[r0:r1, c0:c1]
    ha, hb, hc, hd = has[:-1, :-1], has[:-1, 1:], has[1:, :-1], has[1:, 1:]
    if cells is not None:
        cm = cells[r0:r1 - 1, c0:c1 - 1]
        ha, hb, hc, hd = ha & cm, hb & cm, hc & cm, hd & cm
    if group is not None:
        group = group[r0:r1, c0:c1]
        ga, gb, gc, gd = group[:-1, :-1], group[:-1, 1:], group[1:, :-1], group[1:, 1:]
        ab, ac, bc, bd, cd = ga == gb, ga == gc, gb == gc, gb == gd, gc == gd
        t1 = ha & hb & hc & ac & bc          # (a, c, b)
        t2 = hb & hc & hd & bc & cd          # (b, c, d)
        t3 = ha & hc & hd & ac & cd          # (a, c, d)
        t4 = ha & hb & hd & ab & bd          # (a, d, b)
        full = t1 & t2
    else:
        abc = ha & hb & hc
        t1, t2, t3, t4 = abc, hb & hc & hd, ha & hc & hd, ha & hb & hd
        full = abc & hd
    # Shorter 3D diagonal: |P_b - P_c| vs |P_a - P_d|, on the grid (no gathers).
    P = points.astype(np.float32, copy=False)
    e = P[:-1, 1:] - P[1:, :-1]
    dbc = np.einsum("ijk,ijk->ij", e, e)
    e = P[:-1, :-1] - P[1:, 1:]
    dad = np.einsum("ijk,ijk->ij", e, e)
    del e
    use_bc = (dbc <= dad).ravel()
    # Corner indices are gathered from the contiguous flat index by node position:
    # quad q = (i, j) has its top-left node at i*w + j = q + i.
    h, w = index.shape
    # int32 halves the memory traffic of the gathers (indices of images up to 2^31 pixels).
    small = index.size < 2**31 and (len(index) == 0 or int(index.max()) < 2**31)
    flat = np.ascontiguousarray(index, dtype=np.int32 if small else np.int64).ravel()
    out = []
    qf = np.flatnonzero(full.ravel()).astype(flat.dtype)
    if len(qf):
        p = qf + qf // (w - 1)
        A, B, C, D = flat[p], flat[p + 1], flat[p + w], flat[p + w + 1]
        bcq = use_bc[qf]
        q = np.empty((len(qf), 2, 3), dtype=flat.dtype)
        # Diagonal b-c: (a, c, b), (b, c, d); diagonal a-d: (a, c, d), (a, d, b).
        q[:, 0, 0] = A
        q[:, 0, 1] = C
        q[:, 0, 2] = np.where(bcq, B, D)
        q[:, 1, 0] = np.where(bcq, B, A)
        q[:, 1, 1] = np.where(bcq, C, D)
        q[:, 1, 2] = np.where(bcq, D, B)
        out.append(q.reshape(-1, 3))
    part = ~full
    for t, corners in ((t1, (0, 2, 1)), (t2, (1, 2, 3)), (t3, (0, 2, 3)), (t4, (0, 3, 1))):
        qs = np.flatnonzero((part & t).ravel()).astype(flat.dtype)
        if len(qs):
            p = qs + qs // (w - 1)
            off = (0, 1, w, w + 1)
            out.append(np.stack([flat[p + off[k]] for k in corners], 1))
    if not out:
        return np.zeros((0, 3), dtype=np.int64)
    return np.concatenate(out, axis=0).astype(np.int64, copy=False)


def grid_mesh(depth: np.ndarray, intrinsics: Intrinsics, labels: np.ndarray, light_ids: np.ndarray | None = None,
              *, stride: int = 1, exclude: Iterable[int] | None = None, far_limit: float | None = None,
              name: str = "grid") -> SceneMesh:
    """Worldsheet grid mesh of a depth map (docs/method.md §4): one sheet, every usable pixel a vertex.

    Parameters
    ----------
    depth : (H, W) float
        z-depth in metres; NaN/inf/<=0 invalid (no vertex).
    intrinsics : Intrinsics
        Camera of the depth map.
    labels : (H, W) int
        Cityscapes labelIds.
    light_ids : (H, W) int, optional
        Light instance map (classId*1000+index, 0 = none).
    stride : int
        Vertex spacing in pixels (1 = full resolution; larger for previews).
        The last row and column are always sampled.
    exclude : iterable of labelIds, optional
        Labels that get no vertex; default ``(sky,)``. Pass ``()`` to mesh everything valid.
    far_limit : float, optional
        Pixels deeper than this (metres) get no vertex ("model only what a scene needs").
    name : str
        Name of the single part (default ``"grid"``: the raw Worldsheet mixes background and objects).

    Returns
    -------
    SceneMesh with one part; ``info`` holds stride, counts and ``time_s``.
    """
    t0 = time.perf_counter()
    depth, labels, light_ids = check_mesh_inputs(depth, intrinsics, labels, light_ids)
    H, W = depth.shape
    cols, rows = grid_axes(W, H, stride)
    ok_full = usable_mask(depth, labels, exclude, far_limit)
    sub = np.ix_(rows, cols)
    ok = ok_full[sub]
    d = depth[sub]
    rays = intrinsics.pixel_rays(np.float32)[sub]
    pts = rays * np.where(ok, d, 0.0)[..., None]
    index = np.full(ok.shape, -1, dtype=np.int64)
    n = int(ok.sum())
    index[ok] = np.arange(n, dtype=np.int64)
    faces = quad_faces(index, pts)
    vv, uu = np.nonzero(ok)
    pu, pv = cols[uu], rows[vv]
    part = MeshPart(
        name=name,
        vertices=pts[ok].astype(np.float32, copy=False),
        faces=faces,
        uv=pixel_uv(pu, pv, W, H),
        pixel=np.stack([pu, pv], 1).astype(np.float32),
        label=labels[pv, pu].astype(np.uint8),
        light_id=light_ids[pv, pu].astype(np.int32),
        foreground=False,
    )
    info = {"stage": "grid_mesh", "stride": int(stride), "far_limit": far_limit,
            "vertices": part.n_vertices, "faces": part.n_faces, "time_s": time.perf_counter() - t0}
    return SceneMesh(parts=[part], width=W, height=H, info=info)
