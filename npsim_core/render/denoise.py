"""Monte Carlo noise removal for night renders, guided by what the camera sees.

A path-traced night at 64 spp is speckled: each pixel averages a few dozen random
light paths. Every night is rendered from the day photo's own viewpoint, so the
surfaces behind each pixel are known exactly -- the mesh's depth and normal seen
through the pixel, its label, its albedo -- and can steer an edge-avoiding filter
(the à-trous wavelet filter of Dammertz et al., HPG 2010):

* the render is divided by the albedo (texture is not noise; it is put back after);
* five passes of a 5x5 B3-spline kernel with holes (step 1, 2, 4, 8, 16 px, so the
  footprint grows to 65 px) average a pixel with neighbours that lie on the same
  surface: same label, depth within ``sigma_depth`` (relative, per pixel of distance),
  normals alike (``cos^sigma_normal``) and, to keep shadow edges and light pools, a
  luminance within ``sigma_luminance`` times the local noise (the 5x5 spread);
* light-source pixels (the annotation's masks) are left exactly as rendered and never
  spread into their neighbours.

It runs on the linear render before the camera simulation, so the camera's own
(physical) noise is added to a clean image. Vectorised numpy: 125 shifted-array
passes; about 0.5 s at 512x256.

The alternative (and the default since session 3, ``night.denoiser``): Intel Open Image
Denoise (:func:`denoise_oidn`, the ``pyoidn`` package; its trained "RT" filter for HDR
renders) fed with an albedo and a normal guide. Those come from Mitsuba's ``aov``
integrator on the night scene itself (:func:`.render.render_guides`): box-filtered like
the render, so they match it at every edge, which the mesh rasterised through pixel
centres does not (docs/relight.md has the comparison). OIDN gets the raw render: removing
fireflies first takes energy it would otherwise put back, and pasting the light-source
pixels back over its output made them worse (both measured, docs/relight.md).

:data:`DENOISERS`: ``oidn``, ``guided`` (the filter above) or ``none`` (fireflies only).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import cv2
import numpy as np

from ..camera import Intrinsics
from ..errors import NpsimInputError

__all__ = ["DENOISERS", "OIDN_QUALITIES", "DenoiseParams", "DenoiseGuides", "denoise_guides", "denoise",
           "denoise_oidn", "denoise_night", "isolated_outliers", "remove_isolated"]

#: Monte Carlo denoisers of a night render: Intel Open Image Denoise, the guided à-trous
#: filter, or none (isolated fireflies are still removed).
DENOISERS = ("oidn", "guided", "none")
#: OIDN's quality presets (on a CPU "high" runs the same network as "balanced").
OIDN_QUALITIES = ("fast", "balanced", "high")

_B3 = np.array([1 / 16, 1 / 4, 3 / 8, 1 / 4, 1 / 16], np.float32)
_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)


@dataclass(frozen=True)
class DenoiseParams:
    """Edge-stopping strengths of :func:`denoise` (see module doc).

    iterations : passes (footprint 4·2^iterations + 1 px); 0 = off.
    sigma_depth : relative depth difference, per pixel of distance, that weighs e^-1.
    sigma_normal : exponent on the normals' cosine.
    sigma_luminance : luminance difference, in units of the local noise, that weighs e^-1.
    min_albedo : albedo floor of the demodulation (dark surfaces would amplify noise).
    firefly_ratio : before filtering, a pixel brighter than this multiple of its 3x3 median
        luminance (plus ``firefly_floor``) takes the median colour; light-source pixels are
        never touched (0 = off). Applied even when the filter is off.
    firefly_floor : absolute luminance margin of that test (linear radiance units).
    oidn_quality : Open Image Denoise's preset (:data:`OIDN_QUALITIES`) when the denoiser is
        ``oidn``; the firefly test does not run before OIDN (it would remove real energy).
    oidn_max_memory_mb : OIDN's scratch memory bound (MB; it denoises in overlapping tiles,
        the same result), released after each image. Measured at 2048x1024 (docs/relight.md):
        256 MB peaks at +0.26 GB in 1.4 s, unbounded at +0.70 GB (kept) in 0.84 s.
    """

    iterations: int = 5
    sigma_depth: float = 0.02
    sigma_normal: float = 32.0
    sigma_luminance: float = 2.0
    min_albedo: float = 0.03
    firefly_ratio: float = 4.0
    firefly_floor: float = 0.01
    oidn_quality: str = "fast"
    oidn_max_memory_mb: int = 256

    def __post_init__(self) -> None:
        if int(self.oidn_max_memory_mb) < 16:
            raise NpsimInputError(f"denoise.oidn_max_memory_mb must be >= 16, got {self.oidn_max_memory_mb}")
        if self.oidn_quality not in OIDN_QUALITIES:
            raise NpsimInputError(f"denoise.oidn_quality must be one of {', '.join(OIDN_QUALITIES)}, "
                                  f"got {self.oidn_quality!r}")
        if not 0 <= int(self.iterations) <= 8:
            raise NpsimInputError(f"denoise iterations must be in 0..8, got {self.iterations}")
        if not (self.firefly_ratio >= 0 and self.firefly_floor >= 0):
            raise NpsimInputError(f"denoise firefly_ratio and firefly_floor must be >= 0, "
                                  f"got {self.firefly_ratio}, {self.firefly_floor}")
        for name in ("sigma_depth", "sigma_normal", "sigma_luminance", "min_albedo"):
            if not getattr(self, name) > 0:
                raise NpsimInputError(f"denoise {name} must be > 0, got {getattr(self, name)}")


@dataclass
class DenoiseGuides:
    """Per-pixel guides at the image's full resolution (resized to the render when it is smaller).

    albedo (H, W, 3) linear; depth (H, W) metres, NaN where the camera sees no surface;
    normals (H, W, 3) unit, camera frame (OpenCV: x right, y down, z forward), NaN or 0 where
    the camera sees no surface; labels (H, W) labelIds; protect (H, W) bool light-source pixels.
    kind : ``"mesh"`` -- the mesh rasterised through each pixel centre (:func:`denoise_guides`,
    for the guided filter) -- or ``"aov"`` -- Mitsuba's albedo/normal/depth AOVs, box-filtered
    over each pixel like the render (:func:`.render.render_guides`, for OIDN).
    """

    albedo: np.ndarray
    depth: np.ndarray
    normals: np.ndarray
    labels: np.ndarray
    protect: np.ndarray
    kind: str = "mesh"

    def at(self, height: int, width: int) -> "DenoiseGuides":
        """The guides at a render size: labels, light pixels and mesh guides nearest (not blended);
        AOVs area-averaged, i.e. box-filtered over the smaller render's pixels as the render is."""
        if self.depth.shape == (height, width):
            return self

        def rs(a, blend=False):
            smaller = height <= a.shape[0] and width <= a.shape[1]
            interp = cv2.INTER_AREA if blend and smaller else cv2.INTER_NEAREST
            return cv2.resize(np.ascontiguousarray(a), (width, height), interpolation=interp)

        aov = self.kind == "aov"
        return DenoiseGuides(rs(self.albedo.astype(np.float32), aov), rs(self.depth.astype(np.float32)),
                             rs(self.normals.astype(np.float32), aov), rs(self.labels.astype(np.uint8)),
                             rs(self.protect.astype(np.uint8)).astype(bool), self.kind)


def denoise_guides(mesh, intrinsics: Intrinsics, albedo: np.ndarray, labels: np.ndarray,
                   protect: np.ndarray | None = None) -> DenoiseGuides:
    """Guides from the scene mesh seen through each pixel centre (exact z-buffer, as rendered).

    ``albedo`` is the materials' linear albedo, ``labels`` the day labels, ``protect`` the
    light-source pixels (None = none).
    """
    from ..mesh.quality import rasterize

    H, W = intrinsics.height, intrinsics.width
    if np.shape(albedo) != (H, W, 3) or np.shape(labels) != (H, W):
        raise NpsimInputError(f"denoise guides: albedo must be {H}x{W}x3 and labels {H}x{W}, "
                              f"got {np.shape(albedo)} and {np.shape(labels)}")
    ras = rasterize(mesh, intrinsics)
    normals = np.full((H * W, 3), np.nan, np.float32)
    pf, ff = ras.part.ravel(), ras.face.ravel()
    for i, p in enumerate(mesh.parts):
        sel = np.flatnonzero(pf == i)
        if len(sel):
            normals[sel] = p.face_normals()[ff[sel]]
    prot = np.zeros((H, W), bool) if protect is None else np.asarray(protect, bool)
    return DenoiseGuides(np.asarray(albedo, np.float32), ras.depth, normals.reshape(H, W, 3),
                         np.asarray(labels, np.uint8), prot)


def denoise(linear: np.ndarray, guides: DenoiseGuides, params: DenoiseParams = DenoiseParams()) -> np.ndarray:
    """Edge-avoiding à-trous filter of a linear night render (module doc). Returns float32 (H, W, 3)."""
    lin = np.asarray(linear, np.float32)
    if lin.ndim != 3 or lin.shape[2] != 3:
        raise NpsimInputError(f"denoise: linear image must be HxWx3, got {lin.shape}")
    H, W = lin.shape[:2]
    if params.iterations == 0 or H < 5 or W < 5:
        return lin
    g = guides.at(H, W)
    alb = np.maximum(np.nan_to_num(g.albedo, nan=1.0), params.min_albedo).astype(np.float32)
    seen = np.isfinite(g.depth) & np.isfinite(g.normals).all(2)
    z = np.where(seen, g.depth, 0.0).astype(np.float32)
    n = np.where(seen[..., None], g.normals, 0.0).astype(np.float32)
    lab = g.labels.astype(np.int16)
    src_ok = seen & ~g.protect                      # pixels that may smooth and be smoothed
    x = lin / alb
    for it in range(int(params.iterations)):
        step = 1 << it
        lum = x @ _LUMA
        mean = cv2.blur(lum, (5, 5))
        noise = np.sqrt(np.maximum(cv2.blur(lum * lum, (5, 5)) - mean * mean, 0.0)) + 1e-6
        pad = 2 * step

        def padded(a):
            widths = ((pad, pad), (pad, pad)) + ((0, 0),) * (a.ndim - 2)
            return np.pad(a, widths, mode="constant")

        xp, zp, np_, lp, lup, okp = (padded(a) for a in (x, z, n, lab, lum, src_ok))
        acc = np.zeros_like(x)
        wsum = np.zeros((H, W), np.float32)
        for i in range(5):
            for j in range(5):
                dy, dx = (i - 2) * step, (j - 2) * step
                win = (slice(pad + dy, pad + dy + H), slice(pad + dx, pad + dx + W))
                dist = max(abs(dy), abs(dx), 1)
                w = _B3[i] * _B3[j] * okp[win] * (lp[win] == lab)
                w = w * np.exp(-np.abs(zp[win] - z) / (params.sigma_depth * dist * np.maximum(z, 1e-3)))
                w = w * np.maximum((np_[win] * n).sum(2), 0.0) ** params.sigma_normal
                w = w * np.exp(-np.abs(lup[win] - lum) / (params.sigma_luminance * noise))
                acc += w[..., None] * xp[win]
                wsum += w
        out = acc / np.maximum(wsum, 1e-12)[..., None]
        x = np.where((src_ok & (wsum > 0))[..., None], out, x).astype(np.float32)
    return np.where(src_ok[..., None], x * alb, lin).astype(np.float32)


def denoise_oidn(linear: np.ndarray, guides: DenoiseGuides | None = None,
                 params: DenoiseParams = DenoiseParams()) -> np.ndarray:
    """Intel Open Image Denoise (``pyoidn``, filter "RT", HDR input) of a linear night render,
    guided by ``guides.albedo`` and ``guides.normals`` when given (resized to the render with
    :meth:`DenoiseGuides.at`); quality ``params.oidn_quality``. Returns float32 (H, W, 3) >= 0."""
    lin = np.ascontiguousarray(linear, dtype=np.float32)
    if lin.ndim != 3 or lin.shape[2] != 3:
        raise NpsimInputError(f"denoise: linear image must be HxWx3, got {lin.shape}")
    try:
        import pyoidn
    except ImportError as exc:  # pragma: no cover - a dependency; guard for broken installs
        raise NpsimInputError(f"the 'oidn' denoiser needs the pyoidn package ({exc}); install it "
                              "(pip install pyoidn) or choose --denoiser guided") from None
    aux = {}
    if guides is not None:
        g = guides.at(*lin.shape[:2])
        aux["albedo"] = np.ascontiguousarray(np.clip(np.nan_to_num(g.albedo, nan=0.0), 0.0, 1.0), np.float32)
        aux["normal"] = np.ascontiguousarray(np.clip(np.nan_to_num(g.normals, nan=0.0), -1.0, 1.0), np.float32)
    out = np.empty_like(lin)
    with _OIDN_LOCK:
        if not _OIDN:
            _OIDN.append(pyoidn.Device())
            _OIDN[0].commit()
        f = pyoidn.Filter(_OIDN[0], "RT")
        try:
            for name, img in (("color", lin), *aux.items(), ("output", out)):
                f.set_image(name, img, pyoidn.OIDN_FORMAT_FLOAT3)
            f.set_bool("hdr", True)
            f.set_quality(_OIDN_QUALITY[params.oidn_quality](pyoidn))
            f.set_int("maxMemoryMB", int(params.oidn_max_memory_mb))
            f.commit()
            f.execute()
        finally:
            f.release()  # its scratch memory goes with it
    return np.maximum(np.nan_to_num(out, nan=0.0, posinf=0.0), 0.0).astype(np.float32)


#: The OIDN device (created once; filters are made per image so their memory is released).
_OIDN: list = []
_OIDN_LOCK = threading.Lock()
_OIDN_QUALITY = {"fast": lambda m: m.OIDN_QUALITY_FAST, "balanced": lambda m: m.OIDN_QUALITY_BALANCED,
                 "high": lambda m: m.OIDN_QUALITY_HIGH}


#: A pixel whose albedo-divided luminance is off its 3x3 median by more than this factor (either
#: way) is an outlier when it is also alone (:func:`isolated_outliers`); visible speckle.
OUTLIER_RATIO = 1.5
#: Linear luminance below which a pixel is not "lit" (the outlier test and the exposure meter).
LIT_FLOOR = 2e-3


def _interior(g: DenoiseGuides) -> np.ndarray:
    """Pixels whose 3x3 neighbourhood is one surface: one label, depth within 3 %, albedo within
    30 %, no light-source pixel (an outlier test there would count real edges)."""
    k = np.ones((3, 3), np.uint8)
    lab = g.labels.astype(np.uint8)
    ok = cv2.dilate(lab, k) == cv2.erode(lab, k)
    d = np.nan_to_num(g.depth.astype(np.float32), nan=0.0, posinf=0.0)
    ok &= (d > 0) & (cv2.dilate(d, k) - cv2.erode(d, k) < 0.03 * np.maximum(d, 1e-3))
    a = np.maximum(np.nan_to_num(g.albedo.astype(np.float32), nan=0.0) @ _LUMA, 1e-3)
    ok &= cv2.dilate(a, k) < 1.3 * cv2.erode(a, k)
    ok &= ~cv2.dilate(g.protect.astype(np.uint8), k).astype(bool)
    return ok


def isolated_outliers(linear: np.ndarray, guides: DenoiseGuides, *, ratio: float = OUTLIER_RATIO,
                      lit_floor: float = LIT_FLOOR) -> tuple[np.ndarray, np.ndarray]:
    """(outliers, lit): (H, W) bool masks of isolated dark or bright pixels and of the pixels tested.

    Tested ("lit") pixels: luminance above ``lit_floor`` inside one surface (one label, depth
    within 3 %, albedo within 30 % over the 3x3 neighbourhood, no light source). A tested pixel is
    an outlier when its albedo-divided luminance is more than ``ratio`` times off (above or below)
    the median of its 3x3 neighbourhood and at most one neighbour is off the same way: a lone
    speckle, not a shadow edge or a highlight several pixels wide.
    """
    lin = np.asarray(linear, np.float32)
    g = guides.at(*lin.shape[:2])
    lum = lin @ _LUMA
    alb = np.maximum(np.nan_to_num(g.albedo.astype(np.float32), nan=0.0) @ _LUMA, 0.02)
    e = np.log(np.maximum(lum / alb, 1e-8)).astype(np.float32)
    dev = e - cv2.medianBlur(e, 3)
    t = np.float32(np.log(ratio))
    lit = _interior(g) & (lum > lit_floor)
    out = np.zeros(lum.shape, bool)
    for sign in (1.0, -1.0):
        far = (sign * dev > t)
        ring = np.ones((3, 3), np.float32)
        ring[1, 1] = 0
        n_same = cv2.filter2D(far.astype(np.float32), -1, ring, borderType=cv2.BORDER_CONSTANT)
        out |= far & (n_same <= 1.0)
    return out & lit, lit


def remove_isolated(linear: np.ndarray, guides: DenoiseGuides, *, ratio: float = OUTLIER_RATIO,
                    passes: int = 3) -> tuple[np.ndarray, int]:
    """The denoised night with its isolated outliers (:func:`isolated_outliers`) brought to the
    median albedo-divided luminance of their 3x3 neighbourhood times their own albedo (colour
    kept); ``passes`` rounds, since a pair of
    speckles becomes a lone one once its partner is fixed. Returns the image and the pixels changed."""
    lin = np.ascontiguousarray(linear, np.float32)
    changed = 0
    for _ in range(int(passes)):
        bad, _ = isolated_outliers(lin, guides, ratio=ratio)
        n = int(bad.sum())
        if n == 0:
            break
        lum = lin @ _LUMA
        alb = np.maximum(np.nan_to_num(guides.at(*lin.shape[:2]).albedo.astype(np.float32), nan=0.0) @ _LUMA, 0.02)
        # The median of the albedo-divided luminance, times the pixel's own albedo (what the test measures).
        target = np.exp(cv2.medianBlur(np.log(np.maximum(lum / alb, 1e-8)).astype(np.float32), 3)) * alb
        scale = np.where(bad, target / np.maximum(lum, 1e-8), 1.0).astype(np.float32)
        # A pixel black in every channel has no colour to keep: it takes the median colour.
        lin = np.where((bad & (lum <= 1e-8))[..., None], cv2.medianBlur(lin, 3), lin * scale[..., None])
        changed += n
    return lin.astype(np.float32), changed


def denoise_night(linear: np.ndarray, guides: DenoiseGuides | None, params: DenoiseParams = DenoiseParams(),
                  protect: np.ndarray | None = None, denoiser: str = "guided") -> np.ndarray:
    """A linear night render cleaned of its Monte Carlo noise by ``denoiser`` (:data:`DENOISERS`):

    * ``guided``: fireflies removed, then (with ``guides``) the edge-avoiding filter of :func:`denoise`;
    * ``oidn``: Open Image Denoise on the raw render (:func:`denoise_oidn`; ``guides`` optional);
    * ``none``: fireflies removed only.

    ``protect`` (H, W) bool: light-source pixels at any resolution (resized nearest to the
    render), never taken for fireflies. Returns float32 (H, W, 3)."""
    from .camera_post import remove_fireflies

    if denoiser not in DENOISERS:
        raise NpsimInputError(f"unknown denoiser {denoiser!r}; choose one of {', '.join(DENOISERS)}")
    lin = np.asarray(linear, np.float32)
    if lin.ndim != 3 or lin.shape[2] != 3:
        raise NpsimInputError(f"denoise: linear image must be HxWx3, got {lin.shape}")
    if not np.isfinite(lin).all():
        raise NpsimInputError("linear image contains NaN/inf; the render failed")
    if denoiser == "oidn":
        out = denoise_oidn(lin, guides, params)
        # OIDN leaves a few lone dark/bright pixels on lit surfaces (docs/relight.md, "Speckle").
        return remove_isolated(out, guides)[0] if guides is not None else out
    H, W = lin.shape[:2]
    if params.firefly_ratio > 0 and H >= 3 and W >= 3:
        prot = None
        if protect is not None:
            prot = np.asarray(protect, bool)
            if prot.shape != (H, W):  # preview renders are smaller than the annotation
                prot = cv2.resize(prot.astype(np.uint8), (W, H), interpolation=cv2.INTER_NEAREST).astype(bool)
        lin, _ = remove_fireflies(lin, params.firefly_ratio, params.firefly_floor, prot)
    if guides is not None and denoiser == "guided":
        lin = remove_isolated(denoise(lin, guides, params), guides)[0]
    return lin
