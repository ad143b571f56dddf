"""One frame's chain: the stages of :mod:`.stages` on the :class:`~.engine.Engine`, plus the
per-night steps. The app, every command, the batch and the sweep go through it.

A change of one parameter reruns its stage and what reads it: λ reruns refine → mesh,
σs reruns filter and everything after it, an annotation edit reruns the lights, the materials
and the night scene -- never the mesh, whose geometry does not depend on the lights -- and a
new seed only re-activates lights in the already built night scene.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Iterator

import numpy as np

from ..camera import Intrinsics, valid_depth_mask
from ..errors import NpsimInputError
from ..mesh.types import MeshPart, SceneMesh
from ..scene import Scene
from .engine import Engine, content_key
from .params import ChainParams
from .stages import STAGES, GeometryResult, LightsResult, MeshResult, light_table, mesh_needs

__all__ = ["Chain", "ChainResults", "NightFrame", "DEPTH_STAGES"]

#: Stages a :meth:`Chain.compute` may stop at.
DEPTH_STAGES = ("geometry", "filter", "uncertain", "refine", "mesh")

ProgressFn = Callable[[dict], None] | None


@dataclass
class ChainResults:
    """What :meth:`Chain.compute` produced (None for stages not run).

    timings : seconds each result took to compute (also when it came from the cache);
    recomputed : the stages computed by this call.
    """

    intrinsics: Intrinsics
    depth_in: np.ndarray | None = None
    normals_in: np.ndarray | None = None
    depth_source: str = ""
    filtered: np.ndarray | None = None
    uncertain: np.ndarray | None = None
    refine: Any = None
    mesh_result: MeshResult | None = None
    lights: LightsResult | None = None
    mesh_key: str = ""
    scene: Scene | None = None
    timings: dict[str, float] = field(default_factory=dict)
    recomputed: list[str] = field(default_factory=list)

    @property
    def mesh(self) -> SceneMesh | None:
        return self.mesh_result.mesh if self.mesh_result is not None else None

    @property
    def removed(self) -> MeshPart | None:
        return self.mesh_result.removed if self.mesh_result is not None else None

    @property
    def layers(self):
        return self.mesh_result.layers if self.mesh_result is not None else None

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


@dataclass
class NightFrame:
    """A night: 8-bit sRGB ``image``, the ``linear`` render, ``spp`` so far, ``elapsed`` seconds,
    the Mitsuba ``variant``, the light states ``active``, per-step ``timings`` (s), the
    ``denoiser`` that ran (``oidn``, ``guided`` or ``none``), the rendered mesh's ``faces`` and
    the ``exposure`` chosen."""

    image: np.ndarray
    linear: np.ndarray
    spp: int
    elapsed: float
    variant: str
    active: Any = None
    timings: dict[str, float] = field(default_factory=dict)
    denoiser: str = ""
    faces: int = 0
    #: ``exposure_mode``, ``exposure_ev`` (the stops applied), the meter's reading and the ego
    #: compositing gain (:meth:`Chain.finish`).
    exposure: dict = field(default_factory=dict)
    #: The light annotation the night used (:meth:`Chain.lights`; None = no light sources).
    annotation: Any = None
    #: Realism measures against the day photo (:func:`npsim_core.realism.night_realism`: structure
    #: ratio overall and per class, global statistics); final nights and a preview's last pass.
    realism: dict = field(default_factory=dict)


class Chain:
    """The staged, cached chain of one frame (module doc).

    ``compute`` serialises callers with a lock; a cancelled run leaves its finished
    stages cached.
    """

    def __init__(self, frame: Scene, *, cache_size: int = 4):
        self.scene = frame
        self.annotation = frame.lights
        self._annotation_version = 0
        self._lock = threading.RLock()
        self.engine = Engine(STAGES, cache_size=cache_size)
        self.engine.set_source("frame", frame, key=content_key(frame.with_(lights=None)))
        self.engine.set_source("annotation", self.annotation, key="ann-0")
        self._display: dict[str, Any] = {}

    # ------------------------------------------------------------------ annotation edits
    def set_annotation(self, ann) -> None:
        """Use an edited light annotation (invalidates the mesh and the night scene)."""
        with self._lock:
            self.annotation = ann
            self._annotation_version += 1
            self.engine.set_source("annotation", ann, key=f"ann-{self._annotation_version}")

    def lights(self, params: ChainParams, *, cancel: threading.Event | None = None) -> LightsResult:
        """The light annotation the nights of ``params`` use (``lights`` section: the hand annotation,
        the proposals, a file or none) and where it came from; cached like every stage."""
        with self._lock:
            return self.engine.run(("lights",), params, cancel=cancel).results["lights"]

    # ------------------------------------------------------------------ depth and mesh
    def compute(self, params: ChainParams, until: str = "mesh", *, cancel: threading.Event | None = None,
                progress: ProgressFn = None) -> ChainResults:
        """Run (or reuse) every stage ``until`` needs; returns the results and what was recomputed.

        ``progress`` receives dicts: ``{"stage": name}`` when a stage starts, ``{"stage", "done",
        "seconds"}`` when it ends and, during refinement, ``{"stage": "refine", "step", "of",
        "history"}`` (the loss curves so far).
        """
        if until not in DEPTH_STAGES:
            raise NpsimInputError(f"unknown stage {until!r}; stages are {DEPTH_STAGES}")
        targets = set(DEPTH_STAGES[:DEPTH_STAGES.index(until) + 1])
        if until == "mesh":  # only what the mesh reads (e.g. no refinement for a mesh of the input depth)
            needs = set(mesh_needs(params))
            targets = {"geometry", "mesh"} | (needs & set(DEPTH_STAGES)) | ({"filter"} if "uncertain" in needs else set())
        targets = tuple(st for st in DEPTH_STAGES if st in targets)
        if until == "mesh":  # the lights the mesh is shown, written and rendered with (not its geometry)
            targets += ("lights",)
        with self._lock:
            run = self.engine.run(targets, params, cancel=cancel, progress=_progress_adapter(progress))
        out = run.results
        geo: GeometryResult = out["geometry"]
        return ChainResults(intrinsics=geo.scene.intrinsics, depth_in=geo.scene.depth, normals_in=geo.scene.normals,
                            depth_source=geo.source, filtered=out.get("filter"), uncertain=out.get("uncertain"),
                            refine=out.get("refine"), mesh_result=out.get("mesh"), lights=out.get("lights"),
                            mesh_key=run.keys.get("mesh", "") if "mesh" in out else "", scene=self.scene,
                            timings=dict(run.timings), recomputed=list(run.recomputed))

    def display_mesh(self, results: ChainResults, max_faces: int = 150_000,
                     params: ChainParams | None = None) -> SceneMesh:
        """A lighter version of ``results.mesh`` for interactive 3D display (quadtree reduction to
        about ``max_faces``, cached per mesh); the full mesh when it is small enough. When the
        reduction cannot get near the budget (depth-step and silhouette quads stay at pixel
        resolution: 246 k faces at best for a 2048x1024 street), the post-processed mesh of the
        same depth at a lower resolution is shown instead (:meth:`_coarse_display`; ``params``
        gives its post-processing parameters) -- a software-rendered view redraws every face per
        frame, ~0.1 s for 250 k faces."""
        mesh = results.mesh
        if mesh is None:
            return mesh
        ann = self.lights(params).annotation if params is not None else self.annotation
        ids = ann.instance_map if ann is not None else None
        key = (results.mesh_key, int(max_faces), id(ann))
        if self._display.get("key") == key:
            return self._display["mesh"]
        if mesh.n_faces <= max_faces:
            from .stages import lit_mesh

            shown = lit_mesh(results.mesh_result, ann)[0]
        elif results.layers is not None:
            from ..mesh.reduce import ReduceParams, reduce_mesh

            shown = reduce_mesh(results.layers.with_lights(ids), results.intrinsics,
                                ReduceParams(budget=int(max_faces))).mesh
            if shown.n_faces > 1.5 * max_faces:
                shown = self._coarse_display(results, max_faces, shown.n_faces, params, ids)
        else:
            from ..mesh.grid import grid_mesh

            stride = int(np.ceil(np.sqrt(mesh.n_faces / max_faces)))
            shown = grid_mesh(results.mesh_result.depth, results.intrinsics, self.scene.labels, ids, stride=stride)
        self._display = {"key": key, "mesh": shown, "annotation": ann}  # ann kept: its id stays unique
        return shown

    def _coarse_display(self, results: ChainResults, max_faces: int, floor: int,
                        params: ChainParams | None, light_ids: np.ndarray | None) -> SceneMesh:
        """The post-processing kernel on the meshed depth (labels, U, light ids) resampled by an
        integer factor, reduced to ``max_faces``; vertex pixels in full-resolution coordinates."""
        import cv2

        from ..mesh.postprocess import PostprocessParams, postprocess_mesh
        from ..mesh.reduce import ReduceParams, reduce_mesh
        from ..mesh.types import limit_far

        k = int(np.ceil(np.sqrt(floor / max_faces)))
        H, W = results.mesh_result.depth.shape
        w, h = max(2, -(-W // k)), max(2, -(-H // k))

        def near(a):
            return cv2.resize(a, (w, h), interpolation=cv2.INTER_NEAREST)

        uncertain = results.uncertain if results.uncertain is not None else np.zeros((H, W), bool)
        pp = params.postprocess if params is not None else PostprocessParams()
        far = params.mesh.far_limit if params is not None else None
        intr = results.intrinsics.resized(w, h)
        res = postprocess_mesh(near(results.mesh_result.depth), intr, near(self.scene.labels),
                               near(uncertain.astype(np.uint8)) > 0,
                               near(light_ids) if light_ids is not None else None, params=replace(pp, far_limit=far))
        small = reduce_mesh(res.layers, intr, ReduceParams(budget=int(max_faces))).mesh
        sx, sy = W / w, H / h  # pixel centres: (u + 0.5) * s - 0.5
        parts = [replace(p, source=None,  # its pixels are the coarse grid's
                         pixel=np.stack([(p.pixel[:, 0] + 0.5) * sx - 0.5, (p.pixel[:, 1] + 0.5) * sy - 0.5],
                                        axis=1).astype(np.float32)) for p in small.parts]
        return limit_far(replace(small, parts=parts, width=W, height=H,
                                 info={**small.info, "display_scale": 1.0 / k}), far)

    # ------------------------------------------------------------------ night
    def night_inputs(self, params: ChainParams, *, cancel=None, progress: ProgressFn = None):
        """(built Mitsuba scene, denoise guides or None, materials result, the engine run), built once
        per mesh (the guides once per mesh and denoiser)."""
        targets = ("night_scene", "materials") + (("guides",) if params.night.denoiser_used != "none" else ())
        with self._lock:
            run = self.engine.run(targets, params, cancel=cancel, progress=_progress_adapter(progress))
        built = run.results["night_scene"]
        built.set_ego_headlights(params.night.ego_headlights)
        return built, run.results.get("guides"), run.results["materials"], run

    def activate(self, params: ChainParams, light_override: dict[int, bool] | None = None):
        """One night's light states for ``params.night.seed`` (``light_override``: forced on/off)."""
        from ..render.lights import activate_lights

        return activate_lights(self.lights(params).annotation, light_table(params.night), params.night.seed,
                               group_all_together=params.night.group_all_together, image=self.scene.image,
                               force=light_override)

    def finish(self, linear: np.ndarray, params: ChainParams, guides, materials, *,
               labels: np.ndarray | None = None, info: dict | None = None, active=None,
               spot_ids=()) -> tuple[np.ndarray, dict[str, float]]:
        """Linear render -> denoised by ``night.denoiser_used`` (docs/method.md §6.5) -> ego vehicle
        and frame borders composited from the day (:func:`~npsim_core.render.ego.composite_ego`) ->
        exposure (``night.exposure_mode``: metered, or ``night.exposure`` stops) -> camera -> 8-bit
        sRGB; returns it and the seconds of each step. ``info`` (a dict) receives the exposure chosen
        (``exposure_ev``, stops), the meter's reading and the ego compositing gain. ``active`` and
        ``spot_ids`` (the night's light states, the lights with a spot): the heads of throwing lamps
        are brought to their visible radiance before the camera's glare
        (:func:`~npsim_core.render.lights.visible_head_radiance`)."""
        from ..render.camera_post import CameraParams, apply_camera
        from ..render.denoise import denoise_night

        from ..render.camera_post import auto_exposure, auto_white_balance
        from ..render.ego import composite_ego, ego_mask

        n = params.night
        t0 = time.perf_counter()
        used = n.denoiser_used
        lights = materials.light_classes > 0
        clean = denoise_night(linear, guides if used != "none" else None, params.denoise, lights, denoiser=used)
        t1 = time.perf_counter()
        # The ego vehicle and the frame borders: the day pixels darkened like the scene (docs/relight.md).
        frame = self.scene
        clean, ego = composite_ego(clean, frame.image, frame.labels, lights)
        annotation = self.lights(params).annotation if active is not None and spot_ids else None
        if annotation is not None and float(n.glare) > 0:
            import cv2

            from ..render.lights import visible_head_radiance

            heads = visible_head_radiance(annotation.instance_map, active, light_table(n), spot_ids)
            if heads is not None:
                heads = cv2.resize(heads, (clean.shape[1], clean.shape[0]), interpolation=cv2.INTER_NEAREST) \
                    if heads.shape[:2] != clean.shape[:2] else heads
                clean = np.where(np.isfinite(heads), heads, clean).astype(np.float32)
        ev, meter = n.exposure, {}
        lab_r = _resize_nearest(frame.labels, clean.shape[:2])
        excl_r = _resize_nearest(lights, clean.shape[:2]) | _resize_nearest(ego_mask(frame.labels), clean.shape[:2])
        if n.exposure_mode == "auto":
            ev, meter = auto_exposure(clean, lab_r, excl_r, target=n.exposure_target,
                                      bounds=(n.exposure_min, n.exposure_max), compensation=n.exposure)
        # The camera's white balance reads the same lit pixels as its meter (docs/relight.md).
        wb, wb_info = auto_white_balance(clean, lab_r, excl_r, degree=float(n.white_balance))
        cam = CameraParams(exposure_ev=ev, iso=(n.iso or None) if n.noise else None, seed=n.seed,
                           motion_blur_px=int(n.motion_blur_px), bloom=float(n.bloom), white_balance=wb,
                           tone_contrast=float(n.tone_contrast), glare=float(n.glare),
                           glare_radius=float(n.glare_radius))
        same = labels is not None and labels.shape == clean.shape[:2]
        srgb, _ = apply_camera(clean, cam, labels=labels if same else None,
                               light_classes=materials.light_classes if same else None)
        if info is not None:
            info.update(exposure_mode=n.exposure_mode, exposure_ev=float(ev), **meter, **ego, **wb_info)
        return srgb, {"denoise": t1 - t0, "camera": time.perf_counter() - t1}

    def night_preview(self, results: ChainResults | None, params: ChainParams, *,
                      light_override: dict[int, bool] | None = None,
                      cancel: threading.Event | None = None) -> Iterator[NightFrame]:
        """Progressive night preview: yields post-processed frames as passes accumulate."""
        from ..render.render import PreviewParams, render_preview

        t0 = time.perf_counter()
        built, guides, mats, _ = self.night_inputs(params, cancel=cancel)
        active = self.activate(params, light_override)
        built.apply_lights(active)
        n = params.night
        first = min(4, int(n.spp))  # a quick first frame, then the rest in one pass
        pp = PreviewParams(scale=n.preview_scale, schedule=(first,) + ((int(n.spp) - first,) if n.spp > first else ()),
                           seed=n.seed, max_depth=int(n.preview_max_depth))
        for frame in render_preview(built, pp, cancel=cancel):
            info: dict = {}
            srgb, tm = self.finish(frame.image, params, guides, mats, info=info, active=active,
                                   spot_ids=built.spot_keys)
            real = self.realism(srgb, tm) if frame.spp >= int(n.spp) else {}
            yield NightFrame(srgb, frame.image, frame.spp, time.perf_counter() - t0, built.variant, active, tm,
                             n.denoiser_used, built.n_faces, info, self.lights(params).annotation, real)

    def night_final(self, results: ChainResults | None, params: ChainParams, *, seed: int | None = None,
                    cancel: threading.Event | None = None, scale: float = 1.0,
                    release_scene: bool = False) -> NightFrame:
        """A full-resolution night (``params.night.final_spp``) with denoising and camera.

        ``release_scene`` drops the cached Mitsuba scene right after the render, before denoising
        (a batch frame's last night): the denoiser's memory peak then comes without the scene's
        acceleration structure; a later night of the same mesh builds it again."""
        from ..render.render import render_final

        t0 = time.perf_counter()
        if seed is not None:
            params = replace(params, night=replace(params.night, seed=int(seed)))
        n = params.night
        built, guides, mats, run = self.night_inputs(params, cancel=cancel)
        t1 = time.perf_counter()
        active = self.activate(params)
        built.apply_lights(active)
        t2 = time.perf_counter()
        linear = render_final(built, spp=n.final_spp, seed=n.seed, cancel=cancel, scale=scale,
                              passes=max(1, n.final_spp // 16), max_depth=int(n.final_max_depth))
        t3 = time.perf_counter()
        variant, faces, spot_ids = built.variant, built.n_faces, tuple(built.spot_keys)
        if release_scene:
            from ..render.render import release_jit_memory

            del built, run
            self.engine.clear_cache("night_scene")
            release_jit_memory()  # the scene's buffers, back from Dr.Jit's cache
        info: dict = {}
        srgb, tm = self.finish(linear, params, guides, mats, labels=self.scene.labels, info=info, active=active,
                               spot_ids=spot_ids)
        timings = {"night_inputs": t1 - t0, "lights": t2 - t1, "render": t3 - t2, **tm}
        real = self.realism(srgb, timings)
        return NightFrame(srgb, linear, n.final_spp, time.perf_counter() - t0, variant, active, timings,
                          n.denoiser_used, faces, info, self.lights(params).annotation, real)

    def realism(self, night: np.ndarray, timings: dict | None = None) -> dict:
        """Realism of an sRGB ``night`` of this frame against its day photo (docs/relight.md
        "Realism"); its time goes to ``timings["realism"]``."""
        from ..realism import night_realism

        t0 = time.perf_counter()
        out = night_realism(self.scene.image, self.scene.labels, night)
        if timings is not None:
            timings["realism"] = time.perf_counter() - t0
        return out


def _resize_nearest(a: np.ndarray, hw: tuple[int, int]) -> np.ndarray:
    """A label or mask map at a render's size (a preview is smaller than the frame)."""
    a = np.asarray(a)
    if a.shape[:2] == tuple(hw):
        return a
    import cv2

    out = cv2.resize(a.astype(np.uint8), (hw[1], hw[0]), interpolation=cv2.INTER_NEAREST)
    return out.astype(bool) if a.dtype == bool else out.astype(a.dtype)


def _progress_adapter(progress: ProgressFn):
    if progress is None:
        return None

    def on_progress(stage: str, fraction: float, info: Any) -> None:
        progress(info if isinstance(info, dict) else {"stage": stage, "fraction": fraction, "text": info})

    return on_progress
