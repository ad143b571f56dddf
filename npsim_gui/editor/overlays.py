"""numpy -> RGBA overlay arrays for the annotation canvas (vectorised colour LUTs).

All builders return (H, W, 4) uint8 RGBA arrays or fill a region of one in
place, so the canvas can wrap them in a QImage without copying and repaint only
the rectangle an edit touched.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from npsim_core.labels import cityscapes, light_classes
from npsim_core.superpixels import boundary_mask

#: Largest id an instance PNG can hold (uint16); LUTs cover 0..MAX_ID.
MAX_ID = 21999


@lru_cache(maxsize=1)
def light_color_lut() -> np.ndarray:
    """(MAX_ID+1, 3) uint8: each light id gets its class colour, shaded by index so
    neighbouring instances of one class are told apart."""
    lut = np.zeros((MAX_ID + 1, 3), np.float32)
    idx = np.arange(MAX_ID + 1)
    # Alternate shading by index: 1.0, 0.72, 0.86, 0.58 ... (periodic so ids stay distinct nearby).
    shade = np.array([1.0, 0.70, 0.85, 0.58, 0.93, 0.78])[idx % 1000 % 6]
    for c in light_classes():
        sl = slice(c.id * 1000, min(c.id * 1000 + 1000, MAX_ID + 1))
        lut[sl] = np.asarray(c.color, np.float32)[None, :] * shade[sl, None]
    return np.clip(lut, 0, 255).astype(np.uint8)


def class_color(class_id: int) -> tuple[int, int, int]:
    for c in light_classes():
        if c.id == class_id:
            return c.color
    return (255, 255, 255)


def rgba_from_rgb(rgb: np.ndarray) -> np.ndarray:
    """Opaque RGBA of an RGB image (one pass: 3 ms instead of 26 ms at 2048x1024)."""
    return cv2.cvtColor(np.ascontiguousarray(rgb, dtype=np.uint8), cv2.COLOR_RGB2RGBA)


def _gather_rgba(lut_rgba: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``lut_rgba[index]`` for an (N, 4) uint8 LUT as one 4-byte gather per pixel."""
    lut32 = np.ascontiguousarray(lut_rgba, dtype=np.uint8).view(np.uint32).ravel()
    return lut32[index].view(np.uint8).reshape(index.shape + (4,))


def labels_rgba(labels: np.ndarray) -> np.ndarray:
    """Cityscapes colours, opaque (the layer's opacity is set on the item)."""
    lut = cityscapes().color_lut()
    return _gather_rgba(np.concatenate([lut, np.full((len(lut), 1), 255, np.uint8)], axis=1), labels)


def boundary_rgba(labels: np.ndarray, color=(0, 230, 255)) -> np.ndarray:
    b = boundary_mask(labels)
    out = np.zeros(labels.shape, np.uint32)  # one packed RGBA word per pixel: a single masked store
    out[b] = np.array([*color, 255], np.uint8).view(np.uint32)[0]
    return out.view(np.uint8).reshape(labels.shape + (4,))


def lit_box(instance_map: np.ndarray) -> tuple[int, int, int, int] | None:
    """Half-open box (x0, y0, x1, y1) of the labelled pixels grown by one (their outer outline):
    outside it the light layer is transparent black; None when nothing is labelled."""
    rows = np.flatnonzero(instance_map.any(axis=1))
    if not len(rows):
        return None
    cols = np.flatnonzero(instance_map[rows[0]:rows[-1] + 1].any(axis=0))
    return int(cols[0]) - 1, int(rows[0]) - 1, int(cols[-1]) + 2, int(rows[-1]) + 2


#: Outline colours. Every light gets a dark line on its border pixels and a light line on the free pixels
#: just outside it, so one of the two stands out on any image (a white moving_front mask over a white lamp,
#: a dark-red moving_rear over a black car). Selected lights swap to a white inner line and a green outer
#: line (no class colour is green) over a more opaque fill.
OUTLINE_DARK = (0, 0, 0)
OUTLINE_LIGHT = (255, 255, 255)
SELECTED_INNER = (255, 255, 255)
SELECTED_OUTER = (40, 255, 40)
OUTER_ALPHA = 170


def _touches(mask: np.ndarray) -> np.ndarray:
    """Pixels with a 4-neighbour in ``mask``."""
    out = np.zeros(mask.shape, bool)
    out[:, 1:] |= mask[:, :-1]
    out[:, :-1] |= mask[:, 1:]
    out[1:, :] |= mask[:-1, :]
    out[:-1, :] |= mask[1:, :]
    return out


@lru_cache(maxsize=4)
def _light_words(fill_alpha: int) -> np.ndarray:
    """(MAX_ID+1,) packed RGBA words: each id's colour with ``fill_alpha``; id 0 transparent black."""
    rgba = np.concatenate([light_color_lut(), np.full((MAX_ID + 1, 1), fill_alpha, np.uint8)], axis=1)
    rgba[0] = 0
    return np.ascontiguousarray(rgba).view(np.uint32).ravel()


def _word(rgb: tuple[int, int, int], alpha: int) -> np.uint32:
    return np.array([*rgb, alpha], np.uint8).view(np.uint32)[0]


def lights_region(instance_map: np.ndarray, out: np.ndarray, rect: tuple[int, int, int, int] | None,
                  selected: frozenset[int] | set[int] = frozenset(), fill_alpha: int = 150) -> None:
    """Fill ``out[rect]`` (RGBA) from ``instance_map``. ``rect`` = (x0, y0, x1, y1) half-open.

    Each light: translucent fill in its class colour, its border pixels (4-neighbour of another id) in
    ``OUTLINE_DARK`` and the unlabelled pixels touching it in ``OUTLINE_LIGHT`` -- a dark/light double
    outline. ``selected`` lights: fill more opaque, ``SELECTED_INNER`` / ``SELECTED_OUTER`` outlines.
    A pixel's colour depends on its 4-neighbours only, so after an edit redrawing the edit's box
    grown by one pixel is exact. Pixels are written as packed RGBA words (one gather, then masked
    stores): 2048x1024 in ~20 ms instead of ~50 ms.
    """
    H, W = instance_map.shape
    x0, y0, x1, y1 = rect if rect is not None else (0, 0, W, H)
    x0, y0, x1, y1 = max(0, x0), max(0, y0), min(W, x1), min(H, y1)
    if x0 >= x1 or y0 >= y1:
        return
    # One pixel of context on each side so outlines at the rect border are right.
    ex0, ey0, ex1, ey1 = max(0, x0 - 1), max(0, y0 - 1), min(W, x1 + 1), min(H, y1 + 1)
    m = instance_map[ey0:ey1, ex0:ex1]
    edge = np.zeros(m.shape, bool)
    d = m[:, 1:] != m[:, :-1]  # one comparison per neighbour pair, marking both pixels
    edge[:, 1:] |= d
    edge[:, :-1] |= d
    d = m[1:, :] != m[:-1, :]
    edge[1:, :] |= d
    edge[:-1, :] |= d
    lit = m != 0
    outer = ~lit & _touches(lit)
    sel = np.isin(m, np.fromiter(selected, np.int64)) if selected else None
    outer_sel = outer & _touches(sel) if sel is not None else None
    sub = (slice(y0 - ey0, y1 - ey0), slice(x0 - ex0, x1 - ex0))
    m, edge, outer = m[sub], edge[sub] & lit[sub], outer[sub]
    region = out[y0:y1, x0:x1].view(np.uint32)[..., 0]  # (h, w) words over the RGBA bytes
    region[...] = _light_words(int(fill_alpha))[np.clip(m, 0, MAX_ID)]
    region[edge] = _word(OUTLINE_DARK, 255)
    region[outer] = _word(OUTLINE_LIGHT, OUTER_ALPHA)
    if sel is not None:
        sel, outer_sel = sel[sub], outer_sel[sub]
        out[y0:y1, x0:x1, 3][sel & ~edge] = min(255, fill_alpha + 70)
        region[edge & sel] = _word(SELECTED_INNER, 255)
        region[outer_sel] = _word(SELECTED_OUTER, 255)
