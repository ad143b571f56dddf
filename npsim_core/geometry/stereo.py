"""Stereo depth as the method's input D, N (docs/method.md §2.2).

A dataset's stereo depth (Cityscapes disparity converted with the camera JSON's baseline
and focal length, ``Scene.depth_stereo``) is the best depth a real frame has, but it has
holes: sky, the ego hood, thin structures, occlusion borders, and the far range where a
disparity of a few pixels is mostly noise. The holes are filled from the semantic pop-up
prior scaled to the stereo (the median ratio over pixels valid in both), so the two agree
in scale where they meet; sky stays invalid. Normals come from the fused depth smoothed
by a normalised Gaussian within each label (stereo is noisy pixel to pixel) where the
prior's placement disagrees with the stereo; elsewhere the prior's plane normals are kept
(measured on the Cityscapes-layout fixture: see docs/geometry.md).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import cv2
import numpy as np

from ..camera import normals_from_depth
from ..errors import NpsimInputError
from ..scene import Scene
from . import DEPTH_NEAR_M, GeometryEstimate, invalid_label_mask
from .popup import PopupParams, estimate_popup

__all__ = ["StereoParams", "estimate_stereo", "holdout_mask", "without_holdout", "STEREO_HOLDOUT", "HOLDOUT_SEED"]

#: Fraction of the valid stereo pixels held out of the input depth when the stereo *is* the input,
#: and the seed that picks them: the chain is then scored on those pixels only, so the score
#: measures the chain, not a copy of its input (:func:`npsim_core.scoring.reference_of`).
STEREO_HOLDOUT = 0.1
HOLDOUT_SEED = 0

#: labelIds never taken from stereo: unlabeled, ego vehicle, rectification border, out of ROI, sky.
STEREO_EXCLUDED = (0, 1, 2, 3, 23)


@dataclass(frozen=True)
class StereoParams:
    """max_depth : stereo beyond this (m) counts as a hole (far disparity is mostly noise).
    smooth_px : σ of the Gaussian that smooths the depth (per label) the stereo normals are taken
        from (0 = W/128 px, at least 2).
    agreement : the prior's normal is kept where its scaled depth is within this fraction of the stereo.
    popup : parameters of the prior that fills the holes.
    holdout : fraction of the valid stereo pixels held out of the input (filled from the prior like
        a hole) for scoring (:func:`holdout_mask`); 0 = none."""

    max_depth: float = 80.0
    smooth_px: float = 0.0
    agreement: float = 0.15
    popup: PopupParams = PopupParams()
    holdout: float = STEREO_HOLDOUT

    def __post_init__(self) -> None:
        if not 0 <= self.holdout < 1:
            raise NpsimInputError(f"stereo: holdout must be a fraction in [0, 1), got {self.holdout}")
        if not (self.max_depth > 0 and self.smooth_px >= 0):
            raise NpsimInputError(f"stereo: max_depth must be > 0 and smooth_px >= 0, got {self.max_depth}, "
                                  f"{self.smooth_px}")


def smoothed_depth(depth: np.ndarray, sigma: float) -> np.ndarray:
    """Normalised Gaussian smoothing of a depth map over its valid pixels (NaN stays NaN)."""
    ok = np.isfinite(depth)
    d = np.where(ok, depth, 0.0).astype(np.float32)
    w = ok.astype(np.float32)
    k = int(2 * round(3 * sigma) + 1)
    num = cv2.GaussianBlur(d, (k, k), sigma, borderType=cv2.BORDER_REPLICATE)
    den = cv2.GaussianBlur(w, (k, k), sigma, borderType=cv2.BORDER_REPLICATE)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = num / den
    return np.where(ok & (den > 1e-6), out, np.nan).astype(np.float32)


def segment_normals(depth: np.ndarray, labels: np.ndarray, intrinsics, sigma: float) -> np.ndarray:
    """Normals of ``depth`` smoothed by a normalised Gaussian within each label (NaN where invalid)."""
    out = np.full(depth.shape + (3,), np.nan, np.float32)
    H, W = depth.shape
    r = int(round(3 * sigma)) + 1  # the blur's reach (+1 for the finite differences)
    for lab in np.unique(labels):
        mask = labels == lab
        if not np.isfinite(depth[mask]).any():
            continue
        # Only the label's bounding box plus the blur's reach: outside it the masked depth is NaN
        # (zero weight), so the normals on the label are the same bit for bit, at a fraction of
        # the full-image cost for the small labels.
        rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
        y0, y1 = max(0, rows[0] - r), min(H, rows[-1] + 1 + r)
        # Columns in blocks of 64 from the image's left edge: OpenCV's blur takes the same vector
        # and tail code paths per column as on the full image (a free crop differs by ~1e-4 there).
        x0 = max(0, cols[0] - r) // 64 * 64
        x1 = min(W, x0 + -(-(cols[-1] + 1 + r - x0) // 64) * 64)
        m = mask[y0:y1, x0:x1]
        crop = replace(intrinsics, cx=intrinsics.cx - x0, cy=intrinsics.cy - y0, width=x1 - x0, height=y1 - y0)
        n = normals_from_depth(smoothed_depth(np.where(m, depth[y0:y1, x0:x1], np.nan), sigma), crop)
        out[y0:y1, x0:x1][m] = n[m]
    return out


def stereo_valid(scene: Scene, max_depth: float, near: float = DEPTH_NEAR_M) -> np.ndarray:
    """Pixels whose stereo depth is usable: finite, within [``near``, ``max_depth``] (the near limit
    of every input depth), not sky/ego/border."""
    st = scene.depth_stereo
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(st) & (st >= near) & (st > 0) & (st <= max_depth)
    return ok & ~invalid_label_mask(scene.labels, STEREO_EXCLUDED)


def holdout_mask(scene: Scene, max_depth: float, fraction: float = STEREO_HOLDOUT,
                 seed: int = HOLDOUT_SEED) -> np.ndarray:
    """A fixed random ``fraction`` of the valid stereo pixels (:func:`stereo_valid`), (H, W) bool: the
    same pixels for the same frame, ``max_depth`` and seed, so the input and the scoring agree."""
    ok = stereo_valid(scene, max_depth).ravel()
    out = np.zeros(ok.size, bool)
    idx = np.flatnonzero(ok)
    k = int(round(fraction * idx.size))
    if k:
        out[np.random.default_rng(seed).choice(idx, size=k, replace=False)] = True
    return out.reshape(scene.labels.shape)


def without_holdout(scene: Scene, max_depth: float, fraction: float = STEREO_HOLDOUT) -> tuple[Scene, int]:
    """``scene`` with its held-out stereo pixels (:func:`holdout_mask`) removed from ``depth_stereo``
    (NaN, a hole like any other) and how many they are."""
    if not fraction or scene.depth_stereo is None:
        return scene, 0
    held = holdout_mask(scene, max_depth, fraction)
    return scene.with_(depth_stereo=np.where(held, np.float32(np.nan), scene.depth_stereo)), int(held.sum())


def estimate_stereo(scene: Scene, params: StereoParams | None = None) -> GeometryEstimate:
    """Stereo depth with its holes filled from the scaled pop-up prior; normals as in the module doc."""
    p = params or StereoParams()
    if scene.depth_stereo is None:
        raise NpsimInputError(f"scene {scene.name!r} has no stereo depth (a Cityscapes disparity PNG with its "
                              "camera JSON); use another depth source (--depth prior|network|files)")
    t0 = time.perf_counter()
    scene, n_held = without_holdout(scene, p.max_depth, p.holdout)
    ok = stereo_valid(scene, p.max_depth)
    if ok.mean() < 0.01:
        raise NpsimInputError(f"scene {scene.name!r}: its stereo depth has {100 * ok.mean():.2f} % usable pixels "
                              f"(within {p.max_depth:g} m, off sky/ego/borders); use --depth prior")
    prior = estimate_popup(scene, p.popup)
    both = ok & np.isfinite(prior.depth)
    scale = float(np.median(scene.depth_stereo[both] / prior.depth[both])) if both.sum() >= 100 else 1.0
    aligned = prior.depth * np.float32(scale)
    fused = np.where(ok, scene.depth_stereo, aligned).astype(np.float32)
    sigma = p.smooth_px or max(2.0, scene.width / 128)
    # Pixel-to-pixel stereo noise (~1-2 % of depth) is far larger than a pixel's footprint, so
    # normals from stereo need wide smoothing -- within each label, so objects do not blend.
    # The prior's plane normal is exact where its placement agrees with the stereo; only where
    # it does not (a segment the prior put at the wrong depth) are the smoothed stereo normals used.
    normals = segment_normals(fused, scene.labels, scene.intrinsics, sigma)
    with np.errstate(invalid="ignore", divide="ignore"):
        agrees = np.abs(aligned - fused) <= p.agreement * fused
    use_prior = np.isfinite(prior.normals).all(-1) & (agrees | ~ok | ~np.isfinite(normals).all(-1))
    normals = np.where(use_prior[..., None], prior.normals, normals).astype(np.float32)
    info = {"stereo_valid": round(float(ok.mean()), 4), "prior_scale": round(scale, 4),
            "filled_from_prior": round(float((~ok & np.isfinite(fused)).mean()), 4), "max_depth": p.max_depth,
            "prior_normals": round(float(use_prior.mean()), 4),
            "smooth_px": round(sigma, 2), "time_s": round(time.perf_counter() - t0, 3),
            "holdout": p.holdout, "held_out_pixels": n_held}
    return GeometryEstimate(fused, normals, "stereo", info)
