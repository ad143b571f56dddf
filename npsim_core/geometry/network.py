"""Depth from a monocular depth network in a LOCAL ``transformers`` checkpoint folder.

The folder is what ``model.save_pretrained(dir)`` + ``processor.save_pretrained(dir)``
write (``config.json``, ``model.safetensors``, ``preprocessor_config.json``),
e.g. a copy of ``depth-anything/Depth-Anything-V2-Small-hf`` or ``Intel/dpt-hybrid-midas``.
It is loaded with ``AutoModelForDepthEstimation`` / ``AutoImageProcessor`` and
``local_files_only=True``: nothing is ever downloaded.

Relative networks (Depth-Anything, DPT/MiDaS) predict an affine-invariant
*inverse* depth x. We align it to metric scale against the semantic pop-up
prior on ground pixels, where the prior is reliable (a flat road seen from a
known height): fit ``1/z_prior ~ s x + t`` by robust least squares (iteratively
reweighted with Huber weights on the residuals) over ground pixels nearer than
``align_max_depth``, then ``depth = 1/(s x + t)``. Metric checkpoints
(``config.depth_estimation_type == "metric"``) predict depth directly; they are
aligned the same way on ``1/depth`` (which also absorbs a wrong focal length).
Normals come from the aligned depth (:func:`npsim_core.camera.normals_from_depth`).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..camera import normals_from_depth
from ..errors import NpsimInputError
from ..labels import cityscapes
from ..scene import Scene
from . import GeometryEstimate, invalid_label_mask
from .popup import DEFAULT_INVALID_IDS, PopupParams, estimate_popup


@dataclass(frozen=True)
class NetworkParams:
    """Parameters of the network estimator.

    Attributes
    ----------
    checkpoint : path
        Local checkpoint folder (``config.json`` + weights + ``preprocessor_config.json``).
    output : {"auto", "inverse", "depth"}
        What the network predicts; ``auto`` reads ``config.depth_estimation_type``
        (``metric`` -> depth, anything else -> inverse depth).
    align_max_depth : float
        Ground pixels whose prior depth exceeds this (m) are not used for the fit
        (near the horizon the prior's depth is ill-conditioned).
    huber_delta : float
        Huber threshold in units of the residuals' robust scale (1.4826 MAD).
    iterations : int
        Reweighting iterations of the robust fit.
    max_align_pixels : int
        At most this many reference pixels (a regular subsample) enter the fit.
    max_depth : float
        Depths beyond this (m) and non-positive inverse depths become invalid.
    popup : PopupParams
        Prior used as the metric reference (camera height and pitch).
    """

    checkpoint: str | os.PathLike
    output: str = "auto"
    align_max_depth: float = 60.0
    huber_delta: float = 1.5
    iterations: int = 10
    max_align_pixels: int = 100_000
    max_depth: float = 300.0
    invalid_ids: tuple[int, ...] = DEFAULT_INVALID_IDS
    popup: PopupParams = PopupParams()

    def __post_init__(self) -> None:
        if self.output not in ("auto", "inverse", "depth"):
            raise NpsimInputError(f"NetworkParams.output must be 'auto', 'inverse' or 'depth', got {self.output!r}")


@dataclass(frozen=True)
class Alignment:
    """``target ~ scale * x + shift`` fitted on ``n`` pixels; ``residual`` = robust RMS of the fit."""

    scale: float
    shift: float
    n: int
    residual: float


def align_scale_shift(x: np.ndarray, target: np.ndarray, mask: np.ndarray | None = None, *,
                      huber_delta: float = 1.5, iterations: int = 10, max_pixels: int | None = None) -> Alignment:
    """Robust least-squares fit ``target ~ scale * x + shift`` over ``mask`` (finite pixels only).

    Iteratively reweighted least squares with Huber weights; the residual scale
    is re-estimated each iteration as 1.4826 x the median absolute residual, so
    up to roughly a third of outliers (cars on the road, label errors) barely
    move the fit. Computed in float64 on standardised ``x``; with ``max_pixels``
    a regular subsample of at most that many pixels is used.
    """
    x = np.asarray(x, dtype=np.float64)
    t = np.asarray(target, dtype=np.float64)
    m = np.isfinite(x) & np.isfinite(t)
    if mask is not None:
        m &= np.asarray(mask, dtype=bool)
    xs, ts = x[m], t[m]
    if max_pixels and xs.size > max_pixels:  # a regular subsample: same fit, bounded cost, deterministic
        step = -(-xs.size // max_pixels)
        xs, ts = xs[::step], ts[::step]
    if xs.size < 10:
        raise NpsimInputError(f"cannot align the network's depth: only {xs.size} usable reference pixels "
                              "(the image needs visible ground: road, sidewalk, terrain)")
    mu, sd = xs.mean(), xs.std()
    if not sd > 0:
        raise NpsimInputError("cannot align the network's depth: its output is constant on the ground pixels "
                              "(is the checkpoint a trained depth model?)")
    xn = (xs - mu) / sd
    A = np.stack([xn, np.ones_like(xn)], axis=1)
    w = np.ones_like(xn)
    coef = np.zeros(2)
    for _ in range(max(1, iterations)):
        sw = np.sqrt(w)
        coef, *_ = np.linalg.lstsq(A * sw[:, None], ts * sw, rcond=None)
        r = ts - A @ coef
        sigma = 1.4826 * np.median(np.abs(r - np.median(r)))
        if not sigma > 0:
            break
        k = huber_delta * sigma
        ar = np.abs(r)
        w = np.where(ar <= k, 1.0, k / np.maximum(ar, 1e-300))
    r = ts - A @ coef
    scale = coef[0] / sd
    shift = coef[1] - coef[0] * mu / sd
    return Alignment(scale=float(scale), shift=float(shift), n=int(xs.size),
                     residual=float(1.4826 * np.median(np.abs(r))))


@lru_cache(maxsize=2)
def load_depth_model(checkpoint: str):
    """``(model, processor)`` from a local checkpoint folder (cached per resolved path).

    Raises :class:`NpsimInputError` when the folder is missing or is not a
    ``transformers`` depth checkpoint, or when ``transformers`` is not installed.
    """
    path = Path(checkpoint)
    if not path.exists():
        raise NpsimInputError(f"{path}: depth checkpoint folder not found; download a model once elsewhere "
                              "(e.g. depth-anything/Depth-Anything-V2-Small-hf) and give its local folder")
    if not path.is_dir():
        raise NpsimInputError(f"{path}: is a file; give the checkpoint *folder* (with config.json)")
    if not (path / "config.json").is_file():
        raise NpsimInputError(f"{path}: not a transformers checkpoint (no config.json); it must hold what "
                              "model.save_pretrained() and processor.save_pretrained() write")
    if not (path / "preprocessor_config.json").is_file():
        raise NpsimInputError(f"{path}: preprocessor_config.json is missing; save the image processor too "
                              "(AutoImageProcessor.from_pretrained(name).save_pretrained(folder))")
    try:
        import transformers
        from transformers import AutoImageProcessor, AutoModelForDepthEstimation
    except ImportError as exc:
        raise NpsimInputError(f"the network depth method needs the 'transformers' package ({exc}); install it "
                              "with: pip install 'npsim[net]'") from None
    verbosity = transformers.logging.get_verbosity()
    transformers.logging.set_verbosity_error()
    transformers.utils.logging.disable_progress_bar()
    try:
        model = AutoModelForDepthEstimation.from_pretrained(str(path), local_files_only=True)
        processor = AutoImageProcessor.from_pretrained(str(path), local_files_only=True)
    except (OSError, ValueError, KeyError) as exc:
        raise NpsimInputError(f"{path}: could not load a depth-estimation model from this folder: {exc}") from None
    finally:
        transformers.logging.set_verbosity(verbosity)
    model.eval()
    return model, processor


def predict_raw(scene: Scene, checkpoint: str | os.PathLike) -> tuple[np.ndarray, str]:
    """The network's raw HxW output for ``scene.image`` (bicubic-resized to the image) and its config type."""
    import torch

    model, processor = load_depth_model(str(Path(checkpoint).resolve()))
    inputs = processor(images=scene.image, return_tensors="pt")
    with torch.inference_mode():
        out = model(**inputs).predicted_depth
    if out.ndim == 3:
        out = out[:, None]
    out = torch.nn.functional.interpolate(out.float(), size=(scene.height, scene.width), mode="bicubic",
                                          align_corners=False)
    kind = str(getattr(model.config, "depth_estimation_type", "relative") or "relative")
    return out[0, 0].cpu().numpy().astype(np.float64), kind


def align_to_prior(scene: Scene, inverse: np.ndarray, params: NetworkParams) -> tuple[np.ndarray, Alignment]:
    """Metric z-depth (HxW float32, NaN invalid) from a relative inverse-depth map ``inverse``.

    Fits ``1/z_popup ~ s * inverse + t`` on ground pixels whose pop-up depth is at
    most ``params.align_max_depth`` (robust, :func:`align_scale_shift`), then
    ``depth = 1 / (s * inverse + t)``; non-positive or beyond-``max_depth``
    values and invalid labels (sky) become NaN.
    """
    prior = estimate_popup(scene, params.popup)
    ground = cityscapes().lut("ground").astype(bool)[scene.labels]
    ref = ground & np.isfinite(prior.depth) & (prior.depth <= params.align_max_depth)
    with np.errstate(divide="ignore"):
        target = 1.0 / prior.depth.astype(np.float64)
    al = align_scale_shift(inverse, target, ref, huber_delta=params.huber_delta, iterations=params.iterations,
                           max_pixels=params.max_align_pixels)
    inv = al.scale * np.asarray(inverse, dtype=np.float64) + al.shift
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.where(inv > 1.0 / params.max_depth, 1.0 / inv, np.nan)
    depth[invalid_label_mask(scene.labels, params.invalid_ids)] = np.nan
    return depth.astype(np.float32), al


def estimate_network(scene: Scene, params: NetworkParams) -> GeometryEstimate:
    """Network depth aligned to metric scale on ground pixels; normals from the aligned depth."""
    t0 = time.perf_counter()
    raw, kind = predict_raw(scene, params.checkpoint)
    t_net = time.perf_counter() - t0
    output = params.output if params.output != "auto" else ("depth" if kind == "metric" else "inverse")
    if output == "depth":
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.where(raw > 0, 1.0 / raw, np.nan)
    else:
        x = raw
    depth, al = align_to_prior(scene, x, params)
    normals = normals_from_depth(depth, scene.intrinsics)
    info = {"checkpoint": str(params.checkpoint), "output": output, "config_type": kind,
            "scale": al.scale, "shift": al.shift, "align_pixels": al.n, "align_residual_inv_m": al.residual,
            "valid_fraction": float(np.isfinite(depth).mean()), "network_seconds": round(t_net, 4),
            "seconds": round(time.perf_counter() - t0, 4)}
    if al.scale <= 0:
        info["warning"] = ("the fitted scale is not positive: the network's output does not increase with "
                           "nearness on the ground; check that the checkpoint predicts inverse depth")
    return GeometryEstimate(depth=depth, normals=normals, method="network", info=info)
