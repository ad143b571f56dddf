"""Scene -> mesh pipelines: the NPSim mesh and the thesis's two baselines (SPEC §4, issue 4 item 5).

Variants (as compared in the thesis):

* ``raw``      -- Worldsheet with external depth: :func:`~.grid.grid_mesh` of the predicted depth.
* ``filtered`` -- :func:`~.grid.grid_mesh` of the cross-bilateral-filtered depth, no post-processing.
* ``npsim``    -- filtered depth -> uncertain map U -> normal-guided refinement -> post-processing kernel.

The depth-refinement stages come from :mod:`npsim_core.refine` (cross-bilateral
filter, uncertain map, normal-guided refinement). Each can be skipped; when the
refine package cannot provide a stage it is skipped and the reason recorded in
``info["skipped"]``, never hidden.
"""

from __future__ import annotations

import time
import tracemalloc
from dataclasses import dataclass, field

import numpy as np

from ..errors import NpsimInputError
from ..scene import Scene
from .grid import grid_mesh
from .postprocess import PostprocessParams, PostprocessResult, postprocess_mesh
from .types import SceneMesh

__all__ = ["PipelineParams", "DepthStages", "MeshVariant", "depth_stages", "npsim_mesh", "build_variants",
           "VARIANTS"]

VARIANTS = ("raw", "filtered", "npsim")


@dataclass(frozen=True)
class PipelineParams:
    """Which refinement stages run before meshing.

    Attributes
    ----------
    filter : bool
        Dual-reference cross-bilateral filter (SPEC §2.1).
    refine : bool
        Normal-guided refinement (SPEC §2.3), needs the scene's normals.
    postprocess : PostprocessParams
    stride : int
        Vertex stride of the grid baselines.
    """

    filter: bool = True
    refine: bool = True
    postprocess: PostprocessParams = PostprocessParams()
    stride: int = 1


@dataclass
class DepthStages:
    """Depth maps along the pipeline and what happened to each stage."""

    predicted: np.ndarray
    filtered: np.ndarray
    uncertain: np.ndarray
    refined: np.ndarray
    timings: dict = field(default_factory=dict)
    skipped: dict = field(default_factory=dict)


@dataclass
class MeshVariant:
    name: str
    mesh: SceneMesh
    source_depth: np.ndarray
    seconds: float
    peak_mb: float
    result: PostprocessResult | None = None


def depth_stages(scene: Scene, params: PipelineParams = PipelineParams()) -> DepthStages:
    """Predicted -> filtered -> U -> refined depth for ``scene`` (stages skipped as ``params`` say)."""
    if scene.depth is None:
        raise NpsimInputError(f"scene {scene.name!r} has no predicted depth; run 'npsim estimate' first "
                              "or give the scene a depth map")
    tm: dict[str, float] = {}
    skipped: dict[str, str] = {}
    d = scene.depth.astype(np.float32)
    filtered = d
    if params.filter:
        try:
            from ..refine.bilateral import cross_bilateral
        except ImportError as exc:  # the refine package is optional at this stage
            skipped["filter"] = f"npsim_core.refine.bilateral unavailable ({exc})"
        else:
            t = time.perf_counter()
            filtered = cross_bilateral(d, scene.image, scene.labels).astype(np.float32)
            tm["filter"] = time.perf_counter() - t
    else:
        skipped["filter"] = "disabled"
    t = time.perf_counter()
    try:
        from ..refine.uncertainty import uncertain_map
    except ImportError as exc:
        raise NpsimInputError(f"the uncertain map needs npsim_core.refine.uncertainty ({exc})") from None
    U = uncertain_map(filtered, scene.labels)
    tm["uncertain"] = time.perf_counter() - t
    refined = filtered
    if params.refine and scene.normals is not None:
        try:
            from ..refine.optimize import refine_depth
        except ImportError as exc:
            skipped["refine"] = f"npsim_core.refine.optimize unavailable ({exc})"
        else:
            t = time.perf_counter()
            refined = refine_depth(filtered, scene.normals, scene.intrinsics, U).depth.astype(np.float32)
            tm["refine"] = time.perf_counter() - t
    else:
        skipped["refine"] = "disabled" if not params.refine else "scene has no normals"
    return DepthStages(predicted=d, filtered=filtered, uncertain=U, refined=refined, timings=tm, skipped=skipped)


def _light_ids(scene: Scene) -> np.ndarray | None:
    return None if scene.lights is None else scene.lights.instance_map


def _timed(fn, track_memory: bool):
    """(result, seconds, peak MB). The time comes from an untraced run; with ``track_memory``
    a second run under tracemalloc (which slows numpy allocations) gives the peak."""
    t = time.perf_counter()
    out = fn()
    sec = time.perf_counter() - t
    peak = 0.0
    if track_memory:
        tracemalloc.start()
        fn()
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    return out, sec, peak


def npsim_mesh(scene: Scene, stages: DepthStages, params: PipelineParams = PipelineParams()) -> PostprocessResult:
    """The NPSim mesh of a scene from its depth stages."""
    return postprocess_mesh(stages.refined, scene.intrinsics, scene.labels, stages.uncertain, _light_ids(scene),
                            params=params.postprocess, normals=scene.normals)


def build_variants(scene: Scene, params: PipelineParams = PipelineParams(), stages: DepthStages | None = None,
                   *, track_memory: bool = False) -> dict[str, MeshVariant]:
    """Build the ``raw``, ``filtered`` and ``npsim`` meshes of ``scene`` (module doc).

    ``seconds``/``peak_mb`` cover the meshing only (grid, or post-processing
    kernel incl. its triangulation); the depth stages' times are in ``stages.timings``.
    ``track_memory`` measures the peak (tracemalloc, numpy allocations) in a second run.
    """
    stages = stages if stages is not None else depth_stages(scene, params)
    intr, labels, lights = scene.intrinsics, scene.labels, _light_ids(scene)
    out: dict[str, MeshVariant] = {}
    for name, d in (("raw", stages.predicted), ("filtered", stages.filtered)):
        m, sec, peak = _timed(lambda: grid_mesh(d, intr, labels, lights, stride=params.stride,
                                                far_limit=params.postprocess.far_limit), track_memory)
        out[name] = MeshVariant(name, m, d, sec, peak)
    r, sec, peak = _timed(lambda: npsim_mesh(scene, stages, params), track_memory)
    out["npsim"] = MeshVariant("npsim", r.mesh, stages.refined, sec, peak, r)
    return out
