"""The semantic pop-up prior: depth and normals from labels and the camera pose alone.

Model (in the spirit of Hoiem et al.'s "Automatic Photo Pop-up")
----------------------------------------------------------------
* The camera stands ``h`` metres above a flat ground plane, pitched down by
  ``theta``. In the camera frame (x right, y down, z forward) the world's down
  direction is ``g = (0, cos theta, sin theta)`` and the level forward direction
  ``f = (0, -sin theta, cos theta)``; the ground is ``{P : g.P = h}``, so a pixel
  ray ``r = K^-1 (u, v, 1)`` meets it at z-depth ``h / (g.r)`` (the horizon row
  is ``cy - fy tan theta``). Ground classes (``cityscapes().ground_ids``: road,
  sidewalk, parking, rail track, terrain, ground) lie on it; its normal is
  ``-g`` (toward the camera).
* Every other labelled region is split into segments (4-connected components
  per class). A segment *stands* on the ground where its bottom boundary
  touches ground pixels (or the image's bottom edge, beyond which the ground
  continues). The contact points are placed on the ground plane (at the
  boundary, half a pixel below the segment) and expressed in ground-plane
  coordinates ``(a, b) = (P.x, P.f)``; a line fitted to them (PCA, twice
  trimmed of outliers) defines a vertical plane through the contact line. A
  contact shorter than ``min_contact_extent`` metres, or a line through the
  camera, gives a fronto-parallel vertical plane (normal ``-f``) at the
  contacts' median distance; narrow things (``fronto_ids``: poles, signs,
  people, bikes) are always fronto-parallel. Every pixel of the segment gets
  its plane's depth along its ray, clamped to ``[min_depth, max_depth]``.
* A segment is placed from the ground alone when its ground contacts are at
  least ``ground_fraction`` of its bottom boundary's support, or give a
  successful line fit. Otherwise it rests (also) on other segments (a sign on
  a pole, a facade behind parked cars, a tree crown over a car): in rounds,
  once at least half of its support is placed, it is fitted to the ground
  contacts plus the 3D points of the placed pixels below it -- facades
  (``facade_ids``) by a line (ignoring ``thin_ids``/``fronto_ids`` supports in
  front of them when there is anything else), everything else
  fronto-parallel at its nearest support. What is still unplaced afterwards
  (regions floating in sky) takes the depth of its nearest placed pixel and a
  fronto-parallel normal.
* Sky, ego vehicle, rectification border and out-of-roi pixels are invalid (NaN).

All work is vectorised over the image; the only Python loops are over
segments (fitting a line to each one's contact points) and placement rounds.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

import numpy as np
from scipy import ndimage

from ..errors import NpsimInputError
from ..labels import cityscapes
from ..scene import Scene
from . import GeometryEstimate, invalid_label_mask

#: labelIds never given depth: ego vehicle, rectification border, out of roi, sky.
DEFAULT_INVALID_IDS = (1, 2, 3, 23)
#: Extended planar structures (building, wall, fence, guard rail, bridge, tunnel): when they stand
#: on other segments (a facade behind parked cars) the supports' line still gives their facing.
DEFAULT_FACADE_IDS = (11, 12, 13, 14, 15, 16)
#: Narrow things whose contact line says nothing about their facing (pole, polegroup, traffic
#: light, traffic sign, person, rider, motorcycle, bicycle): always fronto-parallel.
DEFAULT_FRONTO_IDS = (17, 18, 19, 20, 24, 25, 32, 33)


@dataclass(frozen=True)
class PopupParams:
    """Parameters of the semantic pop-up prior.

    Attributes
    ----------
    camera_height : float or None
        Camera height above the ground in metres; ``None`` uses ``scene.camera_height``.
    camera_pitch : float or None
        Downward pitch in radians; ``None`` uses ``scene.camera_pitch``.
    min_depth, max_depth : float
        Clamp range of the depth in metres (far ground near the horizon and
        grazing vertical planes are clamped to ``max_depth``).
    min_contact_extent : float
        Contact lines shorter than this (metres, along the fitted line) are too
        short to give a facing; the segment becomes fronto-parallel.
    trim_residual : float
        Contact points farther than this (metres) from the fitted line (and
        than 2.5x the median residual) are dropped before refitting.
    invalid_ids : tuple of int
        labelIds that get no depth (NaN).
    facade_ids : tuple of int
        labelIds whose segments, when resting on other segments rather than on
        the ground, still take their facing from a line fitted to the support;
        every other class resting on a segment (a tree crown over a car, a sign
        on its pole) becomes fronto-parallel at the nearest support.
    max_rounds : int
        Placement rounds for segments standing on other segments.
    fallback_depth : float
        Depth (m) used only when nothing in the image can be placed (no ground).
    """

    camera_height: float | None = None
    camera_pitch: float | None = None
    min_depth: float = 0.5
    max_depth: float = 300.0
    min_contact_extent: float = 0.5
    trim_residual: float = 0.5
    invalid_ids: tuple[int, ...] = DEFAULT_INVALID_IDS
    facade_ids: tuple[int, ...] = DEFAULT_FACADE_IDS
    fronto_ids: tuple[int, ...] = DEFAULT_FRONTO_IDS
    thin_ids: tuple[int, ...] = (21,)
    ground_fraction: float = 0.5
    max_rounds: int = 32
    fallback_depth: float = 20.0

    def __post_init__(self) -> None:
        if self.camera_height is not None and not (math.isfinite(self.camera_height) and self.camera_height > 0):
            raise NpsimInputError(f"PopupParams.camera_height must be > 0 metres, got {self.camera_height}")
        if self.camera_pitch is not None and not (math.isfinite(self.camera_pitch)
                                                  and abs(self.camera_pitch) < math.pi / 2 - 0.05):
            raise NpsimInputError(f"PopupParams.camera_pitch must be a finite angle in radians well inside "
                                  f"(-pi/2, pi/2), got {self.camera_pitch}")
        if not (0 < self.min_depth < self.max_depth):
            raise NpsimInputError(f"PopupParams needs 0 < min_depth < max_depth, got {self.min_depth}, "
                                  f"{self.max_depth}")


def ground_frame(pitch: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Down ``g``, level-forward ``f`` and right ``e`` unit vectors in the camera frame for ``pitch`` (rad, down > 0)."""
    c, s = math.cos(pitch), math.sin(pitch)
    return np.array([0.0, c, s]), np.array([0.0, -s, c]), np.array([1.0, 0.0, 0.0])


def ground_plane_depth(intr, height: float, pitch: float, *, v_offset: float = 0.0,
                       max_depth: float = 300.0) -> np.ndarray:
    """HxW z-depth (m) of the ground plane along every pixel ray (``max_depth`` at and above the horizon).

    ``v_offset`` shifts the rows (0.5 = the boundary below each pixel).
    """
    g, _, _ = ground_frame(pitch)
    yv = (np.arange(intr.height, dtype=np.float64) + v_offset - intr.cy) / intr.fy
    denom = yv * g[1] + g[2]  # g.r for r = (x', y', 1); independent of the column
    with np.errstate(divide="ignore"):
        z = np.where(denom > 0, height / np.where(denom > 0, denom, 1.0), np.inf)
    z = np.minimum(z, max_depth)
    return np.broadcast_to(z[:, None], (intr.height, intr.width))


def _fit_vertical_plane(a: np.ndarray, b: np.ndarray, e: np.ndarray, f: np.ndarray,
                        p: PopupParams) -> tuple[np.ndarray, float, bool]:
    """Vertical plane (unit normal toward the camera, offset c = n.P < 0) through contacts (a, b).

    Returns ``(n, c, fitted)``; ``fitted`` is False for the fronto-parallel fallback.
    """
    keep = np.ones(a.size, dtype=bool)
    m = None
    for _ in range(3):
        if keep.sum() < 2:
            m = None
            break
        pa, pb = a[keep], b[keep]
        ca, cb = pa.mean(), pb.mean()
        cov = np.cov(np.stack([pa - ca, pb - cb]))
        w, vec = np.linalg.eigh(cov)
        d = vec[:, 1]  # principal direction of the contact line in (a, b)
        m = np.array([-d[1], d[0]])
        c = m[0] * ca + m[1] * cb
        r = np.abs(m[0] * a + m[1] * b - c)
        new_keep = r <= max(p.trim_residual, 2.5 * float(np.median(r[keep])))
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
    if m is not None and keep.sum() >= 2:
        proj = d[0] * a[keep] + d[1] * b[keep]
        if np.ptp(proj) >= p.min_contact_extent and abs(c) > 1e-3:
            n = m[0] * e + m[1] * f
            if c > 0:  # orient toward the camera: n.P < 0 on the plane
                n, c = -n, -c
            return n, float(c), True
    # Fronto-parallel vertical plane: normal -f, at the contacts' median forward distance.
    return -f, -float(np.median(b)), False


def _plane_depth(rays: np.ndarray, planes: np.ndarray, seg: np.ndarray, mask: np.ndarray,
                 p: PopupParams) -> np.ndarray:
    """z-depth on ``mask`` pixels of the vertical plane of their segment (``planes[seg] = (nx, ny, nz, c)``)."""
    pl = planes[seg[mask]]
    nr = np.einsum("ij,ij->i", rays[mask], pl[:, :3])
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(nr < -1e-9, pl[:, 3] / nr, p.max_depth)
    return np.clip(z, p.min_depth, p.max_depth)


def segment_map(labels: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, int]:
    """Connected components (4-connected) of ``mask`` per label value -> (int32 map, 0 = none; count)."""
    seg = np.zeros(labels.shape, dtype=np.int32)
    count = 0
    for cls in np.unique(labels[mask]):
        comp, n = ndimage.label(mask & (labels == cls))
        seg[comp > 0] = comp[comp > 0] + count
        count += n
    return seg, count


def estimate_popup(scene: Scene, params: PopupParams | None = None) -> GeometryEstimate:
    """Semantic pop-up depth and normals for ``scene`` (see the module docstring)."""
    p = params or PopupParams()
    t0 = time.perf_counter()
    intr = scene.intrinsics
    H, W = scene.height, scene.width
    h = float(p.camera_height if p.camera_height is not None else scene.camera_height)
    pitch = float(p.camera_pitch if p.camera_pitch is not None else scene.camera_pitch)
    g, f, e = ground_frame(pitch)
    rays = intr.pixel_rays(np.float64)

    labels = scene.labels
    invalid = invalid_label_mask(labels, p.invalid_ids)
    ground = cityscapes().lut("ground").astype(bool)[labels] & ~invalid
    vertical = ~ground & ~invalid

    depth = np.full((H, W), np.nan, dtype=np.float64)
    normals = np.full((H, W, 3), np.nan, dtype=np.float64)
    depth[ground] = np.clip(ground_plane_depth(intr, h, pitch, max_depth=p.max_depth)[ground],
                            p.min_depth, p.max_depth)
    normals[ground] = -g

    seg, nseg = segment_map(labels, vertical)
    seg_label = np.zeros(nseg + 1, dtype=np.int64)
    seg_label[seg[vertical]] = labels[vertical]
    lut = np.zeros(256, dtype=bool)
    lut[list(p.facade_ids)] = True
    seg_facade = lut[seg_label]
    lut[:] = False
    lut[list(p.fronto_ids)] = True
    seg_fronto = lut[seg_label]
    seg_fronto[0] = False
    lut[list(p.thin_ids)] = True
    seg_thin = lut[seg_label]
    seg_thin[0] = False
    planes = np.zeros((nseg + 1, 4), dtype=np.float64)
    placed = np.zeros(nseg + 1, dtype=bool)
    fitted = np.zeros(nseg + 1, dtype=bool)
    how = np.zeros(nseg + 1, dtype=np.int8)  # 1 stands on the ground, 2 rests (partly) on segments

    # Bottom boundary of every segment, and what it rests on.
    seg_below = np.zeros_like(seg)
    seg_below[:-1] = seg[1:]
    bottom = vertical & (seg_below != seg)
    below_ground = np.zeros((H, W), dtype=bool)
    below_ground[:-1] = ground[1:]
    below_ground[-1] = True  # the ground continues below the frame
    g_sup = bottom & below_ground
    o_sup = bottom & (seg_below > 0)
    n_ground = np.bincount(seg[g_sup], minlength=nseg + 1)
    n_total = n_ground + np.bincount(seg[o_sup], minlength=nseg + 1)
    # Support points (camera frame, m): ground contacts on the plane at the boundary half a pixel
    # below the segment; resting points filled in once the segment below is placed.
    support = np.full((H, W, 3), np.nan)
    zc = ground_plane_depth(intr, h, pitch, v_offset=0.5, max_depth=p.max_depth)
    zc = np.clip(zc, p.min_depth, p.max_depth)
    vs, us = np.nonzero(g_sup)
    support[vs, us] = np.stack([(us - intr.cx) / intr.fx, (vs + 0.5 - intr.cy) / intr.fy,
                                np.ones(vs.size)], axis=1) * zc[vs, us][:, None]

    # --- segments standing on the ground: mostly (any facing), or along a contact line long enough
    #     to give the facing by itself (a facade behind parked cars with a gap between them)
    mostly = (n_ground > 0) & (n_ground >= p.ground_fraction * n_total)
    vs, us = np.nonzero(g_sup)
    _fit_groups(seg[vs, us], support[vs, us], planes, placed, fitted, how, 1, e, f, p,
                mode=np.where(seg_fronto, 0, 1), only_line_fits=~mostly)

    # --- segments resting (also) on other segments, in rounds as their supports get placed
    rounds = 0
    drawn = np.zeros(nseg + 1, dtype=bool)  # segments whose pixels already have their plane depth
    mode_rest = np.where(seg_facade, 1, 2)  # facades: line fit; others: fronto at the nearest support
    for rounds in range(1, p.max_rounds + 1):
        cur = vertical & (placed & ~drawn)[seg]  # only segments placed since the last round
        if cur.any():
            depth[cur] = _plane_depth(rays, planes, seg, cur, p)
            normals[cur] = planes[seg[cur], :3]
        drawn |= placed
        known = g_sup | (o_sup & placed[seg_below])
        n_known = np.bincount(seg[known], minlength=nseg + 1)
        waiting = ~placed & (n_known > 0)
        waiting[0] = False
        ready = waiting & (n_known >= 0.5 * n_total)
        if not ready.any():
            ready = waiting  # stalled (supports in a cycle): place with what is known
        if not ready.any():
            break
        rest_px = o_sup & placed[seg_below] & ready[seg]
        vs, us = np.nonzero(rest_px)
        support[vs, us] = rays[vs + 1, us] * depth[vs + 1, us][:, None]
        use = known & ready[seg]
        # A facade's line is fitted to what it stands behind (ground, cars), not to poles or
        # trees in front of it -- unless those are all it has.
        thin = use & o_sup & seg_thin[seg_below] & seg_facade[seg]
        n_solid = np.bincount(seg[use & ~thin], minlength=nseg + 1)
        use &= ~(thin & (n_solid[seg] > 0))
        vs, us = np.nonzero(use)
        _fit_groups(seg[vs, us], support[vs, us], planes, placed, fitted, how, 2, e, f, p, mode=mode_rest)
    cur = vertical & (placed & ~drawn)[seg]
    depth[cur] = _plane_depth(rays, planes, seg, cur, p)
    normals[cur] = planes[seg[cur], :3]

    # --- whatever is still unplaced: nearest placed depth, fronto-parallel normal
    rest = vertical & ~placed[seg]
    known = np.isfinite(depth)
    notes = []
    if rest.any():
        if known.any():
            _, (iy, ix) = ndimage.distance_transform_edt(~known, return_indices=True)
            depth[rest] = depth[iy[rest], ix[rest]]
        else:
            depth[rest] = p.fallback_depth
            notes.append(f"no ground or placed segment: unplaced regions set to {p.fallback_depth} m")
        normals[rest] = -f

    seg_ids = np.arange(1, nseg + 1)
    info = {"params": asdict(p), "camera_height_m": h, "camera_pitch_rad": pitch,
            "horizon_row": float(intr.cy - intr.fy * math.tan(pitch)),
            "segments": int(nseg), "on_ground": int(np.sum(how[seg_ids] == 1)),
            "on_segments": int(np.sum(how[seg_ids] == 2)),
            "unplaced_pixels": int(rest.sum()), "line_fits": int(fitted[seg_ids].sum()), "rounds": int(rounds),
            "seconds": round(time.perf_counter() - t0, 4)}
    if notes:
        info["notes"] = notes
    return GeometryEstimate(depth=depth.astype(np.float32), normals=normals.astype(np.float32), method="popup",
                            info=info)


def _fit_groups(seg_ids: np.ndarray, pts: np.ndarray, planes: np.ndarray, placed: np.ndarray, fitted: np.ndarray,
                how: np.ndarray, how_code: int, e: np.ndarray, f: np.ndarray, p: PopupParams,
                mode: np.ndarray, only_line_fits: np.ndarray | None = None) -> None:
    """Fit one vertical plane per segment to its support points ``pts`` (N, 3) in place.

    ``mode[s]``: 1 = vertical plane through the line fitted to the support
    (falls back to fronto-parallel when the line is too short); 0 =
    fronto-parallel at the support's median forward distance; 2 = fronto-parallel
    at the support points within 25% of the nearest one: a segment resting on
    several surfaces (a sign over its pole and the facade behind) is attached to
    the nearest, since whatever is farther is seen past its free bottom edge.
    Segments with ``only_line_fits[s]`` are left unplaced unless a line fit succeeds.
    """
    if seg_ids.size == 0:
        return
    ok = np.isfinite(pts).all(axis=1)
    seg_ids, pts = seg_ids[ok], pts[ok]
    order = np.argsort(seg_ids, kind="stable")
    seg_ids, pts = seg_ids[order], pts[order]
    a = pts @ e
    b = pts @ f
    uniq, start = np.unique(seg_ids, return_index=True)
    stops = np.append(start[1:], seg_ids.size)
    for s, i0, i1 in zip(uniq, start, stops):
        if placed[s]:
            continue
        sa, sb = a[i0:i1], b[i0:i1]
        if mode[s] == 1:
            n, c, ok_fit = _fit_vertical_plane(sa, sb, e, f, p)
            if only_line_fits is not None and only_line_fits[s] and not ok_fit:
                continue
        elif only_line_fits is not None and only_line_fits[s]:
            continue
        else:
            if mode[s] == 2:
                z = pts[i0:i1, 2]
                sb = sb[z <= 1.25 * z.min()]
            n, c, ok_fit = -f, -float(np.median(sb)), False
        planes[s, :3], planes[s, 3] = n, c
        placed[s], fitted[s], how[s] = True, ok_fit, how_code
