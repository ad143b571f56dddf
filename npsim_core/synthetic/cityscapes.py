"""A Cityscapes-layout test fixture made from the synthetic street: real-data paths without ground truth.

:func:`write_cityscapes_fixture` writes a small dataset that looks like a
Cityscapes download (docs/method.md §10): ``leftImg8bit`` images, ``gtFine``
labelIds / instanceIds / colour PNGs, stereo ``disparity`` PNGs and ``camera``
JSONs, and nothing else. There is no ground-truth depth or normals and no
NPSim-specific file. The stereo disparity is, by default, real semi-global
matching: the street's right view is rendered (Cityscapes baseline, the same
intrinsics) and OpenCV's ``StereoSGBM`` matches the pair (:func:`sgm_disparity`),
so it has SGM's structured errors (row streaks, fattened edges, speckle, wrong
depth on low-texture and glossy surfaces, no match at the left border). The older
model (``stereo="noise"``) simulates it from the exact depth instead (holes on sky,
the ego vehicle, occlusions, the left border, thin structures, glass, far range and
weakly textured blobs; a few % of disparity noise; 1/256 px quantisation). The
exact depth can be written outside the dataset (``truth``) for benchmarks. The
last ``corrupt`` frames carry a truncated image so batch runs must report and
skip them. Frame ``i`` is ``street_scene(W, H, seed + i)`` (see
:func:`fixture_seed`), which tests use as the hidden truth. See docs/synthetic.md.

Run as a script for a quick dataset: ``python -m npsim_core.synthetic.cityscapes OUT --frames 3
[--stereo sgm|noise] [--truth DIR] [--variant NAME]``.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from ..camera import Intrinsics
from ..errors import NpsimInputError
from ..io import atomic_write_bytes, atomic_write_text, write_image
from ..labels import cityscapes

__all__ = ["write_cityscapes_fixture", "simulate_stereo_disparity", "instance_ids", "ego_vehicle_mask",
           "native_intrinsics", "camera_json", "sgm_disparity", "fixture_seed", "fixture_stem", "BASELINE",
           "NATIVE_SIZE"]

#: Cityscapes' stereo baseline (m), as in every camera JSON of the dataset.
BASELINE = 0.209313
#: Resolution the camera JSON intrinsics refer to.
NATIVE_SIZE = (2048, 1024)
#: Camera position in the vehicle frame of real Cityscapes JSONs (not observable in the synthetic street).
_VEHICLE_XY = (1.7, 0.1)
_SKY = 23
_EGO_VEHICLE = 1
#: Light classes whose panes are glass (window_building, window_parked).
_GLASS_LIGHT_CLASSES = (1, 2)


def fixture_seed(seed: int, index: int) -> int:
    """Street seed of frame ``index``: frame ``i`` is ``street_scene(W, H, seed + i)``."""
    return int(seed) + int(index)


def fixture_stem(city: str, index: int) -> str:
    """Cityscapes-style stem ``<city>_<sequence:06d>_000019`` (gtFine frames are the 20th of a snippet)."""
    return f"{city}_{int(index):06d}_000019"


def fixture_image(root: str | os.PathLike, stem: str, split: str = "val", city: str = "synthcity") -> Path:
    """The day image of frame ``stem`` in a fixture written by :func:`write_cityscapes_fixture`."""
    return Path(root) / "leftImg8bit" / split / city / f"{stem}_leftImg8bit.png"


# --------------------------------------------------------------------------- camera
def native_intrinsics(intr: Intrinsics) -> Intrinsics:
    """The 2048x1024 intrinsics whose ``resized(W, H)`` gives ``intr`` back exactly (bit for bit).

    The plain inverse ``intr.resized(2048, 1024)`` can be off by an ulp after the
    round trip; each value is therefore taken as the shortest decimal (or the
    nearest float) that maps exactly onto ``intr``. Raises when no such value
    exists (never seen; it would mean the forward map skips ``intr``'s value).
    """
    NW, NH = NATIVE_SIZE
    guess = intr.resized(NW, NH)
    sx, sy = intr.width / NW, intr.height / NH
    forward = {"fx": lambda v: v * sx, "fy": lambda v: v * sy,
               "cx": lambda v: (v + 0.5) * sx - 0.5, "cy": lambda v: (v + 0.5) * sy - 0.5}
    out = {}
    for key, fwd in forward.items():
        target, g = getattr(intr, key), getattr(guess, key)
        cands = [round(g, d) for d in range(2, 13)] + [g]
        up = down = g
        for _ in range(16):
            up, down = math.nextafter(up, math.inf), math.nextafter(down, -math.inf)
            cands += [up, down]
        found = next((c for c in cands if fwd(c) == target), None)
        if found is None:
            raise NpsimInputError(f"cannot express {key}={target!r} at {intr.width}x{intr.height} as a "
                                  f"{NW}x{NH} camera JSON value that the reader rescales back exactly")
        out[key] = found
    return Intrinsics(out["fx"], out["fy"], out["cx"], out["cy"], NW, NH)


def camera_json(intr: Intrinsics, camera_height: float, camera_pitch: float) -> dict[str, Any]:
    """A Cityscapes camera JSON document for a camera with intrinsics ``intr`` (any image size).

    Intrinsics are given for the native 2048x1024 image (:func:`native_intrinsics`);
    ``z`` is the camera height (m), ``pitch`` the downward pitch (rad). Roll and
    yaw are 0 (the synthetic camera looks straight down the street); ``x``/``y``
    are the typical in-vehicle position of real files (unused by NPSim).
    """
    nat = native_intrinsics(intr)
    return {"extrinsic": {"baseline": BASELINE, "pitch": float(camera_pitch), "roll": 0.0,
                          "x": _VEHICLE_XY[0], "y": _VEHICLE_XY[1], "yaw": 0.0, "z": float(camera_height)},
            "intrinsic": {"fx": nat.fx, "fy": nat.fy, "u0": nat.cx, "v0": nat.cy}}


# --------------------------------------------------------------------------- labels
def ego_vehicle_mask(width: int, height: int) -> np.ndarray:
    """HxW bool: the ego vehicle's bonnet at the bottom of the frame (labelId 1 in real Cityscapes).

    A parabolic edge, 8 % of the height at the centre and 2 % at the sides
    (about 6 % of the pixels), like the Mercedes bonnet in every Cityscapes frame.
    """
    x = (np.arange(width, dtype=np.float64) + 0.5) / width * 2.0 - 1.0
    top = height * (1.0 - (0.02 + 0.06 * (1.0 - x ** 2)))
    return np.arange(height, dtype=np.float64)[:, None] + 0.5 >= top[None, :]


def _paint_ego_vehicle(image: np.ndarray, hood: np.ndarray) -> np.ndarray:
    """Dark bonnet with a blurred, dimmed reflection of the scene just above its edge."""
    out = image.copy()
    H, W = hood.shape
    if not hood.any():
        return out
    top = np.where(hood.any(axis=0), hood.argmax(axis=0), H)          # first hood row per column
    rows, cols = np.nonzero(hood)
    t = rows - top[cols]                                               # rows below the edge
    src = np.clip(top[cols] - 1 - 2 * t, 0, H - 1)
    refl = np.zeros_like(image, dtype=np.float32)
    refl[rows, cols] = image[src, cols].astype(np.float32)
    refl = cv2.GaussianBlur(refl, (0, 0), max(0.6, W / 400.0))
    depth_frac = t / np.maximum(1, H - top[cols])
    paint = np.array([30.0, 32.0, 36.0], dtype=np.float32)
    val = paint[None, :] * (1.0 - 0.35 * depth_frac[:, None]) + 0.28 * refl[rows, cols]
    out[rows, cols] = np.clip(val + 0.5, 0, 255).astype(np.uint8)
    return out


def instance_ids(labels: np.ndarray, prim: np.ndarray | None = None, prims: Any = None) -> np.ndarray:
    """Cityscapes instanceIds (uint16): ``classId*1000 + k`` on instance classes, the labelId elsewhere.

    With the ray caster's primitive index ``prim`` and the street's ``prims``, the
    primitives of one object (a car's body, cabin, wheels, panes and lamps) are
    grouped by their overlapping footprints, so each object is one instance even
    where two cars overlap in the image. Without them, each connected component
    of a class is an instance. ``k`` counts from 0 per class, in order of each object's lowest
    image row (nearest first for objects standing on the road).
    """
    table = cityscapes()
    inst_classes = [c.id for c in table.classes if c.has_instances]
    out = labels.astype(np.uint16)
    for cls in inst_classes:
        mask = labels == cls
        if not mask.any():
            continue
        if prim is not None and prims is not None:
            obj = _objects_by_footprint(prims, cls)                    # prim index -> object id (or -1)
            ids = np.where(prim >= 0, obj[np.maximum(prim, 0)], -1)
            ids = np.where(mask, ids, -1)
            if (ids[mask] < 0).any():                                  # label without an object: fall back
                ids = None
        else:
            ids = None
        if ids is None:
            ids, _ = ndimage.label(mask)
            ids = np.where(mask, ids, -1)
        present = [int(i) for i in np.unique(ids[mask])]
        rows = np.broadcast_to(np.arange(labels.shape[0])[:, None], labels.shape)
        lowest = {i: int(rows[ids == i].max()) for i in present}
        order = sorted(present, key=lambda i: (-lowest[i], i))
        if len(order) > 1000:
            raise NpsimInputError(f"class {cls}: {len(order)} instances exceed Cityscapes' 1000 per class")
        for k, i in enumerate(order):
            out[ids == i] = cls * 1000 + k
    return out


def _objects_by_footprint(prims: Any, cls: int) -> np.ndarray:
    """Object id per primitive of class ``cls`` (-1 for others): primitives whose x-z footprints
    (grown by 5 cm) overlap belong to the same object."""
    n = len(prims.label)
    sel = np.nonzero(np.asarray(prims.label) == cls)[0]
    obj = np.full(n, -1, dtype=np.int64)
    if len(sel) == 0:
        return obj
    lo, hi = np.asarray(prims.lo)[sel][:, [0, 2]] - 0.05, np.asarray(prims.hi)[sel][:, [0, 2]] + 0.05
    overlap = np.all((lo[:, None, :] <= hi[None, :, :]) & (lo[None, :, :] <= hi[:, None, :]), axis=2)
    _, comp = connected_components(csr_matrix(overlap), directed=False)
    obj[sel] = comp
    return obj


# --------------------------------------------------------------------------- stereo
def _unit_field(rng: np.random.Generator, shape: tuple[int, int], sigma: float) -> np.ndarray:
    """Gaussian-smoothed white noise scaled to zero mean and unit standard deviation.

    Wide kernels are applied on a grid ``sigma/3`` times coarser and interpolated back (same look, fast at 2048 px).
    """
    step = max(1, int(sigma // 3))
    H, W = shape
    small = (-(-H // step) + 1, -(-W // step) + 1)
    f = ndimage.gaussian_filter(rng.standard_normal(small), sigma / step, mode="reflect")
    if step > 1:
        f = cv2.resize(f, (small[1] * step, small[0] * step), interpolation=cv2.INTER_LINEAR)
    f = f[:H, :W]
    sd = f.std()
    return (f - f.mean()) / sd if sd > 0 else f * 0.0


def _shift_max(a: np.ndarray, r: int, axis: int, direction: int) -> np.ndarray:
    """Max of ``a`` over offsets 1..r along ``axis`` on one side (``direction`` -1 before, +1 after); -inf off-image."""
    out = np.full(a.shape, -np.inf)
    n = a.shape[axis]
    for k in range(1, r + 1):
        if k >= n:
            break
        src = [slice(None)] * 2
        dst = [slice(None)] * 2
        if direction > 0:
            src[axis], dst[axis] = slice(k, None), slice(None, n - k)
        else:
            src[axis], dst[axis] = slice(None, n - k), slice(k, None)
        out[tuple(dst)] = np.maximum(out[tuple(dst)], a[tuple(src)])
    return out


def simulate_stereo_disparity(depth: np.ndarray, labels: np.ndarray, fx: float, *, baseline: float = BASELINE,
                              seed: int = 0, noise: float = 0.02, hole_fraction: float = 0.2,
                              glass: np.ndarray | None = None, far_limit: float = 100.0,
                              glass_probability: float = 0.3) -> tuple[np.ndarray, dict[str, float]]:
    """A Cityscapes disparity PNG (uint16, ``p = disparity*256 + 1``, 0 invalid) from exact z-depth.

    Parameters
    ----------
    depth : HxW float
        Exact z-depth (m); NaN/<= 0 where there is none (sky).
    labels : HxW uint8
        labelIds; sky (23) and labelIds 0-3 (ego vehicle, borders) are always holes.
    fx : float
        Focal length (px) at this image size; disparity = ``baseline * fx / depth``.
    noise : float
        Standard deviation of the multiplicative disparity noise (half per-pixel, half
        smooth over ~2 % of the width); the median absolute relative depth error is
        then about ``0.67 * noise``, plus the 1/256 px quantisation.
    hole_fraction : float
        Target fraction of *all* pixels left invalid (coverage ``1 - hole_fraction``).
        Physical holes come first: sky, labelIds 0-3, pixels occluded in the right
        view (bands left of foreground edges) or outside it (left border), disparity
        overflow, depth beyond ``far_limit`` (smoothly jittered, 10 % standard deviation), thin structures (at most
        ~12 px wide at 2048 px, horizontally or vertically, in front of something
        farther). Then, while the target is not reached, glass panes (``glass``: HxW
        light instance ids of window panes; each pane with ``glass_probability``) and
        finally weakly textured blobs and bands biased toward depth edges. If the
        physical holes alone exceed the target, coverage is lower.
    seed : int
        Noise and hole pattern seed.

    Returns
    -------
    (disparity, info)
        The uint16 PNG array, and the fraction of pixels per hole kind plus ``coverage``.
    """
    d = np.asarray(depth, dtype=np.float64)
    H, W = d.shape
    if not (0.0 <= noise < 0.5):
        raise NpsimInputError(f"stereo noise must be in [0, 0.5), got {noise}")
    if not (0.0 <= hole_fraction < 1.0):
        raise NpsimInputError(f"hole_fraction must be in [0, 1), got {hole_fraction}")
    rng = np.random.default_rng([int(seed), 0x57E2E0])
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(d) & (d > 0)
    sky = labels == _SKY
    void = labels <= 3
    disp = np.where(valid, baseline * fx / np.where(valid, d, 1.0), 0.0)
    kinds: dict[str, np.ndarray] = {}
    holes = np.zeros((H, W), bool)

    def add(name: str, mask: np.ndarray) -> None:
        new = mask & ~holes
        kinds[name] = new
        holes[...] = holes | new

    add("sky", sky | ~valid)
    add("void", void)
    # Right camera at +baseline: pixel u lands at u - disp; it is hidden when a pixel to its
    # right lands left of it (a nearer surface), and outside the right image below -0.5.
    xr = np.arange(W, dtype=np.float64)[None, :] - disp
    rmin = np.minimum.accumulate(xr[:, ::-1], axis=1)[:, ::-1]
    rmin_next = np.concatenate([rmin[:, 1:], np.full((H, 1), np.inf)], axis=1)
    add("occluded", valid & (rmin_next < xr - 1e-9))
    add("out_of_view", valid & (xr < -0.5))
    add("overflow", valid & (disp * 256.0 + 1.0 > 65535.0))
    far_jitter = np.exp(0.1 * np.clip(_unit_field(rng, (H, W), max(2.0, 0.05 * W)), -2.0, 2.0))
    add("far", valid & (d > far_limit * far_jitter))
    r = max(1, int(round(12 * W / NATIVE_SIZE[0])))
    dfar = np.where(valid & ~sky, d, np.inf)
    thin = np.zeros((H, W), bool)
    for axis in (1, 0):
        before, after = _shift_max(dfar, r, axis, -1), _shift_max(dfar, r, axis, +1)
        thin |= valid & (before > 1.1 * d) & (after > 1.1 * d)
    add("thin", thin)
    target = int(round(hole_fraction * H * W))
    if glass is not None and holes.sum() < target:
        g = np.asarray(glass)
        ids = [int(i) for i in np.unique(g) if i > 0]
        draw = rng.random(len(ids))
        room = target - int(holes.sum())
        m = np.zeros((H, W), bool)
        for i, u in zip(ids, draw):  # whole panes in id order while they fit the budget
            if u >= glass_probability:
                continue
            pane = (g == i) & ~holes & ~m
            if pane.sum() > room:
                break
            m |= pane
            room -= int(pane.sum())
        add("glass", m)
    else:
        add("glass", np.zeros((H, W), bool))
    budget = target - int(holes.sum())
    blobs = np.zeros((H, W), bool)
    if budget > 0:
        # Depth edges (>5 % jump, or next to a hole-free/invalid boundary) attract bands of holes.
        logd = np.log(np.where(valid, d, 1e6))
        edge = np.zeros((H, W), bool)
        jump_u = np.abs(np.diff(logd, axis=1)) > 0.05
        jump_v = np.abs(np.diff(logd, axis=0)) > 0.05
        edge[:, 1:] |= jump_u
        edge[:, :-1] |= jump_u
        edge[1:, :] |= jump_v
        edge[:-1, :] |= jump_v
        dist = cv2.distanceTransform((~edge).astype(np.uint8), cv2.DIST_L2, 3) if edge.any() else \
            np.full((H, W), np.inf, np.float32)
        score = (_unit_field(rng, (H, W), max(1.5, 0.02 * W)) + 0.35 * rng.standard_normal((H, W))
                 + 1.5 * np.exp(-dist.astype(np.float64) / (1.0 + 0.01 * W)))
        cand = np.flatnonzero(~holes)
        order = np.argsort(-score.ravel()[cand], kind="stable")
        blobs.ravel()[cand[order[:budget]]] = True
    add("blobs", blobs)
    # Multiplicative noise, half white and half smooth, unit variance before scaling.
    n = (_unit_field(rng, (H, W), max(1.0, 0.02 * W)) + rng.standard_normal((H, W))) / math.sqrt(2.0)
    noisy = disp * np.maximum(0.2, 1.0 + noise * n)
    p = np.rint(noisy * 256.0) + 1.0
    ok = ~holes & (p >= 2.0) & (p <= 65535.0)
    out = np.where(ok, p, 0.0).astype(np.uint16)
    info = {k: float(v.mean()) for k, v in kinds.items()}
    info["coverage"] = float(ok.mean())
    return out, info


def sgm_disparity(left: np.ndarray, right: np.ndarray, labels: np.ndarray, *,
                  max_disparity: float | None = None, block: int = 5) -> tuple[np.ndarray, dict[str, float]]:
    """A Cityscapes disparity PNG (uint16, ``p = disparity*256 + 1``, 0 invalid) by semi-global matching.

    Cityscapes' disparity comes from SGM; OpenCV's ``StereoSGBM`` (5 paths, ``MODE_SGBM``) on a
    rendered pair reproduces its structured errors -- streaks along rows, object edges fattened
    toward the background, speckle islands, 1/16 px sub-pixel steps, wrong matches on weakly
    textured and reflective surfaces, no match in the left ``numDisparities`` columns and at
    occlusions (left-right check). No speckle filter runs (``speckleWindowSize`` 0): real
    Cityscapes disparity keeps its islands, so the chain has to cope with them.

    Parameters
    ----------
    left, right : HxWx3 uint8
        Rectified sRGB pair (the right camera to the right of the left one).
    labels : HxW uint8
        labelIds of the left view; sky (23) and labelIds 0-3 (ego vehicle, borders) are holes,
        as in Cityscapes files.
    max_disparity : float, optional
        Largest disparity searched (px); default 256 px at 2048 px wide, scaled to the width
        (about 1.85 m at Cityscapes' baseline and focal length). Rounded up to a multiple of 16.
    block : int
        Matching block size (odd, px).

    Returns
    -------
    (disparity, info)
        The uint16 PNG array and ``coverage`` (fraction of valid pixels), ``num_disparities``.
    """
    H, W = labels.shape
    if left.shape[:2] != (H, W) or right.shape[:2] != (H, W):
        raise NpsimInputError(f"stereo pair {left.shape[:2]} / {right.shape[:2]} does not match labels {(H, W)}")
    md = 256.0 * W / NATIVE_SIZE[0] if max_disparity is None else float(max_disparity)
    nd = int(16 * max(1, math.ceil(md / 16)))
    b = int(block) | 1
    gl = cv2.cvtColor(left, cv2.COLOR_RGB2GRAY)
    gr = cv2.cvtColor(right, cv2.COLOR_RGB2GRAY)
    sgbm = cv2.StereoSGBM_create(minDisparity=0, numDisparities=nd, blockSize=b, P1=8 * b * b, P2=32 * b * b,
                                 disp12MaxDiff=1, uniquenessRatio=10, speckleWindowSize=0, speckleRange=0,
                                 preFilterCap=63, mode=cv2.STEREO_SGBM_MODE_SGBM)
    d16 = sgbm.compute(gl, gr)                                        # int16, disparity * 16, < 0 invalid
    d = d16.astype(np.float64) / 16.0
    ok = (d16 > 0) & (labels != _SKY) & (labels > 3)
    p = np.rint(d * 256.0) + 1.0
    ok &= (p >= 2.0) & (p <= 65535.0)
    out = np.where(ok, p, 0.0).astype(np.uint16)
    return out, {"coverage": float(ok.mean()), "num_disparities": float(nd)}


# --------------------------------------------------------------------------- writer
def _check_name(what: str, value: str) -> str:
    if not isinstance(value, str) or not value or value in (".", "..") or "/" in value or os.sep in value:
        raise NpsimInputError(f"{what} must be a plain folder name, got {value!r}")
    return value


def write_cityscapes_fixture(root: str | os.PathLike, *, frames: int = 3, size: tuple[int, int] = (256, 128),
                             split: str = "val", city: str = "synthcity", seed: int = 0, corrupt: int = 1,
                             noise: float = 0.02, hole_fraction: float = 0.2, ego_vehicle: bool = True,
                             color: bool = True, stereo: str = "sgm", truth: str | os.PathLike | None = None,
                             variant: str = "default") -> list[str]:
    """Write a Cityscapes-layout dataset of synthetic streets under ``root``; return the frame stems.

    Per frame ``i`` (street ``street_scene(W, H, seed + i)``, stem :func:`fixture_stem`)::

        leftImg8bit/<split>/<city>/<stem>_leftImg8bit.png     day RGB (truncated bytes for the last ``corrupt``)
        gtFine/<split>/<city>/<stem>_gtFine_labelIds.png      labelIds (+ ego vehicle 1 when ``ego_vehicle``)
        gtFine/<split>/<city>/<stem>_gtFine_instanceIds.png   uint16, classId*1000+k on instance classes
        gtFine/<split>/<city>/<stem>_gtFine_color.png         colour visualisation (when ``color``)
        disparity/<split>/<city>/<stem>_disparity.png         simulated stereo (:func:`simulate_stereo_disparity`)
        camera/<split>/<city>/<stem>_camera.json              Cityscapes camera JSON (:func:`camera_json`)

    No depth, normals or NPSim files are written. Existing files of the same
    names are replaced; other files under ``root`` are left alone. Same
    arguments -> the same bytes.

    Parameters
    ----------
    frames, corrupt : int
        Number of frames; the last ``corrupt`` of them get a truncated image PNG
        (labels, disparity and camera are intact), so loading them raises
        :class:`~npsim_core.errors.NpsimInputError`.
    size : (W, H)
        Image size (2:1 is Cityscapes' aspect).
    stereo : {"sgm", "noise"}
        ``sgm`` (default): the street's right view is rendered (baseline :data:`BASELINE`, the
        same scaled native intrinsics) and matched with OpenCV's semi-global matching
        (:func:`sgm_disparity`), so the disparity has real SGM errors. ``noise``: the older
        model, exact disparity with simulated holes and i.i.d. + smooth noise
        (:func:`simulate_stereo_disparity`).
    noise, hole_fraction : float
        Stereo defects of ``stereo="noise"``, see :func:`simulate_stereo_disparity` (coverage
        about ``1 - hole_fraction``).
    truth : path, optional
        Folder (outside the dataset tree) that receives each frame's exact z-depth as
        ``<stem>_depth.npy`` (float32 m, NaN on sky), for benchmarks.
    variant : str
        Street variant (:data:`~npsim_core.synthetic.VARIANTS`).
    ego_vehicle : bool
        Paint the ego vehicle's bonnet (labelId 1, no disparity) over the bottom rows.
    """
    from . import street_ground_truth, street_scene

    try:
        W, H = (int(v) for v in size)
    except (TypeError, ValueError):
        raise NpsimInputError(f"size must be (width, height), got {size!r}") from None
    if int(frames) != frames or frames < 1:
        raise NpsimInputError(f"frames must be a positive integer, got {frames!r}")
    if int(corrupt) != corrupt or not (0 <= corrupt <= frames):
        raise NpsimInputError(f"corrupt must be an integer in 0..frames ({frames}), got {corrupt!r}")
    if int(seed) != seed or seed < 0:
        raise NpsimInputError(f"seed must be a non-negative integer, got {seed!r}")
    _check_name("split", split)
    _check_name("city", city)
    if stereo not in ("sgm", "noise"):
        raise NpsimInputError(f"stereo must be 'sgm' or 'noise', got {stereo!r}")
    root = Path(root)
    if truth is not None:
        truth = Path(truth)
        if truth.resolve() == root.resolve() or root.resolve() in truth.resolve().parents:
            raise NpsimInputError(f"truth folder {truth} is inside the dataset {root}; give a folder outside it "
                                  "(a real dataset has no exact depth)")
    table = cityscapes()
    stems = []
    for i in range(int(frames)):
        s = fixture_seed(seed, i)
        stem = fixture_stem(city, i)
        scene = street_scene(W, H, s, variant=variant)
        layout, intr, _, gt = street_ground_truth(W, H, s, variant=variant)
        if intr != scene.intrinsics:
            raise RuntimeError("synthetic scene and ray caster disagree on the intrinsics")
        image, labels = scene.image, scene.labels.copy()
        if ego_vehicle:
            hood = ego_vehicle_mask(W, H)
            image = _paint_ego_vehicle(image, hood)
            labels[hood] = _EGO_VEHICLE
        cam = camera_json(intr, scene.camera_height, scene.camera_pitch)
        # The focal the reader will use: the JSON's native fx rescaled to the disparity PNG's size.
        nat = cam["intrinsic"]
        fx = Intrinsics(nat["fx"], nat["fy"], nat["u0"], nat["v0"], *NATIVE_SIZE).resized(W, H).fx
        glass = None
        if scene.lights is not None:
            inst = scene.lights.instance_map
            glass = np.where(np.isin(inst // 1000, _GLASS_LIGHT_CLASSES), inst, 0)
        if stereo == "sgm":
            from . import street_right_view

            right = street_right_view(W, H, s, baseline=BASELINE * fx / intr.fx, variant=variant)
            if ego_vehicle:  # the bonnet is rigid with the cameras: the same pixels in both views
                right = _paint_ego_vehicle(right, hood)
            disp, _ = sgm_disparity(image, right, labels)
        else:
            disp, _ = simulate_stereo_disparity(scene.depth_gt, labels, fx, seed=s, noise=noise,
                                                hole_fraction=hole_fraction, glass=glass)
        if truth is not None:
            truth.mkdir(parents=True, exist_ok=True)
            np.save(truth / f"{stem}_depth.npy", np.asarray(scene.depth_gt, np.float32))
        inst_ids = instance_ids(labels, gt.prim, layout.prims)

        img_path = fixture_image(root, stem, split, city)
        gt_dir = root / "gtFine" / split / city
        if i >= frames - corrupt:
            ok, buf = cv2.imencode(".png", cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
            if not ok:
                raise RuntimeError("OpenCV could not encode the image")
            data = buf.tobytes()
            atomic_write_bytes(img_path, data[: max(64, int(len(data) * 0.6))])  # header intact, data cut
        else:
            write_image(img_path, image)
        write_image(gt_dir / f"{stem}_gtFine_labelIds.png", labels)
        write_image(gt_dir / f"{stem}_gtFine_instanceIds.png", inst_ids)
        if color:
            write_image(gt_dir / f"{stem}_gtFine_color.png", table.colorize(labels))
        write_image(root / "disparity" / split / city / f"{stem}_disparity.png", disp)
        atomic_write_text(root / "camera" / split / city / f"{stem}_camera.json",
                          json.dumps(cam, indent=4, sort_keys=True) + "\n")
        stems.append(stem)
    return stems


def main(argv: list[str] | None = None) -> int:
    import argparse
    import sys

    ap = argparse.ArgumentParser(prog="python -m npsim_core.synthetic.cityscapes",
                                 description="Write a Cityscapes-layout dataset of synthetic streets "
                                             "(no ground truth; SGM stereo disparity by default).")
    ap.add_argument("root")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--size", default="256x128", help="WxH (default 256x128)")
    ap.add_argument("--split", default="val")
    ap.add_argument("--city", default="synthcity")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--corrupt", type=int, default=1, help="last N frames get a truncated image (default 1)")
    ap.add_argument("--stereo", choices=("sgm", "noise"), default="sgm",
                    help="sgm (default): render the right view and run OpenCV semi-global matching; "
                         "noise: exact disparity with simulated holes and noise")
    ap.add_argument("--truth", default=None, metavar="DIR",
                    help="also write each frame's exact depth to DIR/<stem>_depth.npy (outside the dataset)")
    ap.add_argument("--variant", default="default", help="street variant (default, receding, busy, ...)")
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--hole-fraction", type=float, default=0.2)
    ap.add_argument("--no-ego-vehicle", action="store_true")
    args = ap.parse_args(argv)
    try:
        w, h = (int(v) for v in args.size.lower().split("x"))
        stems = write_cityscapes_fixture(args.root, frames=args.frames, size=(w, h), split=args.split,
                                         city=args.city, seed=args.seed, corrupt=args.corrupt, noise=args.noise,
                                         hole_fraction=args.hole_fraction, ego_vehicle=not args.no_ego_vehicle,
                                         stereo=args.stereo, truth=args.truth, variant=args.variant)
    except (NpsimInputError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for s in stems:
        print(s)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
