"""Worldsheet grid mesh from a depth map (SPEC §3, thesis §3.3).

One vertex per pixel (or per ``stride`` pixels) at ``P(u, v) = d(u, v) K^-1 (u, v, 1)^T``,
two triangles per 2x2 quad of vertices. Conventions (SPEC §0):

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
    """(N, 2) float32 texture coordinates ``((u + 0.5) / W, 1 - (v + 0.5) / H)`` (SPEC §3)."""
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
    if light_ids is None:
        light_ids = np.zeros(depth.shape, dtype=np.int32)
    else:
        light_ids = np.asarray(light_ids)
        if light_ids.shape != depth.shape or not np.issubdtype(light_ids.dtype, np.integer):
            raise NpsimInputError(f"light_ids (light instance map) must be HxW integers of shape {depth.shape}, "
                                  f"got {light_ids.dtype} {light_ids.shape}")
    return depth.astype(np.float32, copy=False), labels.astype(np.uint8, copy=False), light_ids.astype(np.int32,
                                                                                                       copy=False)


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


def quad_faces(index: np.ndarray, points: np.ndarray, group: np.ndarray | None = None) -> np.ndarray:
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

    Returns
    -------
    (F, 3) int64 faces. Full quads come first in row-major order, then the
    single triangles of three-corner quads.
    """
    a, b = index[:-1, :-1].ravel(), index[:-1, 1:].ravel()
    c, d = index[1:, :-1].ravel(), index[1:, 1:].ravel()
    ha, hb, hc, hd = a >= 0, b >= 0, c >= 0, d >= 0
    if group is not None:
        ga, gb = group[:-1, :-1].ravel(), group[:-1, 1:].ravel()
        gc, gd = group[1:, :-1].ravel(), group[1:, 1:].ravel()
        ab, ac, bc, bd, cd = ga == gb, ga == gc, gb == gc, gb == gd, gc == gd
        t1 = ha & hb & hc & ac & bc          # (a, c, b)
        t2 = hb & hc & hd & bc & cd          # (b, c, d)
        t3 = ha & hc & hd & ac & cd          # (a, c, d)
        t4 = ha & hb & hd & ab & bd          # (a, d, b)
        full = t1 & t2
    else:
        t1, t2, t3, t4 = ha & hb & hc, hb & hc & hd, ha & hc & hd, ha & hb & hd
        full = ha & hb & hc & hd
    fq = np.flatnonzero(full)
    # Shorter 3D diagonal: |P_b - P_c| vs |P_a - P_d|.
    P = points.reshape(-1, 3) if points.ndim == 3 else points
    w1 = index.shape[1] - 1
    qi, qj = np.divmod(fq, w1)
    W = index.shape[1]
    ia, ib = qi * W + qj, qi * W + qj + 1
    ic, id_ = ia + W, ib + W
    dbc = np.einsum("ij,ij->i", P[ib] - P[ic], P[ib] - P[ic])
    dad = np.einsum("ij,ij->i", P[ia] - P[id_], P[ia] - P[id_])
    use_bc = dbc <= dad
    fa, fb, fc, fd = a[fq], b[fq], c[fq], d[fq]
    # Two triangles per full quad, chosen per quad.
    tri1 = np.where(use_bc[:, None], np.stack([fa, fc, fb], 1), np.stack([fa, fc, fd], 1))
    tri2 = np.where(use_bc[:, None], np.stack([fb, fc, fd], 1), np.stack([fa, fd, fb], 1))
    full_faces = np.empty((2 * len(fq), 3), dtype=np.int64)
    full_faces[0::2] = tri1
    full_faces[1::2] = tri2
    part = ~full
    s1, s2, s3, s4 = (np.flatnonzero(part & t) for t in (t1, t2, t3, t4))
    singles = [np.stack([a[s1], c[s1], b[s1]], 1), np.stack([b[s2], c[s2], d[s2]], 1),
               np.stack([a[s3], c[s3], d[s3]], 1), np.stack([a[s4], d[s4], b[s4]], 1)]
    return np.concatenate([full_faces] + [s.astype(np.int64) for s in singles], axis=0)


def grid_mesh(depth: np.ndarray, intrinsics: Intrinsics, labels: np.ndarray, light_ids: np.ndarray | None = None,
              *, stride: int = 1, exclude: Iterable[int] | None = None, far_limit: float | None = None,
              name: str = "grid") -> SceneMesh:
    """Worldsheet grid mesh of a depth map (SPEC §3): one sheet, every usable pixel a vertex.

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
