"""The chain's stages: each a pure function ``run(inputs, params, ctx) -> result``.

Data flow (names are the engine's; ``frame`` and ``annotation`` are sources)::

    frame ─► geometry ─► filter ─► uncertain ─► refine ─► mesh ─► night_scene ─► guides (oidn: AOVs)
                │                       │                  │  └─► guides (guided: the mesh)
    annotation ─┴─► lights ─► materials ─┴─────────────────┘   (lights: annotation, proposals or a file)

``geometry`` gives the camera and the input depth and normals (the frame's own, or the
semantic pop-up prior when it has none); ``filter``, ``uncertain`` and ``refine`` are
the depth refinement (docs/method.md §3); ``mesh`` is the Worldsheet grid plus the
post-processing kernel (§4–§5); ``materials``, ``night_scene`` and ``guides`` prepare the
night (§6). The per-night steps -- light activation, render, denoise, camera -- are
functions here too, run by :class:`~npsim_core.chain.chain.Chain` for each seed.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..camera import Intrinsics, normals_from_depth
from ..errors import NpsimInputError
from ..mesh.types import MeshPart, SceneMesh
from ..scene import Scene
from .engine import Stage
from .params import ChainParams

__all__ = ["GeometryResult", "LightsResult", "lights_stage", "lights_needs", "MeshResult", "MaterialsResult", "STAGES", "geometry_stage", "filter_stage",
           "uncertain_stage", "refine_stage", "mesh_stage", "materials_stage", "night_scene_stage",
           "guides_stage", "guides_needs", "lit_mesh", "removed_faces", "light_table", "mesh_needs",
           "input_geometry"]


# --------------------------------------------------------------------------- results
@dataclass
class GeometryResult:
    """The frame as the refinement reads it: intrinsics (or the FOV override), input depth and
    normals. ``source`` says where the depth came from; ``confidence`` is the input depth's
    per-pixel confidence when its source gives one (the pop-up prior; NaN where the depth is
    invalid), read by the uncertain map (docs/geometry.md, "Confidence in the chain")."""

    scene: Scene
    source: str
    confidence: np.ndarray | None = None


@dataclass
class LightsResult:
    """The light annotation the nights use (None: no light sources) and where it came from:
    ``source`` is ``annotation``, ``proposed``, ``file`` or ``none``; ``note`` says it in words;
    ``confidence`` holds the proposals' confidences (light and group id -> [0, 1])."""

    annotation: Any
    source: str
    note: str
    confidence: dict = field(default_factory=dict)


@dataclass
class MeshResult:
    """The scene mesh. ``layers``: the post-processed sheets per pixel (for reduction);
    ``counts``: what post-processing did; ``depth``: the depth meshed; ``labels``: the frame's;
    ``reduced``: how a face budget applied; :attr:`removed`: the grid faces post-processing
    replaced (for display, made when first asked for: 60 MB at 2048x1024)."""

    mesh: SceneMesh
    depth: np.ndarray
    intrinsics: Intrinsics
    labels: np.ndarray | None = None
    layers: Any = None
    counts: dict = field(default_factory=dict)
    reduced: str = ""

    @functools.cached_property
    def removed(self) -> MeshPart | None:
        """The Worldsheet grid faces the post-processing kernel replaced (None without it)."""
        if self.layers is None or self.labels is None:
            return None
        return removed_faces(self.depth, self.intrinsics, self.labels, self.layers)


@dataclass
class MaterialsResult:
    """Albedo, roughness and BSDF kinds, and the light-class map (0 = no light) they were made with."""

    materials: Any
    light_classes: np.ndarray


# --------------------------------------------------------------------------- depth
def geometry_stage(inputs: dict, params, ctx) -> GeometryResult:
    """Intrinsics (FOV override) and input depth/normals: the frame's, else the pop-up prior.

    Depths beyond the far limit (``mesh.far_limit``, metres), nearer than ``depth.near_limit``,
    non-positive or non-finite are invalid (NaN): a sky at 1e6 m would otherwise pull the filter
    and the refinement everywhere, 1e-30 m put vertices on the camera centre. The pixels dropped
    are counted in the depth source sentence. A frame without a single valid depth
    is an error.
    """
    camera, far_limit, src = params
    s: Scene = inputs["frame"]
    hfov = float(camera.hfov_deg or 0.0)
    intr = Intrinsics.from_fov(s.width, s.height, hfov) if hfov > 0 else s.intrinsics
    s = s.with_(intrinsics=intr, provenance=dict(s.provenance, hfov_override=hfov or None))
    s, source, conf = input_geometry(s, src, with_confidence=True)
    from ..geometry import DepthLimits, confidence_summary, limit_depth

    near = min(float(src.near_limit), far_limit / 2)
    d, lim = limit_depth(s.depth, near, far_limit)  # every source, the pixels dropped counted
    if not np.isfinite(d).any():
        raise NpsimInputError(f"scene {s.name!r}: no valid depth within {far_limit:g} m (all sky, NaN, <= 0, "
                              f"nearer than {near:g} m (depth.near_limit) or beyond the far limit, mesh.far_limit); "
                              "there is nothing to reconstruct")
    geo = s.provenance.get("geometry")
    est = geo.get("depth_limits") if isinstance(geo, dict) else None
    if est:  # what the estimator itself dropped (estimate_geometry applies the same limits)
        lim = lim + DepthLimits(**est)
    if lim.dropped:
        source += f"; {lim.sentence()}"
        s = s.with_(depth=d, provenance=dict(s.provenance, depth_limits=lim.to_json()))
    if conf is not None:  # (the manifest's provenance and the log say how much of the depth was guessed)
        conf = np.where(np.isfinite(d), conf, np.float32(np.nan)).astype(np.float32)
        summ = confidence_summary(conf)
        source += f"; {summ['sentence']}"
        s = s.with_(provenance=dict(s.provenance, confidence={k: v for k, v in summ.items() if k != "sentence"}))
    return GeometryResult(s, source, conf)


def input_geometry(s: Scene, src, *, with_confidence: bool = False):
    """``s`` with its input depth and normals from the source ``src`` (:class:`~.params.DepthSource`)
    chose, and a sentence saying which (docs/method.md §2.2); with ``with_confidence`` also the
    depth's per-pixel confidence (the pop-up prior's; None for files, stereo and networks)."""
    out = _input_geometry(s, src)
    return out if with_confidence else out[:2]


def _input_geometry(s: Scene, src) -> tuple[Scene, str, np.ndarray | None]:
    """:func:`input_geometry` with the confidence."""
    from ..geometry import estimate_geometry

    kind = src.source
    if kind == "auto":
        kind = ("files" if s.depth is not None else "stereo" if s.depth_stereo is not None
                else "network" if src.checkpoint else "prior")
    if kind == "files":
        if s.depth is None:
            raise NpsimInputError(f"scene {s.name!r} has no depth of its own (depth_pred.npy); create one with "
                                  "'npsim estimate', or choose --depth auto|stereo|prior|network")
        if s.normals is None:
            return s.with_(normals=normals_from_depth(s.depth, s.intrinsics)), "files: the frame's depth (normals " \
                                                                               "from it)", None
        return s, "files: the frame's depth and normals", None
    if kind == "stereo":
        from ..geometry.stereo import StereoParams, without_holdout

        # Held-out stereo pixels never reach the input (nor the surface fits): they score the chain.
        s, n_held = without_holdout(s, src.stereo_max_m, src.stereo_holdout)
        est = estimate_geometry(s, "stereo", StereoParams(max_depth=src.stereo_max_m, holdout=0.0))
        i = est.info
        note = (f"stereo: {100 * i['stereo_valid']:.1f} % of pixels within {src.stereo_max_m:g} m, "
                f"{100 * i['filled_from_prior']:.1f} % filled from the pop-up prior x {i['prior_scale']:.3f}")
        if n_held:
            note += (f"; {100 * src.stereo_holdout:g} % of the valid stereo pixels ({n_held}) held out of the input "
                     "(fixed seed) and scored on alone")
        out = est.apply(s)
        if getattr(src, "stereo_surfaces", False):
            out, fit = stereo_surfaces(s, out, src.stereo_max_m)
            note += (f"; surfaces fitted on {100 * fit['fitted_fraction']:.1f} % of pixels "
                     f"({fit['segments']} segments, {100 * fit['speckle_fraction']:.2f} % speckle dropped)")
        return out, note, None
    if kind == "network":
        from ..geometry.network import NetworkParams

        if not src.checkpoint:
            raise NpsimInputError("--depth network needs --checkpoint DIR (a local checkpoint folder)")
        return estimate_geometry(s, "network", NetworkParams(checkpoint=src.checkpoint)).apply(s), \
            f"network: {src.checkpoint}", None
    est = estimate_geometry(s, "popup")
    return est.apply(s), "prior: semantic pop-up", est.confidence


def stereo_surfaces(frame: Scene, est: Scene, max_depth: float) -> tuple[Scene, dict]:
    """``est`` (the frame with its stereo estimate applied) with the stereo replaced by robust
    per-segment surface fits and their normals (:func:`npsim_core.geometry.surfaces.fit_surfaces`;
    docs/relight.md "Nights of real frames"); the fit's counts."""
    from ..geometry.stereo import stereo_valid
    from ..geometry.surfaces import fit_surfaces

    valid = stereo_valid(frame, max_depth)
    depth, normals, info = fit_surfaces(frame.depth_stereo, valid, est.depth, frame.labels, est.intrinsics,
                                        frame.instances)
    ok = np.isfinite(normals).all(-1)
    normals = np.where(ok[..., None], normals, est.normals).astype(np.float32)
    depth = np.where(np.isfinite(est.depth), depth, np.float32(np.nan)).astype(np.float32)  # sky stays sky
    return est.with_(depth=depth, normals=normals, provenance=dict(est.provenance, stereo_surfaces=info)), info


def filter_stage(inputs: dict, params, ctx) -> np.ndarray:
    """Dual-reference cross-bilateral filter of the input depth (docs/method.md §3.1); (H, W) float32 m."""
    from ..refine.bilateral import cross_bilateral

    s = inputs["geometry"].scene
    return cross_bilateral(s.depth, s.image, s.labels, params).astype(np.float32)


def uncertain_stage(inputs: dict, params, ctx) -> np.ndarray:
    """Uncertain map U of the *filtered* depth (docs/method.md §3.2); (H, W) bool."""
    from ..refine.uncertainty import uncertain_map

    geo: GeometryResult = inputs["geometry"]
    return uncertain_map(inputs["filter"], geo.scene.labels, params, confidence=geo.confidence)


def refine_stage(inputs: dict, params, ctx):
    """Normal-guided refinement (docs/method.md §3.3); reports its loss curves as it runs."""
    from ..refine.optimize import refine_depth

    s = inputs["geometry"].scene
    hist: dict[str, list[float]] = {"total": [], "normal": [], "continuity": [], "depth": []}
    last = [0.0]

    def on_step(step: int, total: int, losses: dict) -> None:
        for k in hist:
            if k in losses:
                hist[k].append(float(losses[k]))
        now = time.perf_counter()
        if now - last[0] > 0.1 or step == total:
            last[0] = now
            ctx.progress(step / max(total, 1), {"stage": "refine", "step": step, "of": total,
                                                "history": {k: list(v) for k, v in hist.items()}})

    # input_depth: a refinement that makes a good input worse keeps the input.
    return refine_depth(inputs["filter"], s.normals, s.intrinsics, inputs["uncertain"], params,
                        progress=on_step, cancel=ctx.cancel_flag, input_depth=s.depth)


# --------------------------------------------------------------------------- lights
def lights_needs(params: ChainParams) -> tuple[str, ...]:
    """What the lights stage reads: the geometry (for the proposals' depth) only when it may propose."""
    return ("frame", "annotation") + (("geometry",) if params.lights.source in ("auto", "proposed") else ())


def lights_stage(inputs: dict, params, ctx) -> LightsResult:
    """The frame's light annotation by ``lights.source`` (docs/method.md §7.5): the hand annotation,
    the automatic proposals above ``min_confidence``, a file, or none."""
    lp = params
    ann = inputs.get("annotation")
    s: Scene = inputs["frame"]
    if lp.source == "none":
        return LightsResult(None, "none", "no light sources (lights.source=none)")
    if lp.source == "file":
        from ..annotation import load_annotation_file

        if not lp.file:
            raise NpsimInputError("lights.source 'file' needs lights.file, a light annotation JSON "
                                  "(CLI: --lights FILE)")

        ann = load_annotation_file(lp.file)
        if ann.shape != (s.height, s.width):
            raise NpsimInputError(f"{lp.file}: the light annotation is {ann.shape[1]}x{ann.shape[0]} but the frame "
                                  f"{s.name!r} is {s.width}x{s.height}; give the annotation of this frame")
        return LightsResult(ann, "file", f"{len(ann.instance_ids())} lights from {lp.file}")
    # an empty annotation (an editor opened on an unlabelled frame) counts as none for ``auto``
    if ann is not None and (lp.source == "annotation" or (lp.source == "auto" and ann.instance_ids())):
        return LightsResult(ann, "annotation", f"{len(ann.instance_ids())} annotated lights")
    if lp.source == "annotation":
        return LightsResult(None, "annotation", "no light annotation: only the ego headlights and the night sky "
                                                "light the nights (label lights with 'npsim annotate')")
    from ..proposals import propose_for_scene

    geo: GeometryResult = inputs["geometry"]
    props = propose_for_scene(geo.scene)  # the depth and camera the chain chose
    kept = props.above(lp.min_confidence)
    ids = kept.instance_ids()
    conf = {i: float(c) for i, c in props.confidence.items() if i in set(ids) or i in kept.groups}
    return LightsResult(kept if ids else None, "proposed",
                        f"{len(ids)} proposed lights (confidence >= {lp.min_confidence:g}; "
                        f"{len(props.annotation.instance_ids())} proposed in all)", conf)


# --------------------------------------------------------------------------- mesh
def mesh_needs(params: ChainParams) -> tuple[str, ...]:
    """The inputs the mesh stage reads for ``params``: the depth it meshes, U only when
    post-processing, the lights only when reducing to a face budget (the reduction keeps light
    borders; otherwise the geometry does not depend on the lights, :func:`lit_mesh`)."""
    base = ("geometry",) + (("lights",) if params.mesh.face_budget else ())
    if params.mesh.stride == 1 and params.mesh.postprocess:
        base += ("uncertain",)
    return base + {"refined": ("refine",), "filtered": ("filter",), "input": ()}[params.mesh.depth]


def mesh_stage(inputs: dict, params, ctx) -> MeshResult:
    """Worldsheet grid of the chosen depth + post-processing kernel (docs/method.md §4–§5).
    ``stride`` > 1 gives a strided grid without post-processing. The mesh carries no light ids
    (all 0) unless it was reduced to a face budget: an annotation edit does not rebuild it,
    :func:`lit_mesh` gives it the lights."""
    from ..mesh.grid import grid_mesh
    from ..render.ego import extend_over_margin, no_mesh_labels

    mp, pp = params
    s = inputs["geometry"].scene
    depth = {"refined": lambda: inputs["refine"].depth, "filtered": lambda: inputs["filter"],
             "input": lambda: s.depth}[mp.depth]().astype(np.float32)
    depth = extend_over_margin(depth, s.labels)  # the bonnet's depth bleeds into the road above it
    intr = s.intrinsics
    if mp.postprocess and mp.stride == 1:
        from ..mesh.postprocess import postprocess_mesh

        # The ego vehicle and the frame borders are not part of the street (docs/relight.md, "The ego vehicle").
        res = postprocess_mesh(depth, intr, s.labels, inputs["uncertain"],
                               params=replace(pp, far_limit=mp.far_limit, exclude=no_mesh_labels(pp.exclude)),
                               normals=s.normals)
        ctx.cancel()
        out = MeshResult(res.mesh, depth, intr, s.labels, res.layers, dict(res.counts))
        if mp.face_budget and res.mesh.n_faces > mp.face_budget:
            from ..mesh.reduce import ReduceParams, reduce_mesh
            from ..mesh.types import limit_far

            ann = inputs["lights"].annotation
            red = reduce_mesh(res.layers.with_lights(ann.instance_map if ann is not None else None), intr,
                              ReduceParams(budget=int(mp.face_budget)))
            out.mesh, out.reduced = limit_far(red.mesh, mp.far_limit), red.steps
        return out
    mesh = grid_mesh(depth, intr, s.labels, stride=int(mp.stride), far_limit=mp.far_limit,
                     exclude=no_mesh_labels(None))
    return MeshResult(mesh, depth, intr, counts={"faces": mesh.n_faces})


def removed_faces(depth: np.ndarray, intrinsics: Intrinsics, labels: np.ndarray, layers) -> MeshPart:
    """The Worldsheet grid faces of ``depth`` the post-processing kernel did not keep, as one part
    (see :func:`npsim_core.mesh.postprocess.replaced_grid_faces`)."""
    from ..mesh.grid import grid_mesh
    from ..mesh.postprocess import replaced_grid_faces

    parts = [p for p in grid_mesh(depth, intrinsics, labels).parts if p.n_faces]
    if not parts:
        return MeshPart("removed", np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64),
                        np.zeros((0, 2), np.float32), np.zeros((0, 2), np.float32), np.zeros(0, np.uint8),
                        np.zeros(0, np.int32))
    p = parts[0]
    keep = replaced_grid_faces(p, layers)
    return MeshPart("removed", p.vertices, p.faces[keep], p.uv, p.pixel, p.label, p.light_id)


# --------------------------------------------------------------------------- night
def light_table(night):
    """The light table (``night.light_table`` merged over the default) with the per-class
    probability overrides of ``night.probabilities``."""
    from ..render.lights import load_light_table

    table = load_light_table(night.light_table or None)
    if not night.probabilities:
        return table
    specs = dict(table.classes)
    for cid, p in night.probabilities:
        specs[int(cid)] = replace(specs[int(cid)], p=(float(p), float(p)))
    return replace(table, classes=specs)


def materials_stage(inputs: dict, params, ctx) -> MaterialsResult:
    """Albedo/roughness from the frame's maps or the per-class fallback (docs/method.md §6.1)."""
    from ..render.materials import estimate_materials

    s, ann = inputs["frame"], inputs["lights"].annotation
    light_cls = ann.class_map() if ann is not None else np.zeros(s.labels.shape, np.uint8)
    # De-lit textures (night.delight): the day's light divided out with the reconstructed normals.
    geo = inputs.get("geometry")
    normals = geo.scene.normals if (geo is not None and s.albedo is None) else None
    mats = estimate_materials(s.image, s.labels, albedo=s.albedo, roughness=s.roughness, light_classes=light_cls,
                              normals=normals, pitch=float(s.camera_pitch or 0.0), instances=s.instances,
                              depth=geo.scene.depth if normals is not None else None,
                              intrinsics=geo.scene.intrinsics, delight=bool(params))
    return MaterialsResult(mats, light_cls)


def lit_mesh(m: MeshResult, annotation, tolerance: float = 0.0,
             far_limit: float | None = None) -> tuple[SceneMesh, str]:
    """The mesh with the lights of ``annotation`` (None: no lights): the quadtree reduction of the
    post-processed sheets within ``tolerance`` (relative depth) of the full mesh, its merged cells
    kept inside light borders; the mesh itself (light ids looked up per vertex,
    :func:`~npsim_core.mesh.types.with_light_ids`) when ``tolerance`` is 0, it was reduced to a
    face budget already (its ids came with the reduction) or has no sheets. Used for the nights
    (``mesh.render_tolerance``), the written meshes (``export.mesh_tolerance``) and the display.
    Returns (mesh, what it is)."""
    from ..mesh.types import limit_far, with_light_ids

    ids = annotation.instance_map if annotation is not None else None
    if m.reduced:
        return m.mesh, f"the chain's mesh (face budget, {m.reduced})"
    if not tolerance or m.layers is None:
        return with_light_ids(m.mesh, ids), "the chain's mesh"
    from ..mesh.reduce import ReduceParams, reduce_mesh

    red = reduce_mesh(m.layers.with_lights(ids), m.intrinsics, ReduceParams(tol=float(tolerance)))
    return limit_far(red.mesh, far_limit), f"quadtree reduction within {100 * tolerance:g} % of the full mesh's depth"


def night_scene_stage(inputs: dict, params, ctx):
    """The Mitsuba scene of the mesh (built once per mesh; nights switch lights in place): the
    chain's mesh, or its error-bounded reduction when ``mesh.render_tolerance`` > 0
    (:func:`lit_mesh`)."""
    from ..render.scene_builder import BuildParams, build_scene

    light_table_path, variant, tolerance, far_limit, sampler, integrator = params
    m: MeshResult = inputs["mesh"]
    s = inputs["geometry"].scene
    if m.mesh.width != s.width or m.mesh.height != s.height:
        raise NpsimInputError(f"nights are rendered from a full-resolution mesh; this one is "
                              f"{m.mesh.width}x{m.mesh.height} for a {s.width}x{s.height} frame (set mesh.stride=1)")
    if m.mesh.n_faces == 0:
        raise NpsimInputError(f"scene {s.name!r}: the mesh has no faces (all sky, or no valid depth), "
                              "so there is nothing to render")
    from ..chain.params import NightParams

    table = light_table(NightParams(light_table=light_table_path))
    bp = BuildParams(ego_headlights=True, camera_height=s.camera_height, camera_pitch=s.camera_pitch, sampler=sampler,
                     integrator=integrator)
    t0 = time.perf_counter()
    mesh, what = lit_mesh(m, inputs["lights"].annotation, tolerance, far_limit)
    t_reduce = time.perf_counter() - t0
    ctx.cancel()
    # After an annotation edit (same geometry, mesh and parameters) only the shapes it touched are rebuilt.
    prev = ctx.previous
    same = prev is not None and prev.params_key == ctx.params_key and all(
        prev.input_keys.get(k) == ctx.input_keys.get(k) for k in ("geometry", "mesh"))
    reuse = prev.value if same and not tolerance else None
    ctx.previous = prev = None  # a scene that cannot be reused is freed before the new one is built
    built = build_scene(mesh, m.intrinsics, inputs["materials"].materials, table, inputs["lights"].annotation, None,
                        bp, variant=variant or None, previous=reuse)
    del reuse
    built.info.update(render_mesh=what, full_mesh_faces=int(m.mesh.n_faces), reduce_s=round(t_reduce, 3))
    return built


def guides_needs(params: ChainParams) -> tuple[str, ...]:
    """What the denoising guides read: the mesh for the guided filter, the night scene's AOVs for
    OIDN, nothing without a denoiser."""
    return {"guided": ("frame", "mesh", "materials"), "oidn": ("frame", "materials", "night_scene"),
            "none": ()}[params.night.denoiser_used]


def guides_stage(inputs: dict, params, ctx):
    """Denoising guides for the denoiser ``params`` (``night.denoiser_used``): for ``guided`` the
    albedo and the mesh's depth, normal and label seen through each pixel centre; for ``oidn``
    Mitsuba's albedo/normal/depth AOVs of the night scene (box-filtered like the render); None
    for ``none``."""
    if params == "none":
        return None
    mats: MaterialsResult = inputs["materials"]
    if params == "oidn":
        from ..render.render import render_guides

        return render_guides(inputs["night_scene"], inputs["frame"].labels, mats.light_classes > 0)
    from ..render.denoise import denoise_guides

    m: MeshResult = inputs["mesh"]
    return denoise_guides(m.mesh, m.intrinsics, mats.materials.albedo, inputs["frame"].labels,
                          mats.light_classes > 0)


# --------------------------------------------------------------------------- the graph
STAGES: tuple[Stage, ...] = (
    Stage("geometry", geometry_stage, ("frame",), lambda p: (p.camera, float(p.mesh.far_limit), p.depth), version=5),
    Stage("filter", filter_stage, ("geometry",), lambda p: p.filter),
    Stage("uncertain", uncertain_stage, ("geometry", "filter"), lambda p: p.uncertainty, version=2),
    Stage("refine", refine_stage, ("geometry", "filter", "uncertain"), lambda p: p.refine, version=2),
    Stage("lights", lights_stage, ("frame", "annotation", "geometry"), lambda p: p.lights, needs=lights_needs),
    Stage("mesh", mesh_stage, ("geometry", "lights", "uncertain", "filter", "refine"),
          lambda p: (p.mesh, p.postprocess), needs=mesh_needs, version=4),
    Stage("materials", materials_stage, ("frame", "lights", "geometry"), lambda p: bool(p.night.delight), version=3),
    Stage("night_scene", night_scene_stage, ("geometry", "mesh", "materials", "lights"),
          lambda p: (p.night.light_table, p.night.variant, float(p.mesh.render_tolerance), float(p.mesh.far_limit),
                     p.night.sampler, p.night.integrator),
          version=4, incremental=True),
    Stage("guides", guides_stage, ("frame", "mesh", "materials", "night_scene"), lambda p: p.night.denoiser_used,
          needs=guides_needs, version=2),
)
