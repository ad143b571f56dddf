"""Reduced scene mesh for a face budget, built directly on the depth map (quadtree of flat cells).

"Model only what a scene needs" (docs/method.md §5.7). Instead of decimating the full
grid (pymeshlab's quadric edge collapse, kept as the comparison in
:func:`decimate_pymeshlab`), the post-processed sheets are re-triangulated
from a quadtree of square cells on the pixel grid:

* A cell of size ``s = 2^k`` (k = 1..``max_level``) covers the ``(s+1)^2``
  pixel nodes ``[i s, i s + s] x [j s, j s + s]``. It may become one flat leaf
  when all its nodes carry a vertex of the same sheet with the same merge key
  (label and light id for the background; object, label and light id for
  foreground objects) -- so label borders, light-source borders and
  silhouettes stay at pixel resolution -- and when its two triangles
  (diagonal top-right/bottom-left, as the full grid) reproduce the depth of
  every node inside within the tolerance ``tau`` (relative depth error,
  computed exactly: inverse depth is affine across a triangle in the image).
  A cell's error is made monotone (``max`` with its children), so the leaves
  for a tolerance are the cells within it whose parent is not.
* Crack-free seams: all vertices used by neighbouring faces that lie on a
  leaf's perimeter (T-junctions of smaller neighbours) are collected; a leaf
  without such vertices gets its two triangles, a leaf with them a fan around
  its centre pixel through every perimeter vertex in order. Quads no leaf
  covers are triangulated as in the full grid (:func:`~.grid.quad_faces`); quads
  holding a depth step keep the post-processed mesh's fans and walls (:mod:`.steps`).
  So every shared edge is shared exactly -- no cracks and no T-junctions.
* Budget: the tolerance is found by bisection on a face-count estimate from
  the error pyramid, then the mesh is built (and rebuilt, at most three more
  times, with a corrected target while it exceeds the budget by > 5 %). A
  budget below what the pixel-resolution borders need cannot be met: the
  result is then the coarsest mesh (tolerance 1).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numpy.lib.stride_tricks import as_strided

from ..camera import Intrinsics
from ..errors import NpsimInputError
from .grid import quad_faces
from .postprocess import SheetLayers
from .steps import StepFaces
from .types import SceneMesh

__all__ = ["ReduceParams", "ReduceResult", "reduce_mesh", "decimate_pymeshlab", "merge_parts"]


@dataclass(frozen=True)
class ReduceParams:
    """Parameters of :func:`reduce_mesh`.

    Attributes
    ----------
    budget : int or None
        Target total face count; None -> use ``tol`` directly.
    tol : float
        Maximum relative depth error of a merged cell when no budget is given.
    max_level : int
        Largest cell is ``2^max_level`` pixels.
    steps : "auto" | "kept"
        Depth-step quads (fans and edge-on walls, :mod:`.steps`) stay at pixel resolution and
        never merge. ``"auto"``: when that alone exceeds the budget, the steps are bridged by
        plain grid quads instead (2 faces per quad instead of about 6-10; those faces are
        stretched again, as in the raw grid). ``"kept"``: never bridge (the budget may be missed).
    """

    budget: int | None = None
    tol: float = 0.002
    max_level: int = 6
    steps: str = "auto"

    def __post_init__(self) -> None:
        if self.steps not in ("auto", "kept"):
            raise NpsimInputError(f"steps must be 'auto' or 'kept', got {self.steps!r}")
        if self.budget is not None and int(self.budget) < 1:
            raise NpsimInputError(f"face budget must be >= 1, got {self.budget}")
        if not self.tol >= 0:
            raise NpsimInputError(f"tol must be >= 0, got {self.tol}")
        if not 1 <= int(self.max_level) <= 12:
            raise NpsimInputError(f"max_level must be in 1..12, got {self.max_level}")


@dataclass
class ReduceResult:
    """Reduced mesh, the tolerance used, leaf counts, timings, and whether depth steps were
    ``"kept"`` (fans and walls) or ``"bridged"`` (grid quads, to meet a tight budget)."""

    mesh: SceneMesh
    tol: float
    leaves: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    steps: str = "kept"


class _Pyramid:
    """Per-level monotone cell errors of one layer (see module doc)."""

    def __init__(self, depth: np.ndarray, key: np.ndarray, max_level: int, blocked: np.ndarray | None = None):
        H, W = depth.shape
        self.H, self.W = H, W
        valid = np.isfinite(depth) & (key >= 0)
        iz = np.where(valid, 1.0 / np.where(valid, depth, 1.0), np.nan).astype(np.float64)
        k00, k01, k10, k11 = key[:-1, :-1], key[:-1, 1:], key[1:, :-1], key[1:, 1:]
        uni0 = (k00 >= 0) & (k00 == k01) & (k00 == k10) & (k00 == k11) & valid[:-1, :-1] & valid[:-1, 1:] \
            & valid[1:, :-1] & valid[1:, 1:]
        if blocked is not None:
            uni0 &= ~blocked          # mixed quads (depth steps with walls) stay at pixel resolution
        self.err = [np.where(uni0, 0.0, np.inf)]
        self.levels = 0
        for k in range(1, max_level + 1):
            s = 1 << k
            nr, nc = (H - 1) // s, (W - 1) // s
            if nr < 1 or nc < 1:
                break
            ch = self.err[k - 1]
            cmax = np.maximum(np.maximum(ch[0:2 * nr:2, 0:2 * nc:2], ch[0:2 * nr:2, 1:2 * nc:2]),
                              np.maximum(ch[1:2 * nr:2, 0:2 * nc:2], ch[1:2 * nr:2, 1:2 * nc:2]))
            e = np.full((nr, nc), np.inf)
            cand = np.isfinite(cmax)
            if cand.any():
                e[cand] = np.maximum(self._cell_error(iz, s, nr, nc, cand), cmax[cand])
            self.err.append(e)
            self.levels = k
        self.perr = [self._parent_err(k) for k in range(self.levels + 1)]
        # Leaves at tau: e <= tau < parent e; as parent e >= e, their number is
        # #{e <= tau} - #{parent e <= tau}, read from sorted arrays in O(log n).
        self._se = [np.sort(e, axis=None) for e in self.err]
        self._spe = [np.sort(e, axis=None) for e in self.perr]

    @staticmethod
    def _cell_error(iz: np.ndarray, s: int, nr: int, nc: int, cand: np.ndarray) -> np.ndarray:
        """Max relative depth error of the two-triangle approximation of each candidate cell."""
        st0, st1 = iz.strides
        view = as_strided(iz, shape=(nr, nc, s + 1, s + 1), strides=(s * st0, s * st1, st0, st1))
        ci, cj = np.nonzero(cand)
        nodes = view[ci, cj]                                   # (n, s+1, s+1) copy of candidate cells only
        tl, tr = nodes[:, 0, 0][:, None, None], nodes[:, 0, s][:, None, None]
        bl, br = nodes[:, s, 0][:, None, None], nodes[:, s, s][:, None, None]
        x = (np.arange(s + 1) / s)[None, None, :]
        y = (np.arange(s + 1) / s)[None, :, None]
        upper = (x + y) <= 1.0
        interp = np.where(upper, tl + x * (tr - tl) + y * (bl - tl), br + (1 - x) * (bl - br) + (1 - y) * (tr - br))
        with np.errstate(invalid="ignore", divide="ignore"):
            rel = np.abs(nodes / interp - 1.0)
        return rel.reshape(len(ci), -1).max(1)

    def _parent_err(self, k: int) -> np.ndarray:
        """Error of each level-k cell's parent (inf where it has none or k is the top level)."""
        e = self.err[k]
        out = np.full(e.shape, np.inf)
        if k + 1 <= self.levels:
            p = self.err[k + 1]
            pr, pc = p.shape
            out[:2 * pr, :2 * pc] = np.repeat(np.repeat(p, 2, 0), 2, 1)
        return out

    def leaves(self, tau: float) -> list[np.ndarray]:
        return [(self.err[k] <= tau) & (self.perr[k] > tau) for k in range(self.levels + 1)]

    def leaf_counts(self, tau: float) -> list[int]:
        return [int(np.searchsorted(se, tau, "right") - np.searchsorted(spe, tau, "right"))
                for se, spe in zip(self._se, self._spe)]


def _estimate_faces(pyrs: list[_Pyramid], tau: float, fixed: int) -> float:
    n = float(fixed)
    for p in pyrs:
        for k, c in enumerate(p.leaf_counts(tau)):
            n += c * (2.0 if k == 0 else 2.6)        # T-junction fans cost a little more
    return n


def _layer_faces(depth: np.ndarray, pyr: _Pyramid, tau: float, group: np.ndarray | None,
                 intr: Intrinsics, steps: StepFaces) -> tuple[np.ndarray, dict]:
    """Faces (extended vertex ids, see :class:`SheetLayers`) of one layer at tolerance ``tau``."""
    H, W = depth.shape
    leaves = pyr.leaves(tau)
    covered = np.zeros((H - 1, W - 1), dtype=bool)
    for k in range(1, len(leaves)):
        s = 1 << k
        lk = leaves[k]
        if lk.any():
            up = np.repeat(np.repeat(lk, s, 0), s, 1)
            covered[:up.shape[0], :up.shape[1]] |= up
    ok = np.isfinite(depth)
    flat = np.arange(H * W, dtype=np.int64).reshape(H, W)
    pts = intr.pixel_rays(np.float32) * np.where(ok, depth, 0.0)[..., None]
    f0 = quad_faces(np.where(ok, flat, -1), pts, group, cells=~covered & ~steps.mixed)
    used = np.zeros(H * W, dtype=bool)
    used[f0.ravel()] = True
    sf = steps.faces.ravel()
    used[sf[sf < H * W]] = True
    out = [f0, steps.faces]
    info = {"quads": int(len(f0)), "step_faces": int(len(steps.faces))}
    cells = []
    for k in range(1, len(leaves)):
        s = 1 << k
        ci, cj = np.nonzero(leaves[k])
        base = ci * s * W + cj * s
        cells.append((s, base))
        used[base] = True
        used[base + s] = True
        used[base + s * W] = True
        used[base + s * W + s] = True
        info[f"leaves_{s}"] = int(len(base))
    for s, base in cells:
        if len(base) == 0:
            continue
        t = np.arange(s)
        # Perimeter in front-facing order: down the left side, along the bottom, up the right, back along the top.
        off = np.concatenate([t * W, s * W + t, (s - t) * W + s, s - t])
        perim = base[:, None] + off[None, :]
        m = used[perim]
        nused = m.sum(1)
        simple = nused == 4
        b = base[simple]
        if len(b):
            tl, tr, bl, br = b, b + s, b + s * W, b + s * W + s
            q = np.empty((len(b), 2, 3), dtype=np.int64)
            q[:, 0] = np.stack([tl, bl, tr], 1)
            q[:, 1] = np.stack([tr, bl, br], 1)
            out.append(q.reshape(-1, 3))
        fan = ~simple
        if fan.any():
            pm, mm = perim[fan], m[fan]
            centre = base[fan] + (s // 2) * W + s // 2
            r, c = np.nonzero(mm)                         # row-major: grouped by leaf, in perimeter order
            cur = pm[r, c]
            nxt_pos = np.arange(len(r)) + 1
            last = np.ones(len(r), dtype=bool)
            last[:-1] = r[1:] != r[:-1]
            first_idx = np.flatnonzero(np.concatenate([[True], r[1:] != r[:-1]]))
            nxt_pos[last] = first_idx
            out.append(np.stack([centre[r], cur, cur[nxt_pos]], 1))
    return np.concatenate(out, 0), info


def reduce_mesh(layers: SheetLayers, intr: Intrinsics, params: ReduceParams = ReduceParams()) -> ReduceResult:
    """Reduced version of the post-processed mesh (same parts, same attributes), see module doc.

    Parameters
    ----------
    layers : SheetLayers
        ``PostprocessResult.layers``.
    intr : Intrinsics
    params : ReduceParams
        Face budget (or tolerance) and largest cell.

    Returns
    -------
    ReduceResult with the mesh, the tolerance used, leaf counts and timings.
    """
    t0 = time.perf_counter()
    if layers.shape != (intr.height, intr.width):
        raise NpsimInputError(f"layers are {layers.shape} but intrinsics are {intr.height}x{intr.width}")
    bd, fd = layers.background_depth, layers.foreground_depth
    kept = (layers.step(0), layers.step(1))

    def build(st):
        pyrs = [_Pyramid(bd, layers.background_key(), params.max_level, st[0].mixed),
                _Pyramid(fd, layers.foreground_key(), params.max_level, st[1].mixed)]
        tau = params.tol
        if params.budget is None:
            return (_layer_faces(bd, pyrs[0], tau, None, intr, st[0]),
                    _layer_faces(fd, pyrs[1], tau, layers.objects, intr, st[1]), tau)
        # Fans and walls of depth-step quads never merge; other unmerged quads are in the estimate.
        fixed = len(st[0].faces) + len(st[1].faces)
        target = float(params.budget)
        for attempt in range(4):
            lo, hi = 1e-7, 1.0
            if _estimate_faces(pyrs, hi, fixed) > target:
                tau = hi
            else:
                for _ in range(40):
                    mid = np.sqrt(lo * hi)
                    if _estimate_faces(pyrs, mid, fixed) > target:
                        lo = mid
                    else:
                        hi = mid
                tau = hi
            bg = _layer_faces(bd, pyrs[0], tau, None, intr, st[0])
            fg = _layer_faces(fd, pyrs[1], tau, layers.objects, intr, st[1])
            n = len(bg[0]) + len(fg[0])
            if attempt < 3 and n > 1.05 * params.budget and tau < 1.0:
                target *= params.budget / n      # the estimate was off: correct the target and rebuild
                continue
            break
        return bg, fg, tau

    fixed = len(kept[0].faces) + len(kept[1].faces)
    # Step faces alone above the budget: no need to try keeping them.
    hopeless = params.budget is not None and params.steps != "kept" and fixed > params.budget
    steps = "kept"
    if not hopeless:
        (bg_faces, ibg), (fg_faces, ifg), tau = build(kept)
    t1 = time.perf_counter()
    if hopeless or (params.budget is not None and fixed and params.steps != "kept"
                    and len(bg_faces) + len(fg_faces) > 1.05 * params.budget):
        # Over budget with every step at pixel resolution: bridge the steps (two grid triangles per
        # quad instead of fans and walls); their faces are stretched again but cost a fifth.
        empty = StepFaces.empty(layers.shape)
        (bg_faces, ibg), (fg_faces, ifg), tau = build((empty, empty))
        steps = "bridged"
    t2 = time.perf_counter()
    parts = layers.parts(intr, bg_faces, fg_faces)
    t3 = time.perf_counter()
    tm = {"build": t1 - t0, "bridged rebuild": t2 - t1, "parts": t3 - t2, "total": t3 - t0}
    mesh = SceneMesh(parts=parts, width=intr.width, height=intr.height,
                     info={"stage": "reduce", "tol": tau, "budget": params.budget, "timings": tm, "steps": steps,
                           "faces": sum(p.n_faces for p in parts)})
    return ReduceResult(mesh=mesh, tol=float(tau), leaves={"background": ibg, "foreground": ifg}, timings=tm,
                        steps=steps)


def merge_parts(mesh: SceneMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All parts as one (vertices, faces, part index per face) triple."""
    vs, fs, ps = [], [], []
    off = 0
    for i, p in enumerate(mesh.parts):
        vs.append(p.vertices)
        fs.append(p.faces + off)
        ps.append(np.full(p.n_faces, i, dtype=np.int32))
        off += p.n_vertices
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(ps)


def decimate_pymeshlab(mesh: SceneMesh, budget: int) -> tuple[SceneMesh, float]:
    """Comparison: pymeshlab quadric edge collapse of the whole mesh to ``budget`` faces.

    Each part is decimated on its own with a share of the budget proportional
    to its face count, with boundary preservation, so sheets stay separate and
    their borders (silhouettes) are kept; label borders *inside* a sheet are
    not protected. Attributes other than positions are dropped (uv/label/pixel
    are recomputed by projection where needed). Returns (mesh, seconds).
    """
    import pymeshlab

    from .types import MeshPart

    t0 = time.perf_counter()
    total = max(mesh.n_faces, 1)
    parts = []
    for p in mesh.parts:
        if p.n_faces == 0:
            continue
        target = max(4, int(round(budget * p.n_faces / total)))
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=p.vertices.astype(np.float64), face_matrix=p.faces.astype(np.int32)))
        if target < p.n_faces:
            ms.meshing_decimation_quadric_edge_collapse(targetfacenum=target, preserveboundary=True, boundaryweight=2.0,
                                                        preservenormal=True, preservetopology=True,
                                                        planarquadric=True, autoclean=True)
        m = ms.current_mesh()
        v = m.vertex_matrix().astype(np.float32)
        f = m.face_matrix().astype(np.int64)
        n = len(v)
        parts.append(MeshPart(name=p.name, vertices=v, faces=f, uv=np.zeros((n, 2), np.float32),
                              pixel=np.zeros((n, 2), np.float32), label=np.zeros(n, np.uint8),
                              light_id=np.zeros(n, np.int32), foreground=p.foreground))
    out = SceneMesh(parts=parts, width=mesh.width, height=mesh.height, info={"stage": "pymeshlab", "budget": budget})
    return out, time.perf_counter() - t0
