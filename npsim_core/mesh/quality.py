"""Mesh quality measures (docs/method.md §9.3): stretched faces, holes, reprojection error, normal error.

Ray casting is done by an exact z-buffer rasteriser in numpy (:func:`rasterize`):
for every triangle the pixel centres inside its projected bounding box are
tested with edge functions, depth is interpolated as ``1/z`` affinely in screen
space (exact for a planar triangle under perspective), and the nearest hit per
pixel wins. For pixel-centre rays this gives the same answer as a ray caster
(up to float rounding on shared edges, which are tested inclusively), needs no
global Mitsuba variant, and runs a 4 M-face grid at 2048x1024 in a few seconds
in bounded memory (triangles are processed in chunks).

Definitions used by the benchmark:

* **stretched face** -- a *visible* face (not hidden behind another part at
  its centroid pixel) whose longest 3D edge is ``> k * z_min / f`` where ``z_min`` is
  the face's nearest vertex depth and ``f = min(fx, fy)``: a face spanning
  neighbouring pixels on a surface seen head-on has edges of about one pixel
  footprint ``z/f``. Surfaces seen at a grazing angle (far road) legitimately
  have longer edges, so when reference normals are given the footprint is
  divided by ``max(|n_ref . r|, 1/max_slant)`` (r the unit view ray at the
  face's pixel). Default ``k = 0.05 f`` (``max_slant = 50``): an edge longer
  than 5 % of its depth on a head-on surface, i.e. a depth jump of more than
  ~5 % between neighbouring pixels. Tying k to f makes the test independent of
  the image size; a fixed k (say 4) would count ordinary per-pixel depth noise
  of a network prediction (0.5 % relative noise is already ~16 footprints at
  f = 2262) as spurious faces, while object/background jumps are tens of %.
* **edge-on face** -- projected area below ``EDGE_ON_AREA`` (1e-3 px²): no camera
  ray hits it, so it is neither visible nor stretched in the sense above. The walls
  that close depth steps inside a sheet (:mod:`.steps`) are such faces; they are
  counted separately (``MeshQuality.edge_on``).
* **hole** -- a boundary loop (connected set of boundary edges) of a part
  that runs somewhere away from the image border and from "open" pixels (sky,
  excluded labels, beyond the far limit, and foreground pixels whose row run
  is bounded by open pixels or the border on both sides, i.e. where the hidden
  background is sky). A foreground part may have one such loop per connected
  component (its silhouette).
* **reprojection error** -- ``|z_mesh - d| / d`` at each pixel centre where the
  source depth is valid and not excluded; reported as the fraction of those
  pixels within 1 % and the mean.
* **normal error** -- angle between the geometric normal of the face seen at a
  pixel and the reference normal there, over pixels with both.
* **error bound** -- :func:`depth_error_bound`: the relative depth error a mesh built
  from an input with a per-pixel confidence ``c`` (the pop-up prior's) may have against
  the scene, ``tol + CONFIDENCE_SPREAD (1 - c) / c``: the reprojection tolerance where
  the input is sure (c = 1), widening where it guessed. ``reprojection_error`` takes it
  as a per-pixel ``tol``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..camera import Intrinsics, valid_depth_mask
from ..labels import cityscapes
from .types import MeshPart, SceneMesh

#: Projected area (pixels²) below which a face is seen edge-on from the camera. Every face
#: of a grid or post-processed mesh spans at least 1/8 px²; walls (:mod:`.steps`) ~1e-5.
EDGE_ON_AREA = 1e-3

#: Relative depth error per unit of ``(1 - c) / c`` of the input's confidence ``c`` in
#: :func:`depth_error_bound`. Calibrated on the pop-up prior against the exact depth of the 33
#: street-variant frames (11 variants x seeds 0-2, 512x256): 93 % of its pixels are within
#: ``0.01 + 0.2 (1 - c) / c`` (94 % of those below confidence 0.5, 93 % of the rest; with 0.1:
#: 87 %, with 0.5: 98 %). Per confidence bin its AbsRel is 0.00 at c >= 0.9, 0.02-0.05 at
#: 0.6-0.9, 0.09-0.22 at 0.2-0.5 (docs/geometry.md, "Confidence in the chain").
CONFIDENCE_SPREAD = 0.2

__all__ = ["depth_error_bound", "CONFIDENCE_SPREAD",
           "edge_on_faces", "Raster", "rasterize", "project", "stretched_faces", "count_holes", "open_mask",
           "reprojection_error", "normal_error", "MeshQuality", "mesh_quality"]


@dataclass
class Raster:
    """Per-pixel result of :func:`rasterize`: depth (NaN = miss), part index and face index (-1 = miss)."""

    depth: np.ndarray
    part: np.ndarray
    face: np.ndarray


def project(vertices: np.ndarray, intr: Intrinsics) -> np.ndarray:
    """(V, 3) camera-frame points -> (V, 2) pixel coordinates (u, v)."""
    v = vertices.astype(np.float64)
    z = v[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.stack([intr.fx * v[:, 0] / z + intr.cx, intr.fy * v[:, 1] / z + intr.cy], 1)


def _raster_part(verts, faces, intr, zbuf, fbuf, pbuf, part_idx, chunk=1 << 20):
    W, H = intr.width, intr.height
    uv = project(verts, intr)
    iz = 1.0 / verts[:, 2].astype(np.float64)
    for s in range(0, len(faces), chunk):
        f = faces[s:s + chunk]
        p0, p1, p2 = uv[f[:, 0]], uv[f[:, 1]], uv[f[:, 2]]
        umin = np.ceil(np.minimum(np.minimum(p0[:, 0], p1[:, 0]), p2[:, 0]) - 1e-3)
        umax = np.floor(np.maximum(np.maximum(p0[:, 0], p1[:, 0]), p2[:, 0]) + 1e-3)
        vmin = np.ceil(np.minimum(np.minimum(p0[:, 1], p1[:, 1]), p2[:, 1]) - 1e-3)
        vmax = np.floor(np.maximum(np.maximum(p0[:, 1], p1[:, 1]), p2[:, 1]) + 1e-3)
        umin, vmin = np.maximum(umin, 0), np.maximum(vmin, 0)
        umax, vmax = np.minimum(umax, W - 1), np.minimum(vmax, H - 1)
        nu = (umax - umin + 1).clip(0).astype(np.int64)
        nv = (vmax - vmin + 1).clip(0).astype(np.int64)
        cnt = nu * nv
        ok = np.isfinite(cnt.astype(np.float64)) & (cnt > 0)
        tri = np.flatnonzero(ok)
        if len(tri) == 0:
            continue
        c = cnt[tri]
        rep = np.repeat(tri, c)
        start = np.cumsum(c) - c
        k = np.arange(len(rep)) - np.repeat(start, c)
        pu = umin[rep] + k % nu[rep]
        pv = vmin[rep] + k // nu[rep]
        a, b, cc = p0[rep], p1[rep], p2[rep]
        # Edge functions -> barycentrics (sign-independent via area normalisation).
        area = (b[:, 0] - a[:, 0]) * (cc[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (cc[:, 0] - a[:, 0])
        w0 = (b[:, 0] - pu) * (cc[:, 1] - pv) - (b[:, 1] - pv) * (cc[:, 0] - pu)
        w1 = (cc[:, 0] - pu) * (a[:, 1] - pv) - (cc[:, 1] - pv) * (a[:, 0] - pu)
        with np.errstate(divide="ignore", invalid="ignore"):
            w0, w1 = w0 / area, w1 / area
        w2 = 1.0 - w0 - w1
        eps = -1e-4  # a hair of slack so pixel centres on shared edges/sheet borders are not lost to rounding
        # Edge-on faces (walls, projected area ~0) cover no pixel: skipped, not divided by ~0.
        inside = (np.abs(area) > EDGE_ON_AREA) & (w0 >= eps) & (w1 >= eps) & (w2 >= eps)
        if not inside.any():
            continue
        fi = rep[inside] + s
        ff = faces[fi]
        izp = w0[inside] * iz[ff[:, 0]] + w1[inside] * iz[ff[:, 1]] + w2[inside] * iz[ff[:, 2]]
        z = 1.0 / izp
        pix = pv[inside].astype(np.int64) * W + pu[inside].astype(np.int64)
        # Nearest hit per pixel within the chunk, then merge with the buffer.
        order = np.lexsort((z, pix))
        pix, z, fi = pix[order], z[order], fi[order]
        first = np.ones(len(pix), dtype=bool)
        first[1:] = pix[1:] != pix[:-1]
        pix, z, fi = pix[first], z[first], fi[first]
        better = z < zbuf[pix]
        pix, z, fi = pix[better], z[better], fi[better]
        zbuf[pix] = z
        fbuf[pix] = fi
        pbuf[pix] = part_idx


def rasterize(mesh: SceneMesh | MeshPart, intr: Intrinsics) -> Raster:
    """Cast one ray through every pixel centre; return nearest depth, part and face per pixel."""
    parts = mesh.parts if isinstance(mesh, SceneMesh) else [mesh]
    H, W = intr.height, intr.width
    zbuf = np.full(H * W, np.inf)
    fbuf = np.full(H * W, -1, dtype=np.int64)
    pbuf = np.full(H * W, -1, dtype=np.int32)
    for i, p in enumerate(parts):
        if p.n_faces:
            _raster_part(p.vertices, p.faces, intr, zbuf, fbuf, pbuf, i)
    zbuf[~np.isfinite(zbuf)] = np.nan
    return Raster(zbuf.reshape(H, W).astype(np.float32), pbuf.reshape(H, W), fbuf.reshape(H, W))


def _exclude_lut(exclude) -> np.ndarray:
    lut = np.zeros(256, dtype=bool)
    lut[list(exclude if exclude is not None else (cityscapes().sky_id,))] = True
    return lut


def depth_error_bound(confidence: np.ndarray | None, tol: float = 0.01,
                      spread: float = CONFIDENCE_SPREAD) -> np.ndarray | float:
    """Per-pixel relative depth error bound of a mesh whose input depth has ``confidence``.

    Parameters
    ----------
    confidence : (H, W) real in [0, 1] or None
        The input depth's confidence (:attr:`npsim_core.geometry.GeometryEstimate.confidence`);
        NaN (no depth there) and None (a source without one: files, stereo) give ``tol``.
    tol : float
        The bound where the input is sure: the mesh's reprojection tolerance (relative).
    spread : float
        Relative error per unit of ``(1 - c) / c`` (:data:`CONFIDENCE_SPREAD`).

    Returns
    -------
    (H, W) float32 ``tol + spread (1 - c) / c`` (``c`` clipped to [0.01, 1]: at most ~20), or the
    float ``tol`` when ``confidence`` is None.
    """
    if confidence is None:
        return float(tol)
    c = np.asarray(confidence, np.float32)
    c = np.where(np.isfinite(c), np.clip(c, 0.01, 1.0), np.float32(1.0))
    return (np.float32(tol) + np.float32(spread) * (1.0 - c) / c).astype(np.float32)


def reprojection_error(raster: Raster, depth: np.ndarray, labels: np.ndarray, exclude=None,
                       far_limit: float | None = None, tol: float | np.ndarray = 0.01) -> dict:
    """Relative depth error of the ray-cast mesh against the source depth on valid, non-excluded pixels.

    A pixel whose ray misses the mesh counts as an error of 1 (100 %). ``tol`` is a relative
    tolerance, or an (H, W) map of them (:func:`depth_error_bound`: against the scene's true depth,
    the mesh of a guessed input is allowed the input's error).
    Returns ``{"within_tol": fraction with error <= tol, "mean": mean error, "p99": 99th percentile, "pixels": n}``.
    """
    m = valid_depth_mask(depth) & ~_exclude_lut(exclude)[labels]
    if far_limit is not None:
        m &= np.nan_to_num(depth, nan=np.inf) <= far_limit
    d = depth[m].astype(np.float64)
    z = raster.depth[m].astype(np.float64)
    err = np.where(np.isfinite(z), np.abs(z - d) / d, 1.0)
    if len(err) == 0:
        return {"within_tol": 1.0, "mean": 0.0, "p99": 0.0, "pixels": 0}
    if np.ndim(tol):
        t = np.asarray(tol)
        if t.shape != depth.shape:
            raise ValueError(f"tol map has shape {t.shape}, depth {depth.shape}")
        tol = t[m]
    return {"within_tol": float((err <= tol).mean()), "mean": float(err.mean()),
            "p99": float(np.percentile(err, 99)), "pixels": int(len(err))}


def normal_error(mesh: SceneMesh | MeshPart, raster: Raster, ref_normals: np.ndarray) -> dict:
    """Angle (deg) between the seen face's geometric normal and the reference normal per pixel.

    Returns mean, RMSE, median and the fraction within 11.25 deg over pixels with both.
    """
    parts = mesh.parts if isinstance(mesh, SceneMesh) else [mesh]
    H, W = raster.depth.shape
    n_img = np.full((H * W, 3), np.nan, dtype=np.float32)
    pf, ff = raster.part.ravel(), raster.face.ravel()
    for i, p in enumerate(parts):
        sel = np.flatnonzero(pf == i)
        if len(sel):
            n_img[sel] = p.face_normals()[ff[sel]]
    ref = ref_normals.reshape(-1, 3).astype(np.float64)
    ok = np.isfinite(n_img).all(1) & np.isfinite(ref).all(1)
    if not ok.any():
        return {"mean_deg": float("nan"), "rmse_deg": float("nan"), "median_deg": float("nan"),
                "within_11_25": float("nan"), "pixels": 0}
    cos = np.clip(np.einsum("ij,ij->i", n_img[ok].astype(np.float64), ref[ok]), -1, 1)
    ang = np.degrees(np.arccos(cos))
    return {"mean_deg": float(ang.mean()), "rmse_deg": float(np.sqrt((ang ** 2).mean())),
            "median_deg": float(np.median(ang)), "within_11_25": float((ang <= 11.25).mean()),
            "pixels": int(ok.sum())}


def edge_on_faces(part: MeshPart, intr: Intrinsics) -> np.ndarray:
    """Boolean (F,) mask of faces seen edge-on from the camera (projected area < ``EDGE_ON_AREA`` px²).

    Such a face -- its vertices on at most two camera rays, like the walls that close
    depth steps (:mod:`.steps`) -- covers no pixel: no camera ray hits it.
    """
    if part.n_faces == 0:
        return np.zeros(0, dtype=bool)
    uv = project(part.vertices, intr)
    f = part.faces
    a, b, c = uv[f[:, 0]], uv[f[:, 1]], uv[f[:, 2]]
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    return ~(area > EDGE_ON_AREA)


def stretched_faces(part: MeshPart, intr: Intrinsics, k: float | None = None, ref_normals: np.ndarray | None = None,
                    max_slant: float = 50.0, seen_depth: np.ndarray | None = None) -> np.ndarray:
    """Boolean (F,) mask of stretched faces (see module doc for the definition).

    With ``seen_depth`` (the ray-cast depth of the whole scene mesh), faces hidden
    behind another surface at their centroid pixel (deeper by > 1 %) are not
    counted: the reference normal there belongs to the occluder, not to them.
    Faces seen edge-on (:func:`edge_on_faces`, e.g. walls) are never visible and
    never counted; :class:`MeshQuality` reports them separately.
    """
    if part.n_faces == 0:
        return np.zeros(0, dtype=bool)
    v = part.vertices.astype(np.float64)
    f = part.faces
    e = np.stack([np.linalg.norm(v[f[:, 1]] - v[f[:, 0]], axis=1), np.linalg.norm(v[f[:, 2]] - v[f[:, 1]], axis=1),
                  np.linalg.norm(v[f[:, 0]] - v[f[:, 2]], axis=1)], 1).max(1)
    zmin = v[f, 2].min(1)
    foot = zmin / min(intr.fx, intr.fy)
    if ref_normals is not None:
        c = v[f].mean(1)
        uv = project(c, intr)
        ui = np.clip(np.rint(uv[:, 0]), 0, intr.width - 1).astype(np.int64)
        vi = np.clip(np.rint(uv[:, 1]), 0, intr.height - 1).astype(np.int64)
        n = ref_normals[vi, ui].astype(np.float64)
        r = c / np.linalg.norm(c, axis=1, keepdims=True)
        cosang = np.abs(np.einsum("ij,ij->i", n, r))
        cosang = np.where(np.isfinite(cosang), cosang, 1.0)
        foot = foot / np.maximum(cosang, 1.0 / max_slant)
    k = 0.05 * min(intr.fx, intr.fy) if k is None else k
    out = (e > k * foot) & ~edge_on_faces(part, intr)
    if seen_depth is not None:
        c = v[f].mean(1)
        uv = project(c, intr)
        ui = np.clip(np.rint(uv[:, 0]), 0, intr.width - 1).astype(np.int64)
        vi = np.clip(np.rint(uv[:, 1]), 0, intr.height - 1).astype(np.int64)
        seen = seen_depth[vi, ui]
        out &= ~(np.isfinite(seen) & (c[:, 2] > seen * 1.01))
    return out


def open_mask(labels: np.ndarray, depth: np.ndarray | None = None, exclude=None,
              far_limit: float | None = None, occluders: tuple[int, ...] | None = None) -> np.ndarray:
    """Pixels where a mesh boundary is legitimate (besides the image border).

    Excluded labels (sky), pixels beyond ``far_limit``, and object pixels
    (foreground classes and ``occluders``, default as the post-processing kernel)
    whose row run of such pixels is bounded by open pixels or the border on both
    sides (the background hidden there is sky).
    """
    H, W = labels.shape
    op = _exclude_lut(exclude)[labels]
    if far_limit is not None and depth is not None:
        op |= np.nan_to_num(depth, nan=-1.0) > far_limit
    fg_lut = np.zeros(256, dtype=bool)
    fg_lut[list(cityscapes().foreground_ids)] = True
    if occluders is None:
        from .postprocess import default_occluders
        occluders = default_occluders()
    fg_lut[list(occluders)] = True
    fg = fg_lut[labels] & ~op
    idx = np.broadcast_to(np.arange(W), (H, W))
    left = np.maximum.accumulate(np.where(~fg, idx, -1), axis=1)
    right = np.minimum.accumulate(np.where(~fg, idx, W)[:, ::-1], axis=1)[:, ::-1]
    rows = np.broadcast_to(np.arange(H)[:, None], (H, W))
    lo = (left < 0) | op[rows, np.clip(left, 0, W - 1)]
    ro = (right >= W) | op[rows, np.clip(right, 0, W - 1)]
    return op | (fg & lo & ro)


def count_holes(part: MeshPart, intr: Intrinsics, open_px: np.ndarray, radius: int = 1) -> int:
    """Number of boundary loops of ``part`` that are holes (see module doc)."""
    if part.n_faces == 0:
        return 0
    f = part.faces
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], 0)
    e.sort(1)
    V = part.n_vertices
    key = e[:, 0] * V + e[:, 1]
    uk, cnt = np.unique(key, return_counts=True)
    bk = uk[cnt == 1]
    if len(bk) == 0:
        return 0
    b0, b1 = bk // V, bk % V
    H, W = intr.height, intr.width
    pix = project(part.vertices, intr)
    ui = np.clip(np.rint(pix[:, 0]), 0, W - 1).astype(np.int64)
    vi = np.clip(np.rint(pix[:, 1]), 0, H - 1).astype(np.int64)
    near_open = cv2.dilate(open_px.astype(np.uint8), np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)) > 0
    on_border = (ui <= 0) | (ui >= W - 1) | (vi <= 0) | (vi >= H - 1)
    vok = near_open[vi, ui] | on_border
    # An edge is legitimate when one of its ends is on the border or next to an open pixel.
    edge_ok = vok[b0] | vok[b1]
    # Loops = connected components of the boundary-edge graph.
    used = np.unique(np.concatenate([b0, b1]))
    remap = np.full(V, -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    g = coo_matrix((np.ones(len(b0)), (remap[b0], remap[b1])), shape=(len(used), len(used)))
    _, comp = connected_components(g, directed=False)
    ecomp = comp[remap[b0]]
    bad_loops = np.unique(ecomp[~edge_ok])
    if not part.foreground:
        return int(len(bad_loops))
    # Foreground: allow one non-legit loop (the silhouette) per connected mesh component.
    fv = coo_matrix((np.ones(len(f) * 2), (np.concatenate([f[:, 0], f[:, 1]]), np.concatenate([f[:, 1], f[:, 2]]))),
                    shape=(V, V))
    _, mcomp = connected_components(fv, directed=False)
    loop_mesh = {}
    for lp in bad_loops:
        vtx = b0[np.flatnonzero(ecomp == lp)[0]]
        loop_mesh.setdefault(int(mcomp[vtx]), 0)
        loop_mesh[int(mcomp[vtx])] += 1
    return int(sum(max(0, n - 1) for n in loop_mesh.values()))


@dataclass
class MeshQuality:
    """Summary measures of one scene mesh."""

    faces: int
    vertices: int
    stretched: int
    edge_on: int
    holes: int
    reproj_within_1pct: float
    reproj_mean: float
    normal_mean_deg: float | None
    normal_within_11_25: float | None

    def as_row(self) -> dict:
        return dict(self.__dict__)


def mesh_quality(mesh: SceneMesh, intr: Intrinsics, depth: np.ndarray, labels: np.ndarray,
                 ref_normals: np.ndarray | None = None, *, k: float | None = None, exclude=None,
                 far_limit: float | None = None, raster: Raster | None = None,
                 occluders: tuple[int, ...] | None = None) -> MeshQuality:
    """All measures at once. ``depth`` is the depth the mesh came from (reprojection reference);
    ``ref_normals`` (e.g. ground truth) are used for the normal error and the slant-aware stretch test."""
    raster = raster if raster is not None else rasterize(mesh, intr)
    rep = reprojection_error(raster, depth, labels, exclude, far_limit)
    op = open_mask(labels, depth, exclude, far_limit, occluders)
    stretched = sum(int(stretched_faces(p, intr, k, ref_normals, seen_depth=raster.depth).sum()) for p in mesh.parts)
    holes = sum(count_holes(p, intr, op) for p in mesh.parts)
    edge_on = sum(int(edge_on_faces(p, intr).sum()) for p in mesh.parts)
    ne = normal_error(mesh, raster, ref_normals) if ref_normals is not None else None
    return MeshQuality(faces=mesh.n_faces, vertices=mesh.n_vertices, stretched=stretched, edge_on=edge_on, holes=holes,
                       reproj_within_1pct=rep["within_tol"], reproj_mean=rep["mean"],
                       normal_mean_deg=None if ne is None else ne["mean_deg"],
                       normal_within_11_25=None if ne is None else ne["within_11_25"])
