"""False-colour pictures of the chain's results for display (the app's canvas, reports)."""

from __future__ import annotations

import cv2
import numpy as np

from .camera import normals_from_depth
from .errors import NpsimInputError
from .io import depth_to_rgb, normals_to_rgb
from .labels import cityscapes
from .metrics import angular_error_deg
from .scene import Scene

__all__ = ["VIEW_MODES", "view_image", "heat_image", "scene_overview"]

VIEW_MODES = ("RGB", "labels", "predicted depth", "refined depth", "normals (predicted)", "normals (refined)",
              "uncertain map", "depth error vs GT", "normal error vs GT")


def view_image(scene: Scene, results, mode: str) -> np.ndarray:
    """An (H, W, 3) uint8 picture of ``mode`` (one of :data:`VIEW_MODES`); ``results`` is a
    :class:`~npsim_core.chain.ChainResults` or None (black for what needs results)."""
    r = results
    black = np.zeros_like(scene.image)
    if mode == "RGB":
        return scene.image
    if mode == "labels":
        return cityscapes().colorize(scene.labels)
    vmax = None
    if scene.depth is not None and np.isfinite(scene.depth).any():
        vmax = float(np.nanpercentile(scene.depth, 99))
    if mode == "predicted depth":
        d = r.depth_in if r is not None else scene.depth
        return depth_to_rgb(d, vmax) if d is not None else black
    if mode not in VIEW_MODES:
        raise NpsimInputError(f"unknown view mode {mode!r}; choose one of {VIEW_MODES}")
    if r is None:
        return black
    if mode == "refined depth":
        return depth_to_rgb(r.depth, vmax) if r.depth is not None else black
    if mode == "normals (predicted)":
        return normals_to_rgb(r.normals_in) if r.normals_in is not None else black
    if mode == "normals (refined)":
        return normals_to_rgb(normals_from_depth(r.depth, r.intrinsics)) if r.depth is not None else black
    if mode == "uncertain map":
        if r.uncertain is None:
            return black
        out = (scene.image * 0.35).astype(np.uint8)
        out[r.uncertain] = (255, 60, 60)
        return out
    if mode == "depth error vs GT":
        e = r.depth_error()
        return heat_image(e, 0.25) if e is not None else black
    # normal error vs GT
    if scene.normals_gt is None or r.depth is None:
        return black
    return heat_image(angular_error_deg(normals_from_depth(r.depth, r.intrinsics), scene.normals_gt), 45.0)


def heat_image(values: np.ndarray, vmax: float) -> np.ndarray:
    """Inferno colour map of ``values`` / ``vmax`` (clipped to [0, 1]); non-finite values black."""
    v = np.nan_to_num(np.clip(values / vmax, 0, 1), nan=0.0)
    img = cv2.cvtColor(cv2.applyColorMap((v * 255).astype(np.uint8), cv2.COLORMAP_INFERNO), cv2.COLOR_BGR2RGB)
    img[~np.isfinite(values)] = 0
    return img


def scene_overview(scene) -> np.ndarray:
    """2x3 panel: RGB | GT depth | GT normals / labels | lights over RGB | predicted depth (uint8 RGB)."""
    from .labels import light_class

    rgb = scene.image
    vmax = float(np.nanpercentile(scene.depth_gt, 99)) if np.isfinite(scene.depth_gt).any() else None
    lights = rgb.copy() // 3
    if scene.lights is not None:
        inst = scene.lights.instance_map
        cls = inst // 1000
        lut = np.zeros((256, 3), dtype=np.uint8)
        for c in range(1, 13):
            lut[c] = light_class(c).color
        on = inst > 0
        lights[on] = lut[cls[on]]
    panels = [rgb, depth_to_rgb(scene.depth_gt, vmax), normals_to_rgb(scene.normals_gt),
              cityscapes().colorize(scene.labels), lights,
              depth_to_rgb(scene.depth, vmax) if scene.depth is not None else np.zeros_like(rgb)]
    top = np.concatenate(panels[:3], axis=1)
    bottom = np.concatenate(panels[3:], axis=1)
    return np.concatenate([top, bottom], axis=0)
