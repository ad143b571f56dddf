"""The whole NPSim chain for one scene, staged and cached: what the app, ``npsim run``,
``npsim batch`` and ``npsim sweep`` drive.

Stages (each a pure function of its inputs and its parameter section)::

    input      scene depth/normals, or the semantic pop-up prior when the scene has none   [camera]
    filter     dual-reference cross-bilateral filter (SPEC §2.1)                           [filter]
    uncertain  dual-reference variance filter on the filtered depth (SPEC §2.2)           [uncertainty]
    refine     normal-guided refinement (SPEC §2.3)                                       [refine]
    mesh       Worldsheet grid + post-processing kernel (SPEC §3-4), light ids per vertex  [mesh, postprocess]
    night      Mitsuba scene built from the mesh; lights switched in place per seed        [night]

A stage's cache key is its own parameter section plus the keys of the stages it
reads, so changing λ reruns refine → mesh, changing σs reruns filter and everything
after it, and a new seed only re-activates lights in the already built night scene.

"""

from __future__ import annotations

import threading
import time
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from .camera import Intrinsics, normals_from_depth, valid_depth_mask
from .errors import NpsimCancelled, NpsimInputError
from .mesh.postprocess import PostprocessParams
from .mesh.types import MeshPart, SceneMesh
from .refine.bilateral import FilterParams
from .refine.optimize import PRESETS, RefineParams, RefineResult
from .refine.uncertainty import UncertaintyParams
from .scene import Scene

VIEW_MODES = ("RGB", "labels", "predicted depth", "refined depth", "normals (predicted)", "normals (refined)",
              "uncertain map", "depth error vs GT", "normal error vs GT")


# --------------------------------------------------------------------------- parameters
@dataclass(frozen=True)
class CameraSetup:
    """hfov_deg: horizontal field of view in degrees; 0 keeps the scene's intrinsics."""

    hfov_deg: float = 0.0


@dataclass(frozen=True)
class MeshParams:
    """Meshing: vertex ``stride`` (px), ``far_limit`` (m, no vertex deeper), ``postprocess`` on/off,
    ``face_budget`` (0 = keep every face; else the quadtree-reduced mesh of about that many faces)."""

    stride: int = 1
    far_limit: float = 300.0
    postprocess: bool = True
    face_budget: int = 0

    def __post_init__(self) -> None:
        if int(self.stride) < 1:
            raise NpsimInputError(f"mesh stride must be >= 1 pixel, got {self.stride}")
        if int(self.face_budget) < 0:
            raise NpsimInputError(f"face budget must be >= 0 (0 = no reduction), got {self.face_budget}")
        if not self.far_limit > 0:
            raise NpsimInputError(f"far limit must be > 0 m, got {self.far_limit}")


@dataclass(frozen=True)
class NightParams:
    """Night rendering and camera.

    seed : light activation and noise seed. spp : preview samples per pixel (a 4-spp first frame, then the rest).
    preview_scale : preview resolution as a fraction of the image. final_spp : for exports.
    iso : camera noise preset; exposure : stops. ego_headlights, group_all_together, noise : switches.
    probabilities : ((class_id, p), ...) overriding the light table's activation range with (p, p).
    final_max_depth : path length of exported nights: 3 = one bounce (default), 2 = direct light only
        (about half the time; with ``mesh.face_budget`` the fast full-resolution setting).
    denoise : filter the Monte Carlo noise of previews and finals, guided by the refined depth,
        normals, labels and albedo (``npsim_core.render.denoise``), before the camera noise.
    """

    seed: int = 0
    spp: int = 16
    preview_scale: float = 0.5
    final_spp: int = 64
    iso: int = 1600
    exposure: float = 0.0
    ego_headlights: bool = True
    group_all_together: bool = False
    noise: bool = True
    probabilities: tuple = ()
    final_max_depth: int = 3
    denoise: bool = True

    def __post_init__(self) -> None:
        if int(self.final_max_depth) not in (2, 3, 4):
            raise NpsimInputError(f"night.final_max_depth must be 2 (direct light), 3 (one bounce) or 4, "
                                  f"got {self.final_max_depth}")
        if int(self.spp) < 1 or int(self.final_spp) < 1:
            raise NpsimInputError(f"night.spp and night.final_spp must be >= 1, got {self.spp}, {self.final_spp}")

    def probability(self, class_id: int) -> float | None:
        return dict(self.probabilities).get(int(class_id))


@dataclass(frozen=True)
class WorkflowParams:
    """Every parameter of the chain, one frozen section per stage."""

    camera: CameraSetup = CameraSetup()
    filter: FilterParams = FilterParams()
    uncertainty: UncertaintyParams = UncertaintyParams()
    refine: RefineParams = RefineParams()
    mesh: MeshParams = MeshParams()
    postprocess: PostprocessParams = PostprocessParams()
    night: NightParams = NightParams()

    def with_value(self, section: str, name: str, value: Any) -> "WorkflowParams":
        """A copy with one value changed. ``refine.lambda1..3`` address the λ tuple;
        ``night.p_<class>`` a per-class activation probability."""
        if not hasattr(self, section):
            raise NpsimInputError(f"unknown parameter section {section!r}")
        sec = getattr(self, section)
        if section == "refine" and name in ("lambda1", "lambda2", "lambda3"):
            lam = list(sec.lambdas)
            lam[int(name[-1]) - 1] = float(value)
            return replace(self, refine=replace(sec, lambdas=tuple(lam)))
        if section == "night" and name.startswith("p_"):
            probs = dict(sec.probabilities)
            probs[int(name[2:])] = float(np.clip(value, 0.0, 1.0))
            return replace(self, night=replace(sec, probabilities=tuple(sorted(probs.items()))))
        if name not in {f.name for f in fields(sec)}:
            raise NpsimInputError(f"unknown parameter {section}.{name}")
        try:
            return replace(self, **{section: replace(sec, **{name: value})})
        except (TypeError, ValueError) as exc:
            raise NpsimInputError(f"bad value {value!r} for {section}.{name}: {exc}") from None

    def with_preset(self, name: str) -> "WorkflowParams":
        if name not in PRESETS:
            raise NpsimInputError(f"unknown λ preset {name!r}; choose one of {sorted(PRESETS)}")
        return replace(self, refine=replace(self.refine, lambdas=PRESETS[name]))

    def gui_values(self) -> dict[tuple[str, str], Any]:
        """Flat ``{(section, field): value}`` of everything the parameter panel shows."""
        out: dict[tuple[str, str], Any] = {}
        for sec_name in ("camera", "filter", "uncertainty", "refine", "mesh", "night"):
            sec = getattr(self, sec_name)
            for f in fields(sec):
                v = getattr(sec, f.name)
                if isinstance(v, (int, float, str, bool)) or v is None:
                    out[(sec_name, f.name)] = v
        lam = self.refine.lambdas
        out.update({("refine", f"lambda{i + 1}"): lam[i] for i in range(3)})
        out[("refine", "steps")] = self.refine.n_steps
        out[("refine", "lr")] = self.refine.learning_rate
        from .render.lights import load_light_table

        table = load_light_table()
        for cid in range(1, 13):
            p = self.night.probability(cid)
            out[("night", f"p_{cid}")] = p if p is not None else float(np.mean(table.spec(cid).p))
        return out

    def to_json(self) -> dict:
        d = {}
        for f in fields(self):
            sec = asdict(getattr(self, f.name))
            for k, v in list(sec.items()):
                if isinstance(v, (set, frozenset)):
                    sec[k] = sorted(v)
            d[f.name] = sec
        return d

    @classmethod
    def from_json(cls, doc: dict, source: str = "parameters") -> "WorkflowParams":
        out = cls()
        for f in fields(cls):
            if f.name not in doc:
                continue
            sec = getattr(out, f.name)
            kw = {}
            for g in fields(sec):
                if g.name in doc[f.name]:
                    v = doc[f.name][g.name]
                    cur = getattr(sec, g.name)
                    if isinstance(cur, frozenset):
                        v = frozenset(v)
                    elif isinstance(cur, tuple) and isinstance(v, list):
                        v = tuple(tuple(x) if isinstance(x, list) else x for x in v)
                    kw[g.name] = v
            try:
                out = replace(out, **{f.name: replace(sec, **kw)})
            except (TypeError, ValueError) as exc:
                raise NpsimInputError(f"{source}: bad '{f.name}' section: {exc}") from None
        return out


# --------------------------------------------------------------------------- results
@dataclass
class WorkflowResults:
    """What :meth:`Workflow.compute` produced (None for stages not run)."""

    intrinsics: Intrinsics
    depth_in: np.ndarray | None = None
    normals_in: np.ndarray | None = None
    filtered: np.ndarray | None = None
    uncertain: np.ndarray | None = None
    refine: RefineResult | None = None
    mesh: SceneMesh | None = None
    removed: MeshPart | None = None
    layers: Any = None
    mesh_key: str = ""
    scene: Scene | None = None
    timings: dict[str, float] = field(default_factory=dict)
    recomputed: list[str] = field(default_factory=list)

    @property
    def depth(self) -> np.ndarray | None:
        """The best depth available: refined, else filtered, else the input."""
        if self.refine is not None:
            return self.refine.depth
        return self.filtered if self.filtered is not None else self.depth_in

    def refine_history(self) -> dict[str, list[float]]:
        if self.refine is None:
            return {}
        h = self.refine.history
        return {k: list(np.asarray(h[k], dtype=float)) for k in ("total", "normal", "continuity", "depth") if k in h}

    def depth_error(self) -> np.ndarray | None:
        """|d − d_gt| / d_gt per pixel (NaN where either is invalid), when ground truth exists."""
        if self.scene is None or self.scene.depth_gt is None or self.depth is None:
            return None
        d, g = self.depth.astype(np.float64), self.scene.depth_gt.astype(np.float64)
        ok = valid_depth_mask(d) & valid_depth_mask(g)
        out = np.full(d.shape, np.nan, np.float32)
        out[ok] = (np.abs(d[ok] - g[ok]) / g[ok]).astype(np.float32)
        return out


ProgressFn = Callable[[dict], None] | None


def _check_cancel(cancel) -> None:
    if cancel is not None and cancel.is_set():
        raise NpsimCancelled("workflow cancelled")


# --------------------------------------------------------------------------- stages beyond npsim_core.pipeline's
@dataclass(frozen=True)
class MeshStageParams:
    mesh: MeshParams = MeshParams()
    postprocess: PostprocessParams = PostprocessParams()


def _stage_refine_with_history(inputs: dict, params: RefineParams, ctx) -> RefineResult:
    """Normal-guided refinement that also reports its loss curves while it runs (for the GUI)."""
    from .refine.optimize import refine_depth

    scene = inputs["scene"]
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

    return refine_depth(inputs["filter"], scene.normals, scene.intrinsics, inputs["uncertain"], params,
                        progress=on_step, cancel=ctx.cancel_flag)


def _stage_mesh(inputs: dict, params: MeshStageParams, ctx) -> dict:
    """Worldsheet grid of the refined depth + post-processing kernel; light ids per vertex."""
    from .mesh.grid import grid_mesh
    from .mesh.postprocess import postprocess_mesh

    scene, ann = inputs["scene"], inputs["annotation"]
    depth = inputs["refine"].depth
    intr = scene.intrinsics
    light_ids = ann.instance_map if ann is not None else None
    mp = params.mesh
    if mp.postprocess and mp.stride == 1:
        pp = replace(params.postprocess, far_limit=mp.far_limit)
        res = postprocess_mesh(depth, intr, scene.labels, inputs["uncertain"], light_ids=light_ids, params=pp,
                               normals=scene.normals)
        removed = removed_faces(depth, intr, scene.labels, res.layers)
        mesh = res.mesh
        if mp.face_budget and mesh.n_faces > mp.face_budget:
            from .mesh.reduce import ReduceParams, reduce_mesh

            mesh = reduce_mesh(res.layers, intr, ReduceParams(budget=int(mp.face_budget))).mesh
        return {"mesh": mesh, "removed": removed, "counts": res.counts, "layers": res.layers}
    d = np.where(depth <= mp.far_limit, depth, np.nan).astype(np.float32)
    mesh = grid_mesh(d, intr, scene.labels, light_ids, stride=mp.stride)
    return {"mesh": mesh, "removed": None, "counts": {"faces": mesh.n_faces}, "layers": None}



class Workflow:
    """One scene's staged, cached pipeline (see the module docstring).

    Not re-entrant: the GUI runs one :meth:`compute` at a time per workflow (a lock
    serialises callers; a cancelled run leaves completed stages cached).
    """

    STAGES = ("filter", "uncertain", "refine", "mesh")

    def __init__(self, scene: Scene):
        from .pipeline import Pipeline, _stage_filter, _stage_uncertain

        self.scene = scene
        self.annotation = scene.lights
        self._annotation_version = 0
        self._lock = threading.Lock()
        self._inputs: dict[float, Scene] = {}
        self.pipeline = Pipeline(cache_size=4)
        self.pipeline.add_source("scene", scene, key="unset")
        self.pipeline.add_source("annotation", self.annotation, key="ann-0")
        self.pipeline.add_stage("filter", _stage_filter, ("scene",), FilterParams())
        self.pipeline.add_stage("uncertain", _stage_uncertain, ("scene", "filter"), UncertaintyParams())
        self.pipeline.add_stage("refine", _stage_refine_with_history, ("scene", "filter", "uncertain"), RefineParams())
        self.pipeline.add_stage("mesh", _stage_mesh, ("scene", "annotation", "uncertain", "refine"),
                                MeshStageParams())
        self._night: dict[str, Any] = {}
        self._display: dict[str, Any] = {}

    # ------------------------------------------------------------------ annotation edits
    def set_annotation(self, ann) -> None:
        """Use an edited light annotation (invalidates the mesh and the night scene)."""
        with self._lock:
            self.annotation = ann
            self._annotation_version += 1
            self.pipeline.add_source("annotation", ann, key=f"ann-{self._annotation_version}")

    # ------------------------------------------------------------------ inputs
    def intrinsics(self, params: WorkflowParams) -> Intrinsics:
        if params.camera.hfov_deg and params.camera.hfov_deg > 0:
            return Intrinsics.from_fov(self.scene.width, self.scene.height, params.camera.hfov_deg)
        return self.scene.intrinsics

    def input_scene(self, params: WorkflowParams) -> Scene:
        """The scene the refinement reads: its intrinsics (or the FOV override) and its estimated
        depth and normals -- or the semantic pop-up prior's when the scene has none (cached per FOV)."""
        hfov = float(params.camera.hfov_deg or 0.0)
        if hfov not in self._inputs:
            s = self.scene
            intr = self.intrinsics(params)
            s = s.with_(intrinsics=intr, provenance=dict(s.provenance, hfov_override=hfov or None))
            if s.depth is None:
                from .geometry import estimate_geometry

                s = estimate_geometry(s, "popup").apply(s)
            elif s.normals is None:
                s = s.with_(normals=normals_from_depth(s.depth, intr))
            self._inputs = {hfov: s}
        return self._inputs[hfov]

    # ------------------------------------------------------------------ running
    def compute(self, params: WorkflowParams, until: str = "mesh", *, cancel: threading.Event | None = None,
                progress: ProgressFn = None) -> WorkflowResults:
        """Run (or reuse) every stage up to ``until``; returns the results and what was recomputed.

        ``progress`` receives dicts: ``{"stage": name}`` when a stage starts and, during
        refinement, ``{"stage": "refine", "step", "of", "history"}`` (loss curves so far).
        """
        if until not in self.STAGES:
            raise NpsimInputError(f"unknown stage {until!r}; stages are {self.STAGES}")
        with self._lock:
            scene_in = self.input_scene(params)
            self.pipeline.add_source("scene", scene_in, key=f"{self.scene.name}-{id(scene_in)}")
            stage_params = {"filter": params.filter, "uncertain": params.uncertainty, "refine": params.refine,
                            "mesh": MeshStageParams(params.mesh, params.postprocess)}
            stage_params = {k: v for k, v in stage_params.items() if k in self.STAGES[:self.STAGES.index(until) + 1]}

            def on_progress(stage: str, fraction: float, info: Any) -> None:
                if progress is None:
                    return
                progress(info if isinstance(info, dict) else {"stage": stage, "fraction": fraction, "text": info})

            run = self.pipeline.run(until=until, params=stage_params, cancel=cancel, progress=on_progress)
        out = run.results
        mesh = out.get("mesh") or {}
        return WorkflowResults(intrinsics=scene_in.intrinsics, depth_in=scene_in.depth, normals_in=scene_in.normals,
                               filtered=out.get("filter"), uncertain=out.get("uncertain"), refine=out.get("refine"),
                               mesh=mesh.get("mesh"), removed=mesh.get("removed"), layers=mesh.get("layers"),
                               mesh_key=run.keys.get("mesh", ""),
                               scene=self.scene, timings={k: v for k, v in run.timings.items()},
                               recomputed=list(run.recomputed))

    def display_mesh(self, results: WorkflowResults, max_faces: int = 150_000) -> SceneMesh:
        """A lighter version of ``results.mesh`` for interactive 3D display (quadtree reduction to
        about ``max_faces``, cached per mesh); the full mesh when it is small enough."""
        mesh = results.mesh
        if mesh is None or mesh.n_faces <= max_faces:
            return mesh
        key = (results.mesh_key, int(max_faces))
        if self._display.get("key") != key:
            if results.layers is not None:
                from .mesh.reduce import ReduceParams, reduce_mesh

                shown = reduce_mesh(results.layers, results.intrinsics, ReduceParams(budget=int(max_faces))).mesh
            else:
                from .mesh.grid import grid_mesh

                stride = int(np.ceil(np.sqrt(mesh.n_faces / max_faces)))
                ann = self.annotation
                shown = grid_mesh(results.depth, results.intrinsics, self.scene.labels,
                                  ann.instance_map if ann is not None else None, stride=stride)
            self._display = {"key": key, "mesh": shown}
        return self._display["mesh"]

    # ------------------------------------------------------------------ night
    def night_scene(self, results: WorkflowResults, params: WorkflowParams):
        """The Mitsuba scene for ``results.mesh`` (built once per mesh and ego-light setting)."""
        from .render.materials import estimate_materials
        from .render.scene_builder import BuildParams, build_scene

        if results.mesh is None:
            raise NpsimInputError("no mesh yet: compute the pipeline up to 'mesh' first")
        key = results.mesh_key
        if self._night.get("key") != key:
            s = self.scene
            table = self.light_table(params)
            light_cls = (self.annotation.class_map() if self.annotation is not None
                         else np.zeros(s.labels.shape, np.uint8))
            mats = estimate_materials(s.image, s.labels, albedo=s.albedo, roughness=s.roughness,
                                      light_classes=light_cls)
            bp = BuildParams(ego_headlights=True, camera_height=s.camera_height, camera_pitch=s.camera_pitch)
            built = build_scene(results.mesh, results.intrinsics, mats, table, self.annotation, None, bp)
            # Denoising guides: the mesh reproduces the refined depth at every pixel it shows.
            from .camera import normals_from_depth
            from .render.denoise import DenoiseGuides

            d = results.depth
            guides = DenoiseGuides(mats.albedo, d, normals_from_depth(d, results.intrinsics), s.labels,
                                   light_cls > 0)
            self._night = {"key": key, "built": built, "light_classes": light_cls, "guides": guides}
        built = self._night["built"]
        built.set_ego_headlights(params.night.ego_headlights)
        return built

    def light_table(self, params: WorkflowParams):
        """The light table with the per-class probability overrides of ``params.night``."""
        from .render.lights import load_light_table

        table = load_light_table()
        if not params.night.probabilities:
            return table
        specs = dict(table.classes)
        for cid, p in params.night.probabilities:
            specs[int(cid)] = replace(specs[int(cid)], p=(float(p), float(p)))
        return replace(table, classes=specs)

    def activate(self, params: WorkflowParams, light_override: dict[int, bool] | None = None):
        from .render.lights import activate_lights

        return activate_lights(self.annotation, self.light_table(params), params.night.seed,
                               group_all_together=params.night.group_all_together, image=self.scene.image,
                               force=light_override)

    def night_preview(self, results: WorkflowResults, params: WorkflowParams, *,
                      light_override: dict[int, bool] | None = None,
                      cancel: threading.Event | None = None) -> Iterator["NightFrame"]:
        """Progressive night preview: yields post-processed frames as passes accumulate."""
        from .render.camera_post import CameraParams, apply_camera
        from .render.render import PreviewParams, render_preview

        t0 = time.perf_counter()
        built = self.night_scene(results, params)
        active = self.activate(params, light_override)
        built.apply_lights(active)
        n = params.night
        first = min(4, int(n.spp))  # a quick first frame, then the rest in one pass
        pp = PreviewParams(scale=n.preview_scale, schedule=(first,) + ((int(n.spp) - first,) if n.spp > first else ()),
                           seed=n.seed)
        cam = CameraParams(exposure_ev=n.exposure, iso=n.iso if n.noise else None, seed=n.seed, denoise=n.denoise)
        for frame in render_preview(built, pp, cancel=cancel):
            srgb, _ = apply_camera(frame.image, cam, light_classes=self._night["light_classes"],
                                   guides=self._night["guides"])
            yield NightFrame(srgb, frame.image, frame.spp, time.perf_counter() - t0, built.variant, active)

    def night_final(self, results: WorkflowResults, params: WorkflowParams, *, seed: int | None = None,
                    cancel: threading.Event | None = None, scale: float = 1.0) -> "NightFrame":
        """A full-resolution night (``params.night.final_spp``) with camera post-processing."""
        from .render.camera_post import CameraParams, apply_camera
        from .render.render import render_final

        t0 = time.perf_counter()
        n = params.night if seed is None else replace(params.night, seed=int(seed))
        p = replace(params, night=n)
        built = self.night_scene(results, p)
        active = self.activate(p)
        built.apply_lights(active)
        linear = render_final(built, spp=n.final_spp, seed=n.seed, cancel=cancel, scale=scale,
                              passes=max(1, n.final_spp // 16), max_depth=int(n.final_max_depth))
        cam = CameraParams(exposure_ev=n.exposure, iso=n.iso if n.noise else None, seed=n.seed, denoise=n.denoise)
        srgb, _ = apply_camera(linear, cam, labels=self.scene.labels, light_classes=self._night["light_classes"],
                               guides=self._night["guides"])
        return NightFrame(srgb, linear, n.final_spp, time.perf_counter() - t0, built.variant, active)


@dataclass
class NightFrame:
    """A night image: 8-bit sRGB, the linear render, spp so far, seconds, Mitsuba variant, light states."""

    image: np.ndarray
    linear: np.ndarray
    spp: int
    elapsed: float
    variant: str
    active: Any = None


# --------------------------------------------------------------------------- replaced grid faces, for display
def removed_faces(depth: np.ndarray, intrinsics: Intrinsics, labels: np.ndarray, layers) -> MeshPart:
    """The Worldsheet grid faces of ``depth`` the post-processing kernel did not keep, as one part
    (see :func:`npsim_core.mesh.postprocess.replaced_grid_faces`)."""
    from .mesh.grid import grid_mesh
    from .mesh.postprocess import replaced_grid_faces

    full = grid_mesh(depth, intrinsics, labels).parts
    parts = [p for p in full if p.n_faces]
    if not parts:
        return MeshPart("removed", np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64), np.zeros((0, 2), np.float32),
                        np.zeros((0, 2), np.float32), np.zeros(0, np.uint8), np.zeros(0, np.int32))
    p = parts[0]
    keep = replaced_grid_faces(p, layers)
    return MeshPart("removed", p.vertices, p.faces[keep], p.uv, p.pixel, p.label, p.light_id)


# --------------------------------------------------------------------------- views
def view_image(scene: Scene, results: WorkflowResults | None, mode: str) -> np.ndarray:
    """An HxWx3 uint8 picture of ``mode`` (one of :data:`VIEW_MODES`) for the canvas."""
    from .io import depth_to_rgb, normals_to_rgb
    from .labels import cityscapes
    from .metrics import angular_error_deg

    r = results
    black = np.zeros_like(scene.image)
    if mode == "RGB":
        return scene.image
    if mode == "labels":
        return cityscapes().colorize(scene.labels)
    vmax = None
    if scene.depth is not None and np.isfinite(scene.depth).any():
        vmax = float(np.nanpercentile(scene.depth, 99))
    if mode == "predicted depth":
        d = r.depth_in if r is not None else scene.depth
        return depth_to_rgb(d, vmax) if d is not None else black
    if r is None:
        return black
    if mode == "refined depth":
        return depth_to_rgb(r.depth, vmax) if r.depth is not None else black
    if mode == "normals (predicted)":
        return normals_to_rgb(r.normals_in) if r.normals_in is not None else black
    if mode == "normals (refined)":
        return normals_to_rgb(normals_from_depth(r.depth, r.intrinsics)) if r.depth is not None else black
    if mode == "uncertain map":
        if r.uncertain is None:
            return black
        out = (scene.image * 0.35).astype(np.uint8)
        out[r.uncertain] = (255, 60, 60)
        return out
    if mode == "depth error vs GT":
        e = r.depth_error()
        return _heat(e, 0.25) if e is not None else black
    if mode == "normal error vs GT":
        if scene.normals_gt is None or r.depth is None:
            return black
        return _heat(angular_error_deg(normals_from_depth(r.depth, r.intrinsics), scene.normals_gt), 45.0)
    raise NpsimInputError(f"unknown view mode {mode!r}; choose one of {VIEW_MODES}")


def _heat(values: np.ndarray, vmax: float) -> np.ndarray:
    import cv2

    v = np.nan_to_num(np.clip(values / vmax, 0, 1), nan=0.0)
    img = cv2.cvtColor(cv2.applyColorMap((v * 255).astype(np.uint8), cv2.COLORMAP_INFERNO), cv2.COLOR_BGR2RGB)
    img[~np.isfinite(values)] = 0
    return img


# --------------------------------------------------------------------------- files
def load_any_scene(path: str | Path, *, hfov_deg: float | None = None) -> Scene:
    """A scene folder, a project folder, or one image of a dataset (labels found by the dataset readers)."""
    path = Path(path)
    if not path.exists():
        raise NpsimInputError(f"{path}: not found; give a scene folder (see 'npsim sample') or an image")
    if path.is_dir():
        if (path / "project.json").exists():
            return load_project(path)[0]
        from .scene import load_scene

        return load_scene(path)
    from .datasets import open_dataset

    for src in open_dataset(path.parent, hfov_deg=hfov_deg):
        if Path(src.image_path).resolve() == path.resolve():
            return src.load()
    raise NpsimInputError(f"{path}: no labels found for this image; put <stem>_labelIds.png beside it or use a "
                          "Cityscapes/ACDC folder layout")


PROJECT_VERSION = 1


def save_project(folder: str | Path, scene: Scene, params: WorkflowParams,
                 results: WorkflowResults | None = None) -> Path:
    """A project folder: the scene (with its current annotation), ``project.json`` with the
    parameters, and the cached stage results as ``.npy`` arrays (plain JSON and arrays, no pickle)."""
    from .io import write_json, write_npy
    from .scene import save_scene

    folder = Path(folder)
    save_scene(scene, folder / "scene")
    cached = {}
    if results is not None:
        for name, arr in (("filtered_depth", results.filtered), ("uncertain", results.uncertain),
                          ("refined_depth", results.depth if results.refine is not None else None)):
            if arr is not None:
                write_npy(folder / "cache" / f"{name}.npy", np.asarray(arr))
                cached[name] = f"cache/{name}.npy"
    write_json(folder / "project.json", {"format": "npsim-project", "version": PROJECT_VERSION, "scene": "scene",
                                         "params": params.to_json(), "cache": cached})
    return folder


def load_project(folder: str | Path) -> tuple[Scene, WorkflowParams]:
    """Read a project folder written by :func:`save_project`."""
    from .io import read_json
    from .scene import load_scene

    folder = Path(folder)
    doc = read_json(folder / "project.json")
    if doc.get("format") != "npsim-project":
        raise NpsimInputError(f"{folder / 'project.json'}: not an NPSim project file")
    if int(doc.get("version", 0)) > PROJECT_VERSION:
        raise NpsimInputError(f"{folder / 'project.json'}: written by a newer NPSim (version {doc['version']}); "
                              "update NPSim to open it")
    scene = load_scene(folder / doc.get("scene", "scene"))
    return scene, WorkflowParams.from_json(doc.get("params", {}), str(folder / "project.json"))


EXPORT_KINDS = ("masks", "depth", "normals", "mesh", "nights")


def export_scene(wf: Workflow, params: WorkflowParams, folder: str | Path, *, nights: int = 1,
                 kinds: tuple[str, ...] = EXPORT_KINDS, mesh_formats: tuple[str, ...] = ("ply", "glb"),
                 cancel: threading.Event | None = None,
                 progress: Callable[[float, str], None] | None = None) -> list[Path]:
    """Write masks, depth, normals, meshes and ``nights`` night images of ``wf``'s scene to ``folder``.

    Every file is written atomically; returns the written paths (also listed in
    ``<name>_export.json``). ``progress(fraction, text)`` reports as it goes.
    """
    from .annotation import save_annotation
    from .io import depth_to_rgb, normals_to_rgb, write_depth_png, write_image, write_json, write_npy, write_normals_png

    bad = [k for k in kinds if k not in EXPORT_KINDS]
    if bad:
        raise NpsimInputError(f"unknown export kinds {bad}; choose from {EXPORT_KINDS}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    s = wf.scene
    n = s.name
    written: list[Path] = []
    steps = 2 + ("nights" in kinds) * max(nights, 0)
    done = [0]

    def step(text: str) -> None:
        _check_cancel(cancel)
        if progress is not None:
            progress(done[0] / steps, text)
        done[0] += 1

    step("computing depth refinement and mesh")
    res = wf.compute(params, until="mesh", cancel=cancel)
    step("writing masks, depth, normals, mesh")
    if "masks" in kinds:
        p = folder / f"{n}_labelIds.png"
        write_image(p, s.labels)
        written.append(p)
        p = folder / f"{n}_uncertain.png"
        write_image(p, res.uncertain.astype(np.uint8) * 255)
        written.append(p)
        if wf.annotation is not None:
            written += list(save_annotation(wf.annotation, folder, n).values())
    if "depth" in kinds:
        for tag, d in (("input", res.depth_in), ("refined", res.depth)):
            written.append(folder / f"{n}_depth_{tag}.npy")
            write_npy(written[-1], d.astype(np.float32))
            written.append(folder / f"{n}_depth_{tag}.png")
            write_depth_png(written[-1], d)
            written.append(folder / f"{n}_depth_{tag}_vis.png")
            write_image(written[-1], depth_to_rgb(d))
    if "normals" in kinds:
        nr = normals_from_depth(res.depth, res.intrinsics)
        written.append(folder / f"{n}_normals_refined.npy")
        write_npy(written[-1], nr)
        written.append(folder / f"{n}_normals_refined.png")
        write_normals_png(written[-1], nr)
        written.append(folder / f"{n}_normals_refined_vis.png")
        write_image(written[-1], normals_to_rgb(nr))
    if "mesh" in kinds:
        from .mesh.export import export_mesh

        out = export_mesh(res.mesh, folder, stem=f"{n}_mesh", formats=mesh_formats, image=s.image)
        written += list(out.values()) if isinstance(out, dict) else list(out)
    nights_info = []
    if "nights" in kinds:
        for k in range(nights):
            step(f"rendering night {k + 1}/{nights}")
            seed = params.night.seed + k
            frame = wf.night_final(res, params, seed=seed, cancel=cancel)
            stem = f"{n}_night_{k}"
            for path, write, data in ((folder / f"{stem}.png", write_image, frame.image),
                                      (folder / f"{stem}_linear.npy", write_npy, frame.linear),
                                      (folder / f"{stem}_labelIds.png", write_image, s.labels)):
                write(path, data)
                written.append(path)
            written.append(folder / f"{stem}_lights.json")
            write_json(written[-1], frame.active.to_json())
            nights_info.append({"night": k, "seed": seed, "spp": frame.spp, "variant": frame.variant,
                                "seconds": round(frame.elapsed, 3)})
    manifest = folder / f"{n}_export.json"
    write_json(manifest, {"scene": n, "params": params.to_json(), "timings": res.timings, "nights": nights_info,
                          "files": [p.name for p in written]})
    written.append(manifest)
    if progress is not None:
        progress(1.0, f"exported {len(written)} files")
    return written
