"""Depth steps inside one sheet: cut sides, and walls that keep the sheet closed (docs/method.md §5.5).

The post-processing kernel separates objects from the background, but depth steps
remain *inside* a sheet: a façade in front of another façade, the boxes of one car,
flying pixels at an object's rim. A grid face spanning such a step is a stretched
face; deleting it leaves a hole. This module does neither:

* A pixel **side** (two 4-neighbouring pixels of the same sheet) is **cut** when the
  relative depth step ``|d1 - d2| / min(d1, d2)`` exceeds ``tau`` (raised on surfaces
  seen at a grazing angle, see :func:`slant_at` and :func:`cut_sides`).
* A **mixed quad** (a cut side, an open side -- see ``extend_edges`` -- or a lone
  three-corner triangle whose diagonal is a step) is triangulated per **cluster**
  (corners joined by uncut sides). Each side of a cut continues its surface to the
  side's midpoint (``mid_x`` and ``mid_y`` lie on the same pixel ray, at two depths).
  Straight steps and step corners (two clusters, two cut sides) give each cluster a
  polygon on its corners and the two mids, and one wall quad between the mids: 6 faces.
  Other mixed quads fan each cluster around its own vertex on the quad-centre ray: an
  uncut side ``x-y`` gives ``(centre, x, y)``, a cut side ``(centre_x, x, mid_x)`` and
  ``(centre_y, mid_y, y)``.
* **Walls.** Along each cut the two sides are joined by faces whose vertices lie on two
  camera rays (the side's midpoint and the quad centre), so a wall is seen exactly
  edge-on from the camera: it covers no pixel and no pixel sees it, while the sheet
  stays closed (no boundary loop, so no hole) and light cannot leak through the step.
  Walls are the side faces of the step -- the kerb, the façade's return -- reduced to
  what the camera cannot see. Where three or four clusters meet, their walls share
  the edges between their centres on the quad-centre ray (ties split by 0.2 %).
* A cut that ends inside a sheet (a **slit**: the quad's only cut side, both ends in one
  cluster) is closed by the wall triangle ``(centre, mid_x, mid_y)``; its spokes span at
  most half of the quad's three uncut sides.

Continued surfaces (mids, centres) extrapolate inverse depth linearly from the
cluster's corners with one-sided differences over uncut sides (exact on planes, also on
the grazing road), clamped to stay within ``tau / 2`` (mids) and ``tau`` (centres) of
their corners and at least a third of the step away from the other side, so no visible
edge spans more than 1.5 ``tau`` and no wall is degenerate.

Pixel-centre rays only ever hit faces at their own pixel's depth: the mesh reproduces
the depth map at every pixel it keeps, with no stretched visible face.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["StepFaces", "cut_sides", "step_faces", "relative_step", "slant_at"]


@dataclass
class StepFaces:
    """The mixed quads of one sheet layer, triangulated with their walls.

    Vertex ids in ``faces``: ``< H*W`` is the layer's vertex at that flat pixel index;
    ``H*W + k`` is extra vertex ``k`` (a continued surface at a side midpoint or a quad centre).

    Attributes
    ----------
    mixed : (H-1, W-1) bool
        Quads triangulated here (every other quad: :func:`~.grid.quad_faces`).
    faces : (F, 3) int64
        Front faces toward the camera (walls: consistent with their neighbours).
    wall : (F,) bool
        True for wall faces (edge-on from the camera).
    depth : (E,) float32
        z-depth of the extra vertices, metres.
    position : (E, 2) float32
        Image position (u, v) of the extra vertices (half-integer coordinates).
    source : (E,) int64
        Flat pixel index of the corner whose surface an extra vertex continues
        (its label, light id, object and sheet attributes).
    cut : int
        Cut sides.
    """

    mixed: np.ndarray
    faces: np.ndarray
    wall: np.ndarray
    depth: np.ndarray
    position: np.ndarray
    source: np.ndarray
    cut: int = 0

    @classmethod
    def empty(cls, shape: tuple[int, int]) -> "StepFaces":
        H, W = shape
        return cls(mixed=np.zeros((max(H - 1, 0), max(W - 1, 0)), dtype=bool), faces=np.zeros((0, 3), np.int64),
                   wall=np.zeros(0, bool), depth=np.zeros(0, np.float32), position=np.zeros((0, 2), np.float32),
                   source=np.zeros(0, np.int64))

    @property
    def n_walls(self) -> int:
        return int(self.wall.sum())


def relative_step(d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """``|d1 - d2| / min(d1, d2)``, the relative depth step between two vertices (NaN if either is missing)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.abs(d1 - d2) / np.minimum(d1, d2)


def _sides(depth: np.ndarray, group: np.ndarray | None):
    """Same-sheet sides and their relative steps: (same_h, step_h, same_v, step_v)."""
    present = np.isfinite(depth)
    same_h = present[:, :-1] & present[:, 1:]
    same_v = present[:-1, :] & present[1:, :]
    if group is not None:
        same_h &= group[:, :-1] == group[:, 1:]
        same_v &= group[:-1, :] == group[1:, :]
    step_h = np.where(same_h, relative_step(depth[:, :-1], depth[:, 1:]), -np.inf)
    step_v = np.where(same_v, relative_step(depth[:-1, :], depth[1:, :]), -np.inf)
    return same_h, step_h, same_v, step_v


def slant_at(depth: np.ndarray, intr, r: np.ndarray, c: np.ndarray, normals: np.ndarray | None = None,
             max_slant: float = 50.0, strict: np.ndarray | None = None) -> np.ndarray:
    """``max(|n . r|, 1 / max_slant)`` at pixels (r, c): 1 on a surface seen head-on, small at grazing angles.

    A plane seen at a grazing angle (the far road, a façade along the street) has large
    depth steps between neighbouring pixels that are not discontinuities; the cut
    threshold is divided by this factor, as the stretched-face measure divides the pixel
    footprint (:func:`~.quality.stretched_faces`). The normal comes from the depth map with,
    per axis, the one-sided difference of *smaller* depth change, so a step does not tilt
    the normals of the pixels beside it; with ``normals`` (HxWx3, e.g. the estimated normals
    N) the stricter (less grazing) of the two is used: estimated normals are blurred at box
    edges and call them grazing, the depth alone calls a flying-pixel ramp grazing, a plane
    seen at a grazing angle is grazing in both. Pixels with no normal get 1 (strictest).
    """
    H, W = depth.shape
    r = np.asarray(r, dtype=np.int64)
    c = np.asarray(c, dtype=np.int64)
    uv = np.stack([c, r], 1)
    ray = intr.rays_at(uv, np.float64)
    rhat = ray / np.linalg.norm(ray, axis=1, keepdims=True)

    def point(rr, cc):
        ok = (rr >= 0) & (rr < H) & (cc >= 0) & (cc < W)
        d = np.where(ok, depth[np.clip(rr, 0, H - 1), np.clip(cc, 0, W - 1)], np.nan).astype(np.float64)
        return intr.rays_at(np.stack([cc, rr], 1), np.float64) * d[:, None]

    P = point(r, c)

    def tangent(dr, dc):
        fwd = point(r + dr, c + dc) - P
        bwd = P - point(r - dr, c - dc)
        use_b = ~(np.abs(fwd[:, 2]) <= np.abs(bwd[:, 2]))         # NaN forward -> backward
        return np.where(use_b[:, None], bwd, fwd)

    n = np.cross(tangent(1, 0), tangent(0, 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        n /= np.linalg.norm(n, axis=1, keepdims=True)
    cs = np.abs((n * rhat).sum(1))
    cs = np.where(np.isfinite(cs), np.clip(cs, 1.0 / max_slant, 1.0), 1.0)
    if normals is not None:
        nn = np.asarray(normals)[r, c].astype(np.float64)
        cn = np.abs((nn * rhat).sum(1))
        cn = np.where(np.isfinite(cn), np.clip(cn, 1.0 / max_slant, 1.0), 1.0)
        cn = np.where(np.isfinite(nn).all(1), cn, 0.0)
        cs = np.maximum(cs, cn)           # the stricter of the two: a step needs both to call it grazing
    if strict is not None:
        cs = np.where(strict[r, c], 1.0, cs)
    return cs


def cut_sides(depth: np.ndarray, group: np.ndarray | None, tau: float, slant=None,
              surface: np.ndarray | None = None, uncut: np.ndarray | None = None):
    """Sides of one layer to cut (see module doc).

    Parameters
    ----------
    depth : (H, W) float
        Depth of the layer's vertices, metres; NaN where the layer has none.
    group : (H, W) int or None
        Sheet id per pixel (objects); sides only join pixels of one group.
    tau : float
        Relative step above which a side is cut on a surface seen head-on.
    slant : callable (r, c) -> slant factors, optional
        E.g. :func:`slant_at` bound to the layer; the threshold of a side is
        ``tau / max(slant_p, slant_q)``. Only sides stepping by more than ``tau`` ask.
    surface : (H, W) int, optional
        Semantic label of each vertex. The grazing allowance is for *one* surface: a side
        joining two labels (a façade above a pavement) keeps the head-on threshold.
    uncut : (H, W) bool, optional
        Pixels whose sides between each other are never cut (e.g. hidden background, whose
        row-to-row differences come from the row-wise completion, not from the scene).

    Returns
    -------
    cut_h : (H, W-1) bool
        Side between (v, u) and (v, u+1) is cut.
    cut_v : (H-1, W) bool
        Side between (v, u) and (v+1, u) is cut.
    same_h, same_v : bool arrays of the same shapes
        Sides joining two vertices of one sheet (cut or not).
    """
    H, W = depth.shape
    same_h, step_h, same_v, step_v = _sides(depth, group)
    cut_h, cut_v = step_h > tau, step_v > tau
    if uncut is not None:
        cut_h &= ~(uncut[:, :-1] & uncut[:, 1:])
        cut_v &= ~(uncut[:-1, :] & uncut[1:, :])
    if slant is not None:
        # Slant can only raise the threshold: ask it only where the step exceeds tau.
        for cut, step, (dr, dc) in ((cut_h, step_h, (0, 1)), (cut_v, step_v, (1, 0))):
            r, c = np.nonzero(cut)
            if surface is not None:
                one = surface[r, c] == surface[r + dr, c + dc]
                r, c = r[one], c[one]
            s_ = np.maximum(slant(r, c), slant(r + dr, c + dc))
            cut[r, c] = step[r, c] > tau / s_
    return cut_h, cut_v, same_h, same_v


def _inverse_gradient(iz: np.ndarray, cont_h: np.ndarray, cont_v: np.ndarray, r: np.ndarray, c: np.ndarray):
    """d(1/z)/du and d(1/z)/dv at pixels (r, c) from their uncut neighbours (central, one-sided or 0)."""
    H, W = iz.shape

    def axis(cont, along_u):
        if along_u:
            fwd_ok = (c < W - 1) & cont[r, np.minimum(c, W - 2)]
            bwd_ok = (c > 0) & cont[r, np.maximum(c - 1, 0)]
            fwd = iz[r, np.minimum(c + 1, W - 1)] - iz[r, c]
            bwd = iz[r, c] - iz[r, np.maximum(c - 1, 0)]
        else:
            fwd_ok = (r < H - 1) & cont[np.minimum(r, H - 2), c]
            bwd_ok = (r > 0) & cont[np.maximum(r - 1, 0), c]
            fwd = iz[np.minimum(r + 1, H - 1), c] - iz[r, c]
            bwd = iz[r, c] - iz[np.maximum(r - 1, 0), c]
        n = fwd_ok.astype(np.float64) + bwd_ok
        tot = np.where(fwd_ok, fwd, 0.0) + np.where(bwd_ok, bwd, 0.0)
        return np.where(n > 0, tot / np.maximum(n, 1), 0.0)

    return axis(cont_h, True), axis(cont_v, False)


_PERIM = np.array([0, 2, 3, 1])          # corners a, c, d, b: the front-facing perimeter order


def _two_sheet_quads(faces: list, wall: list, tau: float, HW: int, cpix, cdep, lab, s_cut, s_id, x_end,
                     mid_depth) -> np.ndarray:
    """Cheaper triangulation of the commonest mixed quads; returns the mask of quads it handled.

    A quad with all four corners, two clusters and two cut sides is a straight step (cut
    sides opposite) or a corner of one (cut sides adjacent). Each side is then a polygon
    on its corners and the two mids, the contour between the mids is straight, and the
    wall is one quad: 6 faces instead of the 10 of the centre fans, no centre vertex.
    A quad whose polygons would have an edge spanning more than 1.5 ``tau`` keeps the fans.
    """
    n = len(cpix)
    present = (lab < 4).all(1)
    ncl = (lab[:, :, None] == np.arange(4)[None, None, :]).any(1).sum(1)
    ncut = s_cut.sum(1)
    cand = present & (ncl == 2) & (ncut == 2)
    out = np.zeros(n, dtype=bool)
    if not cand.any():
        return out

    def mid(rows, k, corner_first):
        e = x_end[k] if corner_first else 1 - x_end[k]
        return HW + 2 * s_id[rows, k] + e

    def depth_of(ids):
        return np.where(ids < HW, 0.0, mid_depth[np.clip(ids - HW, 0, len(mid_depth) - 1)])

    groups = []
    # Straight: cut sides k1 and k1 + 2 (perimeter sides: k from P[k] to P[k+1]).
    for k1 in (0, 1):
        k2 = k1 + 2
        rows = np.flatnonzero(cand & s_cut[:, k1] & s_cut[:, k2])
        if len(rows) == 0:
            continue
        P = [_PERIM[(k1 + j) % 4] for j in range(4)]           # P[k1], P[k1+1], P[k1+2], P[k1+3]
        p0, q1, q2, r1 = (cpix[rows, c] for c in P)
        z0, zq1, zq2, zr1 = (cdep[rows, c] for c in P)
        M1, M2 = mid(rows, k1, False), mid(rows, k2, True)        # cluster {P1, P2}
        N1, N2 = mid(rows, k1, True), mid(rows, k2, False)        # cluster {P3, P0}
        f = [np.stack([M1, q1, q2], 1), np.stack([M1, q2, M2], 1),
             np.stack([N2, r1, p0], 1), np.stack([N2, p0, N1], 1)]
        w = [np.stack([M1, M2, N2], 1), np.stack([M1, N2, N1], 1)]
        zm1, zm2, zn1, zn2 = depth_of(M1), depth_of(M2), depth_of(N1), depth_of(N2)
        edges = [(zm1, zq1), (zq1, zq2), (zq2, zm1), (zq2, zm2), (zm2, zm1),
                 (zn2, zr1), (zr1, z0), (z0, zn2), (z0, zn1), (zn1, zn2)]
        groups.append((rows, f, w, edges))
    # Corner: cut sides k-1 and k around corner x = P[k] alone.
    for i in range(4):
        kp, kn = (i - 1) % 4, i
        rows = np.flatnonzero(cand & s_cut[:, kp] & s_cut[:, kn])
        if len(rows) == 0:
            continue
        x, nn, o, pp = (_PERIM[(i + j) % 4] for j in range(4))
        X, Nn, O, Pp = (cpix[rows, c] for c in (x, nn, o, pp))
        zx, zn_, zo, zp = (cdep[rows, c] for c in (x, nn, o, pp))
        mpS, mpO = mid(rows, kp, False), mid(rows, kp, True)
        mnS, mnO = mid(rows, kn, True), mid(rows, kn, False)
        f = [np.stack([mpS, X, mnS], 1), np.stack([O, Pp, mpO], 1), np.stack([O, mpO, mnO], 1),
             np.stack([O, mnO, Nn], 1)]
        w = [np.stack([mpS, mnS, mnO], 1), np.stack([mpS, mnO, mpO], 1)]
        zmpS, zmpO, zmnS, zmnO = depth_of(mpS), depth_of(mpO), depth_of(mnS), depth_of(mnO)
        edges = [(zmpS, zx), (zx, zmnS), (zmnS, zmpS), (zo, zp), (zp, zmpO), (zmpO, zo), (zmpO, zmnO),
                 (zmnO, zo), (zmnO, zn_), (zn_, zo)]
        groups.append((rows, f, w, edges))
    for rows, f, w, edges in groups:
        worst = np.max([relative_step(a, b) for a, b in edges], axis=0)
        ok = worst <= 1.5 * tau
        if not ok.any():
            continue
        out[rows[ok]] = True
        faces += [t[ok] for t in f] + [t[ok] for t in w]
        wall += [np.zeros(int(ok.sum()) * len(f), bool), np.ones(int(ok.sum()) * len(w), bool)]
    return out


def step_faces(depth: np.ndarray, group: np.ndarray | None, tau: float | None, slant=None,
               surface: np.ndarray | None = None, uncut: np.ndarray | None = None,
               extend_edges: bool = False) -> StepFaces:
    """Cut the depth steps of one layer and triangulate its mixed quads with walls (see module doc).

    Parameters
    ----------
    depth : (H, W) float
        Depth of the layer's vertices (metres), NaN where it has none.
    group : (H, W) int or None
        Sheet id per pixel (foreground objects); None = one sheet.
    tau : float or None
        Relative step above which a side is cut (head-on); None = no cuts (empty result).
    slant : callable (r, c) -> slant factors, optional
        :func:`slant_at` bound to the layer (None = every surface head-on): thresholds and
        clamps scale by 1/slant.
    surface : (H, W) int, optional
        Semantic label of each vertex (see :func:`cut_sides`).
    uncut : (H, W) bool, optional
        Pixels whose mutual sides are never cut (see :func:`cut_sides`).
    extend_edges : bool
        A sheet's border (a side to a pixel without a vertex of the same sheet: sky, another
        object, the background) runs through the side's midpoint, half a pixel beyond the
        border pixels' centres, like a cut without a wall: each sheet then covers exactly its
        own pixels' area (two objects meet without a crack, an object's outline matches its
        label mask).

    Returns
    -------
    StepFaces
    """
    H, W = depth.shape
    if tau is None or H < 2 or W < 2:
        return StepFaces.empty((H, W))
    d = np.asarray(depth, dtype=np.float32)      # whole-image work in float32; gathered values in float64
    cut_h, cut_v, same_h, same_v = cut_sides(d, group, tau, slant, surface, uncut)

    def tau_at(r, c):
        """Per-pixel threshold tau / slant."""
        return np.full(np.shape(r), float(tau)) if slant is None else tau / slant(r, c)

    cont_h, cont_v = same_h & ~cut_h, same_v & ~cut_v
    present = np.isfinite(d)
    if extend_edges:          # a side with a vertex of this sheet at one end only (or two sheets)
        open_h = (present[:, :-1] | present[:, 1:]) & ~same_h
        open_v = (present[:-1, :] | present[1:, :]) & ~same_v
    else:
        open_h, open_v = np.zeros_like(cut_h), np.zeros_like(cut_v)
    # Mixed quads: a cut or open side, or a lone triangle whose diagonal is a step.
    mixed = cut_h[:-1, :] | cut_h[1:, :] | cut_v[:, :-1] | cut_v[:, 1:]
    mixed |= open_h[:-1, :] | open_h[1:, :] | open_v[:, :-1] | open_v[:, 1:]
    full = same_h[:-1, :] & same_h[1:, :] & same_v[:, :-1] & same_v[:, 1:]
    # Lone triangles as in quad_faces: (a,c,b)/(b,c,d) use diagonal b-c, (a,c,d)/(a,d,b) use a-d.
    a, b, c_, dd = d[:-1, :-1], d[:-1, 1:], d[1:, :-1], d[1:, 1:]
    if group is None:
        g = np.zeros(d.shape, dtype=np.int8)
    else:
        g = group
    ga, gb, gc, gd = g[:-1, :-1], g[:-1, 1:], g[1:, :-1], g[1:, 1:]
    pa, pb, pc, pd = np.isfinite(a), np.isfinite(b), np.isfinite(c_), np.isfinite(dd)
    t_bc = ~full & ((pa & pb & pc & (ga == gb) & (ga == gc)) | (pb & pc & pd & (gb == gc) & (gb == gd)))
    t_ad = ~full & ((pa & pc & pd & (ga == gc) & (ga == gd)) | (pa & pb & pd & (ga == gb) & (ga == gd)))
    for tri, (r0, c0, r1, c1), (p, q) in ((t_bc, (0, 1, 1, 0), (b, c_)), (t_ad, (0, 0, 1, 1), (a, dd))):
        i, j = np.nonzero(tri & (relative_step(p, q) > tau))
        if len(i):
            big = relative_step(p[i, j], q[i, j]) > np.minimum(tau_at(i + r0, j + c0), tau_at(i + r1, j + c1))
            mixed[i[big], j[big]] = True
    qi, qj = np.nonzero(mixed)
    n = len(qi)
    out = StepFaces.empty((H, W))
    out.mixed = mixed
    out.cut = int(cut_h.sum() + cut_v.sum())
    if n == 0:
        return out
    HW = H * W
    with np.errstate(divide="ignore"):
        iz_img = 1.0 / d                                        # NaN stays NaN

    # --- mid vertices: one per (cut or open side, endpoint), shared by the two quads of the side.
    hr, hc = np.nonzero(cut_h | open_h)
    vr, vc = np.nonzero(cut_v | open_v)
    nh = len(hr)
    side_id_h = np.full(cut_h.shape, -1, dtype=np.int64)
    side_id_h[hr, hc] = np.arange(nh)
    side_id_v = np.full(cut_v.shape, -1, dtype=np.int64)
    side_id_v[vr, vc] = nh + np.arange(len(vr))
    # endpoint 0 = left/top pixel, 1 = right/bottom pixel
    m_r = np.concatenate([hr, hr, vr, vr + 1])
    m_c = np.concatenate([hc, hc + 1, vc, vc])
    o_r = np.concatenate([hr, hr, vr + 1, vr])                  # the other endpoint
    o_c = np.concatenate([hc + 1, hc, vc, vc])
    du = np.concatenate([np.full(nh, 0.5), np.full(nh, -0.5), np.zeros(2 * len(vr))])
    dv = np.concatenate([np.zeros(2 * nh), np.full(len(vr), 0.5), np.full(len(vr), -0.5)])
    # Ids: side s, endpoint e -> 2 s + e; the arrays above are ordered (h e0, h e1, v e0, v e1).
    nv_ = len(vr)
    mid_order = np.concatenate([2 * np.arange(nh), 2 * np.arange(nh) + 1,
                                2 * (nh + np.arange(nv_)), 2 * (nh + np.arange(nv_)) + 1])
    gu, gv = _inverse_gradient(iz_img, cont_h, cont_v, m_r, m_c)
    dx, dy = d[m_r, m_c].astype(np.float64), d[o_r, o_c].astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        ext = 1.0 / (iz_img[m_r, m_c].astype(np.float64) + gu * du + gv * dv)
    ext = np.where(np.isfinite(ext) & (ext > 0), ext, dx)
    tx = tau_at(m_r, m_c)
    lo, hi = dx / (1 + tx / 2), dx * (1 + tx / 2)
    is_cut = np.concatenate([cut_h[hr, hc], cut_h[hr, hc], cut_v[vr, vc], cut_v[vr, vc]])
    near = is_cut & (dx < dy)
    far = is_cut & (dx > dy)
    with np.errstate(invalid="ignore"):
        hi = np.where(near, np.minimum(hi, dx + (dy - dx) / 3), hi)
        lo = np.where(far, np.maximum(lo, dx - (dx - dy) / 3), lo)
    mid_depth = np.empty(2 * (nh + nv_))
    mid_depth[mid_order] = np.clip(ext, lo, hi)
    mid_pos = np.empty((2 * (nh + nv_), 2))
    mid_pos[mid_order, 0] = m_c + np.where(du != 0, np.where(du > 0, 0.5, -0.5), 0.0)
    mid_pos[mid_order, 1] = m_r + np.where(dv != 0, np.where(dv > 0, 0.5, -0.5), 0.0)
    mid_src = np.empty(2 * (nh + nv_), dtype=np.int64)
    mid_src[mid_order] = m_r * W + m_c
    n_mid = len(mid_depth)

    # --- per mixed quad: corners a (0,0), b (1,0), c (0,1), d (1,1) as (du, dv).
    cr = np.stack([qi, qi, qi + 1, qi + 1], 1)
    cc = np.stack([qj, qj + 1, qj, qj + 1], 1)
    cpix = cr * W + cc
    cdep = d[cr, cc].astype(np.float64)
    # Sides: index into the 4 corners and whether each is joined / cut.
    # Perimeter order a -> c -> d -> b -> a keeps the fans front-facing (see grid.py winding).
    per = [(0, 2), (2, 3), (3, 1), (1, 0)]
    s_cont = np.stack([cont_v[qi, qj], cont_h[qi + 1, qj], cont_v[qi, qj + 1], cont_h[qi, qj]], 1)
    s_cut = np.stack([cut_v[qi, qj], cut_h[qi + 1, qj], cut_v[qi, qj + 1], cut_h[qi, qj]], 1)
    s_open = np.stack([open_v[qi, qj], open_h[qi + 1, qj], open_v[qi, qj + 1], open_h[qi, qj]], 1)
    s_id = np.stack([side_id_v[qi, qj], side_id_h[qi + 1, qj], side_id_v[qi, qj + 1], side_id_h[qi, qj]], 1)
    # endpoint of the first corner x of each perimeter side (a of (a,c) is v-side's top = 0; ...)
    x_end = np.array([0, 0, 1, 1])
    # Clusters: union over joined sides (labels = smallest corner index of the cluster).
    lab = np.where(np.isfinite(cdep), np.arange(4)[None, :], 99)
    for _ in range(3):
        for k, (x, y) in enumerate(per):
            m = s_cont[:, k]
            lo_ = np.minimum(lab[:, x], lab[:, y])
            lab[m, x] = lo_[m]
            lab[m, y] = lo_[m]
    # Centre of each cluster: mean of the corners' surfaces continued to the quad centre.
    off_u = np.array([0.5, -0.5, 0.5, -0.5])
    off_v = np.array([0.5, 0.5, -0.5, -0.5])
    gu4, gv4 = _inverse_gradient(iz_img, cont_h, cont_v, cr.ravel(), cc.ravel())
    with np.errstate(invalid="ignore"):
        ext4 = iz_img[cr, cc].astype(np.float64) + gu4.reshape(n, 4) * off_u + gv4.reshape(n, 4) * off_v
    onehot = (lab[:, :, None] == np.arange(4)[None, None, :])                # (n, corner, cluster)
    okc = np.isfinite(cdep)[:, :, None] & onehot
    cnt = okc.sum(1)
    with np.errstate(invalid="ignore", divide="ignore"):
        ciz = np.where(okc, ext4[:, :, None], 0.0).sum(1) / cnt
        cz = 1.0 / ciz
    plain_mean = np.where(okc, cdep[:, :, None], 0.0).sum(1) / np.maximum(cnt, 1)
    cz = np.where(np.isfinite(cz) & (cz > 0), cz, plain_mean)
    tc = tau_at(cr.ravel(), cc.ravel()).reshape(n, 4)[:, :, None]
    with np.errstate(invalid="ignore"):
        clo = np.where(okc, cdep[:, :, None] / (1 + tc), -np.inf).max(1)
        chi = np.where(okc, cdep[:, :, None] * (1 + tc), np.inf).min(1)
    # Keep each side of a cut at least a third of the step away from the other side.
    for k, (x, y) in enumerate(per):
        m = s_cut[:, k] & (lab[:, x] != lab[:, y])       # a slit's end joins both sides: no separation
        if not m.any():
            continue
        rows = np.flatnonzero(m)
        dx_, dy_ = cdep[rows, x], cdep[rows, y]
        lx, ly = lab[rows, x], lab[rows, y]
        nx = dx_ < dy_
        # near side: centre <= d_near + gap/3 ; far side: centre >= d_far - gap/3
        gap = np.abs(dy_ - dx_) / 3
        lnear = np.where(nx, lx, ly)
        lfar = np.where(nx, ly, lx)
        dnear = np.minimum(dx_, dy_)
        dfar = np.maximum(dx_, dy_)
        np.minimum.at(chi, (rows, lnear), dnear + gap)
        np.maximum.at(clo, (rows, lfar), dfar - gap)
    feasible = clo <= chi
    with np.errstate(invalid="ignore"):
        cz = np.where(feasible, np.clip(cz, clo, chi), 0.5 * (clo + chi))
    # Centres of different clusters on one ray must differ, or the walls meeting there could not
    # share their edges (a 4-way saddle gives two pairs of equal centres): split ties by 0.1 %.
    has = cnt > 0
    for l_ in range(1, 4):
        for m_ in range(l_):
            tie = has[:, l_] & has[:, m_] & (np.abs(cz[:, l_] - cz[:, m_]) < 1e-3 * cz[:, m_])
            cz[tie, l_] *= 1.0 + 2e-3
    centre_base = n_mid
    centre_id = HW + centre_base + 4 * np.arange(n)[:, None] + np.where(lab < 4, lab, 0)   # (n, 4) per corner

    faces, wall = [], []
    simple = _two_sheet_quads(faces, wall, tau, HW, cpix, cdep, lab, s_cut, s_id, x_end, mid_depth)
    for k, (x, y) in enumerate(per):
        P, Q = cpix[:, x], cpix[:, y]
        Cx, Cy = centre_id[:, x], centre_id[:, y]
        m = s_cont[:, k] & ~simple
        if m.any():
            faces.append(np.stack([Cx[m], P[m], Q[m]], 1))
            wall.append(np.zeros(int(m.sum()), bool))
        m = s_open[:, k] & ~simple
        if m.any():
            # A sheet's border: each present end continues to the midpoint, no wall.
            sid = s_id[:, k]
            px_ = m & (lab[:, x] < 4)
            if px_.any():
                faces.append(np.stack([Cx[px_], P[px_], HW + 2 * sid[px_] + x_end[k]], 1))
                wall.append(np.zeros(int(px_.sum()), bool))
            py_ = m & (lab[:, y] < 4)
            if py_.any():
                faces.append(np.stack([Cy[py_], HW + 2 * sid[py_] + (1 - x_end[k]), Q[py_]], 1))
                wall.append(np.zeros(int(py_.sum()), bool))
        m = s_cut[:, k] & ~simple
        if m.any():
            rows = np.flatnonzero(m)
            sid = s_id[rows, k]
            Mx = HW + 2 * sid + x_end[k]
            My = HW + 2 * sid + (1 - x_end[k])
            cx_, cy_, p_, q_ = Cx[rows], Cy[rows], P[rows], Q[rows]
            faces += [np.stack([cx_, p_, Mx], 1), np.stack([cy_, My, q_], 1), np.stack([cx_, Mx, My], 1)]
            wall += [np.zeros(2 * len(rows), bool), np.ones(len(rows), bool)]
            # The wall's edge on the quad's centre ray runs from centre_y to centre_x through every
            # other cluster centre in between, so the walls of three or four clusters meeting at
            # the centre share their edges exactly (no boundary, no degenerate cap).
            X, Y = lab[rows, x], lab[rows, y]
            zq = cz[rows]                                          # (r, 4) centre depth per cluster label
            zX, zY = zq[np.arange(len(rows)), X], zq[np.arange(len(rows)), Y]
            pres = (lab[rows][:, :, None] == np.arange(4)[None, None, :]).any(1)
            lbl = np.arange(4)[None, :]
            with np.errstate(invalid="ignore"):
                betw = pres & (lbl != X[:, None]) & (lbl != Y[:, None]) & ((zq - zX[:, None]) * (zq - zY[:, None]) < 0)
            key = np.where(betw, np.abs(zq - zY[:, None]), np.inf)
            order = np.argsort(key, axis=1)
            nb = betw.sum(1)
            chain = np.full((len(rows), 6), -1, dtype=np.int64)
            chain[:, 0] = cy_
            base_q = HW + centre_base + 4 * np.flatnonzero(m)
            for j in range(4):
                has = nb > j
                chain[has, 1 + j] = base_q[has] + order[has, j]
            chain[np.arange(len(rows)), 1 + nb] = cx_
            for j in range(5):
                ok = (chain[:, j] >= 0) & (chain[:, j + 1] >= 0) & (chain[:, j] != chain[:, j + 1])
                if ok.any():
                    faces.append(np.stack([My[ok], chain[ok, j], chain[ok, j + 1]], 1))
                    wall.append(np.ones(int(ok.sum()), bool))
    if not faces:
        return out
    F = np.concatenate(faces, 0).astype(np.int64)
    Wl = np.concatenate(wall)
    # Extra vertices: mids then centres; keep only the referenced ones, renumbered.
    ext_ids = F[F >= HW] - HW
    used = np.unique(ext_ids)
    remap = np.full(n_mid + 4 * n, -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    F = np.where(F >= HW, HW + remap[np.maximum(F - HW, 0)], F)
    is_mid = used < n_mid
    q_of = np.where(is_mid, 0, (used - n_mid) // 4)
    l_of = np.where(is_mid, 0, (used - n_mid) % 4)
    mi = np.minimum(used, n_mid - 1) if n_mid else np.zeros_like(used)
    # A centre takes the attributes of its cluster's first corner (label index = corner index).
    cen_src = cpix[q_of, l_of]
    cen_dep = cz[q_of, l_of]
    cen_pos = np.stack([qj[q_of] + 0.5, qi[q_of] + 0.5], 1)
    if n_mid:
        depth_e = np.where(is_mid, mid_depth[mi], cen_dep)
        src_e = np.where(is_mid, mid_src[mi], cen_src)
        pos_e = np.where(is_mid[:, None], mid_pos[mi], cen_pos)
    else:
        depth_e, src_e, pos_e = cen_dep, cen_src, cen_pos
    out.faces, out.wall = F, Wl
    out.depth = depth_e.astype(np.float32)
    out.position = pos_e.astype(np.float32)
    out.source = src_e.astype(np.int64)
    return out
