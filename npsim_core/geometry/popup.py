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

Facades on their contact line (``facades="contact"``, the default; docs/geometry.md)
-----------------------------------------------------------------------------------
The model above gives a facade one plane, fitted to whatever it stands on; a street
wall that recedes, hides its foot behind parked cars or turns a corner is then off by
2-3x. Instead, ``contact_ids`` segments (building, wall, fence, guard rail) are placed
first, column by column:

* Per column, the facade's lowest pixel either touches ground (a *visible* contact at
  the boundary row) or stands above something in front of it, so its foot is *hidden*
  somewhere between that pixel and the next ground row below.
* A vertical plane's foot is a straight line in the image, so the visible contacts of a
  segment (sorted by column) are split into pieces that one image line each fits within
  ``contact_tol`` pixels (recursive least-squares split, then merge) -- a corner building
  gets two pieces. Image lines map to ground lines through the ground homography, so
  each piece is a vertical plane; the rows' half-pixel quantisation stays uniform there.
* A piece that a line through the street's vanishing point fits better than a level
  line is a facade along the street (its line is snapped to that point); the others
  face the camera or are oblique. The vanishing point is on the horizon row, at ``cx``
  or where the long receding pieces meet it (``vanishing``).
* Per side of the street, the receding pieces give a *street line*: their lateral
  offset (weighted median, each weighted by its precision at half a row). A side whose
  facades show no foot gets the offset behind the feet of what hides them, by the other
  side's setback or ``hidden_setback``.
* Hidden columns are filled: between two pieces up to where their lines cross (a corner)
  or via the street line, beyond the end pieces by extending a receding piece or by
  turning from a non-receding piece onto the street line where they cross; a segment
  without any visible contact follows its side's street line. Every hidden row is
  finally clamped between the facade's lowest pixel and the ground below its occluder.
* Each column gets its own plane (normal from its line, offset through its contact
  point); every pixel gets that plane's depth along its ray.

Other classes keep the model above, with two changes in this mode: a contact that a
level image line fits is fronto-parallel (a trunk or post, whose plan-view scatter is
only row quantisation), and a tree crown whose trunk is hidden stands half way between
the nearest support (the car in front) and the facade behind. ``sidewalk_height`` raises
the sidewalk plane (and whatever stands on it) above the road.

Hidden contacts (docs/geometry.md, "Hidden contacts"; default, ``facades="contact"``)
-------------------------------------------------------------------------------------
* Cars (``car_ids``) stand on their own contact lines after the facades, by the same
  per-column model, their visible contacts replaced by the lower hull of each run of
  visible columns (``car_hull``; else the running max over ``car_envelope`` x the width):
  the wheels touch the ground, the body's underside (0.3 m up) would put the car a third
  too far.
* A contact piece wholly beyond ``vp_max_distance`` (buildings across a square) is not
  snapped to the vanishing point and gives no street line; feet more than 15 m off the
  street's axis give no hidden-foot street line either.
* Tree crowns resting on other segments with no trunk in sight (``crowns="columns"``) get
  a depth per column from their lowest pixel: no farther than what is below it and no
  farther than a lower edge ``crown_base`` m up at that row allows (less ``crown_radius``);
  a run of columns whose lower edge stays level is one crown (median of its columns); the
  pixel takes the geometric mean of that and its segment's own placement, and no less than
  a lower edge ``crown_min`` m up allows at the segment's lower edge.
* A crown segment that recedes along the street (``crowns="canopy"``: a row of street
  trees, or its near end cut by the frame) is a slab: each pixel takes the larger of the
  depths of the undersides' plane (``crown_base`` up) and of the inner faces' vertical
  plane (``crown_setback`` in from the street line, or the occluders' feet), no deeper than
  the street line (docs/geometry.md, "Canopy rows").
* A facade segment that shows no foot anywhere and is seen only under such a slab (a bus shelter
  behind a van, labelled building) stands no deeper than where the ray over its top edge enters the
  slab, when that is nearer than half its street-line depth and behind what hides its foot
  (``under_canopy``; docs/geometry.md, "Under a canopy").
* A foot beyond the far limit is placed at the near end of its row's range (visible) or
  half way between the limit and the ground below its occluder (hidden); the far limit
  is a last resort, counted in ``info["far_limit_pixels"]`` and noted.
* ``GeometryEstimate.confidence``: per pixel, how it was placed (ground 1, visible facade or
  car contact 0.9, on the ground 0.8, on other segments or a hidden facade or car foot 0.5,
  crown over an occluder 0.45 / by its lower edge 0.35 / in a canopy slab 0.4, a facade pulled
  under a canopy 0.35, nearest
  fill 0.2) divided
  by ``1 + (z / (h fy)) / 0.1`` (one row's relative depth step at that depth); 0.05 at
  the far limit; NaN where invalid.

All work is vectorised over the image; the only Python loops are over
segments (fitting lines to each one's contact points) and placement rounds.
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
#: Classes placed on their own contact line (building, wall, fence, guard rail) by ``facades="contact"``;
#: bridges and tunnels span the road, their bottom edge is no foot.
DEFAULT_CONTACT_IDS = (11, 12, 13, 14)
#: The ground class raised by ``sidewalk_height`` above the road (sidewalk).
SIDEWALK_ID = 8
#: A hidden-foot facade column seen under a canopy slab is pulled to where its top edge's ray enters the
#: slab only when that is nearer than this fraction of its depth (``PopupParams.under_canopy``): crowns and
#: the gaps between them are about as long, so a wall seen through a gap stands up to about twice as deep
#: as the entry (the far blocks near the vanishing point: 0.53-0.76 on the street variants; the bus
#: shelters behind vans: 0.37).
UNDER_CANOPY_RATIO = 0.5
#: Metres: a crown cut by the frame's top and side whose lower edge (at ``crown_base``) is nearer than
#: this is the near end of a row of street trees (``crowns="canopy"``).
NEAR_CROWN_M = 15.0


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
    facades : str
        ``"contact"`` (default): ``contact_ids`` segments stand on their own contact line,
        piecewise planes per column (docs/geometry.md, "Facades on their contact line");
        ``"flat"``: the earlier model, one line per segment fitted to whatever it stands on
        (with ``sidewalk_height=0`` it reproduces the earlier prior exactly).
    contact_ids : tuple of int
        labelIds placed on their contact line by ``facades="contact"``.
    sidewalk_height : float
        The sidewalk's surface lies this many metres above the road (kerb height); sidewalk
        pixels and everything standing on them use that plane. 0 = one ground plane.
    contact_tol : float
        Pixels (at 2048 columns, scaled with the width, at least 1) a contact may lie off its
        image line before the line is split into pieces.
    hidden_setback : float
        Metres from the feet of what hides a facade's base (parked cars' street side, mostly)
        to the facade, assumed when neither side of the street shows a facade's foot: a car's
        width plus a 3.5-4 m sidewalk (the synthetic street has 7.1 m; the earlier prior used 5 m).
    vp_max_distance : float or None
        Metres: a contact piece wholly farther than this (buildings across a square or crossing)
        is never snapped to the street's vanishing point nor gives a street line -- a level and a
        receding line fit it alike at that range. ``None``: any distance (the earlier prior).
    recede_angle : float
        Degrees: a contact piece that no line through the vanishing point fits within
        ``contact_tol`` (a ragged foot between shop-front crowds) still recedes along the street
        when its own line is within this angle of the street's direction; 0 = off.
    vanishing : str
        ``"auto"``: the street's vanishing column from the long receding contact lines (the
        principal point's column when fewer than two agree); ``"center"``: always ``cx``.
    car_ids : tuple of int
        labelIds placed after the facades on their own contact lines (``facades="contact"``), their
        visible contacts replaced by the lower envelope over ``car_envelope`` x the width (wheels);
        ``()`` keeps the earlier model for them.
    car_hull : bool
        Cars' visible contacts are replaced by the lower hull of each run of consecutive visible
        columns (the chain below every contact: the wheels touch the ground, the body's underside
        between them is seen 0.3 m up) instead of the running maximum over ``car_envelope``.
    crowns : str
        ``"canopy"`` (default): as ``"columns"``, then crown segments that recede along the street
        (a row of street trees) are placed per pixel between the plane of crown undersides and
        the vertical plane of their inner faces (docs/geometry.md, "Canopy"); ``"columns"``: tree
        crowns resting on other segments get a depth per column from what is below each column
        (docs/geometry.md, "Hidden contacts"); ``"segment"``: one fronto-parallel depth per crown
        segment (the earlier prior).
    crown_base : float
        Metres above the ground of a crown's lower edge where no trunk is seen (street trees
        clear pedestrians); a crown bottom seen against what is behind it is placed by it.
    crown_radius : float
        Metres from the far edge of a crown's underside (what ``crown_base`` places) to its front.
    crown_setback : float
        Metres from a side's street line (its facades) to the road-side face of a row of street-tree
        crowns (``crowns="canopy"``): a 4-5 m sidewalk, trunks 1-1.5 m from the kerb, crowns of
        2.5-3 m radius over the parking strip -- about where the parked cars' street side is
        (``hidden_setback``).
    crown_min : float
        Metres: the lowest a crown's underside hangs (street trees clear pedestrians). A crown pixel
        column whose lowest pixel is above the horizon stands no nearer than that height allows there
        (``crowns="columns"``/``"canopy"``: a lower bound over the per-column and segment placements, e.g.
        a tree across a square whose trunk hides behind a near parked car).
    under_canopy : bool
        A facade column whose foot is hidden and whose top edge is seen right under a canopy slab
        (``crowns="canopy"``) stands no deeper than where the ray over its top edge enters the slab --
        a farther wall would be hidden by the crowns there -- and no nearer than what hides its foot
        (a bus shelter behind a van; docs/geometry.md, "Under a canopy"). ``False``: the street line.
    canopy_span, canopy_rise : float
        A crown segment is a receding row (``crowns="canopy"``) when its columns above the horizon
        cover at least a tenth of the width, the outer half of them lies ``canopy_span`` times as far
        from the vanishing column as the inner half (medians; the row spans about that ratio in
        depth), and its lower edge rises toward the vanishing point by at least ``canopy_rise`` of
        what that ratio implies for an edge receding along the street (a single crown's is level).
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
    facades: str = "contact"
    contact_ids: tuple[int, ...] = DEFAULT_CONTACT_IDS
    sidewalk_height: float = 0.12
    contact_tol: float = 1.5
    hidden_setback: float = 6.0
    vp_max_distance: float | None = 60.0
    recede_angle: float = 10.0
    vanishing: str = "auto"
    crowns: str = "canopy"
    car_ids: tuple[int, ...] = (26,)
    car_envelope: float = 0.05
    car_hull: bool = True
    crown_base: float = 2.4
    crown_radius: float = 2.5
    crown_setback: float = 6.0
    crown_min: float = 2.0
    canopy_span: float = 1.4
    canopy_rise: float = 0.25
    under_canopy: bool = True

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
        if self.facades not in ("contact", "flat"):
            raise NpsimInputError(f"PopupParams.facades must be 'contact' or 'flat', got {self.facades!r}")
        if self.vanishing not in ("auto", "center"):
            raise NpsimInputError(f"PopupParams.vanishing must be 'auto' or 'center', got {self.vanishing!r}")
        for name in ("sidewalk_height", "hidden_setback"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise NpsimInputError(f"PopupParams.{name} must be >= 0 metres, got {v}")
        if self.camera_height is not None and self.sidewalk_height >= self.camera_height:
            raise NpsimInputError(f"PopupParams.sidewalk_height ({self.sidewalk_height} m) must be below the "
                                  f"camera ({self.camera_height} m)")
        if self.crowns not in ("canopy", "columns", "segment"):
            raise NpsimInputError(f"PopupParams.crowns must be 'canopy', 'columns' or 'segment', got {self.crowns!r}")
        if not (math.isfinite(self.canopy_rise) and self.canopy_rise >= 0):
            raise NpsimInputError(f"PopupParams.canopy_rise must be >= 0, got {self.canopy_rise}")
        if not (math.isfinite(self.canopy_span) and self.canopy_span >= 1):
            raise NpsimInputError(f"PopupParams.canopy_span must be >= 1, got {self.canopy_span}")
        for name in ("crown_base", "crown_radius", "crown_setback", "crown_min"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise NpsimInputError(f"PopupParams.{name} must be >= 0 metres, got {v}")
        if not (math.isfinite(self.contact_tol) and self.contact_tol > 0):
            raise NpsimInputError(f"PopupParams.contact_tol must be > 0 pixels, got {self.contact_tol}")


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

    if p.sidewalk_height >= h:
        raise NpsimInputError(f"PopupParams.sidewalk_height ({p.sidewalk_height} m) must be below the camera "
                              f"({h} m)")
    walk = ground & (labels == SIDEWALK_ID)
    # Height scale of each ground pixel's plane: the sidewalk lies sidewalk_height above the road.
    hscale = np.where(walk, (h - p.sidewalk_height) / h, 1.0) if p.sidewalk_height else np.ones((H, W))
    depth = np.full((H, W), np.nan, dtype=np.float64)
    normals = np.full((H, W, 3), np.nan, dtype=np.float64)
    depth[ground] = np.clip(ground_plane_depth(intr, h, pitch, max_depth=p.max_depth)[ground] * hscale[ground],
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
    if p.facades == "contact":
        # a contact within a row of the horizon is placed at the near end of its row's range, not at
        # the far limit (the limit is a last resort)
        zc = np.where(zc >= p.max_depth, ground_plane_depth(intr, h, pitch, v_offset=1.0, max_depth=p.max_depth),
                      zc)
    zc = np.clip(zc, p.min_depth, p.max_depth)
    vs, us = np.nonzero(g_sup)
    zs = zc[vs, us] * hscale[np.minimum(vs + 1, H - 1), us] if p.sidewalk_height else zc[vs, us]
    support[vs, us] = np.stack([(us - intr.cx) / intr.fx, (vs + 0.5 - intr.cy) / intr.fy,
                                np.ones(vs.size)], axis=1) * zs[:, None]

    # --- facades on their contact line (piecewise planes per column), before everything else
    drawn = np.zeros(nseg + 1, dtype=bool)  # segments whose pixels already have their plane depth
    fac_seen = np.zeros((H, W), dtype=np.int8)  # facade columns: 2 visible contact, 1 hidden foot
    fac_info: dict = {}
    passes = []
    if p.facades == "contact" and nseg:
        passes.append((p.contact_ids, 0.0, fac_info))
        if p.car_ids:  # then cars, on their own lines: wheels, not the body's underside, touch the ground
            fac_info["cars"] = {}
            passes.append((p.car_ids, p.car_envelope, fac_info["cars"]))
    next_ground = None
    if passes:  # first ground row at or below each pixel (H: none), shared by the passes
        rowidx = np.where(ground, np.arange(H)[:, None], H)
        next_ground = np.minimum.accumulate(rowidx[::-1], axis=0)[::-1]
    for ids_, envelope, pinfo in passes:
        lut[:] = False
        lut[list(ids_)] = True
        is_contact = lut[seg_label] & ~placed
        is_contact[0] = False
        res = _place_facades(labels, seg, nseg, ground, invalid, is_contact, walk, intr, g, f, e, h, p, pinfo,
                             envelope=envelope, next_ground=next_ground)
        if res is not None:
            s_arr, u_arr, n_arr, c_arr, placed_ids, v_arr = res
            fidx = np.full(nseg + 1, -1, dtype=np.int64)
            fidx[placed_ids] = np.arange(placed_ids.size)
            tbl = np.full((placed_ids.size, W), -1, dtype=np.int64)
            tbl[fidx[s_arr], u_arr] = np.arange(s_arr.size)
            m = vertical & (fidx[seg] >= 0)
            pv, pu = np.nonzero(m)
            j = tbl[fidx[seg[pv, pu]], pu]
            nr = np.einsum("ij,ij->i", rays[pv, pu], n_arr[j])
            with np.errstate(divide="ignore", invalid="ignore"):
                z = np.where(nr < -1e-9, c_arr[j] / nr, p.max_depth)
            depth[pv, pu] = np.clip(z, p.min_depth, p.max_depth)
            normals[pv, pu] = n_arr[j]
            fac_seen[pv, pu] = np.where(v_arr[j], 2, 1)
            placed[placed_ids] = True
            drawn[placed_ids] = True
            fitted[placed_ids] = True
            how[placed_ids] = 1
            pinfo["on_contact_lines"] = int(placed_ids.size)

    # --- segments standing on the ground: mostly (any facing), or along a contact line long enough
    #     to give the facing by itself (a facade behind parked cars with a gap between them)
    mostly = (n_ground > 0) & (n_ground >= p.ground_fraction * n_total)
    vs, us = np.nonzero(g_sup)
    # (new default) a contact that a level image line fits is fronto-parallel, whatever its scatter in plan;
    # a fitted plane that runs off to a fraction or a multiple of its contacts' depth at the segment's own
    # outermost columns is a grazing misfit of a few quantised contacts: fronto-parallel too
    flat_tol = max(1.0, p.contact_tol * W / 2048.0) if p.facades == "contact" else None
    row_of = (intr.fy, intr.cy)
    span = None
    if p.facades == "contact":
        span = np.zeros((nseg + 1, 2))
        for k, sl in enumerate(ndimage.find_objects(seg), start=1):
            if sl is not None:
                span[k] = (sl[1].start, sl[1].stop - 1)
        span = (span, intr)
    _fit_groups(seg[vs, us], support[vs, us], planes, placed, fitted, how, 1, e, f, p,
                mode=np.where(seg_fronto, 0, 1), only_line_fits=~mostly, flat_tol=flat_tol, row_of=row_of,
                span=span)

    # --- segments resting (also) on other segments, in rounds as their supports get placed
    rounds = 0
    mode_rest = np.where(seg_facade, 1, 2)  # facades: line fit; others: fronto at the nearest support
    if p.facades == "contact":  # (new default) a tree crown whose trunk is hidden: between car and facade
        crown = np.isin(seg_label, p.thin_ids) & ~np.isin(seg_label, p.fronto_ids) & ~seg_facade
        crown[0] = False
        mode_rest = np.where(crown, 3, mode_rest)
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
        kind = np.where(g_sup[vs, us], 0, np.where(seg_facade[seg_below[vs, us]], 2, 1))
        _fit_groups(seg[vs, us], support[vs, us], planes, placed, fitted, how, 2, e, f, p, mode=mode_rest,
                    kind=kind)
    cur = vertical & (placed & ~drawn)[seg]
    depth[cur] = _plane_depth(rays, planes, seg, cur, p)
    normals[cur] = planes[seg[cur], :3]

    # --- tree crowns resting on other segments: a depth per column from what is below it
    crown_px = np.zeros((H, W), dtype=bool)
    crown_kind = np.zeros((H, W), dtype=np.int8)
    under_canopy = np.zeros((H, W), dtype=bool)
    if p.crowns in ("columns", "canopy") and p.facades == "contact" and nseg:
        crown_seg = np.isin(seg_label, p.thin_ids) & ~seg_fronto & ~seg_facade & (how == 2)
        crown_seg[0] = False
        if crown_seg.any():
            crown_px, crown_kind = _place_crowns(seg, crown_seg, depth, ground, invalid, zc, hscale, intr, h,
                                                 pitch, p)
            normals[crown_px] = -f
            if p.crowns == "canopy":  # rows of crowns receding along the street: the slab overrides
                slab, slab_geom = _canopy_slab(seg, crown_seg, depth, normals, g, f, e, h, intr, fac_info, p,
                                               fac_seen)
                crown_px |= slab
                crown_kind[slab] = 4
                if p.under_canopy and slab_geom is not None:
                    lut[:] = False
                    lut[list(p.contact_ids)] = True
                    lut_c = lut[seg_label]
                    lut_c[0] = False
                    under_canopy = _under_canopy(seg, lut_c, slab, depth, fac_seen, slab_geom, g, h, intr,
                                                 fac_info, p)

    # --- whatever is still unplaced: nearest placed depth, fronto-parallel normal
    rest = vertical & ~placed[seg]
    known = np.isfinite(depth)
    notes = []
    if rest.any():
        if known.any():
            # nearest placed pixel, searched in the unplaced pixels' bounding box grown by 1/8 of the
            # image (the whole image when that box holds no placed pixel): the full-frame transform
            # costs 0.2 s at 2048x1024
            rv, ru = np.nonzero(rest)
            m = max(H, W) // 8
            box = (slice(max(rv.min() - m, 0), min(rv.max() + m + 1, H)),
                   slice(max(ru.min() - m, 0), min(ru.max() + m + 1, W)))
            if not known[box].any():
                box = (slice(0, H), slice(0, W))
            _, (iy, ix) = ndimage.distance_transform_edt(~known[box], return_indices=True)
            sub = rest[box]
            depth[box][sub] = depth[box][iy[sub], ix[sub]]
        else:
            depth[rest] = p.fallback_depth
            notes.append(f"no ground or placed segment: unplaced regions set to {p.fallback_depth} m")
        normals[rest] = -f

    # --- confidence: how the pixel was placed, times the ground's depth resolution at its depth
    conf_how = np.array([0.2, 0.8, 0.5])[how[seg]]  # unplaced (nearest fill), on the ground, on segments
    conf_how = np.where(fac_seen == 2, 0.9, np.where(fac_seen == 1, 0.5, conf_how))
    conf_how = np.where(crown_px, np.array([0.5, 0.5, 0.45, 0.35, 0.4])[crown_kind], conf_how)
    conf_how = np.where(under_canopy, 0.35, conf_how)
    conf_how = np.where(rest, 0.2, np.where(ground, 1.0, conf_how))
    with np.errstate(invalid="ignore"):
        row_err = depth / (h * intr.fy)  # relative depth step of one image row at this depth (on the ground)
        confidence = conf_how / (1.0 + row_err / 0.1)
        at_limit = depth >= 0.999 * p.max_depth
    confidence = np.where(at_limit, 0.05, confidence)
    confidence[invalid] = np.nan
    far_px = int(np.count_nonzero(at_limit & vertical))
    if far_px:
        notes.append(f"{far_px} non-ground pixels placed at the far limit ({p.max_depth:g} m): nothing in the "
                     f"labels bounds them")

    seg_ids = np.arange(1, nseg + 1)
    info = {"params": asdict(p), "camera_height_m": h, "camera_pitch_rad": pitch,
            "horizon_row": float(intr.cy - intr.fy * math.tan(pitch)),
            "segments": int(nseg), "on_ground": int(np.sum(how[seg_ids] == 1)),
            "on_segments": int(np.sum(how[seg_ids] == 2)),
            "unplaced_pixels": int(rest.sum()), "line_fits": int(fitted[seg_ids].sum()), "rounds": int(rounds),
            "far_limit_pixels": far_px, "crown_columns_pixels": int(crown_px.sum()),
            "under_canopy_pixels": int(under_canopy.sum()),
            "mean_confidence": round(float(np.nanmean(confidence)), 3) if np.isfinite(confidence).any() else None,
            "seconds": round(time.perf_counter() - t0, 4), **fac_info}
    if notes:
        info["notes"] = notes
    return GeometryEstimate(depth=depth.astype(np.float32), normals=normals.astype(np.float32), method="popup",
                            info=info, confidence=confidence.astype(np.float32))


def _fit_groups(seg_ids: np.ndarray, pts: np.ndarray, planes: np.ndarray, placed: np.ndarray, fitted: np.ndarray,
                how: np.ndarray, how_code: int, e: np.ndarray, f: np.ndarray, p: PopupParams,
                mode: np.ndarray, only_line_fits: np.ndarray | None = None, flat_tol: float | None = None,
                row_of: tuple[float, float] = (1.0, 0.0), kind: np.ndarray | None = None,
                span: tuple | None = None) -> None:
    """Fit one vertical plane per segment to its support points ``pts`` (N, 3) in place.

    ``mode[s]``: 1 = vertical plane through the line fitted to the support
    (falls back to fronto-parallel when the line is too short); 0 =
    fronto-parallel at the support's median forward distance; 2 = fronto-parallel
    at the support points within 25% of the nearest one: a segment resting on
    several surfaces (a sign over its pole and the facade behind) is attached to
    the nearest, since whatever is farther is seen past its free bottom edge.
    Mode 3 (tree crowns whose trunk is hidden; ``kind`` per point: 0 ground contact, 1 other
    segment, 2 facade): fronto-parallel at the median ground contact when there is one, else half
    way between the nearest support and the nearest facade behind (the crown stands on the sidewalk
    between the car that hides its trunk and the facade), else as mode 2.
    Segments with ``only_line_fits[s]`` are left unplaced unless a line fit succeeds.
    With ``flat_tol`` (pixels), a mode-1 support whose image rows (``fy * y / z + cy``, ``row_of``
    = (fy, cy)) all lie within ``flat_tol`` of their median -- up to 5 % -- is fronto-parallel: its
    contact is level in the image, and the plan-view line through it is only the half-pixel row
    quantisation seen along the viewing rays (a tree trunk or post fitted as a radial plane).
    """
    if seg_ids.size == 0:
        return
    ok = np.isfinite(pts).all(axis=1)
    seg_ids, pts = seg_ids[ok], pts[ok]
    order = np.argsort(seg_ids, kind="stable")
    seg_ids, pts = seg_ids[order], pts[order]
    if kind is not None:
        kind = kind[ok][order]
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
            if ok_fit and flat_tol is not None:
                rows = row_of[0] * pts[i0:i1, 1] / pts[i0:i1, 2] + row_of[1]
                if _fits(rows.size, int(np.count_nonzero(np.abs(rows - np.median(rows)) > flat_tol))):
                    n, c, ok_fit = -f, -float(np.median(sb)), False
            if ok_fit and span is not None:
                cols, intr = span[0][s], span[1]
                r = np.stack([(cols - intr.cx) / intr.fx, np.full(2, (float(np.median(rows)) - intr.cy) / intr.fy),
                              np.ones(2)], axis=1)
                nr = r @ n
                z = pts[i0:i1, 2]
                with np.errstate(divide="ignore"):
                    zz = np.where(nr < -1e-9, c / np.where(nr < -1e-9, nr, -1.0), np.inf)
                if not np.all((zz >= 0.5 * z.min()) & (zz <= 2.0 * z.max())):
                    n, c, ok_fit = -f, -float(np.median(sb)), False
            if only_line_fits is not None and only_line_fits[s] and not ok_fit:
                continue
        elif only_line_fits is not None and only_line_fits[s]:
            continue
        else:
            between = None
            if mode[s] == 3 and kind is not None:
                kk = kind[i0:i1]
                if (kk == 0).any():
                    between = float(np.median(sb[kk == 0]))
                elif (kk == 1).any() and (kk == 2).any():
                    near = float(np.min(sb[kk == 1]))
                    between = 0.5 * (near + max(near, float(np.percentile(sb[kk == 2], 10))))
            if between is not None:
                sb = np.array([between])
            elif mode[s] >= 2:
                z = pts[i0:i1, 2]
                sb = sb[z <= 1.25 * z.min()]
            n, c, ok_fit = -f, -float(np.median(sb)), False
        planes[s, :3], planes[s, 3] = n, c
        placed[s], fitted[s], how[s] = True, ok_fit, how_code


# --------------------------------------------------------------------------- facades on their contact line
class _GroundMap:
    """The ground homography of a plane ``hgt`` metres below the camera, and its inverse.

    A ground point with plan coordinates ``(a, b) = (P.e, P.f)`` is ``P = a e + b f + hgt g``;
    it projects to ``x ~ K [e | f | hgt g] (a, b, 1)``. Image lines and ground lines map
    through the same matrix: a ground line ``L`` appears as the image line ``H^-T L`` and an
    image line ``l`` is the ground line ``H^T l``.
    """

    def __init__(self, intr, g: np.ndarray, f: np.ndarray, e: np.ndarray, hgt: float) -> None:
        self.K = np.asarray(intr.matrix, dtype=np.float64)
        self.g, self.f, self.e, self.hgt = g, f, e, hgt
        self.H = self.K @ np.stack([e, f, hgt * g], axis=1)
        self.Hinv = np.linalg.inv(self.H)

    def plane_of_image_line(self, line: np.ndarray) -> tuple[np.ndarray, float] | None:
        """Vertical plane ``(n, c)`` (n.P = c < 0, toward the camera) standing on the image line's ground line."""
        L = self.H.T @ line
        rho = math.hypot(L[0], L[1])
        if rho < 1e-12 * max(1.0, abs(L[2])):
            return None  # the horizon: no ground line
        n = (L[0] * self.e + L[1] * self.f) / rho
        c = -L[2] / rho
        if c > 0:
            n, c = -n, -c
        if abs(c) < 1e-6:
            return None  # through the camera
        return n, float(c)

    def image_line_of_plane(self, n: np.ndarray, c: float) -> np.ndarray:
        """Image line (α, β, γ), α u + β v + γ = 0, of the foot of the vertical plane n.P = c."""
        L = np.array([n @ self.e, n @ self.f, -c])
        return self.Hinv.T @ L

    def plan(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Plan coordinates (a, b) of the ground points seen at image positions (u, v) (below the horizon)."""
        x = self.Hinv @ np.stack([u, v, np.ones_like(u)])
        return x[0] / x[2], x[1] / x[2]

    def point(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        a, b = self.plan(u, v)
        return a[:, None] * self.e + b[:, None] * self.f + self.hgt * self.g


def _lower_hull_runs(u: np.ndarray, v: np.ndarray, vis: np.ndarray) -> np.ndarray:
    """Per run of consecutive visible columns, the chain below all points (largest rows) evaluated at each column."""
    out = v.astype(np.float64).copy()
    idx = np.flatnonzero(vis)
    if idx.size == 0:
        return out
    br = np.flatnonzero(np.diff(u[idx]) > 1) + 1
    for run in np.split(idx, br):
        if run.size < 3:
            continue
        uu, vv = u[run].astype(np.float64), v[run].astype(np.float64)
        hull: list[int] = []
        for i in range(uu.size):  # monotone chain, keeping the points on the image-bottom side
            while len(hull) >= 2:
                a, b = hull[-2], hull[-1]
                cross = (uu[b] - uu[a]) * (vv[i] - vv[a]) - (vv[b] - vv[a]) * (uu[i] - uu[a])
                if cross >= 0:
                    hull.pop()
                else:
                    break
            hull.append(i)
        out[run] = np.interp(uu, uu[hull], vv[hull])
    return out


def street_direction(u_vp: float, intr, g: np.ndarray) -> np.ndarray:
    """Unit direction ``(a, b)`` in plan (ground coordinates along ``e``, ``f``) of the street whose
    vanishing column is ``u_vp`` (pixels)."""
    ratio = (u_vp - intr.cx) * math.cos(math.asin(g[2])) / intr.fx
    return np.array([ratio, 1.0]) / math.hypot(ratio, 1.0)


def _rows(line: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Row of image line ``line`` in columns ``u`` (NaN where the line is vertical)."""
    if abs(line[1]) < 1e-12:
        return np.full(np.shape(u), np.nan)
    return -(line[0] * u + line[2]) / line[1]


def _ls_line(u: np.ndarray, v: np.ndarray) -> tuple[float, float]:
    """Least-squares ``v = s u + t``."""
    um, vm = float(u.mean()), float(v.mean())
    du = u - um
    suu = float(du @ du)
    s = float(du @ (v - vm)) / suu if suu > 0 else 0.0
    return s, vm - s * um


def _robust_line(u: np.ndarray, v: np.ndarray, tol: float, through: tuple[float, float] | None = None
                 ) -> tuple[float, float, int]:
    """Line ``v = s u + t`` fitted once, trimmed of points off by > 3 tol, refitted; -> (s, t, outliers).

    With ``through = (u0, v0)`` the line is constrained through that point (one parameter).
    """
    def fit(uu, vv):
        if through is None:
            return _ls_line(uu, vv)
        du, dv = uu - through[0], vv - through[1]
        s = float(du @ dv) / max(float(du @ du), 1e-12)
        return s, through[1] - s * through[0]

    s, t = fit(u, v)
    keep = np.abs(v - (s * u + t)) <= 3.0 * tol
    if 2 <= keep.sum() < u.size:
        s, t = fit(u[keep], v[keep])
    bad = int(np.count_nonzero(np.abs(v - (s * u + t)) > tol))
    return s, t, bad


def _fits(n: int, bad: int) -> bool:
    return bad <= max(1, int(0.05 * n))


def _split_pieces(u: np.ndarray, v: np.ndarray, tol: float, min_pts: int) -> list[tuple[int, int]]:
    """Split the contact sequence (sorted by column) into index ranges that each fit one image line.

    Recursive: a range that one (trimmed) line does not fit within ``tol`` pixels is split where
    the two least-squares lines leave the least squared residual (all split points at once from
    prefix sums); neighbours that one line fits again are merged afterwards.
    """
    out, stack = [], [(0, u.size)]
    while stack:
        i0, i1 = stack.pop()
        n = i1 - i0
        uu, vv = u[i0:i1], v[i0:i1]
        s_, t_, bad = _robust_line(uu, vv, tol)
        if _fits(n, bad) or n < 2 * min_pts:
            # the outliers a fit tolerates must not stretch its span: split them off its ends
            good = np.nonzero(np.abs(vv - (s_ * uu + t_)) <= tol)[0]
            if good.size and (good[0] > 0 or good[-1] < n - 1) and n > 2:
                a, b = i0 + int(good[0]), i0 + int(good[-1]) + 1
                stack += [r for r in ((i0, a), (b, i1)) if r[1] > r[0]]
                out.append((a, b))
            else:
                out.append((i0, i1))
            continue
        uc, vc = uu - uu.mean(), vv - vv.mean()
        cs = [np.concatenate([[0.0], np.cumsum(x)]) for x in (uc, vc, uc * uc, uc * vc, vc * vc)]
        k = np.arange(min_pts, n - min_pts + 1)

        def sse(m, su, sv, suu, suv, svv):
            cuu = suu - su * su / m
            cuv = suv - su * sv / m
            cvv = svv - sv * sv / m
            return cvv - np.where(cuu > 1e-9, cuv * cuv / np.maximum(cuu, 1e-9), 0.0)

        left = sse(k, *(c[k] for c in cs))
        right = sse(n - k, *(c[n] - c[k] for c in cs))
        j = int(k[np.argmin(left + right)])
        stack += [(i0, i0 + j), (i0 + j, i1)]
    out.sort()
    merged = True
    while merged and len(out) > 1:
        merged = False
        for q in range(len(out) - 1):
            a0, a1 = out[q]
            _, b1 = out[q + 1]
            s_, t_, bad = _robust_line(u[a0:b1], v[a0:b1], tol)
            ends = np.abs(v[[a0, b1 - 1]] - (s_ * u[[a0, b1 - 1]] + t_)) <= tol
            if _fits(b1 - a0, bad) and ends.all():
                out[q:q + 2] = [(a0, b1)]
                merged = True
                break
    return out


@dataclass
class _Line:
    """One contact line: image line, the vertical plane standing on it, and how it was found."""

    line: np.ndarray      # (α, β, γ)
    n: np.ndarray         # plane normal (toward the camera)
    c: float              # n.P = c < 0
    kind: str             # "free" | "vp" (through the street's vanishing point) | "side" (street line)
    u0: float = 0.0       # columns of its visible support
    u1: float = 0.0
    X: float = 0.0        # lateral offset from the street axis (m, > 0 right) of a "vp" line

    def rows(self, u: np.ndarray) -> np.ndarray:
        return _rows(self.line, u)


def _image_line(s: float, t: float) -> np.ndarray:
    return np.array([s, -1.0, t])


def _crossing(p: _Line, q: _Line) -> float | None:
    """Column where the two image lines cross (None if parallel)."""
    x = np.cross(p.line, q.line)
    if abs(x[2]) < 1e-12:
        return None
    return float(x[0] / x[2])




def _place_facades(labels, seg, nseg, ground, invalid, is_contact_seg, walk_px, intr, g, f, e, h, p, info,
                   envelope: float = 0.0, next_ground: np.ndarray | None = None):
    """Per-(segment, column) vertical planes of the facade segments standing on their contact line.

    Returns ``(seg_ids, cols, normals (N, 3), offsets (N,))`` for every column of every facade
    segment that could be placed, and the set of placed segment ids. See the module docstring.
    """
    H, W = labels.shape
    v_h = intr.cy - intr.fy * math.tan(float(np.arcsin(g[2])))  # horizon row
    fac_px = is_contact_seg[seg]
    seg_below = np.zeros_like(seg)
    seg_below[:-1] = seg[1:]
    bot = fac_px & (seg_below != seg)
    vs, us = np.nonzero(bot)
    if vs.size == 0:
        return None
    key = seg[vs, us].astype(np.int64) * W + us
    uniq, inv = np.unique(key, return_inverse=True)
    vb = np.full(uniq.size, -1, dtype=np.int64)
    np.maximum.at(vb, inv, vs)
    ks = uniq // W
    ku = (uniq % W).astype(np.int64)
    # What is below each column's lowest facade pixel: ground (a visible contact), the image
    # bottom, sky / invalid (no information) or something standing in front (the foot is hidden
    # behind it, between the facade's lowest pixel and the next ground row below).
    vbel = np.minimum(vb + 1, H - 1)
    at_bottom = vb >= H - 1
    visible = ~at_bottom & ground[vbel, ku]
    unknown = ~at_bottom & invalid[vbel, ku]
    if next_ground is None:
        rowidx = np.where(ground, np.arange(H)[:, None], H)
        next_ground = np.minimum.accumulate(rowidx[::-1], axis=0)[::-1]
    ng = next_ground[vbel, ku]
    if envelope > 0:
        # lower envelope of the visible contacts (a car's wheels; the body's underside is seen 0.3 m up,
        # its contact row would be the ground behind it): the lower hull per run of visible columns
        # (car_hull), else the running max of the rows per segment
        win = max(3, int(round(envelope * W)) | 1)
        vb = vb.astype(np.float64)  # (the hull runs between rows)
        _, st_ = np.unique(ks, return_index=True)
        for i0, i1 in zip(st_, np.append(st_[1:], ks.size)):
            if p.car_hull:  # the chain below every contact of a run: through the wheels, under the body
                env = _lower_hull_runs(ku[i0:i1], vb[i0:i1], visible[i0:i1])
            else:
                vv = np.where(visible[i0:i1], vb[i0:i1], -1)
                env = ndimage.maximum_filter1d(vv, size=win, mode="nearest")
            vb[i0:i1] = np.where(visible[i0:i1], env, vb[i0:i1])
    lo = vb + 0.5
    hi = np.where(visible, lo, np.where(at_bottom | unknown | (ng >= H), np.inf, ng - 0.5))
    # Contact height: facades stand on the sidewalk when most visible contacts are sidewalk.
    on_walk = walk_px[vbel, ku] & visible
    hgt = h - p.sidewalk_height if (p.sidewalk_height and on_walk.sum() >= 0.5 * max(visible.sum(), 1)
                                     and walk_px.any()) else h
    gm = _GroundMap(intr, g, f, e, hgt)
    # Lowest row whose ground point is nearer than max_depth (contacts above it are clamped to it).
    gy = (hgt / p.max_depth - g[2]) / g[1]
    v_min = intr.cy + intr.fy * gy
    v_near = intr.cy + intr.fy * (hgt / 60.0 - g[2]) / g[1]
    v_vp = intr.cy + intr.fy * (hgt / p.vp_max_distance - g[2]) / g[1] if p.vp_max_distance else -np.inf
    tol = max(1.0, p.contact_tol * W / 2048.0)
    min_pts = 3

    # --- pieces per segment from the visible contacts
    starts = np.searchsorted(ks, np.arange(nseg + 2))
    segs = np.unique(ks)
    pieces: dict[int, list[tuple]] = {}  # seg -> [(columns, rows, slope, intercept)]
    raw: list[tuple[int, float, float, float, float, int]] = []  # (seg, s, t, u0, u1, n) free fits
    for s_id in segs:
        i0, i1 = starts[s_id], starts[s_id + 1]
        m = visible[i0:i1] & (lo[i0:i1] > v_min)
        uu = ku[i0:i1][m].astype(np.float64)
        vv = lo[i0:i1][m]
        if uu.size == 0:
            continue
        ranges = _split_pieces(uu, vv, tol, min_pts)
        pieces[s_id] = []
        for a0, a1 in ranges:
            s_, t_, _ = _robust_line(uu[a0:a1], vv[a0:a1], tol) if a1 - a0 >= 2 else (0.0, float(vv[a0]), 0)
            raw.append((s_id, s_, t_, float(uu[a0]), float(uu[a1 - 1]), a1 - a0))
            pieces[s_id].append((uu[a0:a1], vv[a0:a1], s_, t_))

    # --- the street's vanishing point on the horizon: where the long receding contact lines meet it
    u_vp = intr.cx
    if p.vanishing == "auto":
        cand, wts = [], []
        for _, s_, t_, u0, u1, n in raw:
            if n >= 2 * min_pts and u1 - u0 >= 0.03 * W and abs(s_) > 0.02:
                ux = (v_h - t_) / s_
                if abs(ux - intr.cx) < 0.2 * W and ((s_ > 0 and ux < u0) or (s_ < 0 and ux > u1)):
                    cand.append(ux)
                    wts.append(u1 - u0)
        if len(cand) >= 2:
            o = np.argsort(cand)
            cw = np.cumsum(np.asarray(wts)[o])
            u_vp = float(np.asarray(cand)[o][np.searchsorted(cw, 0.5 * cw[-1])])
    info["vanishing_column"] = round(u_vp, 1)
    d = street_direction(u_vp, intr, g)

    n_street = d[1] * e - d[0] * f  # normal of a vertical plane along the street

    def lateral(u, v):
        a, b = gm.plan(np.asarray(u, float), np.asarray(v, float))
        return a * d[1] - b * d[0]  # > 0 right of the street axis

    def make(line, kind, u0=0.0, u1=0.0):
        pl = gm.plane_of_image_line(line)
        if pl is None:
            return None
        return _Line(line, pl[0], pl[1], kind, u0, u1)

    # --- snap pieces to the vanishing point where that fits (receding facades); keep free lines otherwise
    lines: dict[int, list[_Line]] = {}
    side_X: dict[int, list[tuple[float, float]]] = {-1: [], 1: []}  # side -> [(offset m, sigma m)]
    for s_id, plist in pieces.items():
        out = []
        for uu, vv, s_, t_ in plist:
            du = uu - u_vp
            one_side = (np.all(du > 2 * tol) or np.all(du < -2 * tol))
            ln = None
            if one_side:
                sv, tv, bad = _robust_line(uu, vv, tol, through=(u_vp, v_h))
                # ... unless a level line (a facade facing the camera, also one parameter) fits
                # at least as well: a short or far piece can be either; it stays free and gives
                # no street line
                r_vp = float(np.sqrt(np.mean((vv - (sv * uu + tv)) ** 2)))
                r_level = float(np.sqrt(np.mean((vv - np.median(vv)) ** 2)))
                # (a piece wholly beyond vp_max_distance -- across a square -- is too coarse to tell: it
                # stays free and gives no street line)
                # (a piece whose own line runs along the street within recede_angle recedes too: a
                # facade whose foot is ragged -- shop fronts, people -- fits no line within tol)
                fits_vp = _fits(uu.size, bad) or uu.size < min_pts
                if not fits_vp and p.recede_angle and uu.size >= 2 * min_pts:
                    s_f, t_f, _ = _robust_line(uu, vv, tol)
                    lf = make(_image_line(s_f, t_f), "free")
                    fits_vp = lf is not None and abs(float(lf.n @ n_street)) > math.cos(math.radians(p.recede_angle))
                if fits_vp and r_vp < r_level and vv.max() > v_vp:
                    ln = make(_image_line(sv, tv), "vp", uu[0], uu[-1])
                    if ln is not None:
                        X = float(np.median(lateral(uu, np.maximum(vv, v_min + 1e-3))))
                        # its precision: half a row at the nearest contact (+ 0.3 m of label noise)
                        j = int(np.argmax(vv))
                        dX = float(np.diff(lateral(uu[[j, j]], vv[[j, j]] + [0.0, 0.5]))[0])
                        side_X[1 if du[0] > 0 else -1].append((X, math.hypot(dX, 0.3)))
                        ln.X = X
            if ln is None:
                if uu.size < min_pts:
                    s_ = 0.0  # too short for a slope: fronto-parallel at its row
                    t_ = float(np.median(vv))
                ln = make(_image_line(s_, t_), "free", uu[0], uu[-1])
            if ln is not None:
                out.append(ln)
        if out:
            lines[s_id] = out

    # --- the street lines: one vertical plane along the street per side, at the lateral offset of
    #     that side's receding facades (weighted median, weights 1/sigma^2); a side whose facades
    #     show no (precise) foot also gets a candidate behind the feet of what hides them: the
    #     other side's offset behind its occluders' feet, else ``hidden_setback``
    def wmedian(vals, sig):
        vals, w = np.asarray(vals, float), 1.0 / np.asarray(sig, float) ** 2
        o = np.argsort(vals)
        cw = np.cumsum(w[o])
        return float(vals[o][np.searchsorted(cw, 0.5 * cw[-1])])

    gm_road = _GroundMap(intr, g, f, e, h)
    hid = ~visible & ~at_bottom & ~unknown & (ng < H)
    hu, hv = ku[hid].astype(float), ng[hid] - 0.5
    keep = hv > v_min
    hu, hv, hl = hu[keep], hv[keep], labels[ng[hid][keep], ku[hid][keep]]
    fa, fb = gm_road.plan(hu, hv)
    # (feet on the sidewalk lie on its raised plane, whichever plane the facade's own contacts use)
    fa2, fb2 = (_GroundMap(intr, g, f, e, h - p.sidewalk_height) if p.sidewalk_height else gm_road).plan(hu, hv)
    on_w = hl == SIDEWALK_ID
    feet_X = np.where(on_w, fa2 * d[1] - fb2 * d[0], fa * d[1] - fb * d[0])
    feet: dict[int, float] = {}
    evid: dict[int, tuple[float, float]] = {}
    for side in (-1, 1):
        # (feet more than 15 m off the axis stand across a square or down a cross street: no street wall)
        fx_ = feet_X[(np.sign(hu - u_vp) == side) & (np.sign(feet_X) == side) & (np.abs(feet_X) < 15.0)]
        if fx_.size >= 3:
            feet[side] = float(np.median(fx_))
        ev = [(x, sg) for x, sg in side_X[side] if x * side > 0.3]
        if ev:
            evid[side] = (wmedian(*zip(*ev)), min(sg for _, sg in ev))
    side_line: dict[int, _Line] = {}
    setbacks = {}
    for side in (-1, 1):
        cands = [(x, sg) for x, sg in side_X[side] if x * side > 0.3]
        if side in feet:
            other = -side
            if other in evid and evid[other][1] < 1.0 and other in feet:
                setback = float(np.clip(abs(evid[other][0]) - abs(feet[other]), 0.5, 15.0))
            else:
                setback = p.hidden_setback
            setbacks[side] = round(setback, 2)
            cands.append((side * (abs(feet[side]) + setback), 2.0))
        if not cands:
            continue
        X = wmedian(*zip(*cands))
        n3 = -side * (d[1] * e - d[0] * f)
        side_line[side] = _Line(gm.image_line_of_plane(n3, -abs(X)), n3, -abs(X), "side")
    info["street_lines_m"] = {("left" if k < 0 else "right"): round(-v.c * k, 2) for k, v in side_line.items()}
    info["hidden_setback_m"] = {("left" if k < 0 else "right"): v for k, v in setbacks.items()}
    info["occluder_feet_m"] = {("left" if k < 0 else "right"): round(v, 2) for k, v in feet.items()}

    def fallback_side(side, cols):
        """Street line behind the ground visible in ``cols`` (+ hidden_setback), when no facade shows its foot."""
        gv, gu = np.nonzero(ground[:, cols.astype(np.int64)])
        near = gv > v_near  # ground nearer than 60 m: far rows are too coarse (and cross streets)
        gv, gu = gv[near], gu[near]
        if gv.size == 0:
            return None
        X = lateral(cols[gu].astype(float), gv.astype(float))
        X = X[np.isfinite(X) & (np.sign(X) == side)]
        if X.size == 0:
            return None
        Xs = side * (float(np.percentile(np.abs(X), 95)) + p.hidden_setback)
        n3 = -side * (d[1] * e - d[0] * f)
        return _Line(gm.image_line_of_plane(n3, -abs(Xs)), n3, -abs(Xs), "side")

    # --- contact row and line per column of every facade segment
    out_s, out_u, out_n, out_c, out_v = [], [], [], [], []
    placed = []
    for s_id in segs:
        i0, i1 = starts[s_id], starts[s_id + 1]
        cols = ku[i0:i1].astype(np.float64)
        lo_s, hi_s = lo[i0:i1], hi[i0:i1]
        vis_s = visible[i0:i1]
        nc = cols.size
        row = np.full(nc, np.nan)
        which = np.full(nc, -1, dtype=np.int64)
        cand: list[_Line] = list(lines.get(s_id, []))
        sides = np.where(cols >= u_vp, 1, -1)

        fallback: dict[int, _Line | None] = {}

        def side_of(k):
            ln = side_line.get(k)
            if ln is None:
                if k not in fallback:
                    fallback[k] = fallback_side(k, cols[sides == k])
                ln = fallback[k]
            return ln

        if cand:
            # within each piece's span: its line
            for j, ln in enumerate(cand):
                m = (cols >= ln.u0) & (cols <= ln.u1)
                row[m], which[m] = ln.rows(cols[m]), j
            # gaps between pieces: the two lines up to where they cross (a corner), else half way
            for j in range(len(lines[s_id]) - 1):
                a_, b_ = cand[j], cand[j + 1]
                m = (cols > a_.u1) & (cols < b_.u0)
                if not m.any():
                    continue
                ux = _crossing(a_, b_)
                if ux is not None and a_.u1 <= ux <= b_.u0:  # a corner between them
                    split = ux
                else:
                    split = 0.5 * (a_.u1 + b_.u0)
                    # ... or the street line between them (a corner building whose receding side is
                    # hidden, next to a facade facing the camera)
                    k = 1 if 0.5 * (a_.u1 + b_.u0) >= u_vp else -1
                    sl = side_of(k)
                    if sl is not None and (a_.kind == "free" or b_.kind == "free"):
                        x1 = _crossing(a_, sl) if sl is not None else None
                        x2 = _crossing(sl, b_) if sl is not None else None
                        if x2 is not None and a_.u1 < x2 <= b_.u0:
                            s0 = x1 if (x1 is not None and a_.u1 <= x1 < x2) else a_.u1
                            ms = m & (cols > s0) & (cols <= x2)
                            cand.append(sl)
                            row[ms], which[ms] = sl.rows(cols[ms]), len(cand) - 1
                            m = m & ~ms
                            split = s0
                ma, mb = m & (cols <= split), m & (cols > split)
                row[ma], which[ma] = a_.rows(cols[ma]), j
                row[mb], which[mb] = b_.rows(cols[mb]), j + 1
            # ends: extend the end pieces; a piece that does not recede along the street meets the
            # street line where they cross (a corner building whose side facade is hidden)
            npc = len(lines[s_id])  # (side lines appended to cand above come after the pieces)
            for j, left, m in ((0, True, cols < cand[0].u0), (npc - 1, False, cols > cand[npc - 1].u1)):
                if not m.any():
                    continue
                ln = cand[j]
                row[m], which[m] = ln.rows(cols[m]), j
                if ln.kind == "vp":
                    # a receding piece well off its side's street line (a facade down a cross street, a
                    # deep set-back) does not carry on past its end: the street line does
                    k = 1 if (ln.u0 + ln.u1) / 2 >= u_vp else -1
                    sl = side_line.get(k)
                    if sl is not None and abs(ln.X - (-sl.c * k)) > max(2.0, 0.2 * abs(sl.c)):
                        beyond = m & (sides == k)
                        cand.append(sl)
                        row[beyond], which[beyond] = sl.rows(cols[beyond]), len(cand) - 1
                    continue
                if ln.kind != "free":
                    continue
                end = ln.u0 if left else ln.u1
                for k in (-1, 1):
                    sl = side_of(k)
                    if sl is None:
                        continue
                    if left == (k < 0):
                        # outward (away from the vanishing point): the street wall is whichever is
                        # nearer -- the street line meeting a facade that faces the camera (an inside
                        # corner), or the nearer block after a cross street's mouth
                        mk = m & (sides == k)
                        rs = sl.rows(cols[mk])
                        nearer = np.zeros_like(mk)
                        nearer[mk] = rs > row[mk]
                        if nearer.any():
                            cand.append(sl)
                            row[nearer], which[nearer] = sl.rows(cols[nearer]), len(cand) - 1
                        continue
                    # inward (toward the vanishing point): the facade turns the corner onto the street line
                    ux = _crossing(ln, sl)
                    if ux is None:
                        continue
                    # crossing in the run: a corner there; within the piece: a short step off the
                    # street line, which carries on right after it; behind the piece: they diverge
                    if (left and ux > ln.u1) or (not left and ux < ln.u0):
                        continue
                    at = min(ux, end) if left else max(ux, end)
                    beyond = m & ((cols < at) if left else (cols > at)) & (sides == k)
                    if beyond.any():
                        cand.append(sl)
                        row[beyond], which[beyond] = sl.rows(cols[beyond]), len(cand) - 1
        else:
            for k in (-1, 1):
                m = sides == k
                sl = side_of(k) if m.any() else None
                if sl is None:
                    continue
                cand.append(sl)
                row[m], which[m] = sl.rows(cols[m]), len(cand) - 1
        ok = which >= 0
        if not ok.any():
            continue  # nothing to stand on: left to the resting rounds
        if not ok.all():  # (a side without any street line): nearest placed column's line
            idx = np.nonzero(ok)[0]
            near = idx[np.clip(np.searchsorted(idx, np.arange(nc)), 0, idx.size - 1)]
            which = np.where(ok, which, which[near])
            rows_near = np.array([cand[w].rows(np.array([c]))[0] for w, c in zip(which[~ok], cols[~ok])])
            row[~ok] = rows_near
        # hidden columns: the foot lies between the facade's lowest pixel and the ground below it
        row = np.where(vis_s, row, np.minimum(np.maximum(row, lo_s), hi_s))
        row = np.where(np.isfinite(row), row, lo_s)
        # (a foot beyond the far limit: a visible contact at the near end of its row's range, a hidden one
        # half way (in rows) between the limit and the ground below its occluder; the limit itself only
        # as a last resort)
        row = np.where(row < v_min, np.where(vis_s, np.maximum(row, lo_s + 0.5),
                                             np.where(np.isfinite(hi_s), 0.5 * (v_min + hi_s), row)), row)
        row = np.maximum(row, v_min + 1e-3)
        P = gm.point(cols, row)
        nrm = np.stack([cand[w].n for w in which])
        c = np.einsum("ij,ij->i", nrm, P)
        flip = c > 0
        nrm[flip], c[flip] = -nrm[flip], -c[flip]
        out_s.append(np.full(nc, s_id))
        out_u.append(cols.astype(np.int64))
        out_n.append(nrm)
        out_c.append(c)
        out_v.append(vis_s)
        placed.append(s_id)
    info["facade_lines"] = int(sum(len(v) for v in lines.values()))
    if not placed:
        return None
    return (np.concatenate(out_s), np.concatenate(out_u), np.concatenate(out_n), np.concatenate(out_c),
            np.array(placed, dtype=np.int64), np.concatenate(out_v))


# --------------------------------------------------------------------------- crowns over hidden trunks
def _place_crowns(seg: np.ndarray, crown_seg: np.ndarray, depth: np.ndarray, ground: np.ndarray,
                  invalid: np.ndarray, zc: np.ndarray, hscale: np.ndarray, intr, h: float, pitch: float,
                  p: PopupParams) -> tuple[np.ndarray, np.ndarray]:
    """Depth per (segment, column) of tree crowns resting on other segments (docs/geometry.md, "Hidden contacts").

    In each column the crown's lowest pixel says where it can stand: on visible ground below it, its
    contact (a trunk); otherwise over what is below -- no farther than that (a crown above people on the
    sidewalk stands over that sidewalk) and no farther than a lower edge ``crown_base`` metres up seen
    at that row allows (minus ``crown_radius``, the underside's depth), whichever is nearer. A run of
    columns whose lower edge stays level is one crown and takes the median of its columns; the pixel
    gets the geometric mean of that and the depth the rounds gave its segment (fronto-parallel between
    the car in front and the facade behind). A segment whose trunk shows anywhere keeps the depth the
    rounds gave it (at the trunk's contact). Writes
    ``depth`` in place; returns the pixels written and, per pixel, where its column's depth came from:
    1 a trunk contact, 2 what is below (an occluder), 3 the crown's lower edge.
    """
    H, W = seg.shape
    px = crown_seg[seg]
    seg_below = np.zeros_like(seg)
    seg_below[:-1] = seg[1:]
    bot = px & (seg_below != seg)
    vs, us = np.nonzero(bot)
    done = np.zeros((H, W), dtype=bool)
    kind_px = np.zeros((H, W), dtype=np.int8)
    if vs.size == 0:
        return done, kind_px
    key = seg[vs, us].astype(np.int64) * W + us
    uniq, inv = np.unique(key, return_inverse=True)
    vb = np.full(uniq.size, -1, dtype=np.int64)
    np.maximum.at(vb, inv, vs)
    ks, ku = uniq // W, (uniq % W).astype(np.int64)
    vbel = np.minimum(vb + 1, H - 1)
    at_bottom = vb >= H - 1
    contact = at_bottom | ground[vbel, ku]
    z_contact = zc[vb, ku] * hscale[vbel, ku]
    d_below = np.where(~contact & ~invalid[vbel, ku], depth[vbel, ku], np.nan)
    v_h = intr.cy - intr.fy * math.tan(pitch)
    dv = v_h - (vb + 0.5)
    with np.errstate(divide="ignore", invalid="ignore"):
        z_far = np.where((dv > 0.5) & (p.crown_base > h), (p.crown_base - h) * intr.fy / dv, np.nan)
    z_h = z_far - p.crown_radius
    # every crown pixel is at least crown_min up: a crown whose lower edge is seen above the horizon stands
    # no nearer than that height allows there (per segment, from the upper quartile of its columns' lowest
    # rows: trunk columns reach lower)
    z_lb = np.zeros(uniq.size)
    z_h = np.where(z_h > p.min_depth, z_h, np.nan)
    z = np.where(contact, z_contact, np.fmin(d_below, z_h))
    src = np.where(contact, 1, np.where(np.isfinite(d_below) & ~(z_h < d_below), 2, 3))
    # per segment: median over a window of columns (outliers: a pole or a far crown under a near one)
    starts = np.searchsorted(ks, np.unique(ks))
    stops = np.append(starts[1:], ks.size)
    jump = max(2.0, 0.004 * W)
    for i0, i1 in zip(starts, stops):
        zz = z[i0:i1]
        ok = np.isfinite(zz)
        if not ok.any():
            continue
        if contact[i0:i1].any():
            z[i0:i1] = np.nan  # a trunk shows: the segment keeps its depth at the trunk's contact
            continue
        dv75 = float(np.percentile(dv[i0:i1], 75))
        if dv75 > 0.5 and p.crown_min > h:
            z_lb[i0:i1] = (p.crown_min - h) * intr.fy / dv75
        # one crown per run of columns whose lower edge stays level (a jump = another crown)
        br = np.nonzero((np.abs(np.diff(vb[i0:i1])) > jump) | (np.diff(ku[i0:i1]) > 1))[0] + 1
        for a, b in zip(np.r_[0, br], np.r_[br, zz.size]):
            zr = zz[a:b][ok[a:b]]
            zz[a:b] = float(np.median(zr)) if zr.size else np.nan
        ok = np.isfinite(zz)
        if not ok.any():
            continue
        idx = np.nonzero(ok)[0]
        near = idx[np.clip(np.searchsorted(idx, np.arange(zz.size)), 0, idx.size - 1)]
        z[i0:i1] = zz[np.where(ok, np.arange(zz.size), near)]
    ok = np.isfinite(z)
    tbl = np.full(uniq.size, np.nan)
    tbl[ok] = np.clip(z[ok], p.min_depth, p.max_depth)
    pv, pu = np.nonzero(px)
    j = np.searchsorted(uniq, seg[pv, pu].astype(np.int64) * W + pu)
    j = np.minimum(j, uniq.size - 1)
    hit = (uniq[j] == seg[pv, pu].astype(np.int64) * W + pu) & np.isfinite(tbl[j])
    pv, pu, j = pv[hit], pu[hit], j[hit]
    # two guesses that fail differently -- this column's and the segment's own placement (half way
    # between the car in front and the facade behind): half way between them in log depth
    depth[pv, pu] = np.fmax(np.sqrt(tbl[j] * depth[pv, pu]), np.clip(z_lb[j], 0.0, p.max_depth))
    done[pv, pu] = True
    kind_px[pv, pu] = src[j]
    return done, kind_px



def _canopy_slab(seg: np.ndarray, crown_seg: np.ndarray, depth: np.ndarray, normals: np.ndarray,
                 g: np.ndarray, f: np.ndarray, e: np.ndarray, h: float, intr, fac_info: dict,
                 p: PopupParams, fac_seen: np.ndarray) -> np.ndarray:
    """Crowns of a row of street trees receding along the street, as one slab (docs/geometry.md, "Canopy").

    A row of crowns seen from the road is bounded by two planes: the plane of their undersides,
    ``crown_base`` metres above the ground, and the vertical plane along the street of their inner
    (road-side) faces, ``crown_setback`` metres in from that side's street line (facade) or at the feet
    of what hides that side's facade bases (parked cars, people), whichever is nearer the axis. A ray meets
    the slab where it has crossed both, so each pixel takes the larger of the two depths (exact on
    undersides and inner faces; through a gap between crowns it sees a front face a little deeper),
    no deeper than the street line nor than the farthest facade standing on its visible foot
    (``fac_seen == 2``: the street's end). Only segments that recede (``canopy_span``, ``canopy_rise``: wide, and a
    lower edge rising toward the vanishing point) are placed so; a single crown or a small group near
    the vanishing point keeps the per-column depth.
    Writes ``depth`` and ``normals`` in place; returns the pixels written.
    """
    H, W = seg.shape
    done = np.zeros((H, W), dtype=bool)
    street = fac_info.get("street_lines_m", {})
    if "vanishing_column" not in fac_info or not street:
        return done, None
    d = street_direction(float(fac_info["vanishing_column"]), intr, g)
    n_lat = d[1] * e - d[0] * f  # lateral unit vector, > 0 right of the street axis
    px = crown_seg[seg]
    # which segments recede: their lower edge (lowest pixel per column, above the horizon) rises toward
    # the vanishing point as a row's outer bottom edge does, not level as a single crown's
    bot = px.copy()
    bot[:-1] &= seg[1:] != seg[:-1]
    bv, bu = np.nonzero(bot)
    if bv.size == 0:
        return done, None
    key = seg[bv, bu].astype(np.int64) * W + bu
    order = np.lexsort((-bv, key))  # per (segment, column) its lowest boundary row first
    key, bv = key[order], bv[order]
    first = np.r_[True, key[1:] != key[:-1]]
    uniq, vb = key[first], bv[first].astype(np.float64)
    ks, ku = uniq // W, (uniq % W).astype(np.float64)
    v_h = intr.cy - intr.fy * math.tan(math.asin(g[2]))
    up, du = v_h - (vb + 0.5), np.abs(ku - float(fac_info["vanishing_column"]))
    recedes = np.zeros(int(seg.max()) + 1, dtype=bool)
    # a crown that leaves the frame at the top and at the side and whose lower edge (median row) at
    # crown_base stands within NEAR_CROWN_M overhangs the camera's side of the street: the near end of a
    # row, whose lower edge is one crown's and level (a farther one at the frame's corner has a trunk in view)
    top = np.zeros_like(recedes)
    top[seg[0][crown_seg[seg[0]]]] = True
    edge = np.zeros_like(recedes)
    for col in (seg[:, 0], seg[:, -1]):
        edge[col[crown_seg[col]]] = True
    for k in np.nonzero(top & edge)[0]:
        dv = v_h - (float(np.median(vb[ks == k])) + 0.5)
        recedes[k] = dv > 0.5 and p.crown_base > h and (p.crown_base - h) * intr.fy / dv < NEAR_CROWN_M
    st = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    for i0, i1 in zip(st, np.r_[st[1:], ks.size]):
        m = up[i0:i1] > 0.5
        if m.sum() < max(6, 0.1 * W):  # a row spans a good part of the frame; a group near the VP: columns
            continue
        uu, dd = du[i0:i1][m], up[i0:i1][m]
        outer = uu > np.median(uu)
        if outer.all() or not outer.any():
            continue
        r_exp = np.median(uu[outer]) / max(np.median(uu[~outer]), 1.0)
        r_obs = np.median(dd[outer]) / max(np.median(dd[~outer]), 0.5)
        recedes[ks[i0]] |= r_exp >= p.canopy_span and r_obs - 1.0 >= p.canopy_rise * (r_exp - 1.0)
    if not recedes.any():
        return done, None
    seen = fac_seen == 2
    z_cap = float(depth[seen].max()) if seen.any() else p.max_depth
    pv, pu = np.nonzero(px & recedes[seg])
    z, ok, on_side, side = _slab_depth(pv.astype(np.float64), pu.astype(np.float64), g, n_lat, h, intr, fac_info,
                                       p, z_cap)
    pv, pu = pv[ok], pu[ok]
    depth[pv, pu] = np.clip(z[ok], p.min_depth, p.max_depth)
    normals[pv, pu] = np.where(on_side[ok][:, None], -side[ok][:, None] * n_lat[None, :], g[None, :])
    done[pv, pu] = True
    fac_info["canopy_pixels"] = int(ok.sum())
    return done, (n_lat, z_cap)


def _under_canopy(seg: np.ndarray, is_contact_seg: np.ndarray, slab: np.ndarray, depth: np.ndarray,
                  fac_seen: np.ndarray, slab_geom: tuple, g: np.ndarray, h: float, intr, fac_info: dict,
                  p: PopupParams) -> np.ndarray:
    """Facade columns with a hidden foot seen right under a canopy slab: no deeper than the slab allows.

    Candidates: the columns of a contact segment that shows no foot anywhere (``fac_seen == 1`` in all
    its columns) and whose top edge lies under the slab (>= 90 % of its topmost pixels have a slab
    pixel right above them; a segment also seen above or beside the crowns is a taller wall). Were such
    a column on its street line, the ray over its top edge would have entered the slab (the crowns'
    undersides or inner faces) in front of it, unless the crowns leave a gap there. So when that entry
    is nearer than ``UNDER_CANOPY_RATIO`` x the column's depth and still behind what hides the column's
    foot (the segment below its lowest pixel), the column's plane is scaled along the rays to the
    entry's depth: a bus shelter, a kiosk or a low wall under the trees (docs/geometry.md, "Under a
    canopy"). Writes ``depth`` in place; returns the pixels moved.
    """
    H, W = seg.shape
    moved = np.zeros((H, W), dtype=bool)
    # (only segments without any visible foot: one that shows its foot elsewhere is a wall, seen under
    # the crowns through a gap between them)
    shows = np.zeros(is_contact_seg.size, dtype=bool)
    shows[seg[fac_seen == 2]] = True
    cpx0 = is_contact_seg[seg]
    # ... and whose whole top edge is under the slab: a segment seen above or beside the crowns too (sky,
    # another segment, the frame's top) is a taller wall, seen under them through a gap
    top_all = cpx0.copy()
    top_all[1:] &= seg[:-1] != seg[1:]
    under = np.zeros((H, W), dtype=bool)
    under[1:] = slab[:-1]
    n_top = np.bincount(seg[top_all], minlength=is_contact_seg.size)
    n_under = np.bincount(seg[top_all & under], minlength=is_contact_seg.size)
    low = n_under >= 0.9 * np.maximum(n_top, 1)
    cpx = (is_contact_seg & ~shows & low)[seg] & (fac_seen == 1)
    top = np.zeros((H, W), dtype=bool)
    top[1:] = cpx[1:] & slab[:-1]
    tv, tu = np.nonzero(top)
    if tv.size == 0:
        return moved
    # lowest pixel of each candidate (segment, column) and the depth of what stands below it
    bot = cpx.copy()
    bot[:-1] &= seg[1:] != seg[:-1]
    bv, bu = np.nonzero(bot)
    bkey = seg[bv, bu].astype(np.int64) * W + bu
    o = np.lexsort((-bv, bkey))
    bkey, bv, bu = bkey[o], bv[o], bu[o]
    first = np.r_[True, bkey[1:] != bkey[:-1]]
    bkey, bv, bu = bkey[first], bv[first], bu[first]
    tkey = seg[tv, tu].astype(np.int64) * W + tu
    j = np.clip(np.searchsorted(bkey, tkey), 0, max(bkey.size - 1, 0))
    has = bkey[j] == tkey
    vb = bv[j]
    below = np.minimum(vb + 1, H - 1)
    z_occ = np.where(has & (vb + 1 < H) & (seg[below, tu] > 0), depth[below, tu], np.nan)
    n_lat, z_cap = slab_geom
    z_in, ok, _, _ = _slab_depth(tv - 0.5, tu.astype(np.float64), g, n_lat, h, intr, fac_info, p, z_cap)
    z_top = depth[tv, tu]
    with np.errstate(invalid="ignore"):
        pull = ok & np.isfinite(z_occ) & (z_in < UNDER_CANOPY_RATIO * z_top) & (z_in > z_occ)
    if not pull.any():
        return moved
    # one factor per (segment, column): the nearest entry over its tops
    key, fac = tkey[pull], z_in[pull] / z_top[pull]
    o = np.lexsort((fac, key))
    key, fac = key[o], fac[o]
    first = np.r_[True, key[1:] != key[:-1]]
    key, fac = key[first], fac[first]
    pv, pu = np.nonzero(cpx)
    pkey = seg[pv, pu].astype(np.int64) * W + pu
    j = np.clip(np.searchsorted(key, pkey), 0, key.size - 1)
    hit = key[j] == pkey
    pv, pu = pv[hit], pu[hit]
    depth[pv, pu] = np.clip(depth[pv, pu] * fac[j[hit]], p.min_depth, p.max_depth)
    moved[pv, pu] = True
    fac_info["under_canopy_columns"] = int(key.size)
    return moved


def _slab_depth(v: np.ndarray, u: np.ndarray, g: np.ndarray, n_lat: np.ndarray, h: float, intr, fac_info: dict,
                p: PopupParams, z_cap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Depth (m) at which the rays through pixel coordinates ``(v, u)`` (rows, columns; fractional allowed)
    enter the canopy slab of :func:`_canopy_slab`; returns ``(z, ok, on_inner_face, side)``."""
    street = fac_info.get("street_lines_m", {})
    # ray components from the pixel coordinates (no gather of the full ray array)
    xr, yr = (u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy
    gr = xr * g[0] + yr * g[1] + g[2]
    lr = xr * n_lat[0] + yr * n_lat[1] + n_lat[2]
    side = np.where(lr < 0, -1, 1)
    x_fac = np.where(side < 0, street.get("left", np.nan), street.get("right", np.nan))  # signed, m
    x_in = np.where(np.abs(x_fac) > p.crown_setback + 0.5, x_fac - side * p.crown_setback, side * 0.5)
    # ... or the feet of what hides the facades' base on that side (parked cars' street side, people),
    # whichever is nearer the axis: crowns overhang the parking strip, and a wide sidewalk moves the
    # street line but not the trees at the kerb
    feet = fac_info.get("occluder_feet_m", {})
    x_ft = np.where(side < 0, feet.get("left", np.nan), feet.get("right", np.nan))
    x_in = np.where(np.isfinite(x_ft) & (x_ft * side > 0) & (np.abs(x_ft) < np.abs(x_in)), x_ft, x_in)
    with np.errstate(divide="ignore", invalid="ignore"):
        z_bot = np.where(gr < -1e-6, (h - p.crown_base) / gr, np.nan)  # the undersides' plane (above the camera)
        z_side = np.where(np.abs(lr) > 1e-6, x_in / lr, np.nan)
        z_fac = np.where(np.abs(lr) > 1e-6, x_fac / lr, np.nan)
    z = np.fmin(np.fmin(np.fmax(z_side, z_bot), z_fac), z_cap)
    ok = (z_side > 0) & (z_fac > 0) & np.isfinite(z)
    return z, ok, ~(z_bot > z_side), side
