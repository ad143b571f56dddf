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

import json
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
    """Meshing: vertex ``stride`` (px), ``far_limit`` (m, no vertex deeper), ``postprocess`` on/off."""

    stride: int = 1
    far_limit: float = 300.0
    postprocess: bool = True

    def __post_init__(self) -> None:
        if int(self.stride) < 1:
            raise NpsimInputError(f"mesh stride must be >= 1 pixel, got {self.stride}")
        if not self.far_limit > 0:
            raise NpsimInputError(f"far limit must be > 0 m, got {self.far_limit}")


@dataclass(frozen=True)
class NightParams:
    """Night rendering and camera.

    seed : light activation and noise seed. spp : preview samples per pixel (progressive, 4 per pass).
    preview_scale : preview resolution as a fraction of the image. final_spp : for exports.
    iso : camera noise preset; exposure : stops. ego_headlights, group_all_together, noise : switches.
    probabilities : ((class_id, p), ...) overriding the light table's activation range with (p, p).
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



# --------------------------------------------------------------------------- stage engine
@dataclass(frozen=True)
class Stage:
    """A named stage: ``fn(params, upstream_outputs, ctx)``; its cache key covers
    ``sections`` of the parameters, the keys of ``deps`` and ``extra_key()``."""

    name: str
    fn: Callable
    deps: tuple[str, ...] = ()
    sections: tuple[str, ...] = ()
    extra_key: Callable[[], Any] | None = None


@dataclass
class StageContext:
    cancel: threading.Event | None
    progress: Callable[[dict], None] | None


@dataclass
class PipelineRun:
    outputs: dict[str, Any]
    keys: dict[str, str]
    timings: dict[str, float]
    recomputed: list[str]


class Pipeline:
    """Runs stages in order, reusing a stage's cached output while its key is unchanged."""

    def __init__(self, stages: list[Stage]):
        self.stages = list(stages)
        self._cache: dict[str, tuple[str, Any, float]] = {}

    def key(self, stage: Stage, params: Any, keys: dict[str, str]) -> str:
        import hashlib

        parts = [stage.name] + [repr(getattr(params, s)) for s in stage.sections] + [keys[d] for d in stage.deps]
        if stage.extra_key is not None:
            parts.append(repr(stage.extra_key()))
        return hashlib.sha1("\x1f".join(parts).encode()).hexdigest()[:16]

    def run(self, params: Any, until: str, *, cancel: threading.Event | None = None,
            progress: Callable[[dict], None] | None = None) -> PipelineRun:
        outputs: dict[str, Any] = {}
        keys: dict[str, str] = {}
        timings: dict[str, float] = {}
        recomputed: list[str] = []
        ctx = StageContext(cancel, progress)
        for st in self.stages:
            _check_cancel(cancel)
            k = self.key(st, params, keys)
            keys[st.name] = k
            hit = self._cache.get(st.name)
            if hit is not None and hit[0] == k:
                outputs[st.name] = hit[1]
                timings[st.name] = hit[2]
            else:
                if progress is not None:
                    progress({"stage": st.name})
                t0 = time.perf_counter()
                out = st.fn(params, {d: outputs[d] for d in st.deps}, ctx)
                dt = time.perf_counter() - t0
                self._cache[st.name] = (k, out, dt)
                outputs[st.name] = out
                timings[st.name] = dt
                recomputed.append(st.name)
            if st.name == until:
                break
        return PipelineRun(outputs, keys, timings, recomputed)

    def clear(self) -> None:
        self._cache.clear()


class Workflow:
    """One scene's staged, cached pipeline (see the module docstring).

    Not re-entrant: the GUI runs one :meth:`compute` at a time per workflow (a lock
    serialises callers; a cancelled run leaves completed stages cached).
    """

    STAGES = ("input", "filter", "uncertain", "refine", "mesh")

    def __init__(self, scene: Scene):
        self.scene = scene
        self.annotation = scene.lights
        self._annotation_version = 0
        self._lock = threading.Lock()
        self.pipeline = Pipeline([
            Stage("input", self._stage_input, deps=(), sections=("camera",)),
            Stage("filter", self._stage_filter, deps=("input",), sections=("filter",)),
            Stage("uncertain", self._stage_uncertain, deps=("filter",), sections=("uncertainty",)),
            Stage("refine", self._stage_refine, deps=("input", "filter", "uncertain"), sections=("refine",)),
            Stage("mesh", self._stage_mesh, deps=("input", "uncertain", "refine"),
                  sections=("mesh", "postprocess"), extra_key=lambda: self._annotation_version),
        ])
        self._night: dict[str, Any] = {}

    # ------------------------------------------------------------------ annotation edits
    def set_annotation(self, ann) -> None:
        """Use an edited light annotation (invalidates the mesh and the night scene)."""
        self.annotation = ann
        self._annotation_version += 1

    # ------------------------------------------------------------------ stages
    def intrinsics(self, params: WorkflowParams) -> Intrinsics:
        if params.camera.hfov_deg and params.camera.hfov_deg > 0:
            return Intrinsics.from_fov(self.scene.width, self.scene.height, params.camera.hfov_deg)
        return self.scene.intrinsics

    def _stage_input(self, params: WorkflowParams, up: dict, ctx) -> dict:
        s = self.scene
        intr = self.intrinsics(params)
        if s.depth is not None:
            depth = s.depth
            normals = s.normals if s.normals is not None else normals_from_depth(depth, intr)
            source = "scene"
        else:
            from .geometry import estimate_geometry

            est = estimate_geometry(s.with_(intrinsics=intr), "popup")
            depth, normals, source = est.depth, est.normals, "popup prior"
        return {"depth": depth.astype(np.float32), "normals": normals.astype(np.float32), "intrinsics": intr,
                "source": source}

    def _stage_filter(self, params: WorkflowParams, up: dict, ctx) -> np.ndarray:
        from .refine.bilateral import cross_bilateral

        return cross_bilateral(up["input"]["depth"], self.scene.image, self.scene.labels, params.filter)

    def _stage_uncertain(self, params: WorkflowParams, up: dict, ctx) -> np.ndarray:
        from .refine.uncertainty import uncertain_map

        return uncertain_map(up["filter"], self.scene.labels, params.uncertainty)

    def _stage_refine(self, params: WorkflowParams, up: dict, ctx) -> RefineResult:
        from .refine.optimize import refine_depth

        progress = ctx.progress
        hist: dict[str, list[float]] = {"total": [], "normal": [], "continuity": [], "depth": []}
        last = [0.0]

        def on_step(step: int, total: int, losses: dict) -> None:
            for k in hist:
                if k in losses:
                    hist[k].append(float(losses[k]))
            now = time.perf_counter()
            if progress is not None and (now - last[0] > 0.1 or step == total):
                last[0] = now
                progress({"stage": "refine", "step": step, "of": total, "history": {k: list(v) for k, v in hist.items()}})

        return refine_depth(up["filter"], up["input"]["normals"], up["input"]["intrinsics"], up["uncertain"],
                            params.refine, anchor=up["input"]["depth"], progress=on_step, cancel=ctx.cancel)

    def _stage_mesh(self, params: WorkflowParams, up: dict, ctx) -> dict:
        from .mesh.grid import grid_mesh
        from .mesh.postprocess import postprocess_mesh

        depth = up["refine"].depth
        intr = up["input"]["intrinsics"]
        light_ids = self.annotation.instance_map if self.annotation is not None else None
        mp = params.mesh
        if mp.postprocess and mp.stride == 1:
            pp = replace(params.postprocess, far_limit=mp.far_limit)
            res = postprocess_mesh(depth, intr, self.scene.labels, up["uncertain"], light_ids=light_ids, params=pp)
            return {"mesh": res.mesh, "removed": getattr(res, "removed", None), "counts": res.counts}
        d = np.where(depth <= mp.far_limit, depth, np.nan).astype(np.float32)
        mesh = grid_mesh(d, intr, self.scene.labels, light_ids, stride=mp.stride)
        return {"mesh": mesh, "removed": None, "counts": {"faces": mesh.n_faces}}

    # ------------------------------------------------------------------ running
    def compute(self, params: WorkflowParams, until: str = "mesh", *, cancel: threading.Event | None = None,
                progress: ProgressFn = None) -> WorkflowResults:
        """Run (or reuse) every stage up to ``until``; returns the results and what was recomputed."""
        if until not in self.STAGES:
            raise NpsimInputError(f"unknown stage {until!r}; stages are {self.STAGES}")
        with self._lock:
            run = self.pipeline.run(params, until=until, cancel=cancel, progress=progress)
        out = run.outputs
        inp = out.get("input", {})
        mesh = out.get("mesh") or {}
        return WorkflowResults(intrinsics=inp.get("intrinsics", self.scene.intrinsics), depth_in=inp.get("depth"),
                               normals_in=inp.get("normals"), filtered=out.get("filter"),
                               uncertain=out.get("uncertain"), refine=out.get("refine"), mesh=mesh.get("mesh"),
                               removed=mesh.get("removed"), mesh_key=run.keys.get("mesh", ""), scene=self.scene,
                               timings=dict(run.timings), recomputed=list(run.recomputed))

    # ------------------------------------------------------------------ night
    def night_scene(self, results: WorkflowResults, params: WorkflowParams):
        """The Mitsuba scene for ``results.mesh`` (built once per mesh and ego-light setting)."""
        from .render.lights import load_light_table
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
            self._night = {"key": key, "built": built, "light_classes": light_cls}
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
        per = 4
        pp = PreviewParams(scale=n.preview_scale, spp_per_pass=per, passes=max(1, int(np.ceil(n.spp / per))),
                           seed=n.seed)
        cam = CameraParams(exposure_ev=n.exposure, iso=n.iso if n.noise else None, seed=n.seed)
        for frame in render_preview(built, pp, cancel=cancel):
            srgb, _ = apply_camera(frame.image, cam)
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
                              passes=max(1, n.final_spp // 16))
        cam = CameraParams(exposure_ev=n.exposure, iso=n.iso if n.noise else None, seed=n.seed)
        srgb, _ = apply_camera(linear, cam, labels=self.scene.labels, light_classes=self._night["light_classes"])
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
