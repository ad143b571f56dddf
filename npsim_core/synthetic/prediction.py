"""Simulated network predictions: ground-truth depth/normals corrupted with realistic errors.

Monocular depth networks (the thesis's iDisc, DPT, Depth-Anything) err in
characteristic ways, modelled here in this order:

1. **Edge bleeding**: the output is smooth across object boundaries regardless
   of semantics. Modelled as a normalised Gaussian blur of *inverse* depth
   (sky excluded) with sigma ``blur_frac * width`` pixels (at least
   ``blur_min_px``): foreground/background mixes at edges give "flying pixels"
   whose depth lies between the two surfaces, exactly what the refinement
   stage and the uncertain map exist for.
2. **Low-frequency warp**: a smooth multiplicative field ``exp(w)`` with ``w``
   interpolated bicubically from a coarse ``warp_cells`` grid of N(0, warp_sigma)
   values (a few % relative error that varies slowly over the image).
3. **Global scale bias** ``scale`` (metric networks are typically off by several %
   on an unseen camera).
4. **Noise**: i.i.d. Gaussian relative noise ``noise_sigma`` per pixel.

Normals: a blur of the GT normals with the same edge-bleeding sigma plus a small
per-pixel Gaussian perturbation ``normal_noise`` (radians, roughly), renormalised.
Normal heads are trained separately from depth, so they are not derived from
the corrupted depth (whose finite differences would be far noisier than any
network's normals). Sky stays NaN in both.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class PredictionErrors:
    """Parameters of the simulated depth/normal prediction (see module docstring).

    Defaults give AbsRel ~0.07-0.09 and a median normal error of a few degrees,
    the range reported for good monocular models on driving scenes (e.g. iDisc
    on KITTI: AbsRel ~0.05; zero-shot transfer to a new camera is worse).
    """

    scale: float = 1.07            # global multiplicative bias
    blur_frac: float = 0.0025      # edge-bleeding Gaussian sigma as a fraction of the image width (5 px at 2048)
    blur_min_px: float = 0.8       # ... but never sharper than this (pixels)
    warp_sigma: float = 0.03       # std of the log-depth warp field
    warp_cells: tuple[int, int] = (3, 5)  # coarse grid (rows, cols) of the warp
    noise_sigma: float = 0.005     # per-pixel relative depth noise
    normal_noise: float = 0.04     # per-pixel normal perturbation (std per component)
    seed_offset: int = 1000        # the prediction's RNG stream = scene seed + this

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _masked_blur(x: np.ndarray, valid: np.ndarray, sigma: float) -> np.ndarray:
    """Normalised Gaussian convolution of ``x`` over ``valid`` pixels (channels last allowed)."""
    w = valid.astype(np.float32)
    xs = np.where(valid[..., None] if x.ndim == 3 else valid, x, 0.0).astype(np.float32)
    k = int(np.ceil(3 * sigma)) * 2 + 1
    num = cv2.GaussianBlur(xs, (k, k), sigma, borderType=cv2.BORDER_REFLECT)
    den = cv2.GaussianBlur(w, (k, k), sigma, borderType=cv2.BORDER_REFLECT)
    if x.ndim == 3:
        den = den[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):
        return num / den


def simulate_prediction(depth_gt: np.ndarray, normals_gt: np.ndarray, params: PredictionErrors,
                        seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Corrupt GT depth (HxW m) and normals (HxWx3) into a plausible network prediction.

    Deterministic in ``seed``; NaN (sky) pixels stay NaN. Returns float32 arrays.
    """
    rng = np.random.default_rng(int(seed) + params.seed_offset)
    H, W = depth_gt.shape
    valid = np.isfinite(depth_gt) & (depth_gt > 0)
    sigma = max(params.blur_frac * W, params.blur_min_px)
    inv = np.where(valid, 1.0 / np.where(valid, depth_gt, 1.0), 0.0)
    inv_b = _masked_blur(inv, valid, sigma)
    d = 1.0 / np.maximum(inv_b, 1e-6)
    gh, gw = params.warp_cells
    coarse = rng.normal(0.0, params.warp_sigma, size=(gh, gw)).astype(np.float32)
    warp = cv2.resize(coarse, (W, H), interpolation=cv2.INTER_CUBIC)
    d = d * np.exp(warp) * params.scale
    d = d * (1.0 + rng.normal(0.0, params.noise_sigma, size=(H, W)))
    d = np.where(valid, d, np.nan).astype(np.float32)

    n = _masked_blur(np.nan_to_num(normals_gt), valid, sigma)
    n = n + rng.normal(0.0, params.normal_noise, size=n.shape)
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / norm
    n[~valid] = np.nan
    return d, n.astype(np.float32)
