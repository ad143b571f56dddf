"""Boundary validation shared by the refinement kernel's stages.

Every public function of :mod:`npsim_core.refine` converts its array inputs
through these helpers, so a wrong shape or dtype gets one clear
:class:`~npsim_core.errors.NpsimInputError` naming the argument and the fix,
and float16 / non-contiguous / read-only inputs are accepted transparently.
"""

from __future__ import annotations

import numpy as np

from ..errors import NpsimInputError


def as_depth(depth, what: str = "depth") -> np.ndarray:
    """HxW real array -> contiguous float32 copy-or-view (NaN/inf/<=0 kept; callers mask them)."""
    d = np.asarray(depth)
    if d.ndim != 2:
        raise NpsimInputError(f"{what} must be a 2-D HxW array of metres, got shape {d.shape}")
    if d.size == 0:
        raise NpsimInputError(f"{what} is empty (shape {d.shape}); give an image of at least 1x1")
    if not (np.issubdtype(d.dtype, np.floating) or np.issubdtype(d.dtype, np.integer)):
        raise NpsimInputError(f"{what} must be a real (float or integer) array, got dtype {d.dtype}")
    return np.ascontiguousarray(d, dtype=np.float32)


def as_labels(labels, shape: tuple[int, int], what: str = "labels") -> np.ndarray:
    """HxW integer labelIds -> contiguous uint8."""
    h = np.asarray(labels)
    if h.shape != tuple(shape):
        raise NpsimInputError(f"{what} has shape {h.shape} but depth is {tuple(shape)} (HxW); pass matching arrays")
    if not (np.issubdtype(h.dtype, np.integer) or h.dtype == np.bool_):
        raise NpsimInputError(f"{what} must be integer labelIds (uint8), got dtype {h.dtype}")
    if h.size and (int(h.min()) < 0 or int(h.max()) > 255):
        raise NpsimInputError(f"{what} must be labelIds in 0..255, got range {int(h.min())}..{int(h.max())}")
    return np.ascontiguousarray(h, dtype=np.uint8)


def as_image(image, shape: tuple[int, int], what: str = "image") -> np.ndarray:
    """HxWx3 RGB (uint8, or float in [0, 1]) -> contiguous float32 RGB in [0, 1]."""
    im = np.asarray(image)
    if im.shape != (*shape, 3):
        raise NpsimInputError(f"{what} must be HxWx3 RGB matching depth {tuple(shape)}, got shape {im.shape}")
    if im.dtype == np.uint8:
        return im.astype(np.float32) / np.float32(255.0)
    if np.issubdtype(im.dtype, np.floating):
        f = np.ascontiguousarray(im, dtype=np.float32)
        if not np.isfinite(f).all():
            raise NpsimInputError(f"{what} contains NaN/inf; give a finite RGB image (uint8 or float in [0, 1])")
        return np.clip(f, 0.0, 1.0)
    raise NpsimInputError(f"{what} must be uint8 RGB or float RGB in [0, 1], got dtype {im.dtype}")


def as_mask(mask, shape: tuple[int, int], what: str) -> np.ndarray:
    m = np.asarray(mask)
    if m.shape != tuple(shape):
        raise NpsimInputError(f"{what} has shape {m.shape} but depth is {tuple(shape)} (HxW); pass matching arrays")
    if not (m.dtype == np.bool_ or np.issubdtype(m.dtype, np.integer) or np.issubdtype(m.dtype, np.floating)):
        raise NpsimInputError(f"{what} must be a boolean mask, got dtype {m.dtype}")
    with np.errstate(invalid="ignore"):
        return np.ascontiguousarray(np.nan_to_num(m.astype(np.float32), nan=0.0) > 0.5)


def as_normals(normals, shape: tuple[int, int], what: str = "normals") -> np.ndarray:
    """HxWx3 normals -> contiguous float32 (no normalisation here)."""
    n = np.asarray(normals)
    if n.shape != (*shape, 3):
        raise NpsimInputError(f"{what} must be HxWx3 matching depth {tuple(shape)}, got shape {n.shape}")
    if not np.issubdtype(n.dtype, np.floating):
        raise NpsimInputError(f"{what} must be a float array of unit vectors, got dtype {n.dtype}")
    return np.ascontiguousarray(n, dtype=np.float32)


def check_positive(value: float, name: str, allow_zero: bool = False) -> float:
    v = float(value)
    ok = np.isfinite(v) and (v >= 0 if allow_zero else v > 0)
    if not ok:
        raise NpsimInputError(f"parameter {name} must be a finite number {'>= 0' if allow_zero else '> 0'}, got {value}")
    return v
