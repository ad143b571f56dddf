"""Geometry from files: a depth map (and optionally normals) computed elsewhere.

Depth: ``.npy`` / ``.pfm`` / ``.exr`` (where OpenCV's EXR codec is available) /
16-bit PNG (metres x 256) / Cityscapes disparity PNG with baseline and focal,
all through :func:`npsim_core.io.read_depth`. Normals: ``.npy`` or 8/16-bit PNG
through :func:`npsim_core.io.read_normals`; when no normal file is given they
are computed from the depth with :func:`npsim_core.camera.normals_from_depth`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..camera import normals_from_depth
from ..errors import NpsimInputError
from ..io import read_depth, read_normals
from ..scene import Scene
from . import GeometryEstimate, invalid_label_mask
from .popup import DEFAULT_INVALID_IDS


@dataclass(frozen=True)
class FilesParams:
    """Where the geometry files are.

    Attributes
    ----------
    depth_path : path
        Depth map in metres (or a disparity PNG when both disparity values are given).
    normals_path : path or None
        Normal map; ``None`` derives normals from the depth.
    disparity_baseline, disparity_focal : float or None
        Stereo baseline (m) and focal length (px) for a Cityscapes disparity PNG.
    mask_invalid_labels : bool
        Set depth/normals to NaN on sky and the other ``invalid_ids`` labels
        (a network's sky depth is meaningless and would be meshed otherwise).
    invalid_ids : tuple of int
        labelIds masked when ``mask_invalid_labels``.
    """

    depth_path: str | os.PathLike
    normals_path: str | os.PathLike | None = None
    disparity_baseline: float | None = None
    disparity_focal: float | None = None
    mask_invalid_labels: bool = True
    invalid_ids: tuple[int, ...] = DEFAULT_INVALID_IDS

    def __post_init__(self) -> None:
        for name in ("disparity_baseline", "disparity_focal"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise NpsimInputError(f"FilesParams.{name} must be a positive number, got {v}")


def estimate_from_files(scene: Scene, params: FilesParams) -> GeometryEstimate:
    """Read depth (and normals) for ``scene`` from files; shapes must match the image."""
    dpath = Path(params.depth_path)
    depth = read_depth(dpath, disparity_baseline=params.disparity_baseline,
                       disparity_focal=params.disparity_focal)
    H, W = scene.height, scene.width
    if depth.shape != (H, W):
        raise NpsimInputError(f"{dpath}: depth is {depth.shape[1]}x{depth.shape[0]} but scene {scene.name!r} is "
                              f"{W}x{H}; resample the depth map to the image size")
    info: dict = {"depth_file": str(dpath)}
    bad = (invalid_label_mask(scene.labels, params.invalid_ids) if params.mask_invalid_labels
           else np.zeros((H, W), dtype=bool))
    # Mask before deriving normals, so sky depth cannot bend the normals at the skyline.
    depth = np.where(bad, np.nan, depth).astype(np.float32)
    if params.normals_path is not None:
        npath = Path(params.normals_path)
        normals = read_normals(npath)
        if normals.shape[:2] != (H, W):
            raise NpsimInputError(f"{npath}: normals are {normals.shape[1]}x{normals.shape[0]} but scene "
                                  f"{scene.name!r} is {W}x{H}")
        normals = normals.copy()
        normals[bad] = np.nan
        info["normals_file"] = str(npath)
    else:
        normals = normals_from_depth(depth, scene.intrinsics)
        info["normals"] = "computed from depth (camera.normals_from_depth)"
    info["valid_fraction"] = float(np.isfinite(depth).mean())
    return GeometryEstimate(depth=depth.astype(np.float32), normals=normals.astype(np.float32), method="files",
                            info=info)
