"""Mitsuba 3 scene from a :class:`~npsim_core.mesh.types.SceneMesh` (docs/method.md §6.4).

Design
------
* **World frame = OpenCV camera frame** (x right, y down, z forward, metres).
  Mitsuba's perspective camera looks along local +z with +y up and +x to the
  *left* of the image, so its ``to_world`` is a 180° rotation about z
  (``diag(-1, -1, 1)``, a proper rotation -- Mitsuba forbids scale there).
* **Intrinsics exactly**: ``fov = 2 atan(W / (2 fx))`` on the x axis, and
  ``principal_point_offset_{x,y} = (W/2 - cx - 0.5) / W``, ``(H/2 - cy - 0.5) / H``:
  Mitsuba adds the offset (in film fractions) to the film sample position
  whose pixel centres are at ``(u + 0.5) / W`` (perspective.cpp, ``sample_ray``),
  while OpenCV centres are at integer ``u``. Mitsuba has one focal length, so for
  ``fy != fx`` every world y coordinate (vertices, lamp positions) is scaled by
  ``fy / fx`` (0.1 % for Cityscapes): the projection is then exact and the
  geometry changes imperceptibly. Fov and offsets do not depend on resolution,
  so previews use the same camera with a smaller film.
* **Meshes in memory**: all parts are concatenated; faces are split into one
  ``mi.Mesh`` per material kind, horizontal band of ``BAND_PX`` image rows and
  background/foreground (non-light faces) plus one per annotated light
  instance (faces two of whose vertices carry that light id). After an annotation
  edit only the bands and lights whose faces changed are rebuilt
  (``build_scene(..., previous=...)``); every other shape is reused. Each light mesh
  has an ``area`` emitter; lights that are off have radiance 0 *and* emitter
  ``sampling_weight`` 0, so :meth:`BuiltScene.apply_lights` toggles lights via
  ``mi.traverse`` + ``params.update()`` and never rebuilds geometry.
* **Directional falloff**: an area emitter on a lamp mask emits (Lambertian)
  toward the camera -- it makes the lamp glow but lights little else. Classes
  with ``throw`` (street lights, car front lamps) also get a Mitsuba ``spot``
  at the mask's 3-D centroid: street lights aim straight down (world down, using
  the camera pitch), car lamps along the mask's mean normal tilted 10° down.
  Spot intensity = radiance · mask area · ``throw.gain``; the lamp's visible
  area emitter is then capped at ``throw.max_visible_radiance`` (max channel, 2.0:
  saturated at any sane exposure) to avoid fireflies. Mitsuba's spot has a
  smooth falloff between ``beam_deg`` and ``cutoff_deg`` (standing in for SOLO's
  cos/cos² falloff).
* **Ego headlights**: two spots 0.5 m left/right of the camera, 0.65 m above the
  ground, aimed level, whose intensity is shaped by a **low-beam pattern**
  (:func:`low_beam_pattern`, projected as the spot's texture): full intensity just below a
  cut-off line 0.57° under the horizon (rising at 15° on the kerb side), about 2 % above it.
  A plain cone would put its full intensity on everything up to 17° above its axis: a
  pedestrian's body facing the lamps 10 m ahead then receives 15x the irradiance of the road
  he stands on and saturates (docs/relight.md, "People in the headlights"). On by default,
  switchable in place.
* **Night sky**: a constant environment of ``sky.radiance`` (dim, bluish);
  sky pixels (no mesh) show it.
* Textures: one bitmap of the albedo map, looked up with the mesh UVs (Mitsuba
  bitmaps have v = 0 at the top row, so v is flipped on upload).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..annotation import LightAnnotation
from ..camera import Intrinsics
from ..errors import NpsimInputError
from ..mesh.types import MeshPart, SceneMesh
from .lights import ActiveLights, LightTable, cct_to_chromaticity
from .materials import GLASS_LIGHT_CLASSES, KINDS, Materials
from .variant import set_variant


#: Emitter sampling weight of a light that is off: (almost) never picked for next-event
#: estimation, but never exactly 0 so a night with no light at all still has a valid
#: emitter distribution (Mitsuba refuses an all-zero one). Changing it through
#: ``params.update()`` rebuilds Mitsuba's emitter distribution (measured).
OFF_WEIGHT = 1e-6
#: Image rows per band of the non-light shapes: an annotation edit rebuilds the bands it touches.
BAND_PX = 64
#: d0² (m²) of the emitter-sampling distance heuristic ``power / (d² + d0²)`` (BuiltScene.apply_lights).
NEAR_D0_M2 = 25.0
#: Mitsuba samplers a render may use (:func:`camera_dict`): ``independent`` (uniform random
#: numbers), ``multijitter`` (correlated multi-jittered, any sample count), ``stratified`` (the
#: count rounded to a square) and ``ldsampler`` (a (0, 2)-sequence, the count rounded to a power of 2).
SAMPLERS = ("independent", "multijitter", "stratified", "ldsampler")
#: The sampler of the nights, previews and guides (``night.sampler``): multi-jittered samples are
#: stratified in every dimension of a path (pixel position, light choice, BSDF), so at the same spp
#: the noise is lower than with ``independent`` (the sampler before): at 128x64 the seed-to-seed mean
#: |difference| was 0.6x at 8 and 16 spp (tests/test_render.py). At 2048x1024 after OIDN, against a
#: 4096-spp reference on the frontier's crops: 8 spp RMSE 18.8 vs 22.4 levels, 16 spp 17.5 vs 17.3
#: (equal within seeds) with SSIM 0.736 vs 0.727; ~5 % more CPU per sample
#: (``python -m benchmarks.render --frontier --samplers independent,multijitter``).
RENDER_SAMPLER = "multijitter"
#: Path tracers of the renders (:attr:`BuildParams.integrator`): Mitsuba's ``path``, or ``onebounce``
#: (:mod:`.integrator`): at one bounce (max_depth 3) the path without its last BSDF ray, 27 % less
#: render CPU at 2048x1024, 16 spp (other depths and the scalar variants use ``path``).
INTEGRATORS = ("path", "onebounce")


@dataclass(frozen=True)
class BuildParams:
    """Scene-building options.

    ego_headlights : the ego vehicle's two low beams (can also be toggled later).
    sky : dim constant night sky (False = black world).
    throw_spots : lamp heads / car lamps also get a spot lighting the scene.
    max_depth : path length of the final render's path tracer (2 = direct light only, 3 = one
        bounce -- the default: at night nearly all light is direct or one bounce from a lamp pool).
    camera_height, camera_pitch : metres / radians, place the ego lamps and the street-light aim.
    sampler : Mitsuba sampler of the scene's renders (:data:`SAMPLERS`).
    integrator : path tracer of the renders (:data:`INTEGRATORS`, :func:`integrator_dict`).
    """

    ego_headlights: bool = True
    sky: bool = True
    throw_spots: bool = True
    max_depth: int = 3
    camera_height: float = 1.22
    camera_pitch: float = 0.038
    sampler: str = RENDER_SAMPLER
    integrator: str = "onebounce"

    def __post_init__(self) -> None:
        if self.sampler not in SAMPLERS:
            raise NpsimInputError(f"sampler must be one of {', '.join(SAMPLERS)}, got {self.sampler!r}")
        if self.integrator not in INTEGRATORS:
            raise NpsimInputError(f"integrator must be one of {', '.join(INTEGRATORS)}, got {self.integrator!r}")


def integrator_dict(mi, max_depth: int, kind: str = "onebounce") -> dict:
    """Mitsuba integrator of a render of path length ``max_depth``: ``onebounce`` (:mod:`.integrator`)
    when asked for at max_depth 3 in a JIT variant, else Mitsuba's ``path``."""
    from .integrator import NAME, register

    if kind == "onebounce" and int(max_depth) == 3 and register(mi):
        return {"type": NAME}
    return {"type": "path", "max_depth": int(max_depth)}


def camera_dict(intr: Intrinsics, width: int | None = None, height: int | None = None, *,
                pixel_centres: bool = False, crop: tuple[int, int, int, int] | None = None,
                sampler: str = RENDER_SAMPLER) -> dict:
    """Mitsuba ``perspective`` sensor reproducing ``intr`` (module docstring), film ``width`` x ``height``.

    ``pixel_centres`` samples each pixel at its centre (stratified, no jitter) --
    for 1-spp label renders; the camera is nudged by 0.01 px so those rays do not
    pass exactly through grid vertices (where a ray can slip between triangles).
    ``crop = (x, y, w, h)`` renders only that window of the film (pixels of the
    ``width`` x ``height`` film), e.g. for high-spp reference patches. ``sampler`` is one of
    :data:`SAMPLERS` (ignored with ``pixel_centres``).
    """
    import mitsuba as mi

    if sampler not in SAMPLERS:
        raise NpsimInputError(f"sampler must be one of {', '.join(SAMPLERS)}, got {sampler!r}")
    W, H = intr.width, intr.height
    w, h = int(width or W), int(height or H)
    fov = math.degrees(2.0 * math.atan(W / (2.0 * intr.fx)))
    sampler = ({"type": "stratified", "sample_count": 1, "jitter": False} if pixel_centres
               else {"type": sampler, "sample_count": 1})
    nudge = 0.01 if pixel_centres else 0.0
    film = {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"},
            "pixel_format": "rgb", "component_format": "float32"}
    if crop is not None:
        cx0, cy0, cw, ch = (int(v) for v in crop)
        film.update(crop_offset_x=cx0, crop_offset_y=cy0, crop_width=cw, crop_height=ch)
    return {"type": "perspective", "fov": fov, "fov_axis": "x",
            "principal_point_offset_x": (W / 2.0 - intr.cx - 0.5 + nudge) / W,
            "principal_point_offset_y": (H / 2.0 - intr.cy - 0.5 + nudge) / H,
            "near_clip": 0.01, "far_clip": 1e5,
            "to_world": mi.ScalarTransform4f().rotate([0, 0, 1], 180.0),
            "sampler": sampler, "film": film}


def _y_scale(intr: Intrinsics) -> float:
    return float(intr.fy / intr.fx)


@dataclass
class _Geometry:
    """All parts concatenated, with per-face attributes."""

    vertices: np.ndarray  # (V, 3) float32, world (y already scaled)
    uv: np.ndarray        # (V, 2) float32, Mitsuba convention (v = 0 top)
    faces: np.ndarray     # (F, 3) int32 (half the memory of int64 at millions of faces)
    face_label: np.ndarray
    face_light: np.ndarray
    face_band: np.ndarray  # (F,) int32: 2 * (image row of the first vertex // BAND_PX) + foreground


def _face_light_majority(light_id: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Light id of each face: the id at least two of its vertices share (0 otherwise).

    Looser than ``MeshPart.face_light_id`` (all three) so that thin light masks
    (one or two pixels wide) still get emissive faces.
    """
    l = np.asarray(light_id)[faces]
    pick = np.where((l[:, 0] == l[:, 1]) | (l[:, 0] == l[:, 2]), l[:, 0], np.where(l[:, 1] == l[:, 2], l[:, 1], 0))
    return pick.astype(np.int32)


def _visible_background_repair(mesh: SceneMesh, labels: np.ndarray, light_ids: np.ndarray | None):
    """Per part: (uv, label, light_id) with *visible* background vertices restored to their own pixel.

    The post-processing kernel gives completed background vertices the uv/label of a
    row neighbour and light id 0 -- right for vertices hidden behind an object, but it
    also does so for completed vertices in the uncertain region U that nothing covers,
    which are *visible*: there the texture, label and light would be a neighbour's
    and the night would no longer fit the day labels. A background vertex is visible
    when no foreground part has a vertex on its pixel; such vertices get their own
    pixel's uv, label and light id back. (No-op for a plain grid mesh.)
    """
    H, W = labels.shape
    covered = np.zeros(H * W, dtype=bool)
    for p in mesh.parts:
        if p.foreground and p.n_vertices:
            px = np.rint(p.pixel).astype(np.int64)
            covered[px[:, 1] * W + px[:, 0]] = True
    out = []
    for p in mesh.parts:
        uv, lab, lid = p.uv, p.label, p.light_id
        if not p.foreground and p.n_vertices:
            px = np.rint(p.pixel).astype(np.int64)
            flat = px[:, 1] * W + px[:, 0]
            # Vertices closing depth steps sit between pixels and carry their own position's uv.
            vis = ~covered[flat] & (p.pixel == np.rint(p.pixel)).all(1)
            own_uv = np.stack([(px[:, 0] + 0.5) / W, 1.0 - (px[:, 1] + 0.5) / H], 1).astype(np.float32)
            uv = np.where(vis[:, None], own_uv, uv)
            lab = np.where(vis, labels.ravel()[flat], lab).astype(np.uint8)
            if light_ids is not None:
                lid = np.where(vis, np.asarray(light_ids).ravel()[flat], lid).astype(np.int32)
        out.append((uv, lab, lid))
    return out


def _gather(mesh: SceneMesh, y_scale: float, labels: np.ndarray | None = None,
            light_ids: np.ndarray | None = None) -> _Geometry:
    vs, uvs, fs, fl, fli, fb = [], [], [], [], [], []
    off = 0
    repaired = (_visible_background_repair(mesh, labels, light_ids) if labels is not None
                else [(p.uv, p.label, p.light_id) for p in mesh.parts])
    for p, (puv, plab, plid) in zip(mesh.parts, repaired):
        if p.n_faces == 0:
            continue
        v = np.asarray(p.vertices, dtype=np.float32)
        if not np.isfinite(v).all():
            raise NpsimInputError(f"mesh part {p.name!r} has non-finite vertices; remove invalid pixels before meshing")
        vs.append(v)
        uv = np.asarray(puv, dtype=np.float32).copy()
        uv[:, 1] = 1.0 - uv[:, 1]
        uvs.append(uv)
        fs.append(np.asarray(p.faces, dtype=np.int32) + np.int32(off))
        fl.append(MeshPart.face_label(dataclasses.replace(p, label=plab)))
        fli.append(_face_light_majority(plid, p.faces))
        rows = np.rint(np.asarray(p.pixel)[np.asarray(p.faces)[:, 0], 1]).astype(np.int32)
        fb.append(2 * (np.clip(rows, 0, None) // BAND_PX) + int(bool(p.foreground)))
        off += p.n_vertices
    if not fs:
        raise NpsimInputError("the scene mesh has no faces (all sky or invalid depth?); check the depth map")
    verts = np.concatenate(vs)
    verts[:, 1] *= y_scale
    return _Geometry(verts, np.concatenate(uvs), np.concatenate(fs), np.concatenate(fl), np.concatenate(fli),
                     np.concatenate(fb))


def _submesh(mi, name: str, geo: _Geometry, face_sel: np.ndarray, props) -> "object":
    """A ``mi.Mesh`` of the selected faces (mask or index array) with compacted vertices."""
    faces = geo.faces[face_sel]
    lo, hi = (int(faces.min()), int(faces.max())) if len(faces) else (0, 0)
    if faces.size * 8 < hi - lo + 1:
        # small subset (one light): sorting its few indices beats touching every vertex
        used, local = np.unique(faces.ravel(), return_inverse=True)
    else:
        # O(range + F) compaction (no sort) over the vertex range the faces use (a band of the
        # row-major background grid is one range): keep used vertices, renumber by running count.
        mask = np.zeros(hi - lo + 1, dtype=bool)
        mask[faces.ravel() - lo] = True
        remap = np.cumsum(mask, dtype=np.int32) - 1
        used, local = np.flatnonzero(mask) + lo, remap[faces - lo]
        del remap, mask
    m = mi.Mesh(name, vertex_count=len(used), face_count=len(faces), has_vertex_normals=False,
                has_vertex_texcoords=True, props=props)
    p = mi.traverse(m)
    FT, UT = type(p["vertex_positions"]), type(p["faces"])
    p["vertex_positions"] = FT(np.ascontiguousarray(geo.vertices[used]).ravel())
    p["faces"] = UT(local.astype(np.uint32, copy=False).ravel())
    p["vertex_texcoords"] = FT(np.ascontiguousarray(geo.uv[used]).ravel())
    p.update()
    return m


def _mesh_area(geo: _Geometry, chunk: int = 1 << 20) -> float:
    """Total face area (m²), in chunks of faces: all at once the float64 temporaries of a
    4.7 M-face mesh took ~0.7 GB (docs/relight.md)."""
    total = 0.0
    for k in range(0, len(geo.faces), chunk):
        f = geo.faces[k:k + chunk]
        a, b, c = (geo.vertices[f[:, i]].astype(np.float64) for i in range(3))
        total += float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())
    return total


def _face_areas_centroid(geo: _Geometry, sel: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Total area (m²), area-weighted centroid and mean unit normal of the selected faces."""
    f = geo.faces[sel]
    v = geo.vertices
    a, b, c = (v[f[:, k]].astype(np.float64) for k in range(3))
    cr = np.cross(b - a, c - a)
    area = 0.5 * np.linalg.norm(cr, axis=1)
    tot = float(area.sum())
    cen = ((a + b + c) / 3.0 * area[:, None]).sum(0) / max(tot, 1e-12)
    n = cr.sum(0)
    n = n / max(np.linalg.norm(n), 1e-12)
    return tot, cen, n


def _lum(rgb) -> float:
    """Rec. 709 luminance of a linear RGB triple."""
    return float(0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2])


def _cone_solid_angle(cutoff_deg: float) -> float:
    return 2.0 * math.pi * (1.0 - math.cos(math.radians(cutoff_deg)))


def _level_to_camera(pitch: float) -> np.ndarray:
    """Rotation taking a level (gravity-aligned, y down) frame to the camera frame pitched down by ``pitch``."""
    c, s = math.cos(pitch), math.sin(pitch)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]], dtype=np.float64)


def _spot_transform(mi, origin: np.ndarray, direction: np.ndarray):
    d = direction / np.linalg.norm(direction)
    up = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    return mi.ScalarTransform4f().look_at(origin=[float(x) for x in origin], target=[float(x) for x in origin + d],
                                          up=[float(x) for x in up])


#: Low-beam pattern (docs/relight.md, "People in the headlights"): cut-off line elevation on the
#: oncoming side (deg), its rise on the kerb side (deg per deg, up to ``LOW_BEAM_RISE_MAX_DEG``),
#: the relative intensity above the cut-off (glare light) and the width of the cut-off's edge (deg).
LOW_BEAM_CUTOFF_DEG = -0.57
LOW_BEAM_RISE = math.tan(math.radians(15.0))
LOW_BEAM_RISE_MAX_DEG = 1.6
LOW_BEAM_ABOVE = 0.02
LOW_BEAM_EDGE_DEG = 0.3


def low_beam_pattern(cutoff_deg: float, rows: int = 1024, cols: int = 128) -> np.ndarray:
    """(rows, cols, 3) float32 relative intensity of a low beam, as a Mitsuba ``spot`` texture.

    Texel (r, c) is the direction ``(a, b, 1)`` in the spot's frame with ``a, b`` spanning
    ``±tan(cutoff_deg)`` (row 0 = down, column 0 = the kerb side, i.e. the image's right, as
    the spot's local x points left). Below the cut-off line the intensity peaks 1.5° under it
    and falls to 25 % far below (the near road is close, so it stays lit); above it only
    ``LOW_BEAM_ABOVE`` of it goes out (glare light), with a ``LOW_BEAM_EDGE_DEG`` soft edge.
    The horizontal spread is the spot's own ``beam_deg``/``cutoff_deg`` falloff.
    """
    t = math.tan(math.radians(float(cutoff_deg)))
    a = ((np.arange(cols) + 0.5) / cols * 2.0 - 1.0) * t
    b = ((np.arange(rows) + 0.5) / rows * 2.0 - 1.0) * t
    A, B = np.meshgrid(a, b)
    h_kerb = np.degrees(np.arctan(-A))                      # + toward the kerb side (image right)
    elev = np.degrees(np.arctan2(B, np.sqrt(1.0 + A * A)))
    line = LOW_BEAM_CUTOFF_DEG + np.minimum(np.maximum(h_kerb, 0.0) * LOW_BEAM_RISE, LOW_BEAM_RISE_MAX_DEG)
    below = 0.25 + 0.75 * np.exp(-((elev - (line - 1.5)) / 5.0) ** 2)
    s = np.clip((elev - line) / LOW_BEAM_EDGE_DEG * 0.5 + 0.5, 0.0, 1.0)
    s = s * s * (3.0 - 2.0 * s)                            # smoothstep across the cut-off's edge
    f = below * (1.0 - s) + LOW_BEAM_ABOVE * s
    return np.repeat(f[..., None], 3, axis=2).astype(np.float32)


@dataclass
class BuiltScene:
    """A loaded Mitsuba scene plus the handles needed to toggle lights in place."""

    scene: object
    variant: str
    intrinsics: Intrinsics
    table: LightTable | None
    #: light id -> traverse key prefix of its area emitter (``<shape>.emitter``).
    area_keys: dict[int, str] = field(default_factory=dict)
    #: light id -> emitting area (m²), for power-proportional emitter sampling.
    area_m2: dict[int, float] = field(default_factory=dict)
    #: light id -> distance (m) of the light's centroid from the camera (emitter sampling heuristic).
    distance_m: dict[int, float] = field(default_factory=dict)
    #: light id -> (spot key prefix, intensity per unit radiance (W/sr per radiance)).
    spot_keys: dict[int, tuple[str, float]] = field(default_factory=dict)
    #: solid angle (sr) of the throw spots' and of the ego spots' cones.
    spot_solid_angle: float = 1.0
    ego_solid_angle: float = 1.0
    ego_keys: list[str] = field(default_factory=list)
    ego_intensity: np.ndarray | None = None
    #: Mitsuba sampler of this scene's renders (:data:`SAMPLERS`; ``BuildParams.sampler``).
    sampler: str = RENDER_SAMPLER
    #: Path tracer of this scene's renders (:data:`INTEGRATORS`; ``BuildParams.integrator``).
    integrator_kind: str = "onebounce"
    thread_env: object = None
    build_seconds: float = 0.0
    n_faces: int = 0
    info: dict = field(default_factory=dict)
    #: Pixel box (x0, y0, x1, y1) whose surfaces changed since the ``previous`` scene it was
    #: built from (empty: none); None when built from scratch.
    changed_box: tuple[int, int, int, int] | None = None
    _params: object = None
    _sensors: dict = field(default_factory=dict)
    # what an incremental rebuild reuses (build_scene(previous=...))
    _shapes: dict = field(default_factory=dict)
    _spots: dict = field(default_factory=dict)
    _bsdfs: dict = field(default_factory=dict)
    _alphas: dict = field(default_factory=dict)
    _texture: object = None
    _face_light: np.ndarray | None = None
    _albedo: np.ndarray | None = None
    _sky_weight: float | None = None
    _active: ActiveLights | None = None
    _ego_on: bool = True

    @property
    def params(self):
        import mitsuba as mi

        if self._params is None:
            self._params = mi.traverse(self.scene)
        return self._params

    def sensor(self, width: int, height: int, *, pixel_centres: bool = False,
               crop: tuple[int, int, int, int] | None = None, sampler: str | None = None):
        """A sensor of the scene's camera with a ``width`` x ``height`` film (cached), optionally
        cropped; ``sampler`` (default: the scene's :attr:`sampler`)."""
        import mitsuba as mi

        sampler = sampler or self.sampler
        key = (int(width), int(height), pixel_centres, None if crop is None else tuple(int(v) for v in crop), sampler)
        if key not in self._sensors:
            self._sensors[key] = mi.load_dict(camera_dict(self.intrinsics, width, height, pixel_centres=pixel_centres,
                                                          crop=crop, sampler=sampler))
        return self._sensors[key]

    def integrator(self, max_depth: int):
        """A path tracer of the given path length (cached), for renders that override the scene's."""
        import mitsuba as mi

        key = ("integrator", int(max_depth))
        if key not in self._sensors:
            self._sensors[key] = mi.load_dict(integrator_dict(mi, int(max_depth), self.integrator_kind))
        return self._sensors[key]

    def apply_lights(self, active: ActiveLights) -> float:
        """Set every light's radiance (0 when off) in place; returns the seconds it took."""
        t0 = time.perf_counter()
        p = self.params
        # Emitters are picked for next-event estimation in proportion to their power
        # (area light: pi * L * A; spot: I * cone solid angle) over (d^2 + d0^2), d = distance
        # from the camera: a street lamp is not sampled as rarely as one of fifty dim windows,
        # and lamps near the camera, which light most of the pixels, get more samples
        # (Mitsuba has no spatial light tree; any weights keep the estimate unbiased).
        cap = float(self.table.throw.get("max_visible_radiance", 2.0)) if self.table is not None else np.inf
        for lid, key in self.area_keys.items():
            st = active.lights.get(lid)
            on = st is not None and st.on
            rad = list(st.radiance) if on else [0.0, 0.0, 0.0]
            if lid in self.spot_keys and max(rad) > cap:
                # A lamp whose light reaches the scene through its spot: its visible surface only
                # has to look saturated; capping it removes fireflies from paths that hit the tiny,
                # very bright lamp head by chance (e.g. in glossy asphalt).
                rad = [r * cap / max(rad) for r in rad]
            p[f"{key}.radiance.value"] = type(p[f"{key}.radiance.value"])(*rad)
            p[f"{key}.sampling_weight"] = (max(math.pi * _lum(rad) * self.area_m2.get(lid, 1.0)
                                               * self._near(lid), OFF_WEIGHT) if on else OFF_WEIGHT)
        for lid, (key, gain) in self.spot_keys.items():
            st = active.lights.get(lid)
            on = st is not None and st.on
            inten = [gain * r for r in st.radiance] if on else [0.0, 0.0, 0.0]
            p[f"{key}.intensity.value"] = type(p[f"{key}.intensity.value"])(*inten)
            p[f"{key}.sampling_weight"] = (max(_lum(inten) * self.spot_solid_angle * self._near(lid), OFF_WEIGHT)
                                           if on else OFF_WEIGHT)
        self._set_ego(p, self._ego_on)
        p.update()
        self._active = active
        return time.perf_counter() - t0

    def _near(self, lid: int) -> float:
        d = self.distance_m.get(lid, 10.0)
        return 1.0 / (d * d + NEAR_D0_M2)

    def set_ego_headlights(self, on: bool) -> None:
        """Switch the ego vehicle's headlights in place."""
        self._ego_on = bool(on)
        p = self.params
        self._set_ego(p, self._ego_on)
        p.update()

    def _set_ego(self, p, on: bool) -> None:
        for key in self.ego_keys:
            val = self.ego_intensity if on else np.zeros(3)
            p[f"{key}.intensity.value"] = type(p[f"{key}.intensity.value"])(*[float(x) for x in val])
            p[f"{key}.sampling_weight"] = (max(_lum(val) * self.ego_solid_angle / NEAR_D0_M2, OFF_WEIGHT)
                                           if on else OFF_WEIGHT)


def kind_alphas(materials: Materials, light_classes: np.ndarray) -> dict[str, float]:
    """Rough-plastic alpha of each BSDF kind: the mean roughness of the pixels of that kind
    (to 0.01), squared, in [0.01, 1] (Mitsuba's rough plastic takes one alpha per BSDF). A pixel's kind is
    its label's, glass where ``light_classes`` ((H, W), 0 = none) marks a window."""
    kind = materials.kind_lut[materials.labels.astype(np.intp)]
    kind = np.where(np.isin(light_classes, GLASS_LIGHT_CLASSES), KINDS.index("glass"), kind).ravel()
    rough = materials.roughness.astype(np.float64).ravel()
    n = np.bincount(kind, minlength=len(KINDS))
    total = np.bincount(kind, weights=rough, minlength=len(KINDS))
    # Rounded to 0.01: a light edit moves a kind's mean by ~1e-4 and then leaves its BSDF as it
    # is -- updating a rough plastic's alpha holds the GIL for 150-285 ms (a stall in the app).
    mean = np.round(np.where(n > 0, total / np.maximum(n, 1), 0.5), 2)
    return {k: float(np.clip(mean[i] * mean[i], 0.01, 1.0)) for i, k in enumerate(KINDS)}


def build_scene(mesh: SceneMesh, intrinsics: Intrinsics, materials: Materials, table: LightTable,
                annotation: LightAnnotation | None = None, active: ActiveLights | None = None,
                params: BuildParams = BuildParams(), *, variant: str | None = None,
                previous: "BuiltScene | None" = None) -> BuiltScene:
    """Build the night scene in memory.

    Parameters
    ----------
    mesh : camera-frame scene mesh (OpenCV frame, front faces toward the camera) with the
        light ids of ``annotation`` (:func:`npsim_core.chain.stages.lit_mesh`).
    intrinsics : the camera of the mesh (``mesh.width`` x ``mesh.height``).
    materials : albedo/roughness maps and BSDF kinds (:func:`materials.estimate_materials`).
    table : light table (units, throw spots, ego headlights, sky).
    annotation : light instances; their faces become separate emissive meshes.
    active : initial light states (None: all off until :meth:`BuiltScene.apply_lights`).
    variant : Mitsuba variant (None -> :func:`variant.choose_variant`).
    previous : a scene built from the same mesh geometry, table, ``params``, variant and albedo
        with another annotation: only the shapes of the bands and lights whose faces changed are
        built again, the others are taken from it (``info["rebuilt"]`` says how many). It must
        not be rendered afterwards (its BSDFs may change). Ignored when it does not match.
    """
    t0 = time.perf_counter()
    _check(mesh, intrinsics)
    mi = set_variant(variant)
    ys = _y_scale(intrinsics)
    geo = _gather(mesh, ys, materials.labels, annotation.instance_map if annotation is not None else None)
    F = len(geo.faces)
    if annotation is None:
        geo.face_light[:] = 0
    light_map = annotation.class_map() if annotation is not None else np.zeros(materials.labels.shape, np.uint8)
    prev = previous if (previous is not None and previous._face_light is not None
                        and len(previous._face_light) == F and previous.variant == mi.variant()
                        and previous._albedo is not None and previous._albedo.shape == materials.albedo.shape
                        and np.array_equal(previous._albedo, materials.albedo)) else None

    if previous is not None:  # its acceleration structure goes before the new one is built (memory)
        previous.scene, previous._params, previous._sensors = None, None, {}
    kind_of_face = materials.kind_lut[geo.face_label.astype(np.intp)]
    light_cls = geo.face_light // 1000
    kind_of_face = np.where(np.isin(light_cls, GLASS_LIGHT_CLASSES), KINDS.index("glass"), kind_of_face)
    alphas = kind_alphas(materials, light_map)

    if prev is not None:
        bsdfs, tex = prev._bsdfs, prev._texture
        for kind, a in alphas.items():  # roughness may follow the lights (windows are glass)
            b = bsdfs.get(kind)
            if b is not None and kind != "diffuse" and prev._alphas.get(kind) != a:
                bp_ = mi.traverse(b)
                bp_["alpha"] = a
                bp_.update()
    else:
        bitmap = mi.Bitmap(np.ascontiguousarray(materials.albedo, dtype=np.float32))
        tex = mi.load_dict({"type": "bitmap", "bitmap": bitmap, "raw": True, "filter_type": "nearest",
                            "wrap_mode": "clamp"})
        bsdfs = {}

    def bsdf(kind: str):
        # One BSDF per kind, shared by all shapes of that kind (rough plastic takes ~0.07 s to build).
        if kind in bsdfs:
            return bsdfs[kind]
        if kind == "diffuse":
            b = mi.load_dict({"type": "diffuse", "reflectance": tex})
        elif kind == "glass":
            # Unlit window: dark glass-like coat (spec 4 % via plastic IOR 1.5, little diffuse).
            b = mi.load_dict({"type": "roughplastic", "diffuse_reflectance": {"type": "rgb", "value": 0.03},
                              "alpha": alphas[kind], "int_ior": 1.5})
        else:
            b = mi.load_dict({"type": "roughplastic", "diffuse_reflectance": tex, "alpha": alphas[kind],
                              "int_ior": 1.5, "nonlinear": kind == "paint"})
        bsdfs[kind] = b
        return b

    # What changed since ``previous``: faces whose light id changed; a band is rebuilt when a face
    # of it joined or left the lights, a light when any of its faces changed.
    if prev is not None:
        changed = np.flatnonzero(geo.face_light != prev._face_light)
        old, new = prev._face_light[changed], geo.face_light[changed]
        dirty_bands = set(np.unique(geo.face_band[changed[(old == 0) | (new == 0)]]).tolist())
        dirty_lights = set(np.unique(np.concatenate([old, new])).tolist()) - {0}
        reused = prev._shapes
    else:
        changed, dirty_bands, dirty_lights, reused = None, set(), set(), {}

    objects: dict[str, object] = {}
    shapes: dict[str, object] = {}
    light_ids = sorted(int(i) for i in np.unique(geo.face_light) if i != 0)
    # non-light faces: one shape per (kind, band); faces grouped by one sort
    n_band = int(geo.face_band.max()) + 1 if F else 1
    base = np.flatnonzero(geo.face_light == 0)
    group = kind_of_face[base].astype(np.int64) * n_band + geo.face_band[base]
    order = np.argsort(group, kind="stable")
    base, group = base[order], group[order]
    del order
    keys, starts = np.unique(group, return_index=True)
    ends = np.append(starts[1:], len(group))
    del group
    for g, i0, i1 in zip(keys.tolist(), starts.tolist(), ends.tolist()):
        ki, band = divmod(g, n_band)
        name = f"mesh_{KINDS[ki]}_{band}"
        if name in reused and band not in dirty_bands:
            shapes[name] = reused[name]
            continue
        props = mi.Properties()
        props["bsdf"] = bsdf(KINDS[ki])
        shapes[name] = _submesh(mi, name, geo, base[i0:i1], props)
    del base

    built = BuiltScene(scene=None, variant=mi.variant(), intrinsics=intrinsics, table=table, n_faces=F,
                       sampler=params.sampler, integrator_kind=params.integrator)
    throw = table.throw
    built.spot_solid_angle = _cone_solid_angle(float(throw.get("cutoff_deg", 70.0)))
    built.ego_solid_angle = _cone_solid_angle(float(table.ego_headlight.get("cutoff_deg", 35.0)))
    pitch = params.camera_pitch
    R = _level_to_camera(pitch)
    down = R @ np.array([0.0, 1.0, 0.0])
    down[1] *= ys
    # Faces of each light via one sort instead of a full scan per light.
    lit_faces = np.nonzero(geo.face_light)[0]
    lit_faces = lit_faces[np.argsort(geo.face_light[lit_faces], kind="stable")]
    bounds = np.searchsorted(geo.face_light[lit_faces], light_ids + [np.iinfo(np.int32).max])
    for j, lid in enumerate(light_ids):
        name = f"light_{lid}"
        if name in reused and lid not in dirty_lights:
            shapes[name] = reused[name]
            built.area_keys[lid] = prev.area_keys[lid]
            built.area_m2[lid], built.distance_m[lid] = prev.area_m2[lid], prev.distance_m[lid]
            if lid in prev.spot_keys:
                built.spot_keys[lid] = prev.spot_keys[lid]
                objects[prev.spot_keys[lid][0]] = prev._spots[prev.spot_keys[lid][0]]
            continue
        sel = lit_faces[bounds[j]:bounds[j + 1]]
        props = mi.Properties()
        kind = KINDS[int(np.bincount(kind_of_face[sel]).argmax())]
        props["bsdf"] = bsdf(kind)
        props["emitter"] = mi.load_dict({"type": "area", "radiance": {"type": "rgb", "value": [0.0, 0.0, 0.0]},
                                         "sampling_weight": OFF_WEIGHT})
        shapes[name] = _submesh(mi, name, geo, sel, props)
        built.area_keys[lid] = f"{name}.emitter"
        area, cen, n = _face_areas_centroid(geo, sel)
        built.area_m2[lid] = area
        built.distance_m[lid] = float(np.linalg.norm(cen))
        spec = table.classes.get(lid // 1000)
        if params.throw_spots and spec is not None and spec.throw:
            if spec.class_id in (8, 9):  # street lights: aim at the ground below the lamp head
                d = down
                origin = cen + 0.15 * d + 0.05 * n
            else:  # car lamps: along the lamp's normal, tilted 10 deg toward the ground
                d = n + math.tan(math.radians(10.0)) * down
                origin = cen + 0.05 * n
            sname = f"spot_{lid}"
            objects[sname] = {"type": "spot", "intensity": {"type": "rgb", "value": [0.0, 0.0, 0.0]},
                              "cutoff_angle": float(throw.get("cutoff_deg", 70.0)),
                              "beam_width": float(throw.get("beam_deg", 45.0)),
                              "to_world": _spot_transform(mi, origin, d), "sampling_weight": OFF_WEIGHT}
            built.spot_keys[lid] = (sname, area * float(throw.get("gain", 20.0)))
    built._spots = {k: v for k, v in objects.items() if k.startswith("spot_")}
    n_rebuilt = sum(1 for k, v in shapes.items() if reused.get(k) is not v)
    if changed is not None and len(changed):
        rows = geo.uv[geo.faces[changed].ravel()]
        x, y = rows[:, 0] * materials.labels.shape[1], rows[:, 1] * materials.labels.shape[0]
        built.changed_box = (int(x.min()), int(y.min()), int(np.ceil(x.max())) + 1, int(np.ceil(y.max())) + 1)
    elif changed is not None:
        built.changed_box = (0, 0, 0, 0)
    objects.update(shapes)
    built._shapes, built._bsdfs, built._texture, built._alphas = shapes, bsdfs, tex, alphas
    built._face_light, built._albedo = geo.face_light, materials.albedo

    # Ego vehicle headlights: level frame (y down), lamps 0.65 m above the ground, aimed 15 m ahead.
    ego = table.ego_headlight
    h = params.camera_height
    chroma = (tuple(ego["chromaticity"]) if "chromaticity" in ego else cct_to_chromaticity(float(ego.get("cct_K", 5000))))
    s_ego = 0.5 * sum(ego["strength"])
    w_m, h_m = ego.get("size_m", [0.3, 0.15])
    built.ego_intensity = table.radiance(s_ego, chroma) * w_m * h_m * float(ego.get("gain", 60.0))
    cutoff = float(ego.get("cutoff_deg", 35.0))
    beam = mi.Bitmap(low_beam_pattern(cutoff))
    for side, x in (("left", -0.5), ("right", 0.5)):
        # Aimed level (the low-beam pattern holds the vertical distribution), local +y = world up.
        o = R @ np.array([x, h - 0.65, 0.3])
        fwd = R @ np.array([0.0, 0.0, 1.0])
        up = R @ np.array([0.0, -1.0, 0.0])
        o[1] *= ys
        fwd[1] *= ys
        up[1] *= ys
        name = f"ego_{side}"
        objects[name] = {"type": "spot", "intensity": {"type": "rgb", "value": [0.0, 0.0, 0.0]},
                         "cutoff_angle": cutoff, "beam_width": float(ego.get("beam_deg", 20.0)),
                         "texture": {"type": "bitmap", "bitmap": beam, "raw": True, "filter_type": "bilinear",
                                     "wrap_mode": "clamp"},
                         "to_world": mi.ScalarTransform4f().look_at(origin=[float(v) for v in o],
                                                                    target=[float(v) for v in o + fwd],
                                                                    up=[float(v) for v in up]),
                         "sampling_weight": OFF_WEIGHT}
        built.ego_keys.append(name)
    built._ego_on = params.ego_headlights

    scene_dict = {"type": "scene", "integrator": integrator_dict(mi, int(params.max_depth), params.integrator),
                  "sensor": camera_dict(intrinsics, sampler=params.sampler)}
    if params.sky:
        # Sky power ~ pi * L_sky * (area it lights): weigh it against the lamps with the mesh's area.
        if prev is not None and prev._sky_weight is not None:
            built._sky_weight = prev._sky_weight
        else:
            mesh_area = _mesh_area(geo)
            v = geo.vertices
            built._sky_weight = max(math.pi * _lum(table.sky_radiance) * mesh_area
                                    / (float(np.median(np.linalg.norm(v, axis=1))) ** 2 + NEAR_D0_M2), OFF_WEIGHT)
        scene_dict["sky"] = {"type": "constant", "radiance": {"type": "rgb", "value": list(table.sky_radiance)},
                             "sampling_weight": built._sky_weight}
    scene_dict.update(objects)
    # The concatenated geometry and its per-face arrays (~0.2 GB at 5 M faces) are copied into the
    # shapes by now: freed before the acceleration structure is built on top of them.
    del geo, kind_of_face, light_cls
    t_load = time.perf_counter()
    built.scene = mi.load_dict(scene_dict)
    t_load = time.perf_counter() - t_load
    built.thread_env = capture_thread_env(mi)
    if active is not None:
        built.apply_lights(active)
    else:
        built.set_ego_headlights(built._ego_on)
    built.build_seconds = time.perf_counter() - t0
    built.info = {"variant": built.variant, "faces": F, "shapes": len(objects), "lights": len(light_ids),
                  "rebuilt": (f"{n_rebuilt} of {len(shapes)} shapes (the bands and lights the annotation edit "
                              f"changed)" if prev is not None else "all"),
                  "throw_spots": len(built.spot_keys), "ego_headlights": params.ego_headlights,
                  "y_scale": ys, "materials": materials.source, "scene_load_s": t_load, "sampler": params.sampler,
                  "integrator": integrator_dict(mi, int(params.max_depth), params.integrator)["type"]}
    return built


def build_label_scene(mesh: SceneMesh, intrinsics: Intrinsics, labels: np.ndarray, *,
                      variant: str | None = None) -> BuiltScene:
    """Unshaded label scene for alignment checks.

    The label map is a texture (nearest texel, mesh UVs) on an area emitter covering
    the whole mesh, radiance ``(labelId + 1, 0, 0)``; no other light, path length 1.
    A render therefore shows, per pixel, the label of the source pixel whose
    surface the camera ray hits -- exactly how the night render looks up albedo.
    """
    t0 = time.perf_counter()
    _check(mesh, intrinsics)
    lab = np.asarray(labels)
    if lab.shape != (intrinsics.height, intrinsics.width):
        raise NpsimInputError(f"labels are {lab.shape}, expected {(intrinsics.height, intrinsics.width)}")
    mi = set_variant(variant)
    geo = _gather(mesh, _y_scale(intrinsics), lab)
    codes = np.zeros(lab.shape + (3,), np.float32)
    codes[..., 0] = lab.astype(np.float32) + 1.0
    tex = {"type": "bitmap", "bitmap": mi.Bitmap(codes), "raw": True, "filter_type": "nearest", "wrap_mode": "clamp"}
    props = mi.Properties()
    props["bsdf"] = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}})
    props["emitter"] = mi.load_dict({"type": "area", "radiance": tex})
    objects = {"labels": _submesh(mi, "labels", geo, np.ones(len(geo.faces), bool), props)}
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "path", "max_depth": 1},
                          "sensor": camera_dict(intrinsics), **objects})
    return BuiltScene(scene=scene, variant=mi.variant(), intrinsics=intrinsics, table=None, n_faces=len(geo.faces),
                      thread_env=capture_thread_env(mi), build_seconds=time.perf_counter() - t0)


def capture_thread_env(mi):
    """Mitsuba's thread environment of the calling thread, or None where the binding no longer
    exists (Mitsuba 3.9 renders from any Python thread without it -- measured here)."""
    env_cls = getattr(mi, "ThreadEnvironment", None)
    return env_cls() if env_cls is not None else None


def thread_env_scope(mi, env):
    """Context manager entering ``env`` (no-op when None)."""
    import contextlib

    scoped = getattr(mi, "ScopedSetThreadEnvironment", None)
    return scoped(env) if (env is not None and scoped is not None) else contextlib.nullcontext()


def _check(mesh: SceneMesh, intr: Intrinsics) -> None:
    if not isinstance(mesh, SceneMesh):
        raise NpsimInputError(f"expected a SceneMesh, got {type(mesh).__name__}")
    if (mesh.width, mesh.height) != (intr.width, intr.height):
        raise NpsimInputError(f"mesh is for {mesh.width}x{mesh.height} but the intrinsics are for "
                              f"{intr.width}x{intr.height}; use Intrinsics.resized()")
