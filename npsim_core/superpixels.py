"""Superpixels for the light annotation editor (OpenCV ``ximgproc``).

``compute_superpixels`` segments an RGB image with SLIC, SLICO, MSLIC, SEEDS
or LSC at an adjustable scale (``region_size``, px) and compactness, returning
an HxW int32 label map with labels 0..n-1. ``cached_superpixels`` memoises the
result per image checksum and settings (in-memory LRU, thread-safe), and
``superpixel_pair`` gives the coarse map plus a finer one (half the region
size) for detail work. Everything here is pure and GIL-releasing inside
OpenCV, so a GUI can run it in a worker thread and ignore stale results.

Measured on 2048×1024 (2 cores): SEEDS ≈ 0.3–0.9 s, SLIC ≈ 0.7–1.4 s,
LSC ≈ 2.5 s (see ``benchmarks/superpixels.py``).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import asdict, dataclass

import cv2
import numpy as np

from .annotation import image_checksum
from .errors import NpsimInputError

METHODS = ("slic", "slico", "mslic", "seeds", "lsc")


@dataclass(frozen=True)
class SuperpixelParams:
    """Superpixel settings.

    method : one of ``METHODS``.
    region_size : float
        Average superpixel edge length in pixels (SEEDS: sets the count H*W/region_size²).
    compactness : float
        SLIC/MSLIC ruler (higher = squarer, 10 typical); LSC ratio = compactness/100;
        SEEDS ignores it.
    iterations : int
        Refinement iterations.
    fine_factor : float
        Region size of the finer, detail scale relative to ``region_size``.
    smooth : int
        Median-filter aperture applied before segmenting (odd; 0 or 1 = off). Sensor,
        JPEG and render noise otherwise makes superpixel borders wander off small
        objects such as windows; a 3x3 median keeps edges.
    """

    method: str = "slic"
    region_size: int = 16
    compactness: float = 10.0
    iterations: int = 10
    fine_factor: float = 0.5
    smooth: int = 3

    def fine(self) -> "SuperpixelParams":
        return SuperpixelParams(self.method, max(3, int(round(self.region_size * self.fine_factor))),
                                self.compactness, self.iterations, self.fine_factor, self.smooth)

    @classmethod
    def for_image(cls, width: int, **kw) -> "SuperpixelParams":
        """Defaults scaled to the image: region size W/128 clipped to 8..24 px (16 at 2048 wide)."""
        kw.setdefault("region_size", default_region_size(width))
        return cls(**kw)


def default_region_size(width: int) -> int:
    """Superpixel size (px) suited to an image ``width`` px wide: W/128 within 8..24."""
    return int(np.clip(round(width / 128), 8, 24))


def compute_superpixels(image: np.ndarray, method: str = "slic", region_size: int = 16, compactness: float = 10.0,
                        iterations: int = 10, smooth: int = 3) -> np.ndarray:
    """Segment ``image`` (HxWx3 uint8 RGB, or HxW grey) into superpixels -> HxW int32 labels 0..n-1.

    ``smooth`` is the median aperture applied first (0/1 = none), see :class:`SuperpixelParams`.
    """
    img = np.asarray(image)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    if img.ndim != 3 or img.shape[2] != 3:
        raise NpsimInputError(f"superpixels need an HxWx3 RGB image, got shape {img.shape}")
    if img.dtype != np.uint8:
        raise NpsimInputError(f"superpixels need a uint8 image, got {img.dtype}")
    method = method.lower()
    if method not in METHODS:
        raise NpsimInputError(f"unknown superpixel method {method!r}; choose one of {', '.join(METHODS)}")
    region_size = int(region_size)
    if region_size < 2:
        raise NpsimInputError(f"region_size must be >= 2 px, got {region_size}")
    H, W = img.shape[:2]
    img = np.ascontiguousarray(img)
    if smooth and int(smooth) > 1:
        img = cv2.medianBlur(img, int(smooth) | 1)
    lab = cv2.cvtColor(img, cv2.COLOR_RGB2Lab)
    xi = cv2.ximgproc
    if method in ("slic", "slico", "mslic"):
        algo = {"slic": xi.SLIC, "slico": xi.SLICO, "mslic": xi.MSLIC}[method]
        sp = xi.createSuperpixelSLIC(lab, algo, region_size, float(compactness))
        sp.iterate(int(iterations))
        sp.enforceLabelConnectivity(25)
    elif method == "lsc":
        sp = xi.createSuperpixelLSC(lab, region_size, float(compactness) / 100.0)
        sp.iterate(int(iterations))
        sp.enforceLabelConnectivity(25)
    else:
        n = max(1, (H * W) // (region_size * region_size))
        sp = xi.createSuperpixelSEEDS(W, H, 3, n, 4, 2, 5, False)
        sp.iterate(lab, int(iterations))
    labels = sp.getLabels().astype(np.int32)
    # Compact the label range (connectivity enforcement can leave gaps).
    _, inv = np.unique(labels, return_inverse=True)
    return inv.reshape(H, W).astype(np.int32)


class _LRU:
    def __init__(self, size: int) -> None:
        self.size = size
        self.data: OrderedDict = OrderedDict()
        self.lock = threading.Lock()

    def get(self, key):
        with self.lock:
            if key in self.data:
                self.data.move_to_end(key)
                return self.data[key]
        return None

    def put(self, key, value) -> None:
        with self.lock:
            self.data[key] = value
            self.data.move_to_end(key)
            while len(self.data) > self.size:
                self.data.popitem(last=False)


_CACHE = _LRU(8)


def cached_superpixels(image: np.ndarray, params: SuperpixelParams = SuperpixelParams(),
                       image_key: str | None = None) -> np.ndarray:
    """:func:`compute_superpixels` memoised on (image checksum, settings); treat the result as read-only."""
    key = (image_key or image_checksum(image), tuple(sorted(asdict(params).items())))
    hit = _CACHE.get(key)
    if hit is not None:
        return hit
    labels = compute_superpixels(image, params.method, params.region_size, params.compactness, params.iterations,
                                 params.smooth)
    labels.setflags(write=False)
    _CACHE.put(key, labels)
    return labels


def superpixel_pair(image: np.ndarray, params: SuperpixelParams = SuperpixelParams()) -> tuple[np.ndarray, np.ndarray]:
    """(coarse, fine) label maps; the fine one uses ``params.fine()``."""
    key = image_checksum(image)
    return cached_superpixels(image, params, key), cached_superpixels(image, params.fine(), key)


def clear_cache() -> None:
    with _CACHE.lock:
        _CACHE.data.clear()


def boundary_mask(labels: np.ndarray) -> np.ndarray:
    """HxW bool, True on pixels whose right or lower neighbour has another label."""
    lab = np.asarray(labels)
    out = np.zeros(lab.shape, dtype=bool)
    out[:, :-1] |= lab[:, :-1] != lab[:, 1:]
    out[:-1, :] |= lab[:-1, :] != lab[1:, :]
    return out


def superpixel_index(labels: np.ndarray, ids) -> np.ndarray:
    """Flat pixel indices of the superpixels ``ids`` (a LUT gather, not ``isin``)."""
    lab = np.asarray(labels)
    ids = np.asarray(list(ids) if not isinstance(ids, np.ndarray) else ids, dtype=np.int64)
    if ids.size == 0:
        return np.zeros(0, np.int32)
    lut = np.zeros(int(lab.max()) + 1, dtype=bool)
    lut[ids[(ids >= 0) & (ids < lut.size)]] = True
    return np.flatnonzero(lut[lab.reshape(-1)]).astype(np.int32)


def superpixel_means(image: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """(n, 3) mean CIELab colour per superpixel (float32; L 0..100 scale of OpenCV's 8-bit Lab / 2.55)."""
    lab = cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2Lab).reshape(-1, 3).astype(np.float64)
    flat = np.asarray(labels).reshape(-1)
    n = int(flat.max()) + 1
    cnt = np.maximum(np.bincount(flat, minlength=n), 1)
    return np.stack([np.bincount(flat, lab[:, c], minlength=n) / cnt for c in range(3)], axis=1).astype(np.float32)


#: CIELab (8-bit units) radius of the background colour in :func:`similar_superpixels`.
BACKGROUND_RADIUS = 10.0


def similar_superpixels(means: np.ndarray, candidates, seed: int, tolerance: float | None = None) -> np.ndarray:
    """The ``candidates`` that look like superpixel ``seed``.

    With a ``tolerance`` (8-bit CIELab units): those whose mean colour lies within
    it of the seed's. Without (``None`` or <= 0, "auto"): a drag along a row of
    windows touches windows and the wall between them. The wall is the densest
    colour among the candidates (the most others within ``BACKGROUND_RADIUS``); when
    the seed is not of it, everything not of it is kept -- windows differ from the
    wall in different ways (darker, brighter, tinted), so they need not resemble
    each other; a seed of the densest colour keeps that colour. Without a dense colour
    (no two candidates within the radius), the candidates are split into two colour
    clusters (2-means, started from the seed and the candidate farthest from it) and
    the seed's cluster is kept.
    """
    cand = np.asarray(sorted(set(int(c) for c in candidates) | {int(seed)}), dtype=np.int64)
    X = means[cand].astype(np.float64)
    c0 = means[int(seed)].astype(np.float64)
    if tolerance is not None and tolerance > 0:
        return cand[np.linalg.norm(X - c0, axis=1) <= tolerance]
    dist = np.linalg.norm(X[:, None] - X[None], axis=2)
    dense = dist <= BACKGROUND_RADIUS
    mode = int(np.argmax(dense.sum(1)))
    background = np.linalg.norm(X - X[dense[mode]].mean(axis=0), axis=1) <= BACKGROUND_RADIUS
    if background.sum() >= 2:
        return cand[background] if background[cand == int(seed)].any() else cand[~background]
    c1 = X[np.argmax(np.linalg.norm(X - c0, axis=1))]
    near0 = np.ones(len(cand), bool)
    for _ in range(20):
        d0 = np.linalg.norm(X - c0, axis=1)
        d1 = np.linalg.norm(X - c1, axis=1)
        new = d0 <= d1
        if new.all() or not new.any() or (new == near0).all():
            near0 = new
            break
        near0 = new
        c0, c1 = X[near0].mean(axis=0), X[~near0].mean(axis=0)
    return cand[near0]


def line_pixels(x0: float, y0: float, x1: float, y1: float) -> tuple[np.ndarray, np.ndarray]:
    """Integer pixels (x, y) sampled densely along a segment (for mouse drags)."""
    n = int(max(abs(x1 - x0), abs(y1 - y0))) + 1
    t = np.linspace(0.0, 1.0, n + 1)
    xs = np.round(x0 + (x1 - x0) * t).astype(np.int64)
    ys = np.round(y0 + (y1 - y0) * t).astype(np.int64)
    return xs, ys


def disk_index(shape: tuple[int, int], xs: np.ndarray, ys: np.ndarray, radius: float) -> np.ndarray:
    """Flat indices of all pixels within ``radius`` of any of the points (brush footprint)."""
    H, W = shape
    r = max(0.0, float(radius))
    ri = int(np.ceil(r))
    oy, ox = np.mgrid[-ri:ri + 1, -ri:ri + 1]
    keep = ox * ox + oy * oy <= r * r + 1e-9
    ox, oy = ox[keep], oy[keep]
    px = (np.asarray(xs)[:, None] + ox[None, :]).ravel()
    py = (np.asarray(ys)[:, None] + oy[None, :]).ravel()
    ok = (px >= 0) & (px < W) & (py >= 0) & (py < H)
    return np.unique(py[ok] * W + px[ok]).astype(np.int32)
