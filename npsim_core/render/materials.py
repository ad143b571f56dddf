"""Surface materials for the night render (docs/method.md §6.1).

When the scene carries albedo / roughness maps (the thesis's inverse-rendering
network F_ir, or ground truth of the synthetic scene) they are used as given.
Otherwise a documented fallback:

* **albedo** -- the daytime image is linearised (sRGB decoding); per semantic
  class its pixels are rescaled so the class's mean luminance equals a prior
  albedo for that class (asphalt 0.10, buildings 0.25, vegetation 0.08, ...),
  which removes the daylight's overall level; relative luminance inside a class
  is compressed (``contrast`` exponent 0.7) to weaken baked-in cast shadows.
  Chroma is kept. Result clipped to [0.01, 0.9].
* **roughness** -- per-class priors (asphalt 0.6, paint 0.25, glass 0.05, ...).
* **kind** -- which BSDF each class gets: ``diffuse`` (buildings, vegetation,
  people, ...), ``asphalt`` (rough plastic: the faint glossy sheen of roads and
  sidewalks at night), ``paint`` (vehicles: glossy plastic coat over the albedo),
  ``metal`` (poles, signs: rough plastic), and ``glass`` for the pixels of window
  light classes (1, 2, 7): a dark glossy surface when the window is unlit.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from ..labels import cityscapes
from .lights import srgb_to_linear

KINDS = ("diffuse", "asphalt", "paint", "metal", "glass")
#: Light classes whose pixels are glass (window_building, window_parked, window_transport).
GLASS_LIGHT_CLASSES = (1, 2, 7)

_ALBEDO_PRIOR = {"road": 0.10, "sidewalk": 0.18, "parking": 0.12, "rail track": 0.1, "ground": 0.12,
                 "building": 0.25, "wall": 0.30, "fence": 0.20, "guard rail": 0.3, "bridge": 0.25, "tunnel": 0.2,
                 "pole": 0.20, "polegroup": 0.2, "traffic light": 0.08, "traffic sign": 0.35, "vegetation": 0.08,
                 "terrain": 0.12, "person": 0.20, "rider": 0.2, "car": 0.25, "truck": 0.3, "bus": 0.3,
                 "caravan": 0.3, "trailer": 0.3, "train": 0.3, "motorcycle": 0.2, "bicycle": 0.2}
_KIND = {"road": "asphalt", "sidewalk": "asphalt", "parking": "asphalt", "rail track": "asphalt",
         "car": "paint", "truck": "paint", "bus": "paint", "caravan": "paint", "trailer": "paint", "train": "paint",
         "motorcycle": "paint", "bicycle": "metal", "pole": "metal", "polegroup": "metal", "traffic light": "metal",
         "traffic sign": "metal", "guard rail": "metal"}
_ROUGHNESS = {"diffuse": 1.0, "asphalt": 0.6, "paint": 0.25, "metal": 0.4, "glass": 0.05}


@dataclass(frozen=True)
class MaterialParams:
    """Fallback material estimation parameters.

    contrast : exponent applied to within-class relative luminance (1 = keep day contrast).
    albedo_prior : optional overrides ``{class name: albedo}``.
    delit_per_class : the de-lit albedo's level per class is the prior (its median), as in the
        fallback; off = one global scale (relative class albedos from the photo).
    vehicle_cap : on vehicles, albedo luminance is limited to this multiple of the median of
        its vehicle (instance): number plates, chrome and sky reflections in the day photo are
        small bright details that the headlights would otherwise turn into glowing white
        rectangles (docs/relight.md, "Nights of real frames": plates do not glow). 0 = off.
    delit_vehicles : de-lighting also divides vehicles by the day's shading per pixel (the normals
        of their fitted smooth surfaces; off = the fallback). Car albedo error on the fixture from
        SGM geometry 0.461 -> 0.350 (512x256), 0.428 -> 0.320 (1024x512), from exact geometry
        0.265 / 0.215; the photo's is 0.419 / 0.401: better, not halved (docs/relight.md
        "De-lit textures").
    """

    contrast: float = 0.7
    albedo_prior: dict = field(default_factory=dict)
    delit_per_class: bool = False
    vehicle_cap: float = 2.0
    delit_vehicles: bool = True


@dataclass(frozen=True)
class Materials:
    """Per-pixel material maps aligned with the image.

    albedo : (H, W, 3) float32 linear RGB; roughness : (H, W) float32 in [0, 1];
    kind_lut : (256,) int index into :data:`KINDS` per labelId; source : 'scene' or 'fallback'.
    labels : (H, W) uint8 labelIds the maps were made for (the builder uses them to repair
        texture coordinates of visible vertices, see ``scene_builder``).
    """

    albedo: np.ndarray
    roughness: np.ndarray
    kind_lut: np.ndarray
    source: str
    labels: np.ndarray | None = None


def kind_lut() -> np.ndarray:
    """(256,) material kind index per Cityscapes labelId."""
    lut = np.zeros(256, dtype=np.int32)
    for c in cityscapes().classes:
        lut[c.id] = KINDS.index(_KIND.get(c.name, "diffuse"))
    return lut


def estimate_materials(image: np.ndarray, labels: np.ndarray, *, albedo: np.ndarray | None = None,
                       roughness: np.ndarray | None = None, light_classes: np.ndarray | None = None,
                       params: MaterialParams = MaterialParams(), normals: np.ndarray | None = None,
                       pitch: float = 0.038, instances: np.ndarray | None = None,
                       depth: np.ndarray | None = None, intrinsics=None, delight: bool = False) -> Materials:
    """Albedo, roughness and BSDF kinds for a scene.

    Parameters
    ----------
    image : (H, W, 3) uint8 daytime sRGB.
    labels : (H, W) uint8 labelIds.
    albedo, roughness : maps from the scene (used as given when not None).
    light_classes : (H, W) light class per pixel (0 = none); window classes get glass roughness.
    normals, depth, intrinsics : the reconstructed geometry (camera-frame normals, z-depth m).
        With normals, roughness is raised where the surface is not smooth
        (:func:`geometry_roughness`); with ``delight`` and all three (and no albedo map), the
        day's light is divided out (:func:`delit_albedo`, camera ``pitch`` rad),
        else the per-class prior fallback is used. ``instances``: Cityscapes instanceIds (one
        surface per instance) or None.
    """
    kl = kind_lut()
    H, W = labels.shape
    source = "scene" if albedo is not None else "fallback"
    # Each vehicle's upright box (de-lighting's normals, and where the rendered surface is a car's flat face).
    box = None
    if normals is not None and depth is not None and intrinsics is not None and \
            (roughness is None or (albedo is None and delight)):
        box = vehicle_box_normals(labels, instances, normals, depth, intrinsics, pitch)
    if albedo is None and delight and normals is not None and depth is not None and intrinsics is not None:
        albedo, day = delit_albedo(image, labels, normals, depth, intrinsics, pitch, params, instances=instances,
                                   box_normals=box)
        source = (f"de-lit (sun {', '.join(f'{v:.2f}' for v in day.sun)}, sun/sky {day.ratio:g}, "
                  f"{100 * day.shadow_fraction:.0f} % of sun-facing pixels in shadow)" if np.isfinite(day.score)
                  else "fallback (de-lighting found no usable day light)")
    elif albedo is None:
        albedo = fallback_albedo(image, labels, params)
    if source != "scene":
        albedo = cap_vehicle_details(albedo, labels, instances, params.vehicle_cap)
    if roughness is None:
        rough_of_kind = np.array([_ROUGHNESS[k] for k in KINDS], dtype=np.float32)
        roughness = rough_of_kind[kl[labels]]
        if normals is not None:  # gloss only where the geometry is smooth enough to reflect coherently
            roughness = np.maximum(roughness, geometry_roughness(normals, labels))
            if box is not None:  # ... and where a vehicle's surface is the flat face of its box
                roughness = np.maximum(roughness, vehicle_shape_roughness(normals, box, labels))
            source += "+geometry gloss"
        if light_classes is not None:
            roughness = np.where(np.isin(light_classes, GLASS_LIGHT_CLASSES), _ROUGHNESS["glass"], roughness)
        source += "+prior roughness"
    return Materials(np.ascontiguousarray(albedo, dtype=np.float32),
                     np.ascontiguousarray(roughness, dtype=np.float32).reshape(H, W), kl, source,
                     np.asarray(labels, dtype=np.uint8))


def fallback_albedo(image: np.ndarray, labels: np.ndarray, params: MaterialParams = MaterialParams()) -> np.ndarray:
    """Per-class normalised linear daytime colour (module docstring)."""
    lin = srgb_to_linear(image.astype(np.float32) / 255.0)
    lum = lin @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    lab = labels.astype(np.intp).ravel()
    sums = np.bincount(lab, weights=lum.ravel(), minlength=256)
    counts = np.bincount(lab, minlength=256)
    mean = np.where(counts > 0, sums / np.maximum(counts, 1), 1.0)
    prior = np.full(256, 0.2)
    for c in cityscapes().classes:
        prior[c.id] = params.albedo_prior.get(c.name, _ALBEDO_PRIOR.get(c.name, 0.2))
    eps = 1e-4
    rel = lum / np.maximum(mean[labels], eps)
    target = prior[labels] * np.power(np.maximum(rel, 0.0), params.contrast)
    albedo = lin * (target / np.maximum(lum, eps))[..., None]
    # Black day pixels (lum ~ 0) get the class prior as grey.
    dark = lum < eps
    albedo[dark] = prior[labels][dark][:, None]
    return np.clip(albedo, 0.01, 0.9).astype(np.float32)


def photo_albedo(image: np.ndarray) -> np.ndarray:
    """The linearised day photo as albedo (the reference "photo as albedo" of docs/relight.md)."""
    return srgb_to_linear(np.asarray(image, np.float32) / 255.0).astype(np.float32)


@dataclass(frozen=True)
class DayLight:
    """The day's illumination estimated by :func:`estimate_daylight` (camera frame, OpenCV axes).

    sun : unit vector toward the sun; ratio : sun irradiance on a surface facing it over the sky
    light on an upward-facing surface (both in the same units); score : mean robust residual
    (log albedo) of the best hypothesis (not finite: no usable estimate, :func:`delit_albedo`
    returned the fallback); shadow_fraction : share of sun-facing pixels found in
    cast shadow; above_height : (W,) height (m along world up, camera frame) up to which what
    continues above the frame's top edge casts shadows, per column (None: unlimited).
    """

    sun: tuple[float, float, float]
    ratio: float
    score: float
    shadow_fraction: float
    above_height: np.ndarray | None = field(default=None, compare=False, repr=False)


#: Ground bounce relative to the sky light (a downward surface sees the street, ~1/3 as bright).
_GROUND_BOUNCE = 0.3
#: Classes whose pixels estimate the light (large, matte, well-labelled surfaces).
_DAYLIGHT_CLASSES = (7, 8, 9, 11, 12, 13, 22)


def _up_vector(pitch: float) -> np.ndarray:
    """World up in the OpenCV camera frame of a camera pitched down by ``pitch`` rad."""
    return np.array([0.0, -np.cos(pitch), -np.sin(pitch)])


def _shading(n: np.ndarray, sun: np.ndarray, ratio: float, up: np.ndarray, lit: np.ndarray | float) -> np.ndarray:
    """Day shading of unit normals ``n`` (..., 3): ``ratio·max(0, n·sun)·lit + sky(n) + ground(n)``."""
    cu = n @ up
    amb = 0.5 * (1 + cu) + _GROUND_BOUNCE * 0.5 * (1 - cu)
    return ratio * np.maximum(n @ sun, 0.0) * lit + amb


def _log_lum(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lin = srgb_to_linear(np.asarray(image, np.float32) / 255.0)
    lum = lin @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    return lin, np.log(np.maximum(lum, 1e-4))


def _surface_segments(labels: np.ndarray, instances: np.ndarray | None) -> np.ndarray:
    """Connected components of the instance (or label) map: one surface material each (0 = none)."""
    from ..geometry.surfaces import _segments

    return _segments(labels, instances)[0]


#: Log-luminance penalty of explaining a sun-facing pixel as cast shadow (most of them are lit).
_SHADOW_PENALTY = 0.15


#: Labels that go on above the frame where they touch its top row (building, wall, fence,
#: vegetation): :func:`above_frame_depth`. Poles are left out: one is a few centimetres wide, and
#: going on above the frame with the 4 m thickness of a façade it cast a wide band of shadow.
_TALL_CLASSES = (11, 12, 13, 21)
#: Thin objects (pole, polegroup, traffic light, sign): a shadow ray is inside them only within
#: ``_THIN_M`` behind their visible surface (a façade's or car's thickness is ``_THICK_M``).
_THIN_CLASSES = (17, 18, 19, 20)
_THIN_M, _THICK_M = 0.5, 4.0
#: Shadow-ray margins of the daylight estimate (relative, metres): the render geometry's ground
#: and façades are fitted planes, not raw stereo (docs/relight.md "De-lit textures").
_SUN_MARGIN, _SUN_OFFSET = 0.01, 0.05


def above_frame_depth(depth: np.ndarray, labels: np.ndarray, rows: int = 3) -> np.ndarray:
    """(W,) depth (m) of what continues above the frame per column, NaN where nothing does.

    A façade, wall or tree cut by the image's top edge goes on upward; a vertical
    surface keeps its z-depth up a column, so the median depth of its top ``rows`` rows stands
    for it. Without it, shadow rays toward a high sun leave the frame before they reach the
    building that casts the shadow (its upper floors are out of view), and the sun estimate
    preferred low suns whose rays hit visible geometry (docs/relight.md "De-lit textures").
    How high it goes is not in the frame: :func:`estimate_daylight` fits it per segment.
    """
    top = np.asarray(depth, np.float64)[:rows]
    tall = np.isin(np.asarray(labels)[:rows], _TALL_CLASSES) & np.isfinite(top) & (top > 0)
    k = tall.sum(0)
    d = np.sort(np.where(tall, top, np.inf), axis=0)  # finite values first, per column
    med = d[np.clip((k - 1) // 2, 0, rows - 1), np.arange(top.shape[1])]
    return np.where(k >= (rows + 1) // 2, med, np.nan)


def _above_segments(labels: np.ndarray, above: np.ndarray) -> np.ndarray:
    """(W,) id of the connected tall segment (:data:`_TALL_CLASSES`) each column's above-frame part
    belongs to (0 = none): one unknown height each."""
    import cv2

    _, comp = cv2.connectedComponents(np.isin(labels, _TALL_CLASSES).astype(np.uint8), connectivity=4)
    return np.where(np.isfinite(above), comp[0], 0)


def far_depth(depth: np.ndarray) -> np.ndarray:
    """(H, W) float64 depth with each pixel the farthest of its 3x3 neighbourhood (NaN stays NaN):
    what shadow rays test against. A ray point rounded to a pixel of the ground a row nearer is
    "behind" it by the ground's depth step per row (1.2 m at 20 m at 256 px wide), which cast
    false shadows along low suns' rays at small sizes."""
    import cv2

    d = np.asarray(depth, np.float64)
    ok = np.isfinite(d)
    far = cv2.dilate(np.where(ok, d, 0.0).astype(np.float32), np.ones((3, 3), np.uint8)).astype(np.float64)
    return np.where(ok, far, np.nan)


def thickness_map(labels: np.ndarray) -> np.ndarray:
    """(H, W) thickness (m) behind each pixel's visible surface for shadow rays: thin objects
    are thin (:data:`_THIN_CLASSES`)."""
    return np.where(np.isin(labels, _THIN_CLASSES), _THIN_M, _THICK_M)


def _shadow_rays(points: np.ndarray, sun: np.ndarray, depth: np.ndarray, intrinsics, *, steps: int, min_dist: float,
                 max_dist: float, thickness, margin: float, offset: float, above: np.ndarray | None,
                 up: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Screen-space shadow rays (:func:`sun_visibility`): (hit by the visible geometry (N,) bool,
    the lowest height along ``up`` at which the ray is inside what continues above the frame
    (N,) m, +inf if never, and that ray point's column (N,))."""
    H, W = depth.shape
    thick = np.asarray(thickness, np.float64)
    t = np.geomspace(min_dist, max_dist, steps)
    q = points[:, None, :] + t[None, :, None] * np.asarray(sun, np.float64)[None, None, :]
    z = q[..., 2]
    front = z > 0.1
    u = np.rint(intrinsics.fx * q[..., 0] / np.where(front, z, 1) + intrinsics.cx).astype(np.int64)
    v = np.rint(intrinsics.fy * q[..., 1] / np.where(front, z, 1) + intrinsics.cy).astype(np.int64)
    inside = front & (u >= 0) & (u < W) & (v >= 0) & (v < H)
    vc, uc = np.clip(v, 0, H - 1), np.clip(u, 0, W - 1)
    d = np.where(inside, depth[vc, uc], np.nan)
    if thick.ndim == 2:  # per pixel (thin objects are thin)
        thick = np.where(inside, thick[vc, uc], _THICK_M)
    with np.errstate(invalid="ignore"):
        hit = (inside & np.isfinite(d) & (z > d * (1 + margin) + offset) & (z < d + thick)).any(axis=1)
        h_over = np.full(len(points), np.inf)
        u_over = np.zeros(len(points), np.int64)
        if above is not None:
            da = np.asarray(above, np.float64)[uc]
            over = front & (u >= 0) & (u < W) & (v < 0) & np.isfinite(da) & (z > da * (1 + margin) + offset) \
                & (z < da + _THICK_M)
            if over.any():
                h = q @ (np.asarray(up, np.float64) if up is not None else np.array([0.0, -1.0, 0.0]))
                h = np.where(over, h, np.inf)
                k = np.argmin(h, axis=1)
                h_over = h[np.arange(len(points)), k]
                u_over = uc[np.arange(len(points)), k]
    return hit, h_over, u_over


def sun_visibility(points: np.ndarray, sun: np.ndarray, depth: np.ndarray, intrinsics, *,
                   steps: int = 24, min_dist: float = 0.5, max_dist: float = 40.0, thickness=_THICK_M,
                   margin: float = 0.04, offset: float = 0.2, above: np.ndarray | None = None,
                   above_height: np.ndarray | None = None, up: np.ndarray | None = None) -> np.ndarray:
    """1 where camera-frame ``points`` (N, 3) see the sun along ``sun`` over the depth map, else 0.

    Screen-space shadow rays: ``steps`` points from ``min_dist`` to ``max_dist`` m (geometric)
    toward the sun are projected into the image; a point more than ``margin`` (relative, plus
    ``offset`` m) and up to ``thickness`` m (a number, or (H, W) per pixel: :func:`thickness_map`)
    behind the visible surface there is inside an object (the visible surface occludes it). The
    margins keep stereo depth noise from casting shadows. ``above`` ((W,) m,
    :func:`above_frame_depth`): what continues above the frame's top edge per column; a ray point
    projected above the frame is tested against it the same way, up to ``above_height`` ((W,)
    m along ``up``, world up in the camera frame; unlimited if not given).
    """
    hit, h_over, u_over = _shadow_rays(points, sun, depth, intrinsics, steps=steps, min_dist=min_dist,
                                       max_dist=max_dist, thickness=thickness, margin=margin, offset=offset,
                                       above=above, up=up)
    if above is not None:
        cap = np.inf if above_height is None else np.asarray(above_height, np.float64)[u_over]
        hit = hit | (np.isfinite(h_over) & (h_over <= cap))
    return (~hit).astype(np.float32)


def _dark_ground(y: np.ndarray, lab: np.ndarray) -> np.ndarray:
    """Observed cast shadow on ground samples (luminance ``y``, labels ``lab``): per label, below
    0.55x its 75th percentile of luminance, or -- where most of the label lies in shadow, so
    that percentile is itself a shadow -- below the split of its log luminance into two classes
    (Otsu) when the two are more than 1.8x apart."""
    dark = np.zeros(len(y), bool)
    for c in np.unique(lab):
        m = lab == c
        yc = y[m]
        dk = yc < 0.55 * np.percentile(yc, 75)
        ly = np.log(np.maximum(yc, 1e-4))
        hist, edges = np.histogram(ly, bins=64)
        p = hist / max(hist.sum(), 1)
        mids = 0.5 * (edges[1:] + edges[:-1])
        w0 = np.cumsum(p)
        mu = np.cumsum(p * mids)
        with np.errstate(invalid="ignore", divide="ignore"):
            between = (mu[-1] * w0 - mu) ** 2 / (w0 * (1 - w0))
        j = int(np.nanargmax(np.where(np.isfinite(between), between, -1)))
        lo, hi = ly <= edges[j + 1], ly > edges[j + 1]
        if lo.sum() >= 10 and hi.sum() >= 10 and np.median(ly[hi]) - np.median(ly[lo]) > np.log(1.8):
            dk = dk | lo
        dark[m] = dk
    return dark


def estimate_daylight(image: np.ndarray, labels: np.ndarray, normals: np.ndarray, depth: np.ndarray, intrinsics,
                      pitch: float = 0.038, *, instances: np.ndarray | None = None, samples: int = 4000,
                      seed: int = 0, sun: np.ndarray | None = None) -> DayLight:
    """Sun direction and sun/sky ratio of a day photo from the cast shadows on its ground
    (docs/relight.md "De-lit textures").

    The ground (road, sidewalk, parking) has the most reliable normals and shows the cast
    shadows. Observed shadow: :func:`_dark_ground`. For each sun direction (elevation 10–85°, any
    azimuth; a 10° x 20° grid, then 5° around the best) the shadows the reconstructed geometry
    casts (screen-space shadow rays, :func:`sun_visibility`, plus the pixels facing away) are
    compared with the observed ones; the direction with the highest intersection over union
    wins (the photo's texture does not enter: a score of albedo constancy was dominated by it and
    picked wrong suns from stereo geometry). What continues above the frame's top edge
    (:func:`above_frame_depth`) has a height the frame does not show: per tall segment it is
    the one that explains the observed shadows best (ground samples whose ray enters it, in
    order of the height where they do: the prefix with most shadowed minus lit samples) -- an
    unlimited height made every high sun shadow the whole street, and the low sun won. Thin
    objects are 0.5 m thick for the rays (:func:`thickness_map`). The sun/sky ratio ``k``
    follows from the median luminance of lit over shadowed ground: ``lit/shadow = (k·n·s +
    sky)/sky``. Model of the shading: ``k·max(0, n·s)·V + sky(n)``, ``sky(n) = (1+n·up)/2 +
    0.3·(1−n·up)/2``. ``score`` is 1 − IoU. ``sun`` (unit, camera frame): no search, the ratio
    and score of that sun.
    """
    from ..camera import backproject

    lin, ly = _log_lum(image)
    y_all = np.exp(ly)
    ground = np.isin(labels, (7, 8, 9)) & np.isfinite(normals).all(-1) & np.isfinite(depth)
    idx = np.flatnonzero(ground.ravel())
    if idx.size < 200:
        return DayLight((0.0, -1.0, 0.0), 0.0, float("nan"), 0.0)
    rng = np.random.default_rng(seed)
    idx = rng.choice(idx, size=min(samples, idx.size), replace=False)
    n = normals.reshape(-1, 3)[idx].astype(np.float64)
    y = y_all.ravel()[idx].astype(np.float64)
    lab = labels.ravel()[idx]
    pts = backproject(np.where(np.isfinite(depth), depth, 0), intrinsics).reshape(-1, 3)[idx].astype(np.float64)
    pts = pts + 0.03 * n  # off the surface, so it does not shadow itself
    dark = _dark_ground(y, lab)
    R_cw = np.array([[1.0, 0.0, 0.0], [0.0, -np.cos(pitch), -np.sin(pitch)], [0.0, -np.sin(pitch), np.cos(pitch)]])
    dmap = far_depth(depth)
    above = above_frame_depth(dmap, labels)
    seg_top = _above_segments(labels, above)
    thick = thickness_map(labels)
    up = _up_vector(pitch)
    best: tuple = (-1.0, None, None, None, 0.0, 0.0)

    def score(s: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(IoU, lit samples, (W,) height of what continues above the frame) of sun ``s``."""
        f = n @ s > 0
        hit = np.zeros(len(y), bool)
        h_over = np.full(len(y), np.inf)
        u_over = np.zeros(len(y), np.int64)
        if f.any():
            hit[f], h_over[f], u_over[f] = _shadow_rays(
                pts[f], s, dmap, intrinsics, steps=24, min_dist=0.5, max_dist=40.0, thickness=thick,
                margin=_SUN_MARGIN, offset=_SUN_OFFSET, above=above, up=up)
        shadow = ~f | hit
        heights = np.full(above.shape, -np.inf)  # ends at the frame's top unless the shadows say otherwise
        cand = ~shadow & np.isfinite(h_over)
        seg = seg_top[u_over]
        for g in np.unique(seg[cand]):
            m = np.flatnonzero(cand & (seg == g))
            o = m[np.argsort(h_over[m], kind="stable")]
            gain = np.cumsum(np.where(dark[o], 1.0, -1.0))
            j = int(np.argmax(gain))
            if gain[j] > 0:
                shadow[o[:j + 1]] = True
                heights[seg_top == g] = h_over[o[j]]
        return float((shadow & dark).sum() / max((shadow | dark).sum(), 1)), ~shadow, heights

    def search(elevations, azimuths) -> None:
        nonlocal best
        for el_d in elevations:
            for az_d in azimuths:
                el, az = np.radians(el_d), np.radians(az_d)
                s = R_cw @ np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
                iou, vis, heights = score(s)
                if iou > best[0]:
                    best = (iou, s, vis, heights, el_d, az_d)

    if sun is not None:
        s = np.asarray(sun, np.float64) / np.linalg.norm(sun)
        best = (*score(s)[:1], s, *score(s)[1:], 0.0, 0.0)
    else:
        # Coarse (10° x 20°), then fine (5°) around the best.
        search(np.arange(10, 81, 10), np.arange(0, 360, 20))
        e0, a0 = best[4], best[5]
        search([e for e in np.arange(e0 - 10, e0 + 11, 5) if 10 <= e <= 85], np.arange(a0 - 20, a0 + 21, 5) % 360)
    iou, s, vis, heights = best[:4]
    cs = np.maximum(n @ s, 0.0)
    cu = n @ up
    amb = 0.5 * (1 + cu) + _GROUND_BOUNCE * 0.5 * (1 - cu)
    lit, shd = vis & ~dark, ~vis & dark
    k = 3.0
    if lit.sum() >= 20 and shd.sum() >= 20:
        ratio = float(np.median(y[lit]) / max(np.median(y[shd]), 1e-6))
        k = (ratio - 1.0) * float(np.median(amb[lit])) / max(float(np.median(cs[lit])), 0.1)
    shadow = float((~vis & (cs > 0.2)).mean() / max((cs > 0.2).mean(), 1e-6))
    return DayLight(tuple(float(v) for v in s), float(np.clip(k, 0.5, 10.0)), 1.0 - iou, shadow,
                    above_height=heights)


def day_light_colours(image: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sun, sky) colours of a day photo's light, linear RGB each scaled to luminance 1.

    The day's light is not white: surfaces in shadow are lit by the blue sky alone, sunlit ones by
    the sun plus the sky. Dividing the photo by a grey shading left that blue in the albedo, so
    de-lit façades came out grey-blue and pale (docs/relight.md "De-lit textures"). Sky: the median
    colour of the photo's sky pixels (labelId 23; not clipped ones). Sun: on the ground (road,
    sidewalk, parking, each label by itself: one albedo), lit over shadowed pixels per channel is
    ``(sun + sky)/sky``, so ``sun ∝ (lit/shadow − 1)·sky`` (shadowed: below 0.55x the label's 75th
    percentile of luminance, as :func:`estimate_daylight`; lit: above its 60th). Grey where the
    photo shows too little sky (< 50 pixels) or ground shadow (< 50 pixels each).
    """
    w = np.array([0.2126, 0.7152, 0.0722])
    grey = np.ones(3)
    lin = srgb_to_linear(np.asarray(image, np.float32) / 255.0).astype(np.float64)
    sky_px = lin[(labels == 23) & (np.asarray(image).max(-1) < 250)]
    if len(sky_px) < 50:
        return grey, grey
    sky = np.median(sky_px, axis=0)
    if not (sky > 1e-4).all():
        return grey, sky
    sky = sky / (sky @ w)
    y = lin @ w
    num, den = np.zeros(3), 0.0
    for c in (7, 8, 9):
        m = labels == c
        if m.sum() < 200:
            continue
        yc = y[m]
        dark, lit = yc < 0.55 * np.percentile(yc, 75), yc > np.percentile(yc, 60)
        if dark.sum() < 50 or lit.sum() < 50:
            continue
        ratio = np.median(lin[m][lit], axis=0) / np.maximum(np.median(lin[m][dark], axis=0), 1e-6)
        sun_c = np.maximum(ratio - 1.0, 0.0) * sky
        if sun_c @ w <= 1e-6:
            continue
        num += m.sum() * sun_c / (sun_c @ w)
        den += m.sum()
    sun = num / den if den > 0 else grey
    return sun / (sun @ w), sky


#: Yaw of a vehicle's box against the camera's forward axis searched by :func:`vehicle_box_normals`
#: (deg; parked and driving cars follow the street), the fewest columns a vehicle needs, and the
#: largest visible side length and rear width of a car (m; other vehicles: bus, truck, train).
_BOX_YAW_DEG, _BOX_MIN_COLUMNS = 30.0, 12
_BOX_MAX = {26: (5.5, 2.3)}
_BOX_MAX_OTHER = (25.0, 3.2)
#: Relative depth residual above which a column counts as an outlier of the box fit.
_BOX_OUTLIER = 0.1


def _row_medians(a: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Median of ``a`` (n >= 1,) over each row's ``mask`` (k, n) entries; NaN for an empty row (as
    ``np.nanmedian``, which goes through masked arrays for short rows and was 10x slower here)."""
    srt = np.sort(np.where(mask, a[None, :], np.inf), axis=1)
    cnt = mask.sum(1)
    lo = np.take_along_axis(srt, np.maximum(cnt - 1, 0)[:, None] // 2, 1)[:, 0]
    hi = np.take_along_axis(srt, np.minimum(cnt // 2, srt.shape[1] - 1)[:, None], 1)[:, 0]
    return np.where(cnt > 0, 0.5 * (lo + hi), np.nan)


def vehicle_box_normals(labels: np.ndarray, instances: np.ndarray | None, normals: np.ndarray,
                        depth: np.ndarray, intrinsics, pitch: float = 0.038) -> np.ndarray:
    """``normals`` (H, W, 3; camera frame) with each vehicle's normals replaced by those of an
    upright box fitted to its depth, for de-lighting (docs/relight.md "Cars as boxes for
    de-lighting").

    The vehicle fits (:func:`~npsim_core.geometry.surfaces._upright_columns`) smooth the inverse
    depth along a car's columns (σ 32 px) and stereo smears a nearer car into the one behind it,
    so a rear face beside a long side takes the side's slope (2048x1024 fixture: rear normals a
    median 68° off) and the de-lit rear keeps the sun's step between the faces. Per vehicle
    (instance segment) the top view of its columns (the median point per column, world
    horizontal plane) is fitted with the two visible faces of a box: perpendicular lines at a yaw
    within ±30° of the camera's axis, each column on the face its ray enters first (the farther
    of the two lines' hits, as a ray entering a convex box). Grid over the yaw (2.5°), the column
    where the faces meet (41 steps) and the side the rear is on; each face's offset is the median
    of its columns; the least mean relative depth residual (truncated at 10 %) wins among boxes
    whose visible side and rear fit a car (5.5 m, 2.3 m; other vehicles 25 m, 3.2 m). Every
    vertical pixel of a column gets its face's normal (horizontal, facing the camera); pixels
    the input calls horizontal (|n·up| >= 0.5) keep theirs. Vehicles narrower than 12 columns, or
    without depth, keep ``normals``. Pixels with non-finite normals stay non-finite.
    """
    from ..camera import backproject
    from ..geometry.surfaces import VEHICLE_CLASSES, _segments

    out = np.array(normals, np.float32, copy=True)
    veh = np.isin(labels, VEHICLE_CLASSES) & np.isfinite(depth) & np.isfinite(normals).all(-1)
    if not veh.any():
        return out
    seg = np.where(veh, _segments(labels, instances)[0], 0)
    c, s = np.cos(pitch), np.sin(pitch)
    # The world-from-camera rotation (x right, y up, z forward; it is its own inverse).
    R = np.array([[1.0, 0.0, 0.0], [0.0, -c, -s], [0.0, -s, c]])
    P = backproject(np.where(veh, depth, 0.0), intrinsics)
    xw, zw = P[..., 0], -s * P[..., 1] + c * P[..., 2]
    yaws = np.radians(np.arange(-_BOX_YAW_DEG, _BOX_YAW_DEG + 1e-6, 2.5))
    for g in np.unique(seg[veh]):
        if g == 0:
            continue
        m = seg == g
        ys, xs = np.nonzero(m)
        x0, x1, y0, y1 = xs.min(), xs.max() + 1, ys.min(), ys.max() + 1
        mc = m[y0:y1, x0:x1]
        cols = np.flatnonzero(mc.sum(0) >= 2)
        if len(cols) < _BOX_MIN_COLUMNS:
            continue
        px = np.nanmedian(np.where(mc, xw[y0:y1, x0:x1], np.nan)[:, cols], axis=0)
        pz = np.nanmedian(np.where(mc, zw[y0:y1, x0:x1], np.nan)[:, cols], axis=0)
        d = np.hypot(px, pz)
        if not (d > 0.1).all():
            continue
        rx, rz = px / d, pz / d
        cls = int(np.bincount(labels[y0:y1, x0:x1][mc]).argmax())
        max_len, max_wid = _BOX_MAX.get(cls, _BOX_MAX_OTHER)
        best = (np.inf, None, None)
        splits = np.unique(np.linspace(0, len(cols), 41).astype(int))
        left = np.arange(len(cols))[None, :] < splits[:, None]          # (splits, columns)
        for th in yaws:
            # Rear/front face normal (toward the camera) and side normal (toward the camera).
            ma = -np.array([np.sin(th), np.cos(th)])
            mb = np.array([np.cos(th), -np.sin(th)])
            mb = mb if np.median(px * mb[0] + pz * mb[1]) < 0 else -mb
            oa, ob = px * ma[0] + pz * ma[1], px * mb[0] + pz * mb[1]
            ra, rb = rx * ma[0] + rz * ma[1], rx * mb[0] + rz * mb[1]
            for amask in (left, ~left):  # the rear on the left or on the right of the split
                with np.errstate(all="ignore"), warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    a_off = _row_medians(oa, amask)[:, None]
                    b_off = _row_medians(ob, ~amask)[:, None]
                    la = np.where((a_off < 0) & (ra < -1e-3), a_off / np.minimum(ra, -1e-6), -np.inf)
                    lb = np.where((b_off < 0) & (rb < -1e-3), b_off / np.minimum(rb, -1e-6), -np.inf)
                    lam = np.maximum(la, lb)
                    on_a = la >= lb
                    fin = np.isfinite(lam)
                    qx, qz = np.where(fin, lam, 0.0) * rx, np.where(fin, lam, 0.0) * rz
                    along, across = qx * ma[1] - qz * ma[0], qx * mb[1] - qz * mb[0]
                    # A car's side is at most 5.5 m long and its rear 2.3 m wide (as fitted).
                    fa, fb_ = on_a & fin, ~on_a & fin
                    wid = np.nanmax(np.where(fa, along, np.nan), 1) - np.nanmin(np.where(fa, along, np.nan), 1)
                    lng = np.nanmax(np.where(fb_, across, np.nan), 1) - np.nanmin(np.where(fb_, across, np.nan), 1)
                    cost = np.mean(np.where(fin, np.minimum(np.abs(d - lam) / d, _BOX_OUTLIER), _BOX_OUTLIER), 1)
                cost = np.where((np.nan_to_num(wid) > max_wid) | (np.nan_to_num(lng) > max_len), np.inf, cost)
                j = int(np.argmin(cost))
                if cost[j] < best[0]:
                    best = (float(cost[j]), on_a[j], (ma, mb))
        if best[1] is None:
            continue
        on_a, (ma, mb) = best[1], best[2]
        face = np.where(on_a[:, None], np.array([ma[0], 0.0, ma[1]]), np.array([mb[0], 0.0, mb[1]])) @ R.T
        col_n = np.full((x1 - x0, 3), np.nan)
        col_n[cols] = face
        # Columns with too few pixels take the nearest fitted column's face.
        near = cols[np.clip(np.searchsorted(cols, np.arange(x1 - x0)), 0, len(cols) - 1)]
        col_n = col_n[near]
        # Faces the input calls horizontal (a roof, a bonnet) keep their normals. Vertical ones
        # take the box's even when close to it: at a grazing sun, 15° off turns a shaded rear's
        # shading into a third of a sunlit one.
        sub = out[y0:y1, x0:x1]
        box = np.broadcast_to(col_n[None], (y1 - y0, x1 - x0, 3)).astype(np.float32)
        vert = mc & (np.abs(sub @ _up_vector(pitch).astype(np.float32)) < 0.5)
        sub[vert] = box[vert]
    return out


def delit_albedo(image: np.ndarray, labels: np.ndarray, normals: np.ndarray, depth: np.ndarray, intrinsics,
                 pitch: float = 0.038, params: MaterialParams = MaterialParams(), light: DayLight | None = None,
                 instances: np.ndarray | None = None,
                 box_normals: np.ndarray | None = None) -> tuple[np.ndarray, DayLight]:
    """Albedo of a day photo with the day's light divided out (docs/relight.md "De-lit textures").

    1. :func:`estimate_daylight` gives the sun direction and the sun/sky ratio (from the cast
       shadows on the ground).
    2. Cast shadows: the sun's visibility of every pixel from the depth map
       (:func:`sun_visibility`, at 512 px wide, softened over 3x3 for penumbra and antialiasing).
    3. ``albedo = photo / shading`` per pixel, the shading coloured by the day's sun and sky
       (:func:`day_light_colours`: the sun's part of it in the sun's colour, the rest in the
       sky's, so shadowed façades do not keep the sky's blue), then one global scale so that the
       frame's pixels match the per-class albedo priors in the median (a single photo does not
       give the absolute level; relative albedos between and within classes come from the photo).
    4. Clamped where the estimate is unreliable: only façades, walls, fences and the ground
       (:data:`~npsim_core.geometry.surfaces.PLANE_CLASSES`, whose normals the surface fits
       get right) are de-lit, and vehicles (``params.delit_vehicles``, the normals of an
       upright box fitted to each: :func:`vehicle_box_normals`); every other pixel (vegetation,
       people, thin objects, pixels without normals or depth) gets the prior fallback
       (:func:`fallback_albedo`).
       Albedo is limited to [0.01, 0.9] and to 4x its label's median (saturated or specular
       day pixels).

    ``box_normals``: :func:`vehicle_box_normals` of these inputs when already computed.
    """
    import cv2

    from ..camera import backproject

    H, W = labels.shape
    lin, _ = _log_lum(image)
    fb = fallback_albedo(image, labels, params)
    light = light or estimate_daylight(image, labels, normals, depth, intrinsics, pitch, instances=instances)
    if not np.isfinite(light.score):
        return fb, light
    from ..geometry.surfaces import PLANE_CLASSES, VEHICLE_CLASSES

    # Per pixel only where the reconstructed normals are reliable: façades, walls, fences and the
    # ground (planes the surface fits get right), vehicles (their fitted smooth surfaces);
    # vegetation, people keep the prior fallback.
    geo = np.isfinite(normals).all(-1) & np.isfinite(depth)
    valid = geo & np.isin(labels, PLANE_CLASSES)
    veh = geo & np.isin(labels, VEHICLE_CLASSES) if params.delit_vehicles else np.zeros_like(valid)
    if veh.any():  # a box per vehicle: the stereo fits blur the rear into the side
        normals = box_normals if box_normals is not None else \
            vehicle_box_normals(labels, instances, normals, depth, intrinsics, pitch)
    n = np.where((valid | veh)[..., None], normals, 0.0).astype(np.float64)
    up = _up_vector(pitch)
    s = np.asarray(light.sun)
    # Visibility at <= 512 px wide (a shadow edge a few pixels soft is what the photo shows too).
    f = max(1, int(round(W / 512)))
    dz = np.where(np.isfinite(depth), depth, np.nan).astype(np.float32)
    small = dz[f // 2::f, f // 2::f]
    pts = backproject(np.nan_to_num(depth), intrinsics)[f // 2::f, f // 2::f].reshape(-1, 3).astype(np.float64)
    ns = n[f // 2::f, f // 2::f].reshape(-1, 3)
    vis = np.ones(len(pts), np.float32)
    above = above_frame_depth(depth, labels)
    thick = thickness_map(labels)
    dfar = far_depth(depth)
    sel = np.flatnonzero((ns @ s > 0) & np.isfinite(small.ravel()))
    for i in range(0, len(sel), 20000):
        j = sel[i:i + 20000]
        vis[j] = sun_visibility(pts[j] + 0.03 * ns[j], s, dfar, intrinsics, above=above,
                                above_height=light.above_height, up=up, thickness=thick, margin=_SUN_MARGIN,
                                offset=_SUN_OFFSET)
    vis = cv2.blur(vis.reshape(small.shape), (3, 3))
    vis = cv2.resize(vis, (W, H), interpolation=cv2.INTER_LINEAR) if f > 1 else vis
    vis = vis[:H, :W]
    shading = _shading(n, s, light.ratio, up, vis)
    # The shading's colour: the sun's part of it has the sun's colour, the rest the sky's.
    sun_rgb, sky_rgb = day_light_colours(image, labels)
    sun_part = light.ratio * np.maximum(n @ s, 0.0) * vis
    f_sun = (sun_part / np.maximum(shading, 1e-6))[..., None]
    chroma = (f_sun * sun_rgb + (1.0 - f_sun) * sky_rgb).astype(np.float32)
    alb = lin / np.maximum(shading[..., None] * chroma, 1e-3).astype(np.float32)
    # Vehicles per pixel, from the smooth surfaces the stereo fits give them (their faces in the
    # sun and in the shade; one median shading per vehicle was worse from SGM geometry).
    valid = valid | veh
    lum = alb @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    use = valid & np.isin(labels, _DAYLIGHT_CLASSES) & (lum > 1e-4)
    if use.sum() < 100:  # too little de-lit surface to set the level: the fallback (score NaN says so)
        return fb, replace(light, score=float("nan"))
    prior = np.full(256, 0.2)
    for c in cityscapes().classes:
        prior[c.id] = params.albedo_prior.get(c.name, _ALBEDO_PRIOR.get(c.name, 0.2))
    lab = labels.astype(np.intp)
    if params.delit_per_class:  # each class's median on its prior; the de-lit texture within it
        cnt = np.bincount(lab[valid], minlength=256)
        med = np.ones(256)
        for c in np.flatnonzero(cnt):
            med[c] = np.median(lum[valid & (lab == c)])
        g = np.where(valid, prior[lab] / np.maximum(med[lab], 1e-6), 1.0)
        alb, lum = alb * g[..., None], lum * g
    else:
        g = float(np.median(prior[labels[use]] / lum[use]))
        alb, lum = alb * g, lum * g
    cnt = np.bincount(lab[valid], minlength=256)
    med = np.ones(256)
    for c in np.flatnonzero(cnt):
        med[c] = np.median(lum[valid & (lab == c)])
    alb = alb * np.minimum(1.0, 4 * med[lab] / np.maximum(lum, 1e-6))[..., None]
    alb = np.where(valid[..., None], alb, fb)
    return np.clip(alb, 0.01, 0.9).astype(np.float32), light


def cap_vehicle_details(albedo: np.ndarray, labels: np.ndarray, instances: np.ndarray | None,
                        factor: float = 2.0) -> np.ndarray:
    """``albedo`` with each vehicle's pixels limited to ``factor`` x its median luminance (chroma
    kept; per instance when ``instances`` are given, else per connected component of the class).
    See :class:`MaterialParams` ``vehicle_cap``."""
    if not factor:
        return albedo
    from ..geometry.surfaces import VEHICLE_CLASSES, _segments

    veh = np.isin(labels, VEHICLE_CLASSES)
    if not veh.any():
        return albedo
    seg = np.where(veh, _segments(labels, instances)[0], 0)
    lum = albedo @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    sv = seg[veh].astype(np.int64)
    lv = lum[veh].astype(np.float64)
    order = np.lexsort((lv, sv))
    cnt = np.bincount(sv)
    start = np.concatenate([[0], np.cumsum(cnt)[:-1]])
    med = np.zeros(len(cnt))
    has = cnt > 0
    med[has] = lv[order][start[has] + (cnt[has] - 1) // 2]
    cap = factor * med[seg]
    scale = np.where(veh & (lum > cap), cap / np.maximum(lum, 1e-6), 1.0).astype(np.float32)
    return (albedo * scale[..., None]).astype(np.float32)


def geometry_roughness(normals: np.ndarray, labels: np.ndarray, *, full_deg: float = 20.0) -> np.ndarray:
    """(H, W) float32 roughness floor from the geometry: 0 where the normals agree with their
    5x5 neighbourhood, rising linearly to 1 at ``full_deg`` degrees of deviation.

    A glossy BSDF on a facet that is tilted every which way mirrors the lamps in sparkles and
    streaks (docs/relight.md); where the reconstructed surface is not smooth it must not be
    glossy. Only pixels whose 5x5 neighbourhood is one label and has normals are judged (a
    label border is an edge, not roughness); the others get 0 (no floor). 0.4 s at 2048x1024
    (load 9)."""
    import cv2

    ok = np.isfinite(normals).all(-1)
    n = np.where(ok[..., None], normals, 0.0).astype(np.float32)
    k = np.ones((5, 5), np.uint8)
    lab = labels.astype(np.uint8)
    pure = (cv2.erode(lab, k) == cv2.dilate(lab, k)) & cv2.erode(ok.astype(np.uint8), k).astype(bool)
    mean = cv2.blur(n, (5, 5))
    cosv = (mean * n).sum(-1) / np.maximum(np.linalg.norm(mean, axis=-1), 1e-6)
    dev = np.degrees(np.arccos(np.clip(cosv, -1, 1)))
    return np.where(pure, np.clip(dev / full_deg, 0, 1), 0).astype(np.float32)


def vehicle_shape_roughness(normals: np.ndarray, box_normals: np.ndarray, labels: np.ndarray, *,
                            start_deg: float = 5.0, full_deg: float = 20.0) -> np.ndarray:
    """(H, W) float32 roughness floor on vehicles: 0 where the rendered normals are within
    ``start_deg`` of the vehicle's upright box (:func:`vehicle_box_normals`), rising linearly to 1
    at ``full_deg``; 0 elsewhere.

    A car's body is a few flat or gently curved panels; a glossy coat mirrors a lamp where the
    panel's normal points it at the camera, so the highlight is only where it should be when the
    normal is right to within the gloss lobe (paint's alpha 0.25: ~15°). Stereo vehicle fits are
    smooth at the 5-px scale :func:`geometry_roughness` judges, but their normals wander from
    column to column (upright fits; on the 2048x1024 fixture's seed 1 a median 6° and for 37 % of
    the car pixels over 20° off the box), and each column's normal mirrored the street lamps in a
    white vertical strip on the glossy paint (docs/relight.md "De-lit textures and gloss"). The
    box's own faces, horizontal faces (which keep their normals in the box) and vehicles too
    narrow for a box keep their gloss; from exact depth, only wheels and cabins deviate.
    """
    n = np.asarray(normals, np.float32)
    b = np.asarray(box_normals, np.float32)
    cosv = np.clip(np.nan_to_num((n * b).sum(-1), nan=1.0), -1.0, 1.0)
    dev = np.degrees(np.arccos(cosv))
    from ..geometry.surfaces import VEHICLE_CLASSES

    veh = np.isin(labels, VEHICLE_CLASSES)
    return np.where(veh, np.clip((dev - start_deg) / (full_deg - start_deg), 0.0, 1.0), 0.0).astype(np.float32)
