"""Camera post-processing of the linear night render (docs/method.md §6.6, thesis §3.6 "Image Post-processing").

Order (a simple camera pipeline): firefly removal (isolated Monte Carlo outliers,
light-source pixels protected) -> exposure gain ``2**exposure_ev`` on the linear
render -> optional horizontal motion blur of moving vehicles -> lens glare (the optics' point-spread
function: a share of *all* light scattered over a long-tailed kernel, :func:`lens_glare`, so that
lamps far above white saturate a halo larger than themselves) -> optional bloom around what exceeds
sensor white -> heteroscedastic Gaussian noise
``I_n = I_c + N(0, β1·I_c + β2)`` (shot + read noise, variance in linear units where
1.0 = sensor white) -> white balance (per-channel gains; :func:`auto_white_balance` gives a camera's automatic ones) ->
tone contrast (the camera's global tone curve around its mid-grey, :func:`tone_contrast`) ->
highlight shoulder (linear below ``highlight_knee``, rolling off smoothly to white,
:func:`highlight_shoulder`) -> clip to [0, 1] -> sRGB encoding -> 8-bit quantisation
(round half up). Labels
are never touched: the label map of a night is the day's, copied unchanged.

ISO presets (:data:`ISO_PRESETS`): analogue gain g = ISO/100; shot-noise
variance grows with g and read-noise variance with g² (the standard
Poisson-Gaussian sensor model, Foi et al. 2008), anchored at ISO 100 to
β1 = 1e-4, β2 = 2e-8 (σ ≈ 0.7 % at mid-grey, a clean daylight sensor). At ISO 1600
this gives σ ≈ 0.9 % at a signal of 0.05 and a read-noise floor σ ≈ 0.23 % (about
8/255 in sRGB near black: typical night grain); the thesis
calibrates β1, β2 from real noisy/clean pairs, which can be passed explicitly.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import NpsimInputError

_BETA1_ISO100 = 1e-4
_BETA2_ISO100 = 2e-8


def iso_noise(iso: float) -> tuple[float, float]:
    """(β1, β2) for an ISO setting: β1 = 1e-4·g, β2 = 2e-8·g², g = ISO/100."""
    if not (iso > 0):
        raise NpsimInputError(f"ISO must be positive, got {iso}")
    g = float(iso) / 100.0
    return _BETA1_ISO100 * g, _BETA2_ISO100 * g * g


ISO_PRESETS: dict[int, tuple[float, float]] = {iso: iso_noise(iso) for iso in (100, 400, 800, 1600, 3200, 6400)}

#: Light classes of moving vehicles (moving_front, moving_rear).
MOVING_LIGHT_CLASSES = (5, 6)
#: Cityscapes labelIds of vehicles (car .. bicycle).
VEHICLE_LABELS = (26, 27, 28, 29, 30, 31, 32, 33)


@dataclass(frozen=True)
class CameraParams:
    """Camera simulation parameters.

    exposure_ev : exposure in stops (gain ``2**ev`` on the linear render).
    iso : noise preset (None = no noise); ``beta1``/``beta2`` override it when both given.
    white_balance : per-channel gains (R, G, B) applied after the noise.
    motion_blur_px : horizontal blur length for vehicles carrying moving lights (0 = off).
    seed : noise seed.
    bloom : glare strength in [0, 1] (0 = off, the default): that fraction of the light above
        ``bloom_threshold`` (after exposure; 1.0 = sensor white) is spread by a glare
        point-spread function (:func:`bloom`), so lamps get halos; energy is conserved.
    bloom_threshold : linear level above which light glares.
    bloom_radius : σ of the PSF's core as a fraction of the image width (the wider lobes are
        3x and 9x it), so a preview at a smaller scale shows the same halo.
    glare : share of the light that the lens (and windscreen) scatter out of the pixel it
        images, in [0, 0.5] (0 = off, the default here; the chain's nights use ``night.glare``).
        Applied to the whole linear image with the long-tailed PSF of :func:`lens_glare`, so it
        conserves energy and leaves broad areas as they are: only sources far above white (lamp
        heads at their visible radiance, :func:`.lights.visible_head_radiance`) get a saturated halo.
    glare_radius : core radius r0 of that PSF as a fraction of the image width (a lens PSF is
        fixed in angle, so a preview at a smaller scale shows the same halo).
    tone_contrast : slope of the camera's global tone curve in log luminance around
        ``tone_pivot`` (:func:`tone_contrast`; 1 = the plain sRGB camera, the default here). The
        chain's nights use ``night.tone_contrast`` (0.73): real night photos hold a narrower range
        between their median and their highlights than a linear sensor with an sRGB curve gives
        (docs/relight.md "The camera of real night photos").
    tone_pivot : linear level (1.0 = sensor white) the tone curve leaves unchanged (the camera's
        mid-grey; the automatic exposure brings the metered scene near it).
    highlight_knee : linear level (1.0 = sensor white) above which the tone curve rolls off to
        white (:func:`highlight_shoulder`; 1.0 = a hard clip, the camera before the shoulder).
        A camera's JPEG tone curve compresses highlights instead of clipping them: real night
        photos have 0.24 % of their pixels above 240/255, a hard clip at 1.0 gave the fixture's
        nights 0.5 % (docs/relight.md "Global statistics").

    The render's own Monte Carlo noise (fireflies, speckle) is removed before the camera by
    :func:`.denoise.denoise_night`, so the camera's physical noise is added to a clean image.
    """

    exposure_ev: float = 0.0
    iso: int | None = 1600
    beta1: float | None = None
    beta2: float | None = None
    white_balance: tuple[float, float, float] = (1.0, 1.0, 1.0)
    motion_blur_px: int = 0
    seed: int = 0
    bloom: float = 0.0
    bloom_threshold: float = 1.0
    bloom_radius: float = 0.002
    glare: float = 0.0
    glare_radius: float = 0.0008
    highlight_knee: float = 0.5
    tone_contrast: float = 1.0
    tone_pivot: float = 0.025

    def __post_init__(self) -> None:
        if not (0.3 <= float(self.tone_contrast) <= 1.5 and float(self.tone_pivot) > 0):
            raise NpsimInputError(f"tone_contrast must be in [0.3, 1.5] (1 = off) and tone_pivot > 0, got "
                                  f"{self.tone_contrast}, {self.tone_pivot}")
        if not 0.0 < float(self.highlight_knee) <= 1.0:
            raise NpsimInputError(f"highlight_knee must be in (0, 1] (1 = hard clip), got {self.highlight_knee}")
        if not 0.0 <= float(self.bloom) <= 1.0:
            raise NpsimInputError(f"bloom must be in [0, 1] (0 = off), got {self.bloom}")
        if not (float(self.bloom_threshold) >= 0 and float(self.bloom_radius) > 0):
            raise NpsimInputError(f"bloom_threshold must be >= 0 and bloom_radius > 0, got "
                                  f"{self.bloom_threshold}, {self.bloom_radius}")

        if not (0.0 <= float(self.glare) <= 0.5 and 0.0 < float(self.glare_radius) <= 0.05):
            raise NpsimInputError(f"glare must be in [0, 0.5] (0 = off) and glare_radius in (0, 0.05] image "
                                  f"widths, got {self.glare}, {self.glare_radius}")

    def betas(self) -> tuple[float, float]:
        if self.beta1 is not None and self.beta2 is not None:
            return float(self.beta1), float(self.beta2)
        if self.iso is None:
            return 0.0, 0.0
        return iso_noise(self.iso)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB encoding of linear values (clipped to [0, 1])."""
    x = np.clip(np.asarray(x, dtype=np.float32), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055).astype(np.float32)


def highlight_shoulder(x: np.ndarray, knee: float = 0.5) -> np.ndarray:
    """A camera tone curve's highlight shoulder on linear values (1.0 = sensor white).

    Identity up to ``knee``; above it ``y = k + (1-k)·(1 - (1-t)^3)`` with
    ``t = (x-k) / (3(1-k))``, which joins the identity with the same slope and reaches white
    with zero slope at ``x = k + 3(1-k)`` (2.0 for the default 0.5); beyond, white. So what
    a hard clip put at white between 1 and 2 keeps its gradation, and lamps (far above) stay
    white. ``knee = 1`` is the hard clip.
    """
    x = np.asarray(x, dtype=np.float32)
    k = float(knee)
    if k >= 1.0:
        return x
    t = np.clip((x - k) / (3.0 * (1.0 - k)), 0.0, 1.0)
    return np.where(x > k, k + (1.0 - k) * (1.0 - (1.0 - t) ** 3), x).astype(np.float32)


def tone_contrast(x: np.ndarray, contrast: float = 1.0, pivot: float = 0.025) -> np.ndarray:
    """A camera's global tone curve on linear RGB: luminance ``Y -> pivot·(Y/pivot)^contrast``,
    colour ratios kept (each pixel's RGB scaled by the same factor, so hues do not shift).

    ``contrast`` < 1 lifts what is darker than ``pivot`` and compresses what is brighter -- the
    range between a night's median and its lit highlights narrows, as in the JPEGs of real night
    cameras (their tone curves and shadow lifting; docs/relight.md "The camera of real night
    photos"). 1 returns the input. Pixels with luminance <= 0 (read noise) are left as they are.
    """
    x = np.asarray(x, dtype=np.float32)
    c = float(contrast)
    if c == 1.0:
        return x
    y = x @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    pos = y > 1e-12
    ratio = np.ones_like(y)
    ratio[pos] = np.power(y[pos] / np.float32(pivot), np.float32(c - 1.0))
    return (x * ratio[..., None]).astype(np.float32)


def add_noise(linear: np.ndarray, beta1: float, beta2: float, rng: np.random.Generator) -> np.ndarray:
    """Heteroscedastic Gaussian noise: ``I + N(0, β1·max(I, 0) + β2)`` per pixel and channel."""
    if beta1 < 0 or beta2 < 0:
        raise NpsimInputError(f"noise parameters must be >= 0, got beta1={beta1}, beta2={beta2}")
    var = beta1 * np.maximum(linear, 0.0) + beta2
    return (linear + rng.standard_normal(linear.shape, dtype=np.float32) * np.sqrt(var)).astype(np.float32)


def moving_vehicle_mask(labels: np.ndarray, light_classes: np.ndarray) -> np.ndarray:
    """Vehicle segments (connected components of vehicle labels) that contain a moving_front/rear light pixel."""
    veh = np.isin(labels, VEHICLE_LABELS).astype(np.uint8)
    if not veh.any():
        return np.zeros(labels.shape, bool)
    n, comp = cv2.connectedComponents(veh, connectivity=4)
    moving = np.isin(light_classes, MOVING_LIGHT_CLASSES)
    hit = np.unique(comp[moving & (veh > 0)])
    hit = hit[hit != 0]
    return np.isin(comp, hit) | moving


def remove_fireflies(linear: np.ndarray, ratio: float = 4.0, floor: float = 0.01,
                     protect: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Replace isolated over-bright pixels (Monte Carlo fireflies) by their 3x3 median.

    A pixel is a firefly when its luminance exceeds ``ratio`` x the 3x3 median luminance
    + ``floor`` and none of its 8 neighbours reaches half of it (isolated: the corners and
    edges of genuinely bright regions are kept); ``protect`` (HxW bool, e.g. the light
    masks) is left alone so that small lamps keep glowing. Returns the image and the
    number of pixels replaced.
    """
    lin = np.ascontiguousarray(linear, dtype=np.float32)
    lum = np.ascontiguousarray(lin @ np.array([0.2126, 0.7152, 0.0722], np.float32))
    med = cv2.medianBlur(lum, 3)
    ring = np.ones((3, 3), np.uint8)
    ring[1, 1] = 0
    neighbour_max = cv2.dilate(lum, ring, borderType=cv2.BORDER_REPLICATE)
    bad = (lum > ratio * med + floor) & (neighbour_max < 0.5 * lum)
    if protect is not None:
        bad &= ~cv2.dilate(protect.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    n = int(bad.sum())
    if n == 0:
        return lin, 0
    return np.where(bad[..., None], cv2.medianBlur(lin, 3), lin).astype(np.float32), n


def motion_blur(linear: np.ndarray, mask: np.ndarray, length: int) -> np.ndarray:
    """Horizontal box blur of ``length`` px inside ``mask`` (grown by half the length so the streak shows)."""
    if length <= 1 or not mask.any():
        return linear
    blurred = cv2.blur(linear, (int(length), 1), borderType=cv2.BORDER_REPLICATE)
    grow = cv2.dilate(mask.astype(np.uint8), np.ones((1, int(length) | 1), np.uint8)) > 0
    return np.where(grow[..., None], blurred, linear).astype(np.float32)


#: Glare PSF: Gaussian lobes of σ = (1, 3, 9) x ``bloom_radius`` x width with these weights (sum 1),
#: a short-tailed stand-in for a lens's veiling glare.
BLOOM_LOBES = ((1.0, 0.6), (3.0, 0.3), (9.0, 0.1))


def bloom(linear: np.ndarray, strength: float, threshold: float = 1.0, radius: float = 0.002) -> np.ndarray:
    """Glare around bright emitters: ``strength`` of the light above ``threshold`` (per channel) is
    replaced by its convolution with the PSF of :data:`BLOOM_LOBES` (σ relative to the width).
    Energy-conserving (the image sum is unchanged up to the border); light below the threshold is
    untouched, so only lamps (and whatever else clips) get halos. ``strength`` 0 returns the input."""
    lin = np.asarray(linear, dtype=np.float32)
    if strength <= 0:
        return lin
    excess = np.maximum(lin - np.float32(threshold), 0.0)
    if not excess.any():
        return lin
    W = lin.shape[1]
    glare = np.zeros_like(excess)
    for k, weight in BLOOM_LOBES:
        sigma = max(0.5, float(radius) * W * k)
        glare += np.float32(weight) * cv2.GaussianBlur(excess, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    return (lin + np.float32(strength) * (glare - excess)).astype(np.float32)


#: Exponent β of the glare PSF's Moffat profile ``(1 + (r/r0)²)^-β``: 1.5 gives wings falling as
#: r^-3, the long tail of a lens's veiling glare (stray light from surfaces, coatings, the windscreen).
GLARE_BETA = 1.5
#: The PSF ends at this many core radii, tapered smoothly to zero (the share of a β = 1.5 kernel
#: beyond R is about r0/R; the kernel is renormalised, so energy stays conserved).
GLARE_EXTENT = 96.0


def glare_kernel(r0_px: float, beta: float = GLARE_BETA, extent: float = GLARE_EXTENT) -> np.ndarray:
    """The glare PSF on a pixel grid: Moffat ``(1 + (r/r0)²)^-β`` for r <= R = ``extent``·r0 (at least
    8 px), tapered by ``(1 - (r/R)²)²``, integrated over each pixel (5 x 5 samples, so a core narrower than a pixel -- a preview
    -- keeps its share of the tail), sum 1."""
    r0 = float(r0_px)
    R = max(8, int(np.ceil(float(extent) * r0)))
    n = 5
    t = (np.arange(-R * n, (R + 1) * n) + 0.5) / n - 0.5          # sub-pixel sample centres
    r2 = t[:, None] ** 2 + t[None, :] ** 2
    # Tapered to zero at R (no visible rim around a lamp's halo where a hard cut would be).
    k = np.where(r2 <= R * R, (1.0 + r2 / r0 ** 2) ** (-float(beta)) * (1.0 - r2 / (R * R)) ** 2, 0.0)
    k = k.reshape(2 * R + 1, n, 2 * R + 1, n).sum(axis=(1, 3))
    return (k / k.sum()).astype(np.float32)


def lens_glare(linear: np.ndarray, fraction: float, radius: float = 0.0008) -> np.ndarray:
    """A lens's glare on a linear HDR image: ``(1 - f)·x + f·(K * x)``, K = :func:`glare_kernel`
    with core radius ``radius`` x width (px), f = ``fraction``.

    A real camera images a point source as a PSF with a long tail (veiling glare: scattering in the
    glass, coatings, barrel and the windscreen; a few per cent of the light). Applied to every pixel
    it conserves energy (the image sum is unchanged: reflected borders) and changes broad areas
    little -- their scattered light is replaced by their neighbours' -- while a lamp head hundreds
    of times above sensor white spreads a halo that itself exceeds white over several times the
    head's area, and lifts the dark surroundings a little (docs/relight.md, "Glare").
    ``fraction`` 0 returns the input. Convolution by FFT (float32, about 1 s at 2048x1024).
    """
    from scipy import fft as sfft

    lin = np.asarray(linear, dtype=np.float32)
    f = float(fraction)
    if f <= 0:
        return lin
    H, W = lin.shape[:2]
    k = glare_kernel(max(0.05, float(radius) * W))
    R = k.shape[0] // 2
    pad = cv2.copyMakeBorder(np.ascontiguousarray(lin), R, R, R, R, cv2.BORDER_REFLECT)
    shape = (sfft.next_fast_len(pad.shape[0] + 2 * R, real=True), sfft.next_fast_len(pad.shape[1] + 2 * R, real=True))
    fk = sfft.rfft2(k, s=shape)
    fx = sfft.rfft2(pad, s=shape, axes=(0, 1))
    conv = sfft.irfft2(fx * fk[..., None], s=shape, axes=(0, 1))
    # Full convolution: output (i, j) sits at (i + R, j + R); the image starts R further in.
    out = conv[2 * R:2 * R + H, 2 * R:2 * R + W]
    return ((1.0 - f) * lin + f * out).astype(np.float32)


#: Linear luminance below which a scene pixel counts as unlit (the night sky's ambient light alone
#: leaves a grey surface around 1e-3): the meter reads only what the lights reveal.
LIT_FLOOR = 2e-3


def auto_exposure(linear: np.ndarray, labels: np.ndarray, exclude: np.ndarray | None = None, *,
                  target: float = 0.1, bounds: tuple[float, float] = (-3.0, 4.0), compensation: float = 0.0,
                  sky_id: int = 23) -> tuple[float, dict]:
    """A camera's automatic exposure for a linear night render: (stops, meter info).

    The meter reads the *lit* scene pixels -- not sky, not ``exclude`` (light sources, the ego
    vehicle), luminance above :data:`LIT_FLOOR` -- and takes their geometric mean (the mean of log
    luminance, so a few lamp pools do not dominate). The exposure brings that value to
    ``target`` (linear, after exposure; 1.0 = sensor white), clipped to ``bounds`` (stops, a
    camera's shutter/gain range), plus ``compensation`` stops. A frame with fewer than 0.1 % lit
    pixels gets ``compensation`` alone. Deterministic: same render, same exposure.

    Returns ``(ev, {"meter": geometric mean before exposure, "metered_fraction": share of pixels
    metered, "exposure_auto_ev": the clipped metered stops})``.
    """
    lin = np.asarray(linear, dtype=np.float32)
    if lin.ndim != 3 or lin.shape[2] != 3:
        raise NpsimInputError(f"auto_exposure: linear image must be HxWx3, got {lin.shape}")
    lo, hi = (float(b) for b in bounds)
    if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi) or not float(target) > 0:
        raise NpsimInputError(f"auto_exposure: bounds must be finite with min <= max and target > 0, got "
                              f"{bounds}, {target}")
    try:
        lit = _lit_pixels(lin, labels, exclude, sky_id)
    except NpsimInputError as e:
        raise NpsimInputError(f"auto_exposure: {e}") from None
    lum = lin @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    frac = float(lit.mean())
    if frac < 1e-3:
        return float(compensation), {"meter": float("nan"), "metered_fraction": frac, "exposure_auto_ev": 0.0}
    meter = float(np.exp(np.mean(np.log(lum[lit].astype(np.float64)))))
    auto = float(np.clip(np.log2(float(target) / meter), lo, hi))
    return auto + float(compensation), {"meter": meter, "metered_fraction": frac, "exposure_auto_ev": auto}


#: Bounds of the automatic white balance's per-channel gains (a camera's AWB range).
AWB_GAIN_BOUNDS = (0.5, 2.0)


def auto_white_balance(linear: np.ndarray, labels: np.ndarray, exclude: np.ndarray | None = None, *,
                       degree: float = 0.3, sky_id: int = 23) -> tuple[tuple[float, float, float], dict]:
    """A camera's automatic white balance for a linear night render: (R, G, B gains, info).

    The illuminant is estimated as the mean colour of the *lit* scene pixels (grey world over the
    pixels :func:`auto_exposure` meters: not sky, not ``exclude``, luminance above
    :data:`LIT_FLOOR`). A full correction would make that mean grey; a camera under warm night
    light corrects only part of the way, so sodium, halogen and tungsten light stays warm in its
    photos (AWB algorithms keep the "atmosphere" of low colour temperatures, and real night
    photos' lit pixels are warm: R/B 1.61 on ACDC nights, docs/relight.md). ``degree`` is that part, in
    log-gain (0 = the render's own D65 white, 1 = full grey world); gains are relative to green
    and bounded by :data:`AWB_GAIN_BOUNDS`. Fewer than 0.1 % lit pixels: no correction.
    Deterministic: same render, same gains.

    Returns ``((gR, gG, gB), {"awb_illuminant": (r/g, 1, b/g) of the lit mean, "awb_gains": ...})``.
    """
    lin = np.asarray(linear, dtype=np.float32)
    if lin.ndim != 3 or lin.shape[2] != 3:
        raise NpsimInputError(f"auto_white_balance: linear image must be HxWx3, got {lin.shape}")
    if not 0.0 <= float(degree) <= 1.0:
        raise NpsimInputError(f"auto_white_balance: degree must be in [0, 1] (0 = off), got {degree}")
    lit = _lit_pixels(lin, labels, exclude, sky_id)
    if float(degree) == 0.0 or lit.mean() < 1e-3:
        return (1.0, 1.0, 1.0), {}
    m = lin[lit].astype(np.float64).mean(0)
    if not (m > 0).all():
        return (1.0, 1.0, 1.0), {}
    g = np.clip((m[1] / m) ** float(degree), *AWB_GAIN_BOUNDS)
    gains = (float(g[0]), 1.0, float(g[2]))
    return gains, {"awb_illuminant": [round(float(v), 4) for v in m / m[1]],
                   "awb_gains": [round(v, 4) for v in gains]}


def _lit_pixels(lin: np.ndarray, labels: np.ndarray, exclude: np.ndarray | None, sky_id: int) -> np.ndarray:
    """The scene pixels a camera's meters read: not sky, not ``exclude``, luminance > :data:`LIT_FLOOR`."""
    lab = np.asarray(labels)
    if lab.shape != lin.shape[:2] or (exclude is not None and np.shape(exclude) != lin.shape[:2]):
        raise NpsimInputError(f"labels {lab.shape} and exclude {np.shape(exclude)} must match the render "
                              f"{lin.shape[:2]}")
    lum = lin @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    lit = (lab != sky_id) & np.isfinite(lum) & (lum > LIT_FLOOR)
    if exclude is not None:
        lit &= ~np.asarray(exclude, bool)
    return lit


def apply_camera(linear: np.ndarray, params: CameraParams = CameraParams(), *, labels: np.ndarray | None = None,
                 light_classes: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Linear render -> (8-bit sRGB image, the noisy white-balanced, tone-mapped linear image before the
    shoulder and clipping).

    Parameters
    ----------
    linear : (H, W, 3) float32 linear RGB (Mitsuba radiance units).
    params : exposure, noise, white balance, motion blur, glare, bloom.
    labels, light_classes : (H, W) maps of the render's size: motion blur needs both.
    """
    lin = np.asarray(linear, dtype=np.float32)
    if lin.ndim != 3 or lin.shape[2] != 3:
        raise NpsimInputError(f"linear image must be HxWx3, got shape {lin.shape}")
    if not np.isfinite(lin).all():
        raise NpsimInputError("linear image contains NaN/inf; the render failed")
    x = lin * np.float32(2.0 ** float(params.exposure_ev))
    if params.motion_blur_px > 1 and labels is not None and light_classes is not None \
            and np.asarray(light_classes).shape == lin.shape[:2]:
        x = motion_blur(x, moving_vehicle_mask(labels, light_classes), int(params.motion_blur_px))
    if params.glare > 0:
        x = lens_glare(x, float(params.glare), float(params.glare_radius))
    if params.bloom > 0:
        x = bloom(x, float(params.bloom), float(params.bloom_threshold), float(params.bloom_radius))
    b1, b2 = params.betas()
    if b1 > 0 or b2 > 0:
        x = add_noise(x, b1, b2, np.random.default_rng(int(params.seed)))
    wb = np.asarray(params.white_balance, dtype=np.float32).reshape(1, 1, 3)
    if wb.size != 3 or not (wb > 0).all():
        raise NpsimInputError(f"white_balance must be three positive gains, got {params.white_balance}")
    x = x * wb
    x = tone_contrast(x, float(params.tone_contrast), float(params.tone_pivot))
    out = np.floor(linear_to_srgb(highlight_shoulder(x, params.highlight_knee)) * 255.0 + 0.5).astype(np.uint8)
    return out, x
