"""Scoring a frame against whatever reference it has (docs/method.md §9.2).

Ground truth where it exists (the synthetic street); otherwise the dataset's stereo depth
(valid pixels within ``stereo_max_m``, off sky, ego vehicle and borders), with reference
normals from the smoothed stereo only where it is dense (every pixel of a 5x5 window
valid). A frame with neither gets no score -- never an error.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .camera import Intrinsics, normals_from_depth
from .metrics import depth_metrics, normal_metrics
from .scene import Scene

__all__ = ["SCORED_CLASSES", "Reference", "reference_of", "score_depth", "held_out"]

#: Classes scored separately (Cityscapes labelIds).
SCORED_CLASSES = {"road": 7, "sidewalk": 8, "building": 11, "vegetation": 21, "car": 26}


@dataclass
class Reference:
    """A frame's reference depth (m, NaN = not scored), normals (or None) and what they are."""

    depth: np.ndarray
    normals: np.ndarray | None
    kind: str


def held_out(depth_source: str, provenance: dict, fraction: float) -> float:
    """The fraction of the frame's stereo held out of its input depth: ``fraction`` when the chain
    took the stereo (``depth_source`` 'stereo: ...'), a scene folder's depth's own record when
    ``npsim estimate --method stereo`` made it (``provenance['geometry']``), else 0."""
    if depth_source.startswith("stereo"):
        return float(fraction)
    geo = provenance.get("geometry") if isinstance(provenance, dict) else None
    if depth_source.startswith("files") and isinstance(geo, dict) and geo.get("method") == "stereo":
        return float(geo.get("holdout", 0.0) or 0.0)
    return 0.0


def reference_of(scene: Scene, stereo_max_m: float = 80.0, holdout: float = 0.0) -> Reference | None:
    """Ground truth when the frame has it, else its stereo depth, else None.

    ``holdout`` > 0: the input depth is this stereo with that fraction of its valid pixels held out
    (:func:`npsim_core.geometry.stereo.holdout_mask`); the reference is those pixels alone, so the
    score measures the chain, not the copy of its input."""
    if scene.depth_gt is not None:
        return Reference(scene.depth_gt, scene.normals_gt, "ground truth")
    if scene.depth_stereo is None:
        return None
    from .geometry.stereo import smoothed_depth, stereo_valid

    ok = stereo_valid(scene, stereo_max_m)
    if not ok.any():
        return None
    depth = np.where(ok, scene.depth_stereo, np.nan).astype(np.float32)
    dense = cv2.erode(ok.astype(np.uint8), np.ones((5, 5), np.uint8), borderType=cv2.BORDER_CONSTANT,
                      borderValue=0).astype(bool)
    normals = normals_from_depth(smoothed_depth(depth, max(1.0, scene.width / 1024)), scene.intrinsics)
    normals[~dense] = np.nan
    kind = f"stereo (within {stereo_max_m:g} m)"
    if holdout:
        from .geometry.stereo import holdout_mask

        held = holdout_mask(scene, stereo_max_m, holdout)
        depth = np.where(held, depth, np.float32(np.nan))
        normals[~held] = np.nan
        kind = f"stereo (within {stereo_max_m:g} m; the {100 * holdout:g} % of its pixels held out of the input)"
    return Reference(depth, normals, kind)


def score_depth(depth: np.ndarray, intrinsics: Intrinsics, labels: np.ndarray, ref: Reference) -> dict:
    """Depth AbsRel, δ1, RMSElog, RMSE (m), per-class AbsRel, and the normal error of ``depth``'s
    normals against the reference normals (where it has them); plain floats (NaN = no pixel)."""
    m = depth_metrics(depth, ref.depth)
    out = {"abs_rel": m.abs_rel, "delta1": m.delta1, "rmse_log": m.rmse_log, "rmse_m": m.rmse, "pixels": m.n,
           "classes": {name: depth_metrics(depth, ref.depth, labels == cid).abs_rel
                       for name, cid in SCORED_CLASSES.items()}}
    if ref.normals is not None:
        nm = normal_metrics(normals_from_depth(depth, intrinsics), ref.normals)
        out.update(normal_rmse_deg=nm.rmse_deg, normal_median_deg=nm.median_deg, normal_within_11_25=nm.within_11_25)
    return out
