"""Rendering a :class:`~npsim_core.render.scene_builder.BuiltScene`: progressive preview and final quality.

Both return (or yield) the **linear** RGB image, float32 HxWx3, in Mitsuba
radiance units (camera post-processing is separate: :mod:`camera_post`).

Threads: older Mitsuba 3 releases need the builder thread's environment in
every thread that renders; the builder captures it (``BuiltScene.thread_env``)
and these functions enter it, so they may be called from worker threads (the
GUI's render worker). Mitsuba 3.9 dropped ``ThreadEnvironment`` and renders
from any Python thread as is (measured); then ``thread_env`` is None.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np

from ..errors import NpsimCancelled, NpsimInputError
from .scene_builder import BuiltScene, thread_env_scope

CancelCheck = Callable[[], bool] | threading.Event | None


@dataclass(frozen=True)
class PreviewParams:
    """Progressive preview: ``passes`` passes of ``spp_per_pass`` at ``scale`` of the full resolution,
    path length ``max_depth`` (2 = direct light only: ~40 % cheaper than the final's one bounce)."""

    scale: float = 0.25
    spp_per_pass: int = 4
    passes: int = 4
    seed: int = 0
    max_depth: int = 2
    #: Optional spp of each pass, e.g. (4, 12): a quick first frame, then the rest in one
    #: render (each Mitsuba call costs ~0.1 s of set-up at 512x256); overrides spp_per_pass/passes.
    schedule: tuple[int, ...] = ()

    def pass_spp(self) -> tuple[int, ...]:
        if self.schedule:
            return tuple(int(x) for x in self.schedule)
        return (int(self.spp_per_pass),) * int(self.passes)


@dataclass(frozen=True)
class PreviewFrame:
    """One progressive step: the running average after ``pass_index + 1`` passes."""

    image: np.ndarray
    pass_index: int
    spp: int
    seconds: float


def _cancelled(cancel: CancelCheck) -> bool:
    if cancel is None:
        return False
    if isinstance(cancel, threading.Event):
        return cancel.is_set()
    return bool(cancel())


def _size(built: BuiltScene, scale: float) -> tuple[int, int]:
    if not (0 < scale <= 4):
        raise NpsimInputError(f"render scale must be in (0, 4], got {scale}")
    W, H = built.intrinsics.width, built.intrinsics.height
    return max(1, int(round(W * scale))), max(1, int(round(H * scale)))


def render_linear(built: BuiltScene, *, spp: int, seed: int = 0, scale: float = 1.0,
                  width: int | None = None, height: int | None = None, pixel_centres: bool = False,
                  max_depth: int | None = None, crop: tuple[int, int, int, int] | None = None,
                  sampler: str | None = None) -> np.ndarray:
    """One render of ``spp`` samples per pixel -> (H, W, 3) float32 linear RGB.

    ``max_depth`` overrides the scene's path length for this render only;
    ``crop = (x, y, w, h)`` renders only that window of the film (result h x w);
    ``sampler`` overrides the scene's Mitsuba sampler (``scene_builder.SAMPLERS``).
    """
    import mitsuba as mi

    if spp < 1:
        raise NpsimInputError(f"spp must be >= 1, got {spp}")
    w, h = (width, height) if width and height else _size(built, scale)
    with thread_env_scope(mi, built.thread_env):
        kw = {} if max_depth is None else {"integrator": built.integrator(int(max_depth))}
        sensor = built.sensor(w, h, pixel_centres=pixel_centres, crop=crop, sampler=sampler)
        img = mi.render(built.scene, sensor=sensor, spp=int(spp), seed=int(seed), **kw)
        return np.array(img, dtype=np.float32)[..., :3]


def render_preview(built: BuiltScene, params: PreviewParams = PreviewParams(),
                   cancel: CancelCheck = None) -> Iterator[PreviewFrame]:
    """Progressive preview: yields the running mean after each pass (different seeds).

    ``cancel`` (a ``threading.Event`` or a callable returning True) is checked
    before every pass; when set the generator raises :class:`NpsimCancelled`.
    """
    acc = None
    done = 0
    t0 = time.perf_counter()
    for k, spp in enumerate(params.pass_spp()):
        if _cancelled(cancel):
            raise NpsimCancelled("preview render cancelled")
        if spp < 1:
            raise NpsimInputError(f"preview pass {k} has {spp} spp; every pass needs >= 1")
        img = render_linear(built, spp=spp, seed=params.seed * 100003 + k, scale=params.scale,
                            max_depth=params.max_depth)
        acc = img * spp if acc is None else acc + img * spp  # passes weighted by their samples
        done += spp
        yield PreviewFrame(acc / done, k, done, time.perf_counter() - t0)


def render_final(built: BuiltScene, *, spp: int = 64, seed: int = 0, scale: float = 1.0,
                 cancel: CancelCheck = None, passes: int = 1, max_depth: int | None = None) -> np.ndarray:
    """Final-quality linear render at ``scale`` of the full resolution.

    With ``passes`` > 1 the spp are split into passes (cancellable between them);
    ``max_depth`` overrides the scene's path length (2 = direct light only).
    """
    passes = max(1, int(passes))
    per = max(1, int(spp) // passes)
    acc = None
    for k in range(passes):
        if _cancelled(cancel):
            raise NpsimCancelled("final render cancelled")
        img = render_linear(built, spp=per, seed=seed * 100003 + 7919 + k, scale=scale, max_depth=max_depth)
        acc = img if acc is None else acc + img
    release_jit_memory()
    return acc / passes


def release_jit_memory() -> None:
    """Hand Dr.Jit's cache of freed buffers back to the system: a 2048x1024 render leaves ~0.3 GB
    there, on top of which the denoiser reached the frame's peak (1.90 GiB before); a dropped
    scene's vertex and face buffers go there too."""
    try:
        import drjit as dr

        dr.flush_malloc_cache()
    except (ImportError, AttributeError):  # pragma: no cover - older Dr.Jit keeps its cache
        pass


#: Samples per pixel of the denoising guides (:func:`render_guides`): albedo and normal converge
#: almost at once (only the pixel footprint is sampled); 8 and 64 gave the same OIDN error, and 4
#: the same as 8 on the frontier crops at 2048x1024 (RMSE 17.213 vs 17.217, SSIM 0.7056 vs 0.7055,
#: one 16-spp render) for 0.5 CPU s less a frame (1.64 vs 2.17 s at load 14).
GUIDE_SPP = 4


def render_guides(built: BuiltScene, labels: np.ndarray, protect: np.ndarray | None = None, *,
                  spp: int = GUIDE_SPP, seed: int = 0, scale: float = 1.0):
    """Denoising guides from Mitsuba's ``aov`` integrator on the night scene itself -> a
    :class:`~.denoise.DenoiseGuides` of kind ``"aov"`` (for Open Image Denoise).

    albedo (``albedo`` AOV: the BSDF's reflectance), normals (``sh_normal``, the world = OpenCV
    camera frame, 0 on the sky) and depth (the ``depth`` AOV is the distance along the ray; here
    converted to z, NaN on the sky), each box-filtered over the pixel exactly as the render's
    film is, at ``scale`` of the full resolution; ``labels`` and ``protect`` (the light-source
    pixels) are the frame's, resized nearest. Lights and their states do not change them, so
    they are rendered once per scene.
    """
    import cv2
    import mitsuba as mi

    from .denoise import DenoiseGuides

    w, h = _size(built, scale)
    with thread_env_scope(mi, built.thread_env):
        integrator = mi.load_dict({"type": "aov", "aovs": "albedo:albedo,normal:sh_normal,depth:depth"})
        aov = np.array(mi.render(built.scene, sensor=built.sensor(w, h), integrator=integrator, spp=int(spp),
                                 seed=int(seed)), dtype=np.float32)
    release_jit_memory()
    K = built.intrinsics
    sx, sy = w / K.width, h / K.height  # the film's pixel centres in the full-resolution camera
    u, v = np.meshgrid((np.arange(w) + 0.5) / sx - 0.5, (np.arange(h) + 0.5) / sy - 0.5)
    ray = np.sqrt(((u - K.cx) / K.fx) ** 2 + ((v - K.cy) / K.fy) ** 2 + 1.0).astype(np.float32)
    dist = aov[..., 6]
    depth = np.where(dist > 0, dist / ray, np.nan).astype(np.float32)

    def nearest(a):
        a = np.asarray(a)
        return a if a.shape[:2] == (h, w) else cv2.resize(np.ascontiguousarray(a), (w, h),
                                                          interpolation=cv2.INTER_NEAREST)

    prot = np.zeros((h, w), bool) if protect is None else nearest(np.asarray(protect, np.uint8)).astype(bool)
    return DenoiseGuides(np.ascontiguousarray(aov[..., 0:3]), depth, np.ascontiguousarray(aov[..., 3:6]),
                         nearest(np.asarray(labels, np.uint8)), prot, kind="aov")


def render_labels(built_label_scene: BuiltScene, *, passes: int = 8, seed: int = 0) -> np.ndarray:
    """Decode a :func:`scene_builder.build_label_scene` render -> (H, W) int32 labelIds, -1 = no surface (sky).

    ``passes`` renders of 1 spp (box filter: each pixel holds exactly one sample's
    code, no averaging of codes) at random positions inside the pixel; each pixel
    takes the label hit most often (ties -> lowest id). A pixel is -1 only when
    every sample missed the mesh (sky, or the outer half-pixel of the mesh border:
    a Worldsheet grid spans pixel centres, not pixel extents).
    """
    b = built_label_scene
    W, H = b.intrinsics.width, b.intrinsics.height
    counts = np.zeros((257, H * W), dtype=np.int32)
    flat = np.arange(H * W)
    for k in range(max(1, int(passes))):
        img = render_linear(b, spp=1, seed=seed * 7919 + k, width=W, height=H)
        code = np.rint(img[..., 0]).astype(np.int64).ravel()  # labelId + 1, 0 = miss
        code = np.clip(code, 0, 256)
        np.add.at(counts, (code, flat), 1)
    hits = counts[1:]
    best = hits.argmax(axis=0)
    out = np.where(hits.max(axis=0) > 0, best, -1)
    return out.reshape(H, W).astype(np.int32)
