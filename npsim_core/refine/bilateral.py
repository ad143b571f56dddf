"""Dual-reference cross-bilateral depth filter (docs/method.md §3.1, thesis eq. 3.2).

    d(p) = Σ_q G_σs(|q−p|) [δ(h_q = h_p) + μ G_σc(|J_q − J_p|)] w_q d̂(q)
           ------------------------------------------------------------
           Σ_q G_σs(|q−p|) [δ(h_q = h_p) + μ G_σc(|J_q − J_p|)] w_q

* ``G_σ(x) = exp(-x² / 2σ²)`` *unnormalised* (peak 1), so identical colours
  weigh μ times a same-class neighbour; the spatial kernel's normalisation
  cancels anyway. The window is the square |q−p|∞ ≤ r, r = ceil(3σs), cut at
  the image border.
* ``J`` is CIELAB (L in 0..100) of the sRGB image, from OpenCV's
  ``COLOR_RGB2Lab`` (which applies the sRGB transfer curve).
* ``w_q`` = 1 where d̂(q) is valid (finite, > 0), else 0: invalid depth
  contributes nothing, and invalid pixels stay NaN in the output (nothing is
  filled). Numerator and denominator share every weight.
* Same-class pixels feed the semantic term (the formula, not the thesis's prose).

Two implementations:

:func:`cross_bilateral_reference`
    Exact brute force over the (2r+1)² offsets in float64. O(N r²): for tests
    and the benchmark at 512x256.
:func:`cross_bilateral`
    Fast. The semantic term is computed *exactly*: for each class c present,
    a separable truncated Gaussian blur of (1[h=c] w d̂, 1[h=c] w) over the
    class's bounding box grown by r, read back at the class's pixels. The
    colour term is approximated by a *clustered, moment-matched bilateral
    grid*: the Lab guide is quantised into K k-means colours; every valid
    pixel q is splatted into the cell (x/s, y/s, cluster(q)) of a grid
    downsampled s times in space, carrying (w, w d̂, w (J−c_k), w |J−c_k|²);
    each cluster slice is blurred with the spatial Gaussian (σ corrected for
    the splat's box and the slice's tent interpolation); at p the M clusters
    nearest J_p are read back bilinearly and weighted by the Gaussian colour
    kernel *averaged over the cluster's local colour distribution*
    (moment matching: E[G_σ(J_p − J)] for J ~ N(m, v I₃) =
    (σ²/(σ²+v))^{3/2} exp(−|J_p − m|² / 2(σ²+v))). Cost O(N·M + K·N/s²).
    Measured error against the reference: see ``docs/refine.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from ..camera import valid_depth_mask
from ..errors import NpsimInputError
from ._inputs import as_depth, as_image, as_labels, check_positive


@dataclass(frozen=True)
class FilterParams:
    """Parameters of the dual-reference cross-bilateral filter.

    Attributes
    ----------
    mu : float
        Weight μ of the colour term relative to the semantic term (thesis: 5).
    sigma_s : float
        Spatial Gaussian σ in pixels of an image ``scale_width`` pixels wide (thesis: 10 at
        Cityscapes' 2048). Window radius ceil(3σs) of the effective σs.
    sigma_c : float
        Colour Gaussian σ in CIELAB units (thesis: 5).
    clusters : int
        Fast filter only: number K of k-means guide colours.
    neighbours : int
        Fast filter only: clusters M read back per pixel (nearest to its colour).
    downsample : int
        Fast filter only: spatial grid step s of the colour term in pixels;
        0 = automatic (ceil(σs/2) of the effective σs, at least 1, at most min(H, W)/32).
    domain : {'inverse', 'depth'}
        Average inverse depth and invert the result (default), or depth (the
        thesis's formula). On a perspective ground plane inverse depth is linear
        in the image row, so averaging it is unbiased while averaging depth (convex
        in the row) pushes the road farther (docs/refine.md).
    scale_width : int
        Image width at which ``sigma_s`` is given; at width W the filter uses
        σs·W/scale_width (at least 0.5 px), so it smooths the same part of the
        scene at every resolution. 0 = ``sigma_s`` in pixels at every size. With
        the thesis's fixed 10 px, a 512x256 image is smoothed over 4x more of the
        scene and the filtered depth is worse than its input (docs/refine.md).
    """

    mu: float = 5.0
    sigma_s: float = 10.0
    sigma_c: float = 5.0
    clusters: int = 16
    neighbours: int = 3
    downsample: int = 0
    domain: str = "inverse"
    scale_width: int = 2048

    def validate(self) -> None:
        check_positive(self.mu, "FilterParams.mu", allow_zero=True)
        check_positive(self.sigma_s, "FilterParams.sigma_s")
        check_positive(self.sigma_c, "FilterParams.sigma_c")
        if int(self.scale_width) < 0:
            raise NpsimInputError(f"FilterParams.scale_width must be >= 0 pixels (0 = no scaling), "
                                  f"got {self.scale_width}")
        if self.domain not in ("depth", "inverse"):
            raise NpsimInputError(f"FilterParams.domain must be 'depth' or 'inverse', got {self.domain!r}")
        if int(self.clusters) < 1 or int(self.neighbours) < 1 or int(self.downsample) < 0:
            raise NpsimInputError(f"FilterParams.clusters and neighbours must be >= 1 and downsample >= 0, got "
                                  f"{self.clusters}, {self.neighbours}, {self.downsample}")

    @property
    def radius(self) -> int:
        return max(1, int(math.ceil(3.0 * self.sigma_s - 1e-9)))

    def at_width(self, width: int) -> "FilterParams":
        """These parameters with σs scaled to an image ``width`` pixels wide (``scale_width`` = 0 after)."""
        if not self.scale_width:
            return self
        sig = max(0.5, float(self.sigma_s) * float(width) / float(self.scale_width))
        return replace(self, sigma_s=sig, scale_width=0)


#: Depths below this (m) are invalid in the filter (module doc).
MIN_DEPTH_M = 1e-6


def _prepare(depth, image, labels, params: FilterParams, image_u8=None):
    params = params if params is not None else FilterParams()
    if not isinstance(params, FilterParams):
        raise NpsimInputError(f"params must be FilterParams, got {type(params).__name__}")
    params.validate()
    d = as_depth(depth)
    shape = d.shape
    params = params.at_width(shape[1])
    h = as_labels(labels, shape)
    if image_u8 is not None:  # fast path keeps uint8 (no float round trip)
        if image_u8.shape != (*shape, 3):
            raise NpsimInputError(f"image must be HxWx3 RGB matching depth {shape}, got shape {image_u8.shape}")
        rgb = image_u8
    else:
        rgb = as_image(image, shape)
    valid = valid_depth_mask(d)
    with np.errstate(invalid="ignore"):
        # Below a micrometre a depth is no measurement (every entrance drops < 0.1 m);
        # its inverse (1e30 for 1e-30 m) would overflow the float32 sums.
        valid &= d >= MIN_DEPTH_M
    if params.domain == "inverse":
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.where(valid, 1.0 / d, np.nan).astype(np.float32)
        valid = valid_depth_mask(d)  # 1/d underflows to 0 only beyond float32 range: then invalid
    return params, d, h, rgb, valid


def _finish(out: np.ndarray, params: FilterParams) -> np.ndarray:
    if params.domain == "inverse":
        with np.errstate(divide="ignore"):
            out = (1.0 / out).astype(np.float32)
    return out


def rgb_to_lab(rgb: np.ndarray) -> np.ndarray:
    """Float32 sRGB in [0, 1] (HxWx3) -> CIELAB float32 (L 0..100, a/b about -128..127)."""
    return cv2.cvtColor(np.ascontiguousarray(rgb, dtype=np.float32), cv2.COLOR_RGB2Lab)


def cross_bilateral_reference(depth, image, labels, params: FilterParams | None = None) -> np.ndarray:
    """Exact dual-reference cross-bilateral filter (brute force, float64).

    Parameters
    ----------
    depth : (H, W) real
        Input depth d̂ in metres; NaN / inf / <= 0 are invalid.
    image : (H, W, 3) uint8 sRGB, or float RGB in [0, 1]
        Colour reference.
    labels : (H, W) integer
        Semantic labelIds (the semantic reference).
    params : FilterParams

    Returns
    -------
    (H, W) float32 filtered depth in metres, NaN where the input is invalid.
    """
    params, d, h, rgb, valid = _prepare(depth, image, labels, params)
    H, W = d.shape
    r = params.radius
    lab = rgb_to_lab(rgb).astype(np.float64)
    pad = ((r, r), (r, r))
    dz = np.pad(np.where(valid, d, 0.0).astype(np.float64), pad)
    wq = np.pad(valid.astype(np.float64), pad)
    hq = np.pad(h.astype(np.int16), pad, constant_values=-1)
    labq = np.pad(lab, pad + ((0, 0),))
    num = np.zeros((H, W))
    den = np.zeros((H, W))
    inv2s = 1.0 / (2.0 * params.sigma_s ** 2)
    inv2c = 1.0 / (2.0 * params.sigma_c ** 2)
    for dy in range(-r, r + 1):
        ys = slice(r + dy, r + dy + H)
        for dx in range(-r, r + 1):
            xs = slice(r + dx, r + dx + W)
            gs = math.exp(-(dx * dx + dy * dy) * inv2s)
            diff = labq[ys, xs] - lab
            wc = np.exp(-np.einsum("ijk,ijk->ij", diff, diff) * inv2c)
            wgt = (gs * wq[ys, xs]) * ((hq[ys, xs] == h) + params.mu * wc)
            num += wgt * dz[ys, xs]
            den += wgt
    out = np.full((H, W), np.nan, dtype=np.float32)
    ok = valid & (den > 0)
    out[ok] = (num[ok] / den[ok]).astype(np.float32)
    return _finish(out, params)


def _gauss_kernel(sigma: float, radius: int, step: float = 1.0) -> np.ndarray:
    x = np.arange(-radius, radius + 1, dtype=np.float64) * step
    return np.exp(-x * x / (2.0 * sigma * sigma))


def _semantic_term(dz: np.ndarray, w: np.ndarray, h: np.ndarray, sigma_s: float, r: int):
    """Exact per-class Gaussian-weighted sums Σ G δ(h_q=h_p) w d̂ and Σ G δ w (float32)."""
    H, W = h.shape
    k = _gauss_kernel(sigma_s, r).astype(np.float32)
    num = np.zeros((H, W), np.float32)
    den = np.zeros((H, W), np.float32)
    # Per-class bounding boxes from one pass over rows and one over columns.
    rows = np.bincount((np.arange(H)[:, None] * 256 + h).ravel(), minlength=H * 256).reshape(H, 256) > 0
    cols = np.bincount((np.arange(W)[None, :] * 256 + h).ravel(), minlength=W * 256).reshape(W, 256) > 0
    present = np.flatnonzero(rows.any(axis=0))
    stack = np.empty((H, W, 2), np.float32)
    stack[..., 0] = dz
    stack[..., 1] = w
    for c in present:
        ry = np.flatnonzero(rows[:, c])
        rx = np.flatnonzero(cols[:, c])
        y0, y1 = max(0, ry[0] - r), min(H, ry[-1] + r + 1)
        x0, x1 = max(0, rx[0] - r), min(W, rx[-1] + r + 1)
        hc = h[y0:y1, x0:x1] == c
        src = stack[y0:y1, x0:x1] * hc[..., None]
        if not src[..., 1].any():
            continue
        blur = cv2.sepFilter2D(src, cv2.CV_32F, k, k, borderType=cv2.BORDER_CONSTANT)
        np.copyto(num[y0:y1, x0:x1], blur[..., 0], where=hc)
        np.copyto(den[y0:y1, x0:x1], blur[..., 1], where=hc)
    return num, den


def _kmeans(x: np.ndarray, k: int, iters: int = 8) -> np.ndarray:
    """k-means (k-means++ seeding, ``iters`` Lloyd steps) of (N, 3) colours -> (k', 3) float32 centres.

    ``cv2.kmeans`` seeded with ``cv2.setRNGSeed(0)`` (OpenCV's RNG is per thread), so equal
    inputs give equal centres; fewer distinct colours than ``k`` are returned as they are.
    """
    uniq = np.unique(x, axis=0)
    if len(uniq) <= k:
        return uniq.astype(np.float32)
    cv2.setRNGSeed(0)
    criteria = (cv2.TERM_CRITERIA_MAX_ITER | cv2.TERM_CRITERIA_EPS, int(iters), 1e-3)
    _, _, centres = cv2.kmeans(np.ascontiguousarray(x, dtype=np.float32), int(k), None, criteria, 1,
                               cv2.KMEANS_PP_CENTERS)
    return centres


def _lab_from_rgb_u8(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """uint8 path (fast LUT conversion in OpenCV): returns (uint8 Lab codes, float32 Lab).

    ``rgb`` is uint8 sRGB or float sRGB in [0, 1] (rounded to 8 bits first; the
    0.4-unit Lab quantisation is far below σc).
    """
    u8 = rgb if rgb.dtype == np.uint8 else np.clip(np.rint(rgb * 255.0), 0, 255).astype(np.uint8)
    u8 = np.ascontiguousarray(u8)
    lab8 = cv2.cvtColor(u8, cv2.COLOR_RGB2Lab)
    lab = lab8.astype(np.float32)
    lab[..., 0] *= np.float32(100.0 / 255.0)
    lab[..., 1:] -= np.float32(128.0)
    return lab8, lab


def _colour_term_fast(dz: np.ndarray, valid: np.ndarray, rgb: np.ndarray, params: FilterParams):
    """Approximate Σ_q G_s G_c(J_q − J_p) w d̂ and Σ_q G_s G_c w (float32), see module docstring."""
    H, W = dz.shape
    sig_s, sig_c = float(params.sigma_s), float(params.sigma_c)
    lab8, lab = _lab_from_rgb_u8(rgb)
    num = np.zeros((H, W), np.float32)
    den = np.zeros((H, W), np.float32)
    vflat = valid.ravel()
    if not vflat.any():
        return num, den
    # 1. Guide colours: k-means on a seeded sample of valid pixels.
    rng = np.random.default_rng(0)
    idx = np.flatnonzero(vflat)
    sample = lab.reshape(-1, 3)[rng.choice(idx, size=min(len(idx), 4096), replace=False)]
    C = _kmeans(sample, int(params.clusters))
    K = len(C)
    M = min(int(params.neighbours), K)
    # 2. Nearest clusters per pixel through a LUT on uint8 Lab codes (bins of 4 codes, 64^3 entries);
    #    the first one is also the pixel's hard splat assignment.
    code = ((lab8[..., 0] >> 2).astype(np.int32) << 12) | ((lab8[..., 1] >> 2).astype(np.int32) << 6) | \
        (lab8[..., 2] >> 2).astype(np.int32)
    used = np.flatnonzero(np.bincount(code.ravel(), minlength=1 << 18))
    bl = np.stack([(used >> 12) * 4 + 1.5, ((used >> 6) & 63) * 4 + 1.5, (used & 63) * 4 + 1.5], -1)
    bl = (bl * np.array([100.0 / 255.0, 1.0, 1.0]) - np.array([0.0, 128.0, 128.0])).astype(np.float32)
    dist = ((bl[:, None, :] - C[None]) ** 2).sum(-1)
    lut = np.zeros(((1 << 18), M), np.uint8)
    lut[used] = np.argsort(dist, axis=1)[:, :M]
    near = np.take(lut, code, axis=0)  # (H, W, M); np.take is ~2x faster than fancy indexing here
    # 3. Splat into the (cluster, y/s, x/s) grid, stored as a zero-padded atlas of K tiles.
    # Auto step: ceil(σs/2), but at least 32 grid cells across the short side (small images: full resolution).
    s = int(params.downsample) or max(1, min(int(math.ceil(sig_s / 2.0 - 1e-9)), min(H, W) // 32))
    hl, wl = -(-H // s), -(-W // s)
    # splat box + tent compensation (none at s = 1: full resolution, exact)
    sig_low = sig_s if s == 1 else math.sqrt(max(sig_s ** 2 - s * s / 4.0, (0.5 * sig_s) ** 2))
    r_low = max(1, int(math.ceil(3.0 * sig_s / s - 1e-9)))
    P = 2 * r_low + 2
    th = hl + P
    aw = wl + 2 * P
    cell_yx = ((np.arange(H) // s)[:, None] * aw + (P + np.arange(W) // s)[None, :])
    cell = (P + near[..., 0].astype(np.int64) * th) * aw + cell_yx
    size = (K * th + P) * aw
    w = valid.astype(np.float32)
    wl_ = lab * w[..., None]
    chans = [w, dz, wl_[..., 0], wl_[..., 1], wl_[..., 2], np.einsum("ijk,ijk->ij", wl_, lab)]
    raw = np.empty((6, K * th + P, aw), np.float32)
    for i, ch in enumerate(chans):
        raw[i] = np.bincount(cell.ravel(), weights=ch.ravel(), minlength=size).reshape(raw.shape[1:])
    # 4. Spatial blur of every tile at once; kernel scaled so a constant field matches the full-res window sum.
    r_full = params.radius
    k_full = _gauss_kernel(sig_s, r_full).sum()
    k_low = _gauss_kernel(sig_low, r_low, step=s)
    k_low = (k_low * (k_full / (k_low.sum() * s))).astype(np.float32)
    blur = cv2.sepFilter2D(np.ascontiguousarray(raw.transpose(1, 2, 0)), cv2.CV_32F, k_low, k_low,
                           borderType=cv2.BORDER_CONSTANT)
    # Per cell and cluster: local colour mean m and per-axis variance v of the cluster's members; the
    # Gaussian colour kernel averaged over N(m, v I3) is A exp(-|J_p - m|^2 / 2(σc² + v)),
    # A = (σc² / (σc² + v))^{3/2}. Stored so that the slice below is a bilinear read plus one exp.
    cnt = blur[..., 0]
    ok = cnt > 1e-6
    inv = np.where(ok, 1.0 / np.where(ok, cnt, 1.0), 0.0).astype(np.float32)
    mean = blur[..., 2:5] * inv[..., None]
    var = np.maximum(blur[..., 5] * inv - (mean * mean).sum(-1), 0.0) / 3.0
    tot = sig_c * sig_c + var
    amp = ((sig_c * sig_c) / tot) ** 1.5
    # Two 3-channel atlases: OpenCV's remap has a fast path for 3 channels.
    sl_w = np.empty((K * th + P, aw, 3), np.float32)
    sl_w[..., 0] = amp * blur[..., 1]
    sl_w[..., 1] = amp * cnt
    sl_w[..., 2] = 0.5 / tot
    # Empty cells take their cluster's centre so bilinear reads near them stay on the cluster's colour.
    tile = np.clip((np.arange(K * th + P) - P) // th, 0, K - 1)
    sl_m = np.ascontiguousarray(mean, dtype=np.float32)
    np.copyto(sl_m, C[tile][:, None, :], where=~ok[..., None])
    # 5. Slice: bilinear read-back of the M nearest clusters of J_p.
    fx = ((np.arange(W, dtype=np.float32) - (s - 1) / 2.0) / s + P)
    fy = ((np.arange(H, dtype=np.float32) - (s - 1) / 2.0) / s + P)
    map_x = np.ascontiguousarray(np.broadcast_to(fx[None, :], (H, W)), dtype=np.float32)
    for m in range(M):
        map_y = fy[:, None] + near[..., m].astype(np.float32) * np.float32(th)
        gw = cv2.remap(sl_w, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
        gm = cv2.remap(sl_m, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
        gm -= lab
        wgt = np.exp(-np.einsum("ijk,ijk->ij", gm, gm) * gw[..., 2])
        num += wgt * gw[..., 0]
        den += wgt * gw[..., 1]
    return num, den


def cross_bilateral(depth, image, labels, params: FilterParams | None = None) -> np.ndarray:
    """Fast dual-reference cross-bilateral filter (exact semantic term, approximate colour term).

    Same inputs, outputs and conventions as :func:`cross_bilateral_reference`;
    the design of the colour-term approximation is in the module docstring.
    """
    im = np.asarray(image)
    params, d, h, rgb, valid = _prepare(depth, None if im.dtype == np.uint8 else image, labels, params,
                                        image_u8=im if im.dtype == np.uint8 else None)
    dz = np.where(valid, d, 0.0).astype(np.float32)
    w = valid.astype(np.float32)
    num, den = _semantic_term(dz, w, h, float(params.sigma_s), params.radius)
    if params.mu > 0:
        cn, cd = _colour_term_fast(dz, valid, rgb, params)
        num += np.float32(params.mu) * cn
        den += np.float32(params.mu) * cd
    out = np.full(d.shape, np.nan, dtype=np.float32)
    ok = valid & (den > 0)
    out[ok] = num[ok] / den[ok]
    # A pixel always carries its own semantic weight, so den > 0 wherever valid; keep the input as a guard.
    out[valid & ~ok] = d[valid & ~ok]
    return _finish(out, params)
