"""The ego vehicle and the frame-border labels at night (docs/relight.md, "The ego vehicle and the frame borders").

Cityscapes labels the ego vehicle's bonnet (labelId 1, the bottom of every frame), the
rectification border (2) and the out-of-ROI frame (3). None of them is part of the street:

* **No geometry.** They are excluded from the scene mesh (:func:`no_mesh_labels`), like the
  sky: a depth network or the completion of invalid depth would otherwise give the bonnet a
  sheet about a metre ahead, stretched toward the road, that hides the ego headlights (they
  sit below it) and is lit by them in streaks.
* **No depth next to the bonnet.** A depth network blurs the bonnet's depth (about a metre)
  into the road rows just above it, which lifts the road's last rows toward the camera, into
  the headlights: a bright line along the bonnet. The depth of the pixels within
  :func:`ego_margin` of the bonnet is replaced by the continuation of the surface above them
  (:func:`extend_over_margin`: inverse depth is linear in the image row on any plane, so a
  line fitted to the rows just above the margin, per column, continues the road exactly).
* **Composited from the day pixels, darkened consistently** (:func:`composite_ego`). After
  denoising, each such pixel gets its day colour (linear) times one gain per night: the
  median night/day luminance ratio of the frame's lit scene pixels -- what the night did to
  a typical surface -- capped so that the bonnet's brightest pixels (99th percentile) reach at
  most :data:`EGO_CAP` (80 %) of the median of the road just above it. The bonnet sits behind the
  headlights, so nothing lights it more than that road. One gain for the whole bonnet keeps
  its day shading and reflections (the emblem stays a small highlight, not a lit blob) and
  cannot create row streaks. The rectification border is black in the day photo and stays
  black.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..errors import NpsimInputError

__all__ = ["EGO_LABELS", "no_mesh_labels", "ego_mask", "ego_margin", "extend_over_margin", "composite_ego",
           "road_band_above"]

#: Cityscapes labelIds that are not part of the street: ego vehicle, rectification border, out of ROI.
EGO_LABELS = (1, 2, 3)
_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)
#: Labels whose pixels form the "road just above the bonnet" (road, sidewalk, parking).
_GROUND = (7, 8, 9)
#: The bonnet's brightest pixels (99th percentile) reach at most this fraction of the median of the
#: lit road just above it: it is behind the headlights and gets less light than that road.
EGO_CAP = 0.8
#: Day luminance (linear) below which a pixel's night/day ratio is not trusted (near black).
_MIN_DAY = 0.01


def no_mesh_labels(exclude: tuple | None, sky_id: int = 23) -> tuple[int, ...]:
    """The labels the mesh leaves out: ``exclude`` (None = the sky) plus :data:`EGO_LABELS`."""
    base = (int(sky_id),) if exclude is None else tuple(int(e) for e in exclude)
    return base + tuple(i for i in EGO_LABELS if i not in base)


def ego_mask(labels: np.ndarray) -> np.ndarray:
    """(H, W) bool: the ego-vehicle and frame-border pixels (:data:`EGO_LABELS`)."""
    return np.isin(np.asarray(labels), EGO_LABELS)



def ego_margin(labels: np.ndarray, frac: float = 0.02) -> np.ndarray:
    """(H, W) bool: the pixels within ``max(2, ceil(frac * H))`` px of the ego vehicle (labelId 1)
    that are not ego pixels themselves -- where a depth estimate mixes the bonnet into the road."""
    lab = np.asarray(labels)
    ego = lab == 1
    if not ego.any():
        return np.zeros(lab.shape, bool)
    r = max(2, int(np.ceil(frac * lab.shape[0])))
    grown = cv2.dilate(ego.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    return grown.astype(bool) & ~ego_mask(lab)


def extend_over_margin(depth: np.ndarray, labels: np.ndarray, frac: float = 0.02) -> np.ndarray:
    """``depth`` with the :func:`ego_margin` pixels continued from the surface above them.

    Per column, 1/z is fitted as a line in the row over the ``2 r`` valid pixels just above the
    margin (``r`` its width) and extended down over the margin (exact on a plane); columns
    without enough support, or where the line would pass behind the camera, get NaN there
    (completed by the mesh like any invalid depth). Returns float32 (H, W).
    """
    d = np.asarray(depth, np.float32)
    margin = ego_margin(labels, frac)
    if not margin.any():
        return d
    H, W = d.shape
    r = max(2, int(np.ceil(frac * H)))
    rows = np.arange(H)[:, None]
    below = np.maximum.accumulate(margin | (np.asarray(labels) == 1), axis=0)  # margin, bonnet and below
    first = np.where(below.any(0), below.argmax(0), H)                  # first such row per column
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(np.isfinite(d) & (d > 0), 1.0 / d, np.nan)
    support = (rows >= first[None, :] - 2 * r) & (rows < first[None, :]) & np.isfinite(inv)
    n = support.sum(0).astype(np.float64)
    x = np.where(support, rows, 0.0)
    y = np.where(support, inv, 0.0)
    sx, sy, sxx, sxy = x.sum(0), y.sum(0), (x * x).sum(0), (x * y).sum(0)
    den = n * sxx - sx * sx
    ok = (n >= 3) & (den > 0)
    b = np.where(ok, (n * sxy - sx * sy) / np.where(ok, den, 1.0), 0.0)
    a = np.where(ok, (sy - b * sx) / np.maximum(n, 1.0), 0.0)
    pred = a[None, :] + b[None, :] * rows
    with np.errstate(divide="ignore"):
        fill = np.where(ok[None, :] & (pred > 0), 1.0 / pred, np.nan)
    return np.where(margin, fill, d).astype(np.float32)

def road_band_above(labels: np.ndarray, frac: float = 0.08) -> np.ndarray:
    """(H, W) bool: ground pixels (road, sidewalk, parking) in the ``frac`` of the rows just above
    the bonnet's top row (empty when the frame has no bonnet)."""
    lab = np.asarray(labels)
    ego = lab == 1
    out = np.zeros(lab.shape, bool)
    if not ego.any():
        return out
    top = int(np.nonzero(ego.any(1))[0].min())
    out[max(0, top - max(1, int(round(frac * lab.shape[0])))):top] = True
    return out & np.isin(lab, _GROUND)


def _fit(a: np.ndarray, shape: tuple[int, int], interp: int) -> np.ndarray:
    if a.shape[:2] == shape:
        return a
    return cv2.resize(np.ascontiguousarray(a), (shape[1], shape[0]), interpolation=interp)


def composite_ego(linear: np.ndarray, day_image: np.ndarray, labels: np.ndarray,
                  light_pixels: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """Replace the ego/border pixels of a (denoised) linear night by the darkened day pixels.

    Parameters
    ----------
    linear : (h, w, 3) float32 linear night render (any size: a preview is smaller than the frame).
    day_image : (H, W, 3) uint8 day sRGB; labels : (H, W) labelIds (resized nearest to the render).
    light_pixels : (H, W) bool light-source pixels, left out of the gain's statistics.

    Returns
    -------
    (image, info) : the composited float32 render, and ``{"ego_gain": g, "ego_pixels": n}``
    (``g`` the linear gain applied to the day pixels; 0 pixels when the frame has none).
    """
    from .lights import srgb_to_linear

    lin = np.asarray(linear, np.float32)
    if lin.ndim != 3 or lin.shape[2] != 3:
        raise NpsimInputError(f"composite_ego: linear image must be HxWx3, got {lin.shape}")
    if np.shape(day_image)[:2] != np.shape(labels) or np.ndim(day_image) != 3:
        raise NpsimInputError(f"composite_ego: day image {np.shape(day_image)} and labels {np.shape(labels)} "
                              "must be (H, W, 3) and (H, W)")
    hw = lin.shape[:2]
    lab = _fit(np.asarray(labels, np.uint8), hw, cv2.INTER_NEAREST)
    ego = ego_mask(lab)
    if not ego.any():
        return lin, {"ego_gain": 0.0, "ego_pixels": 0}
    day = srgb_to_linear(_fit(np.asarray(day_image), hw, cv2.INTER_AREA).astype(np.float32) / 255.0)
    lum_n, lum_d = lin @ _LUMA, day @ _LUMA
    ref = ~ego & (lab != 23) & (lum_d > _MIN_DAY)
    if light_pixels is not None:
        ref &= ~_fit(np.asarray(light_pixels, np.uint8), hw, cv2.INTER_NEAREST).astype(bool)
    gain = float(np.median(lum_n[ref] / lum_d[ref])) if ref.any() else 0.0
    hood = lab == 1
    band = road_band_above(lab)
    if hood.any() and band.any():
        cap = EGO_CAP * float(np.median(lum_n[band]))
        top = float(np.percentile(lum_d[hood], 99)) * gain
        if top > cap:
            gain *= cap / max(top, 1e-12)
    out = np.where(ego[..., None], day * np.float32(gain), lin).astype(np.float32)
    return out, {"ego_gain": gain, "ego_pixels": int(ego.sum())}
