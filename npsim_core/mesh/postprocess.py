"""Mesh post-processing kernel (docs/method.md §5, thesis §3.5 and Algorithm 1).

Everything happens on the pixel grid, so each step is a handful of whole-image
array operations; the sheets are triangulated at the end with the same
:func:`~npsim_core.mesh.grid.quad_faces` as the raw Worldsheet grid.

1. **Uncertain-face deletion.** A face with any vertex in the uncertain map U is
   spurious. On the grid this is the same as dropping the U vertices from the
   raw sheet (a face survives iff its three pixels are outside U).
2. **Background completion** (Algorithm 1). The region to complete is
   R = U ∪ (foreground segments adjacent to U) ∪ (non-sky pixels with invalid
   depth). Foreground = the thesis's classes plus ``occluders`` (default
   vegetation, see :class:`PostprocessParams`). In the default ``complete_behind="all"`` mode *every* foreground
   segment is in R, so every object becomes its own sheet as the method's result
   asks ("background sheet + foreground sheets", docs/method.md §5.6); ``"adjacent"`` is the thesis's
   literal rule, where objects untouched by U stay welded into the background
   sheet. For each row, each run of R pixels is filled from the pixels just left
   and right of it: if both are background vertices, *depth* (or inverse depth,
   ``interpolation="inverse_depth"``, exact on planes) is interpolated linearly
   in u and back-projected, so vertices stay on their pixel rays (this is the
   thesis's ``(G_l (j_r-j+1) + G_r (j-j_l+1)) / (j_r-j_l+2)``, applied to depth).
   A run whose other end is the image border or sky extends its one background
   neighbour; a run with sky/border on both ends is left empty (the background
   behind an object seen against the sky is sky). Runs are taken per row over the
   whole image, which equals the thesis's per-region loop because runs never
   cross known background. An optional vertical pass then interpolates runs that
   the row pass could not reach but that have background above and below
   (e.g. a NaN island spanning a whole row segment between sky).
   Completed background vertices *hidden* behind an object vertex take label and
   texture coordinates (uv) from the nearer row neighbour and light id 0 (what is
   hidden cannot be annotated), and are pushed behind the object by at least
   ``behind_margin`` (relative) so the hidden sheet can never poke through.
   Completed vertices nothing covers (background pixels in U, invalid-depth
   islands) are visible and keep their own pixel's label, uv and light id, so the
   mesh seen from the camera carries exactly the input labels.
3. **Foreground completion.** Objects are connected components per foreground
   class (8-connected) or, where an instance map is given, its instances. In
   U ∩ object (and at the object's invalid-depth pixels) depth is filled by a
   breadth-first frontier: each frontier pixel gets the mean depth of its known
   8-neighbours of the same object, then becomes known. Implemented on the list
   of target pixels with precomputed neighbour indices (cost per round ∝ targets).
   An object without any surviving vertex keeps its own (valid) input depth.
4. **Visible vertices keep their depth** (``keep_consistent``, default: always).
   After completion a *visible* U vertex (background nothing covers, an object's own
   pixel) gets its input depth back; only hidden background keeps the completed
   depth. The thesis replaces every U vertex, because in a single grid sheet a U
   vertex is where faces stretch across a depth step. Here the faces that span a
   step are removed and the step closed by edge-on walls (5.), so U's job -- no
   stretched face, objects separated, background completed behind them -- is done
   without moving visible geometry: the mesh then reproduces the refined depth at
   every pixel. Measured on the synthetic street at 2048x1024 with refinement (U is
   5 % of the pixels): within 1 % of the source depth 96.2 % (thesis) -> 100.0 %,
   face-normal error 17.40 -> 17.86 deg, stretched faces 0 either way. A finite
   tolerance keeps only vertices within it of the completed surface; None is the
   thesis's rule.
5. **Depth steps inside a sheet** (``step_cut``, :mod:`.steps`): a side between two
   pixels of one sheet whose depths differ by more than 3 % (up to 4.5 % on surfaces
   seen at a grazing angle) is cut, its quads triangulated as fans on either side and
   the two sides joined by walls that lie along camera rays -- invisible from the
   camera, so the sheet stays closed (hole-free) without a stretched face.
   Each object is triangulated only with itself, so no face bridges two objects
   or an object and the background.

The output :class:`SceneMesh` has part ``"background"`` and one part per
foreground object named ``<class>_<k>`` (k counts objects of that class in
raster order of their first pixel).
"""

from __future__ import annotations

import math
import time
from functools import partial
from dataclasses import asdict, dataclass, field, replace

import cv2
import numpy as np

from ..camera import Intrinsics, valid_depth_mask
from ..errors import NpsimInputError
from ..labels import cityscapes
from .grid import check_mesh_inputs, light_id_map, pixel_uv, quad_faces, usable_mask
from .steps import StepFaces, slant_at, step_faces
from .types import MeshPart, SceneMesh

__all__ = ["PostprocessParams", "PostprocessResult", "SheetLayers", "postprocess_mesh", "object_map",
           "default_occluders", "replaced_grid_faces"]

_N8 = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]


def default_occluders() -> tuple[int, ...]:
    """Background classes meshed as their own sheets by default: vegetation."""
    return (cityscapes().by_name("vegetation").id,)


@dataclass(frozen=True)
class PostprocessParams:
    """Parameters of the post-processing kernel.

    Attributes
    ----------
    complete_behind : "all" | "adjacent"
        Which foreground segments the background is completed behind (see module doc).
    keep_consistent : float or None
        A *visible* vertex in U (background not hidden by an object, or an object's own pixel)
        keeps its own depth when it lies within this relative distance of the completed
        surface there (row interpolation / breadth-first fill). Default ``inf``: every visible
        vertex keeps its depth (depth steps are cut by ``step_cut`` instead, module doc 4-5).
        None = the thesis's rule: every U vertex is replaced by completed depth.
    interpolation : "depth" | "inverse_depth"
        Quantity interpolated along a row run (default depth, as docs/method.md §5.2 states).
    vertical_pass : bool
        Also fill runs with background above and below that the row pass left empty.
    behind_margin : float
        Completed background is kept at least ``(1 + behind_margin) * d_object``
        deep where an object vertex is in front of it.
    exclude : tuple of labelIds or None
        Never meshed (None = sky).
    far_limit : float or None
        No vertex deeper than this (metres), also for completed vertices.
    occluders : tuple of labelIds or None
        Background classes treated like foreground objects for completion (own sheets,
        ``foreground=True``, background completed behind them). None = vegetation
        (:func:`default_occluders`): U only flags jumps that involve a foreground class,
        so tree crowns in front of façades would otherwise stay bridged to the façade
        inside the background sheet (measured at 2048x1024: stretched faces 5,202 ->
        2,680, face-normal error 21.38 -> 21.22 deg, holes 0 either way). ``()`` = the
        thesis's classes only.
    step_cut : float or None
        Relative depth step (``|d1 - d2| / min(d1, d2)``) between neighbouring pixels of one
        sheet above which the sheet is cut and closed by edge-on walls instead of a stretched
        face (:mod:`.steps`), on a surface seen head-on. None = no cuts (steps stay bridged).
    step_cut_grazing : float
        The threshold rises with the surface's slant (a plane seen at a grazing angle has
        large steps between pixels) up to this. With the defaults no face edge spans more
        than 4.5 %, below the 5 % the stretched-face measure calls a discontinuity
        (:mod:`.quality`): a slit's end is closed by a fan whose spokes span at most half of
        the three other sides of its quad (3 x 3 % / 2), every other edge at most the threshold.
    extend_edges : bool
        Sheet borders (silhouettes, the sky line, two objects meeting) run half a pixel beyond
        the border pixels' centres, through the sides' midpoints, so each sheet covers exactly
        its pixels' area and a render's outlines match the label masks. Needs ``step_cut``.
    """

    complete_behind: str = "all"
    keep_consistent: float | None = math.inf
    interpolation: str = "depth"
    vertical_pass: bool = True
    behind_margin: float = 0.01
    exclude: tuple[int, ...] | None = None
    far_limit: float | None = None
    occluders: tuple[int, ...] | None = None
    step_cut: float | None = 0.03
    step_cut_grazing: float = 0.045
    extend_edges: bool = True

    def __post_init__(self) -> None:
        for name in ("keep_consistent", "step_cut", "step_cut_grazing", "behind_margin", "far_limit"):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))):
                raise NpsimInputError(f"{name} must be a number{'' if name == 'step_cut_grazing' else ' or null'}, "
                                      f"got {v!r}")
        if not (self.step_cut or 0) <= self.step_cut_grazing < 1:
            raise NpsimInputError(f"step_cut_grazing must be in [step_cut, 1), got {self.step_cut_grazing}")
        if self.step_cut is not None and not 0 < self.step_cut < 1:
            raise NpsimInputError(f"step_cut must be in (0, 1) (relative depth step) or None, got {self.step_cut}")
        if self.complete_behind not in ("all", "adjacent"):
            raise NpsimInputError(f"complete_behind must be 'all' or 'adjacent', got {self.complete_behind!r}")
        if self.keep_consistent is not None and not self.keep_consistent >= 0:
            raise NpsimInputError(f"keep_consistent must be >= 0 or None, got {self.keep_consistent}")
        if self.interpolation not in ("depth", "inverse_depth"):
            raise NpsimInputError(f"interpolation must be 'depth' or 'inverse_depth', got {self.interpolation!r}")
        if not self.behind_margin >= 0:
            raise NpsimInputError(f"behind_margin must be >= 0, got {self.behind_margin}")


@dataclass
class PostprocessResult:
    """Output of :func:`postprocess_mesh`.

    Attributes
    ----------
    mesh : SceneMesh
        ``"background"`` + one part per foreground object (part ``k`` = object ``k``).
    layers : SheetLayers
        The same sheets as per-pixel layers (input of :mod:`.reduce`).
    counts : dict
        uncertain pixels, deleted vertices, completed background / foreground vertices, objects, faces.
    timings : dict
        Seconds per step.
    """

    mesh: SceneMesh
    layers: "SheetLayers"
    counts: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)


def object_map(labels: np.ndarray, mask: np.ndarray, fg_lut: np.ndarray,
               instance_ids: np.ndarray | None = None) -> tuple[np.ndarray, list[int]]:
    """Foreground objects: 8-connected components per class (or instances), numbered 1.. in raster order.

    Returns the HxW int32 object map (0 = none) and the class labelId of each object (index k-1).
    """
    H, W = labels.shape
    fgm = mask & fg_lut[labels]
    key = np.zeros((H, W), dtype=np.int64)
    classes = np.unique(labels[fgm])
    nxt = 1
    for c in classes:
        m = fgm & (labels == c)
        if instance_ids is not None:
            inst = instance_ids.astype(np.int64)
            has = m & (inst > 0)
            if has.any():
                ids, inv = np.unique(inst[has], return_inverse=True)
                key[has] = nxt + inv
                nxt += len(ids)
            m = m & ~has
        if m.any():
            n, cc = cv2.connectedComponents(m.astype(np.uint8), connectivity=8, ltype=cv2.CV_32S)
            key[m] = cc[m] + (nxt - 1)
            nxt += n - 1
    # Renumber in raster order of each object's first pixel, so names are stable.
    flat = key.ravel()
    nz = np.flatnonzero(flat)
    if len(nz) == 0:
        return np.zeros((H, W), dtype=np.int32), []
    ids, first = np.unique(flat[nz], return_index=True)
    order = np.argsort(nz[first], kind="stable")
    remap = np.zeros(int(ids.max()) + 1, dtype=np.int32)
    remap[ids[order]] = np.arange(1, len(ids) + 1, dtype=np.int32)
    obj = remap[key]
    obj_class = [int(labels.ravel()[nz[first[o]]]) for o in order]
    return obj.astype(np.int32), obj_class


def _row_runs(target: np.ndarray, known: np.ndarray):
    """Left/right bounding indices of each target pixel's row run and whether they are known.

    A run is a maximal horizontal stretch of ``target``; its neighbours are the
    pixels just outside it (-1 / W at the image border).
    """
    H, W = target.shape
    idx = np.broadcast_to(np.arange(W, dtype=np.int32), (H, W))
    left = np.maximum.accumulate(np.where(~target, idx, -1), axis=1)
    right = np.minimum.accumulate(np.where(~target, idx, W)[:, ::-1], axis=1)[:, ::-1]
    rows = np.broadcast_to(np.arange(H)[:, None], (H, W))
    lk = (left >= 0) & known[rows, np.clip(left, 0, W - 1)]
    rk = (right < W) & known[rows, np.clip(right, 0, W - 1)]
    return left, right, lk, rk


def _fill_runs(target, known, depth, inverse: bool, allow_extend: bool):
    """Fill ``target`` pixels row-wise from known neighbours (see module doc).

    Returns (filled mask, depth, source flat-index of the nearer neighbour) on full HxW arrays.
    """
    H, W = target.shape
    left, right, lk, rk = _row_runs(target, known)
    both = target & lk & rk
    only_l = target & lk & ~rk
    only_r = target & rk & ~lk
    out = np.full((H, W), np.nan, dtype=np.float64)
    src = np.full((H, W), -1, dtype=np.int64)
    # Both neighbours known: linear interpolation in u.
    r_, c_ = np.nonzero(both)
    L, R = left[r_, c_], right[r_, c_]
    dL, dR = depth[r_, L].astype(np.float64), depth[r_, R].astype(np.float64)
    t = (c_ - L) / (R - L)
    if inverse:
        out[r_, c_] = 1.0 / ((1 - t) / dL + t / dR)
    else:
        out[r_, c_] = (1 - t) * dL + t * dR
    src[r_, c_] = r_ * W + np.where(c_ - L <= R - c_, L, R)
    filled = both
    if allow_extend:
        for m, nb in ((only_l, left), (only_r, right)):
            r_, c_ = np.nonzero(m)
            n = nb[r_, c_]
            out[r_, c_] = depth[r_, n]
            src[r_, c_] = r_ * W + n
        filled = both | only_l | only_r
    return filled, out, src


def _bfs_fill(depth: np.ndarray, known: np.ndarray, target: np.ndarray, obj: np.ndarray):
    """Breadth-first fill of ``target`` from ``known`` pixels of the same object (8-neighbours).

    Each round fills every target pixel that has a known same-object neighbour
    with the mean of those neighbours, then marks it known. Returns
    (depth with filled values, filled mask).
    """
    H, W = depth.shape
    out = depth.astype(np.float64).copy()
    out[~known] = np.nan
    tidx = np.flatnonzero(target)
    filled = np.zeros((H, W), dtype=bool)
    if len(tidx) == 0:
        return out, filled
    tr, tc = np.divmod(tidx, W)
    nbr = np.full((len(tidx), 8), -1, dtype=np.int64)
    oflat = obj.ravel()
    for k, (dr, dc) in enumerate(_N8):
        rr, cc = tr + dr, tc + dc
        ok = (rr >= 0) & (rr < H) & (cc >= 0) & (cc < W)
        n = np.where(ok, rr * W + cc, 0)
        ok &= oflat[n] == oflat[tidx]
        nbr[:, k] = np.where(ok, n, -1)
    kn = known.ravel().copy()
    flat = out.ravel()
    # Only the still-pending targets are visited each round (cost per round ∝ frontier + pending).
    pend = np.arange(len(tidx))
    done = np.zeros(len(tidx), dtype=bool)
    while len(pend):
        nb = nbr[pend]
        kmask = (nb >= 0) & kn[np.maximum(nb, 0)]
        cnt = kmask.sum(1)
        front = cnt > 0
        if not front.any():
            break
        fp = pend[front]
        vals = np.where(kmask[front], flat[np.maximum(nb[front], 0)], 0.0).sum(1) / cnt[front]
        fi = tidx[fp]
        flat[fi] = vals
        kn[fi] = True
        done[fp] = True
        pend = pend[~front]
    filled.ravel()[tidx[done]] = True
    return out, filled


def _index_dtype(n: int):
    """Vertex index type of a part with ``n`` vertices: int32 (half the memory of int64: 45 MB
    less for a 2048x1024 background sheet) unless it cannot hold them."""
    return np.int32 if n < 2**31 else np.int64


def postprocess_mesh(depth: np.ndarray, intrinsics: Intrinsics, labels: np.ndarray, uncertain: np.ndarray,
                     light_ids: np.ndarray | None = None, instance_ids: np.ndarray | None = None,
                     params: PostprocessParams = PostprocessParams(),
                     normals: np.ndarray | None = None) -> PostprocessResult:
    """Build the post-processed scene mesh (docs/method.md §5) directly from the depth map and U.

    Parameters
    ----------
    depth : (H, W) float
        z-depth in metres (typically the refined depth), NaN invalid.
    intrinsics : Intrinsics
    labels : (H, W) int
        Cityscapes labelIds.
    uncertain : (H, W) bool
        Uncertain map U (docs/method.md §3.2).
    light_ids : (H, W) int, optional
        Light instance map (0 = none).
    instance_ids : (H, W) int, optional
        Object instance ids (> 0) for foreground classes; 0 = use connected components.
    params : PostprocessParams
    normals : (H, W, 3) float, optional
        Estimated unit normals (camera frame). Only used to tell a plane seen at a grazing
        angle from a depth step when cutting steps (``params.step_cut``,
        :func:`~.steps.slant_at`); without them the normals come from the depth itself.

    Returns
    -------
    PostprocessResult
    """
    t0 = time.perf_counter()
    tm: dict[str, float] = {}
    # The layers are built in their own function so that its full-frame temporaries (float64
    # completions, run indices, masks) are freed before triangulation allocates the faces:
    # at 4000x3000 that is what kept the peak above 4 GB (docs/mesh.md, "Export").
    layers, counts = _sheet_layers(depth, intrinsics, labels, uncertain, light_ids, instance_ids, params,
                                   normals, tm)
    # Triangulate.
    t = time.perf_counter()
    parts = layers.full_parts(intrinsics)
    tm["triangulate"] = time.perf_counter() - t
    tm["total"] = time.perf_counter() - t0
    counts.update(faces=sum(p.n_faces for p in parts), vertices=sum(p.n_vertices for p in parts))
    mesh = SceneMesh(parts=parts, width=layers.shape[1], height=layers.shape[0],
                     info={"stage": "postprocess", "params": asdict(params), "counts": counts, "timings": tm})
    return PostprocessResult(mesh=mesh, layers=layers, counts=counts, timings=tm)


def _sheet_layers(depth, intrinsics: Intrinsics, labels, uncertain, light_ids, instance_ids,
                  params: PostprocessParams, normals, tm: dict[str, float]) -> tuple["SheetLayers", dict]:
    """The background and foreground sheets of :func:`postprocess_mesh` (steps 1-3 and the step
    cuts) and the counts; stage timings are added to ``tm``."""
    t0 = time.perf_counter()
    depth, labels, light_ids = check_mesh_inputs(depth, intrinsics, labels, light_ids)
    U = np.asarray(uncertain)
    if U.shape != depth.shape:
        raise NpsimInputError(f"uncertain map must have the depth's shape {depth.shape}, got {U.shape}")
    U = U.astype(bool, copy=False)
    if instance_ids is not None:
        instance_ids = np.asarray(instance_ids)
        if instance_ids.shape != depth.shape or not np.issubdtype(instance_ids.dtype, np.integer):
            raise NpsimInputError(f"instance_ids must be an HxW integer map of shape {depth.shape}")
    H, W = depth.shape
    table = cityscapes()
    fg_lut = np.zeros(256, dtype=bool)
    fg_lut[list(table.foreground_ids)] = True
    occluders = default_occluders() if params.occluders is None else tuple(params.occluders)
    fg_lut[list(occluders)] = True
    exclude = params.exclude if params.exclude is not None else (table.sky_id,)

    valid = valid_depth_mask(depth)
    usable = usable_mask(depth, labels, exclude, params.far_limit)     # may carry a vertex as is
    ex_lut = np.zeros(256, dtype=bool)
    ex_lut[list(exclude)] = True
    # Pixels that should end up with a vertex somewhere: not excluded, not known to be too far.
    meshable = ~ex_lut[labels] & ~(valid & ~usable)
    obj, obj_class = object_map(labels, meshable, fg_lut, instance_ids)
    fg = obj > 0
    tm["objects"] = time.perf_counter() - t0

    # 1. Uncertain-face deletion == drop U vertices.
    survive = usable & ~U
    # 2. Background completion.
    t = time.perf_counter()
    if params.complete_behind == "all":
        in_r = fg.copy()
    else:
        near_u = cv2.dilate(U.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        touched = np.unique(obj[near_u & fg])
        in_r = np.isin(obj, touched[touched > 0])
        # Objects U does not touch stay welded into the background sheet: renumber the others.
        obj, obj_class = object_map(labels, meshable & in_r, fg_lut, instance_ids)
        fg = obj > 0
    bg_known = survive & ~in_r
    target = meshable & ~bg_known
    bg_depth = np.where(bg_known, depth, np.nan).astype(np.float64)
    bg_src = np.where(bg_known, np.arange(H * W).reshape(H, W), -1)
    filled, d_fill, s_fill = _fill_runs(target, bg_known, depth, params.interpolation == "inverse_depth", True)
    bg_depth[filled] = d_fill[filled]
    bg_src[filled] = s_fill[filled]
    n_row = int(filled.sum())
    n_col = 0
    if params.vertical_pass:
        known2 = bg_known | filled
        rest = target & ~filled
        if rest.any():
            f2, d2, s2 = _fill_runs(rest.T.copy(), known2.T.copy(), bg_depth.T.copy(),
                                    params.interpolation == "inverse_depth", False)
            f2, d2 = f2.T, d2.T
            # Source pixel index for texture/label: transposed flat index -> HxW flat index.
            s2 = s2.T
            s2 = np.where(s2 >= 0, (s2 % H) * W + s2 // H, -1)
            # The column neighbour may itself be completed: follow it to a real pixel.
            s2 = np.where(s2 >= 0, bg_src.ravel()[np.clip(s2, 0, None)], -1)
            bg_depth[f2] = d2[f2]
            bg_src[f2] = s2[f2]
            filled |= f2
            n_col = int(f2.sum())
    n_kept = 0
    if params.keep_consistent is not None:
        # Visible background in U whose own depth agrees with the completed surface keeps it.
        vis = usable & U & ~in_r & filled
        with np.errstate(invalid="ignore", divide="ignore"):
            agree = vis & (np.abs(depth - bg_depth) <= params.keep_consistent * bg_depth)
        bg_depth[agree] = depth[agree]
        bg_src[agree] = np.flatnonzero(agree.ravel())
        filled &= ~agree
        n_kept += int(agree.sum())
    tm["background"] = time.perf_counter() - t

    # 3. Foreground completion.
    t = time.perf_counter()
    fg_known = fg & survive
    fg_target = fg & ~fg_known
    fg_depth, fg_filled = _bfs_fill(depth, fg_known, fg_target, obj)
    if params.keep_consistent is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            agree = fg_filled & usable & (np.abs(depth - fg_depth) <= params.keep_consistent * fg_depth)
        fg_depth[agree] = depth[agree]
        n_kept += int(agree.sum())
    # Objects with no surviving vertex at all keep their own valid input depth.
    orphan = fg_target & ~fg_filled & usable
    fg_depth[orphan] = depth[orphan]
    fg_filled |= orphan
    fgv = fg_known | fg_filled
    fg_depth[~fgv] = np.nan
    tm["foreground"] = time.perf_counter() - t

    # Keep hidden background behind the objects in front of it; drop what the far limit cuts.
    bgv = np.isfinite(bg_depth) & (bg_depth > 0)
    both = filled & bgv & fgv
    # Behind the deepest object vertex around (3x3): an object face between two of its pixels
    # (e.g. across a step of the object) can then never be behind a hidden background face.
    fg_max = cv2.dilate(np.where(fgv, fg_depth, 0.0).astype(np.float32), np.ones((3, 3), np.uint8))
    bg_depth[both] = np.maximum(bg_depth[both], fg_max[both] * (1.0 + params.behind_margin))
    if params.far_limit is not None:
        bgv &= bg_depth <= params.far_limit
        fgv &= fg_depth <= params.far_limit
    bg_depth[~bgv] = np.nan
    fg_depth[~fgv] = np.nan

    # Only *hidden* completed background (an object vertex in front of it) takes its
    # row neighbour's label/uv and light id 0; completed vertices nothing covers (background
    # in U, invalid-depth islands) are visible and keep their own pixel's attributes.
    hidden = filled & fgv
    visible_fill = filled & ~fgv
    bg_src = np.where(visible_fill, np.arange(H * W).reshape(H, W), bg_src)
    bg_light = np.where(hidden, 0, light_ids).astype(np.int32)
    bg_src = np.where(bgv, bg_src, -1)
    # Depth steps left inside a sheet: cut and closed by walls (no stretched face, no hole).
    t = time.perf_counter()
    bg32, fg32 = bg_depth.astype(np.float32), fg_depth.astype(np.float32)
    if params.step_cut is not None:
        if normals is not None and np.shape(normals) != (H, W, 3):
            raise NpsimInputError(f"normals must be HxWx3 of shape {(H, W, 3)}, got {np.shape(normals)}")
        # Hidden background (an object in front) is the row-wise completion: its row-to-row
        # differences are interpolation, not scene steps, and no camera ray sees them -- never cut
        # where one object covers all around. Along silhouettes (and between two objects) a sliver
        # of it shows; nobody measured its orientation (the normals there are the object's): no
        # grazing allowance on that band.
        k3 = np.ones((3, 3), np.uint8)
        o = np.where(fgv, obj, -1).astype(np.float32)
        interior = fgv & (cv2.erode(o, k3) == cv2.dilate(o, k3))     # 3x3 all behind one object
        band = fgv & ~interior
        bg_normals = None if normals is None else np.where(fgv[..., None], np.nan, normals)
        bg_label = labels.ravel()[np.clip(bg_src, 0, None)].reshape(H, W)
        cap = params.step_cut_grazing / params.step_cut
        steps = tuple(step_faces(d_, g_, params.step_cut, partial(slant_at, d_, intrinsics, normals=n_,
                                                                    strict=strict, max_slant=cap), surface, uncut,
                                 params.extend_edges)
                      for d_, g_, n_, strict, surface, uncut in ((bg32, None, bg_normals, band, bg_label, interior),
                                                                 (fg32, obj, normals, None, labels, None)))
    else:
        steps = (StepFaces.empty((H, W)), StepFaces.empty((H, W)))
    tm["steps"] = time.perf_counter() - t
    layers = SheetLayers(background_depth=bg32, background_source=bg_src,
                         background_light=bg_light, foreground_depth=fg32, objects=obj,
                         object_classes=obj_class, labels=labels, light_ids=light_ids, steps=steps,
                         background_hidden=hidden)
    counts = {"uncertain_pixels": int(U.sum()), "deleted_vertices": int((usable & U).sum()),
              "background_completed_rows": n_row, "background_completed_cols": n_col,
              "foreground_completed": int(fg_filled.sum()), "kept_consistent": n_kept, "objects": len(obj_class),
              "cut_sides": steps[0].cut + steps[1].cut, "wall_faces": steps[0].n_walls + steps[1].n_walls}
    return layers, counts


def replaced_grid_faces(grid: MeshPart, layers: "SheetLayers", tol: float = 0.01) -> np.ndarray:
    """(F,) mask of the faces of a full-resolution grid mesh that the post-processed sheets replace.

    A grid face is replaced when its pixels belong to different sheets (an object and the
    background, two objects), when it lies in a quad that holds a depth step of its sheet
    (cut and walled, :mod:`.steps`), or when the kernel moved one of its vertices by more
    than ``tol`` (relative; the thesis rule replaces U vertices by completed depth).
    """
    H, W = layers.shape
    px = np.rint(grid.pixel).astype(np.int64)
    flat = px[:, 1] * W + px[:, 0]
    fd, bd = layers.foreground_depth.ravel()[flat], layers.background_depth.ravel()[flat]
    on_fg = np.isfinite(fd)
    sheet = np.where(on_fg, layers.objects.ravel()[flat], 0)
    z = np.where(on_fg, fd, bd).astype(np.float64)
    zg = grid.vertices[:, 2].astype(np.float64)
    with np.errstate(invalid="ignore"):
        moved = ~(np.abs(z - zg) <= tol * zg)
    f = grid.faces
    s = sheet[f]
    differ = (s[:, 0] != s[:, 1]) | (s[:, 1] != s[:, 2])
    q = px[f, 1].min(1) * (W - 1) + px[f, 0].min(1)
    mixed = np.where(s[:, 0] > 0, layers.step(1).mixed.ravel()[q], layers.step(0).mixed.ravel()[q])
    return differ | mixed | moved[f].any(1)


@dataclass
class SheetLayers:
    """The post-processed sheets as per-pixel layers (what the triangulators and the reducer consume).

    Attributes
    ----------
    background_depth : (H, W) float32
        Depth of the background vertex at each pixel, NaN where none.
    background_source : (H, W) int64
        Flat pixel index whose label and uv the background vertex takes (itself, or the
        nearer row neighbour for hidden completed vertices); -1 where none.
    background_light : (H, W) int32
        Light id of the background vertex (0 for hidden completed vertices).
    foreground_depth : (H, W) float32
        Depth of the foreground vertex at each pixel, NaN where none.
    objects : (H, W) int32
        Object id per pixel (0 = none); object k is ``mesh.parts[k]``.
    object_classes : list[int]
        labelId of object k at index k-1.
    labels, light_ids : (H, W)
        The input label and light maps.
    steps : tuple of StepFaces
        (background, foreground) depth steps cut inside the sheets, their mixed quads
        triangulated with walls (:mod:`.steps`); empty = no cuts. Face vertex ids are
        "extended": ``< H*W`` a layer's pixel vertex, ``H*W + k`` extra vertex ``k`` of that layer.
    """

    background_depth: np.ndarray
    background_source: np.ndarray
    background_light: np.ndarray
    foreground_depth: np.ndarray
    objects: np.ndarray
    object_classes: list
    labels: np.ndarray
    light_ids: np.ndarray
    steps: tuple = ()
    #: (H, W) bool: completed background vertices behind an object (their light id is 0);
    #: None: where a foreground vertex is in front of a background one.
    background_hidden: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return self.background_depth.shape

    def with_lights(self, light_ids: np.ndarray | None) -> "SheetLayers":
        """These sheets with the light instance map ``light_ids`` ((H, W) int, 0 = none; None: no
        lights): foreground and visible background vertices take their pixel's id, background
        completed behind an object 0 (the light is on the object in front). The geometry does not
        depend on the lights; only the merge keys of a reduction (:mod:`.reduce`) and the ids do."""
        H, W = self.shape
        lid = light_id_map(light_ids, (H, W))
        hidden = (self.background_hidden if self.background_hidden is not None
                  else np.isfinite(self.foreground_depth) & np.isfinite(self.background_depth))
        return replace(self, light_ids=lid, background_light=np.where(hidden, 0, lid).astype(np.int32))

    def step(self, layer: int) -> StepFaces:
        """Depth steps of layer 0 (background) or 1 (foreground)."""
        if len(self.steps) > layer and self.steps[layer] is not None:
            return self.steps[layer]
        return StepFaces.empty(self.shape)

    def background_key(self) -> np.ndarray:
        """Per-pixel merge key of the background sheet: (label, light id) of each vertex, -1 where none."""
        H, W = self.shape
        src = self.background_source.ravel()
        lab = self.labels.ravel()[np.clip(src, 0, None)].astype(np.int64)
        key = (lab << 32) | (self.background_light.ravel().astype(np.int64) & 0xFFFFFFFF)
        return np.where(src >= 0, key, -1).reshape(H, W)

    def foreground_key(self) -> np.ndarray:
        """Per-pixel merge key of the foreground sheets: (object, label, light id), -1 where none."""
        ok = np.isfinite(self.foreground_depth)
        key = ((self.objects.astype(np.int64) << 40) | (self.labels.astype(np.int64) << 32)
               | (self.light_ids.astype(np.int64) & 0xFFFFFFFF))
        return np.where(ok, key, -1)

    def node_source(self, layer: int, ids: np.ndarray) -> np.ndarray:
        """Flat pixel of each extended vertex id: the pixel itself, or the corner an extra vertex continues."""
        HW = self.labels.size
        ids = np.asarray(ids, dtype=np.int64)
        src = self.step(layer).source
        return np.where(ids < HW, ids, src[np.clip(ids - HW, 0, max(len(src) - 1, 0))] if len(src) else ids)

    def full_faces(self, intr: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
        """Full-resolution triangulation: (background faces, foreground faces) in extended vertex ids."""
        H, W = self.shape
        rays = intr.pixel_rays(np.float32)
        flat = np.arange(H * W, dtype=np.int64).reshape(H, W)
        out = []
        for layer, (d, group) in enumerate(((self.background_depth, None), (self.foreground_depth, self.objects))):
            ok = np.isfinite(d)
            pts = rays * np.where(ok, d, 0.0)[..., None]
            st = self.step(layer)
            out.append(np.concatenate([quad_faces(np.where(ok, flat, -1), pts, group, cells=~st.mixed), st.faces]))
        return out[0], out[1]

    def _vertices(self, layer: int, nodes: np.ndarray, intr: Intrinsics):
        """Positions and attributes of extended vertex ids ``nodes`` of a layer.

        Returns (vertices, pixel position, uv, label, light id, corner pixel). An extra vertex
        takes its corner's label and light id, and the corner's texture coordinate moved by its
        offset.
        """
        H, W = self.shape
        HW = H * W
        st = self.step(layer)
        ispx = nodes < HW
        k = np.clip(nodes - HW, 0, None)
        corner = np.where(ispx, nodes, st.source[np.minimum(k, len(st.source) - 1)] if len(st.source) else nodes)
        cv_, cu_ = np.divmod(corner, W)
        pos = np.stack([cu_, cv_], 1).astype(np.float64)
        if len(st.source) and not ispx.all():
            pos[~ispx] = st.position[k[~ispx]]
        if layer == 0:
            depth = self.background_depth.ravel()
            label_src = self.background_source.ravel()[corner]
            light = self.background_light.ravel()[corner]
        else:
            depth = self.foreground_depth.ravel()
            label_src = corner
            light = self.light_ids.ravel()[corner]
        z = np.where(ispx, depth[np.minimum(nodes, HW - 1)],
                     st.depth[np.minimum(k, len(st.depth) - 1)] if len(st.depth) else 0.0)
        verts = (intr.rays_at(pos, np.float64) * z[:, None]).astype(np.float32)
        sv, su = np.divmod(label_src, W)
        uv = pixel_uv(su + (pos[:, 0] - cu_), sv + (pos[:, 1] - cv_), W, H)
        return (verts, pos.astype(np.float32), uv, self.labels.ravel()[label_src].astype(np.uint8), light.astype(np.int32),
                corner.astype(np.int32 if H * W < 2**31 else np.int64))

    def full_parts(self, intr: Intrinsics) -> list[MeshPart]:
        """Full-resolution parts. Fast path for the big background sheet: compact vertex
        numbering on the grid (no index remapping); its isolated pixels (no face) stay as
        unreferenced vertices. Objects go through :meth:`parts`."""
        H, W = self.shape
        rays = intr.pixel_rays(np.float32)
        d = self.background_depth
        ok = np.isfinite(d)
        n = int(ok.sum())
        st = self.step(0)
        ne = len(st.depth)
        index = np.full((H, W), -1, dtype=np.int32 if n + ne < 2**31 else np.int64)
        index[ok] = np.arange(n, dtype=index.dtype)
        pts = rays * np.where(ok, d, 0.0)[..., None]
        faces = quad_faces(index, pts, cells=~st.mixed)
        src = self.background_source[ok]
        sv, su = np.divmod(src, W)
        vv, uu = np.nonzero(ok)
        verts, pix, uv = pts[ok], np.stack([uu, vv], 1).astype(np.float32), pixel_uv(su, sv, W, H)
        label = self.labels.ravel()[src].astype(np.uint8)
        light = self.background_light[ok].astype(np.int32)
        corner = np.flatnonzero(ok.ravel()).astype(np.int32 if H * W < 2**31 else np.int64)
        if ne:
            HW = H * W
            sf = st.faces
            faces = np.concatenate([faces, np.where(sf < HW, index.ravel()[np.minimum(sf, HW - 1)], n + sf - HW)])
            ev, ep, euv, el, eli, ec = self._vertices(0, HW + np.arange(ne), intr)
            verts, pix, uv = np.concatenate([verts, ev]), np.concatenate([pix, ep]), np.concatenate([uv, euv])
            label, light = np.concatenate([label, el]), np.concatenate([light, eli])
            corner = np.concatenate([corner, ec])
        faces = faces.astype(_index_dtype(len(verts)), copy=False)
        bg = MeshPart(name="background", vertices=verts, faces=faces, uv=uv,
                      pixel=pix, label=label, light_id=light, foreground=False, source=corner)
        fd = self.foreground_depth
        okf = np.isfinite(fd)
        flat = np.arange(H * W, dtype=np.int64).reshape(H, W)
        sf = self.step(1)
        fg_faces = np.concatenate([quad_faces(np.where(okf, flat, -1), rays * np.where(okf, fd, 0.0)[..., None],
                                              self.objects, cells=~sf.mixed), sf.faces])
        return [bg] + self.parts(intr, np.zeros((0, 3), dtype=np.int64), fg_faces)[1:]

    def parts(self, intr: Intrinsics, bg_faces: np.ndarray, fg_faces: np.ndarray) -> list[MeshPart]:
        """Mesh parts from faces given as extended vertex ids into the background / foreground layers.

        Only referenced vertices are kept; part k (k >= 1) is object k, possibly empty.
        """
        H, W = self.shape
        table = cityscapes()

        lookup = np.full(H * W + max(len(self.step(0).depth), len(self.step(1).depth)), -1, dtype=np.int64)

        def build(name, faces, layer, fg):
            if faces.size * 8 < H * W:       # small part: sorting its indices is cheaper than a full mask
                nodes = np.unique(faces)
            else:
                used = np.zeros(len(lookup), dtype=bool)
                used[faces.ravel()] = True
                nodes = np.flatnonzero(used)
            lookup[nodes] = np.arange(len(nodes))
            verts, pix, uv, label, light, corner = self._vertices(layer, nodes, intr)
            faces = lookup[faces].reshape(-1, 3).astype(_index_dtype(len(verts)))
            return MeshPart(name=name, vertices=verts, faces=faces, uv=uv, pixel=pix, label=label, light_id=light,
                            foreground=fg, source=corner)

        parts = [build("background", bg_faces, 0, False)]
        n_obj = len(self.object_classes)
        if n_obj:
            fo = self.objects.ravel()[self.node_source(1, fg_faces[:, 0])] if len(fg_faces) else np.zeros(0, np.int64)
            order = np.argsort(fo, kind="stable")
            fg_faces, fo = fg_faces[order], fo[order]
            starts = np.searchsorted(fo, np.arange(1, n_obj + 2))
            counter: dict[int, int] = {}
            for k in range(n_obj):
                c = self.object_classes[k]
                counter[c] = counter.get(c, 0) + 1
                cname = table.by_id(c).name.replace(" ", "_")
                parts.append(build(f"{cname}_{counter[c]}", fg_faces[starts[k]:starts[k + 1]], 1, True))
        return parts
