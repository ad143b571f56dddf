"""The built-in synthetic street scene with exact ground truth: the input of every test and benchmark (docs/synthetic.md).

``make_street_scene(W, H, seed)`` lays out a seeded street (:mod:`.street`) as
axis-aligned primitives, computes depth / normals / labels / light instances /
albedo / roughness by exact pixel-centre ray casting in numpy
(:mod:`.primitives`), renders the daytime RGB with Mitsuba 3 ``scalar_rgb``
(:mod:`.render`, pixel-aligned with the ray caster), and simulates a network's
depth and normal prediction from the ground truth (:mod:`.prediction`).
``street_scene`` caches the result as a scene folder. See ``docs/synthetic.md``.

Importing this package does not import Mitsuba.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from ..annotation import GroupInstance, LightAnnotation
from ..camera import Intrinsics, backproject
from ..errors import NpsimInputError
from ..scene import Scene, load_scene, save_scene
from .prediction import PredictionErrors, simulate_prediction
from .primitives import MATERIALS, ROUGHNESS, CameraPose, GroundTruth, Primitives, raycast
from .street import (RECTIFICATION_BORDER, SKY, VARIANTS, StreetLayout, build_street, check_variant,
                     frame_border_labels)
from .texture import albedo_factor

__all__ = ["make_street_scene", "street_scene", "PredictionErrors", "simulate_prediction", "SCENE_VERSION",
           "CAMERA_HEIGHT", "CAMERA_PITCH", "build_street", "raycast", "CameraPose", "street_ground_truth",
           "cache_dir", "auto_spp", "VARIANTS", "street_right_view"]

#: Bump whenever the scene's content changes (it is part of the cache key; it covers the
#: hard variants too, whose layouts are new in version 4 and leave the default street unchanged).
#: Version 6: windows, panes and lamps vary in brightness, frames, curtains (texture.light_factor);
#: every third street light is a post-top lantern (street_light_LT).
#: Version 7: Cityscapes instance ids (``Scene.instances``, ``<name>_instanceIds.png``).
SCENE_VERSION = 7
#: Revisions of one variant's content within a scene version (part of its cache key), so a change to
#: one variant does not re-render every cached street. lights 2: a pedestrian signal (issue #26).
VARIANT_REVISION = {"lights": 2}
CAMERA_HEIGHT = 1.22
CAMERA_PITCH = 0.038
#: Exposure applied to the linear render before sRGB encoding.
EXPOSURE = 1.0


def _check_size(width: int, height: int) -> tuple[int, int]:
    try:
        w, h = int(width), int(height)
    except (TypeError, ValueError):
        raise NpsimInputError(f"synthetic scene size must be integers, got {width!r}x{height!r}") from None
    if w != width or h != height or w < 2 or h < 2 or w > 16384 or h > 16384:
        raise NpsimInputError(f"synthetic scene size must be whole numbers in 2..16384, got {width}x{height}")
    return w, h


def _check_variant(variant: str) -> str:
    try:
        return check_variant(variant)
    except ValueError as exc:
        raise NpsimInputError(str(exc)) from None


def street_ground_truth(width: int, height: int, seed: int = 0, *, include_lights: bool = True,
                        variant: str = "default") -> tuple[StreetLayout, Intrinsics, CameraPose, GroundTruth]:
    """Layout, camera and exact GT buffers (no render, no prediction).

    ``variant`` picks a hard street layout (:data:`VARIANTS`, docs/synthetic.md).

    ``include_lights=False`` casts without the light panes, i.e. the host surfaces
    under them; the returned ``GroundTruth.prim`` then indexes
    ``layout.prims.subset(layout.prims.light == 0)``, not ``layout.prims``.
    """
    width, height = _check_size(width, height)
    if int(seed) != seed or seed < 0:
        raise NpsimInputError(f"synthetic scene seed must be a non-negative integer, got {seed!r}")
    layout = build_street(int(seed), _check_variant(variant))
    intr = Intrinsics.cityscapes(width, height)
    pose = CameraPose(CAMERA_HEIGHT, CAMERA_PITCH)
    prims = layout.prims if include_lights else layout.prims.subset(layout.prims.light == 0)
    return layout, intr, pose, raycast(prims, intr, pose)


def _lights(prims: Primitives, prim_map: np.ndarray, layout: StreetLayout) -> LightAnnotation:
    """Instance map from the hit primitives; groups keep only members that own pixels."""
    inst = np.where(prim_map >= 0, prims.light[np.maximum(prim_map, 0)], 0).astype(np.int32)
    present = set(int(i) for i in np.unique(inst) if i != 0)
    groups = {}
    for gid, members in layout.groups.items():
        kept = tuple(m for m in members if m in present)
        if kept:
            groups[gid] = GroupInstance(gid, kept)
    return LightAnnotation(inst, groups)


def linear_to_srgb8(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.clip(s * 255.0 + 0.5, 0, 255).astype(np.uint8)


def auto_spp(width: int, height: int) -> int:
    """Samples per pixel when none are given: 16 up to 512x256 pixels, 4 above.

    The sun is a delta light, so samples only antialias edges (see
    :func:`.render.render_day`); render time is linear in pixels x spp.
    """
    return 16 if width * height <= 512 * 256 else 4


def _pow4(n: int) -> int:
    """Mitsuba's low-discrepancy sampler needs a square power-of-two count >= 4 (4, 16, 64, ...)."""
    k = 4
    while k < n:
        k *= 4
    return k


def make_street_scene(width: int = 256, height: int = 128, seed: int = 0, *, spp: int | None = None,
                      prediction: PredictionErrors | None = None, variant: str = "default") -> Scene:
    """Generate the synthetic street at ``width`` x ``height`` (deterministic in ``seed``).

    Parameters
    ----------
    width, height : int
        Image size in pixels (any size >= 2x2; 2:1 matches Cityscapes).
    seed : int
        Varies the layout (buildings, windows, cars, colours, pole spacing) and the
        simulated prediction errors.
    spp : int, optional
        Mitsuba samples per pixel for the daytime RGB (rounded up to 4, 16, 64, ...);
        default :func:`auto_spp`.
    prediction : PredictionErrors, optional
        Error model of the simulated depth/normal network (defaults documented there).
    variant : str
        ``"default"`` (the street every test and cached result uses, unchanged), or a hard
        layout for the depth prior: ``"receding"``, ``"occluded_base"``, ``"corner"``,
        ``"clutter"``, ``"hard"`` (all of them), or ``"busy"`` (people, riders, a truck or bus,
        the ego hood and the frame-border labels), see docs/synthetic.md.

    Returns
    -------
    Scene
        ``image`` (Mitsuba render, sRGB uint8), ``labels`` (Cityscapes labelIds),
        ``depth_gt``/``normals_gt`` (exact at pixel centres; NaN on sky),
        ``depth``/``normals`` (simulated prediction), ``lights`` (instances + groups),
        ``albedo`` (linear RGB) and ``roughness`` maps, camera height/pitch.
    """
    from .render import render_day

    params = prediction or PredictionErrors()
    width, height = _check_size(width, height)
    variant = _check_variant(variant)
    spp = auto_spp(width, height) if spp is None else int(spp)
    if spp < 1:
        raise NpsimInputError(f"spp must be >= 1, got {spp}")
    spp = _pow4(spp)
    t0 = time.perf_counter()
    layout, intr, pose, gt = street_ground_truth(width, height, seed, variant=variant)
    prims = layout.prims
    hit = gt.prim >= 0
    idx = np.maximum(gt.prim, 0)
    labels = np.where(hit, prims.label[idx], SKY).astype(np.uint8)
    albedo = np.where(hit[..., None], prims.color[idx], 0.0).astype(np.float32)
    rough_lut = np.array([ROUGHNESS[m] for m in MATERIALS], dtype=np.float32)
    roughness = np.where(hit, rough_lut[prims.material[idx]], 1.0).astype(np.float32)
    lights = _lights(prims, gt.prim, layout)
    glass = hit & (prims.material[idx] == MATERIALS.index("glass"))
    points_w = backproject(gt.depth, intr) @ pose.R_cw.astype(np.float32) + pose.center.astype(np.float32)
    tex = albedo_factor(points_w, labels, lights.instance_map, seed)
    t1 = time.perf_counter()
    linear = render_day(prims, intr, pose, spp=spp, seed=seed, sun=layout.sun, albedo=albedo,
                        normals=gt.normals, prim=gt.prim, glass_mask=glass.astype(np.float32), texture=tex)
    albedo = np.clip(albedo * tex[..., None], 0.0, 1.0)
    t2 = time.perf_counter()
    depth, normals = simulate_prediction(gt.depth, gt.normals, params, seed)
    t3 = time.perf_counter()
    image = linear_to_srgb8(linear * EXPOSURE)
    if VARIANTS[variant].busy:  # Cityscapes' image-space border labels; no data on the rectification border
        border = frame_border_labels(width, height)
        labels = np.where(border > 0, border, labels).astype(np.uint8)
        image[border == RECTIFICATION_BORDER] = 0
    from .cityscapes import instance_ids  # (cityscapes imports this package)

    instances = instance_ids(labels, gt.prim, prims)
    name = f"street_s{seed}" if variant == "default" else f"street_{variant}_s{seed}"
    provenance = {"generator": "npsim_core.synthetic.make_street_scene", "version": SCENE_VERSION,
                  "seed": int(seed), "spp": int(spp)}
    if variant != "default":  # (the default scene's provenance stays as it was)
        provenance["variant"] = variant
    return Scene(name=name, image=image, labels=labels, intrinsics=intr, depth=depth, normals=normals,
                 depth_gt=gt.depth, normals_gt=gt.normals, lights=lights, albedo=albedo, roughness=roughness,
                 instances=instances,
                 camera_height=pose.height, camera_pitch=pose.pitch,
                 provenance={**provenance,
                             "renderer": "mitsuba scalar_rgb direct (sun) + sky ambient (numpy)",
                             "prediction": params.as_dict(), "layout": layout.info,
                             "timing_s": {"ground_truth": round(t1 - t0, 3), "render": round(t2 - t1, 3),
                                          "prediction": round(t3 - t2, 3)}})


def cache_dir() -> Path:
    """``$NPSIM_CACHE`` or ``~/.cache/npsim``."""
    env = os.environ.get("NPSIM_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "npsim"


def _cache_name(width: int, height: int, seed: int, variant: str) -> str:
    """Cache folder name without the version: the default street keeps its historical name."""
    tag = "" if variant == "default" else f"_{variant}"
    rev = VARIANT_REVISION.get(variant)
    return f"street_{width}x{height}_s{int(seed)}{tag}{'' if rev is None else f'r{rev}'}"


def _prune_old_versions(root: Path, width: int, height: int, seed: int, variant: str = "default") -> None:
    """Delete this size, seed and variant's cache entries of older scene versions (never read again)."""
    for old in root.glob(f"{_cache_name(width, height, seed, variant)}_v*"):
        v = old.name.rsplit("_v", 1)[-1]
        if v.isdigit() and int(v) < SCENE_VERSION:
            shutil.rmtree(old, ignore_errors=True)


def street_scene(width: int = 256, height: int = 128, seed: int = 0, variant: str = "default") -> Scene:
    """:func:`make_street_scene` with default parameters, cached as a scene folder.

    The folder ``<cache_dir()>/street_<W>x<H>_s<seed>_v<SCENE_VERSION>`` (for a hard
    ``variant``: ``street_<W>x<H>_s<seed>_<variant>_v<SCENE_VERSION>``) is written
    to a temporary sibling and renamed into place, so concurrent callers and
    crashes never see a half-written scene; entries of older scene versions for the
    same size and seed are deleted then.
    """
    width, height = _check_size(width, height)
    variant = _check_variant(variant)
    root = cache_dir()
    folder = root / f"{_cache_name(width, height, seed, variant)}_v{SCENE_VERSION}"
    if (folder / "scene.json").exists():
        try:
            return load_scene(folder)
        except NpsimInputError:
            shutil.rmtree(folder, ignore_errors=True)  # corrupt cache entry: regenerate
    scene = make_street_scene(width, height, seed, variant=variant)
    try:
        root.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.tmp-", dir=root))
    except OSError as exc:  # read-only or full cache location: still give the caller the scene
        warnings.warn(f"npsim: cannot write the scene cache in {root} ({exc}); set NPSIM_CACHE to a writable "
                      "folder to avoid regenerating", RuntimeWarning, stacklevel=2)
        return scene
    try:
        save_scene(scene, tmp)
        try:
            os.replace(tmp, folder)
        except OSError:
            # Another process won the race (target exists and is non-empty): use theirs.
            shutil.rmtree(tmp, ignore_errors=True)
        _prune_old_versions(root, width, height, seed, variant)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return load_scene(folder)


def street_right_view(width: int, height: int, seed: int = 0, *, baseline: float = 0.209313,
                      spp: int | None = None, variant: str = "default") -> np.ndarray:
    """The street's day image (sRGB uint8, HxWx3) seen by a right stereo camera ``baseline`` m to the
    right of the left one (same intrinsics, pose and sun), rendered exactly as :func:`make_street_scene`
    renders the left view (Mitsuba sun + numpy sky ambient, same surface texture in world coordinates).

    The scene is shifted by ``-baseline`` along x instead of moving the camera (world x = camera x,
    the pitch is about x), so the ray caster and the renderer are reused unchanged. Used by the
    Cityscapes-layout fixture's semi-global matching (:mod:`.cityscapes`, docs/synthetic.md).
    """
    from dataclasses import replace as _replace

    from .render import render_day

    width, height = _check_size(width, height)
    variant = _check_variant(variant)
    spp = _pow4(auto_spp(width, height) if spp is None else int(spp))
    layout = build_street(int(seed), variant)
    shift = np.array([float(baseline), 0.0, 0.0])
    prims = _replace(layout.prims, lo=layout.prims.lo - shift, hi=layout.prims.hi - shift)
    intr = Intrinsics.cityscapes(width, height)
    pose = CameraPose(CAMERA_HEIGHT, CAMERA_PITCH)
    gt = raycast(prims, intr, pose)
    hit = gt.prim >= 0
    idx = np.maximum(gt.prim, 0)
    labels = np.where(hit, prims.label[idx], SKY).astype(np.uint8)
    albedo = np.where(hit[..., None], prims.color[idx], 0.0).astype(np.float32)
    lights = _lights(prims, gt.prim, layout)
    glass = hit & (prims.material[idx] == MATERIALS.index("glass"))
    # World points of the *unshifted* street, so the texture sticks to the surfaces.
    points_w = (backproject(gt.depth, intr) @ pose.R_cw.astype(np.float32) + pose.center.astype(np.float32)
                + shift.astype(np.float32))
    tex = albedo_factor(points_w, labels, lights.instance_map, seed)
    linear = render_day(prims, intr, pose, spp=spp, seed=seed, sun=layout.sun, albedo=albedo,
                        normals=gt.normals, prim=gt.prim, glass_mask=glass.astype(np.float32), texture=tex)
    image = linear_to_srgb8(linear * EXPOSURE)
    if VARIANTS[variant].busy:
        image[frame_border_labels(width, height) == RECTIFICATION_BORDER] = 0
    return image
