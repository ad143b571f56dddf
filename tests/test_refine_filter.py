"""Dual-reference cross-bilateral filter: exact reference, fast version, stability."""

import numpy as np
import pytest

from npsim_core.errors import NpsimInputError
from npsim_core.refine.bilateral import FilterParams, cross_bilateral, cross_bilateral_reference

SMALL = FilterParams(sigma_s=3.0, scale_width=0)  # 9x9... 19x19 window keeps the brute force quick


def blocks_scene(H=40, W=64, seed=0):
    """Ramp background, a few boxes of other classes/colours/depths, noisy image, sky rows invalid."""
    rng = np.random.default_rng(seed)
    v = np.mgrid[0:H, 0:W][0].astype(np.float32)
    d = 5.0 + 30.0 * v / H
    lab = np.full((H, W), 7, np.uint8)
    img = np.full((H, W, 3), 0.45, np.float32)
    for _ in range(5):
        y0, x0 = rng.integers(0, H - 8), rng.integers(0, W - 8)
        hh, ww = rng.integers(4, H // 2), rng.integers(4, W // 3)
        d[y0:y0 + hh, x0:x0 + ww] = rng.uniform(3, 30)
        lab[y0:y0 + hh, x0:x0 + ww] = rng.choice([26, 11, 17, 20])
        img[y0:y0 + hh, x0:x0 + ww] = rng.uniform(0, 1, 3)
    img = np.clip(img + rng.normal(0, 0.03, img.shape), 0, 1)
    d = (d * (1 + rng.normal(0, 0.01, d.shape))).astype(np.float32)
    d[:3] = np.nan
    lab[:3] = 23
    return d, (img * 255).round().astype(np.uint8), lab


@pytest.mark.parametrize("fn", [cross_bilateral, cross_bilateral_reference])
def test_constant_depth_is_fixed_point(fn):
    _, img, lab = blocks_scene(seed=1)
    d = np.full(lab.shape, 7.25, np.float32)
    out = fn(d, img, lab, SMALL)
    np.testing.assert_allclose(out, 7.25, rtol=1e-5)


def test_fast_matches_reference_within_bound():
    d, img, lab = blocks_scene()
    ref = cross_bilateral_reference(d, img, lab, SMALL)
    fast = cross_bilateral(d, img, lab, SMALL)
    valid = np.isfinite(d)
    assert np.array_equal(np.isfinite(ref), valid) and np.array_equal(np.isfinite(fast), valid)
    rng = np.nanmax(d) - np.nanmin(d)
    mae = np.nanmean(np.abs(fast - ref)) / rng
    assert mae < 0.01
    # the filter does something: the reference moves depth far more than the approximation's error
    assert np.nanmean(np.abs(ref - d)) / rng > 3 * mae


def test_semantic_term_is_exact():
    d, img, lab = blocks_scene(seed=2)
    p = FilterParams(mu=0.0, sigma_s=3.0, scale_width=0)
    np.testing.assert_allclose(cross_bilateral(d, img, lab, p), cross_bilateral_reference(d, img, lab, p),
                               rtol=2e-5, equal_nan=True)


def test_same_class_only_semantic_filter_does_not_mix_classes():
    # mu = 0: pixels of a class only average pixels of the same class
    H, W = 20, 30
    lab = np.full((H, W), 7, np.uint8)
    lab[:, 15:] = 26
    d = np.where(lab == 7, 10.0, 40.0).astype(np.float32)
    img = np.full((H, W, 3), 128, np.uint8)
    out = cross_bilateral(d, img, lab, FilterParams(mu=0.0, sigma_s=4, scale_width=0))
    np.testing.assert_allclose(out, d, rtol=1e-6)


def test_extreme_depths_and_invalid_pixels():
    rng = np.random.default_rng(3)
    H, W = 33, 47  # odd sizes
    d = np.where(rng.random((H, W)) < 0.5, 0.1, 1000.0).astype(np.float32)
    d[5, 5], d[6, 6], d[7, 7], d[8, 8] = np.nan, np.inf, 0.0, -3.0
    img = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    lab = rng.choice(np.array([7, 26, 23], np.uint8), (H, W))
    for fn in (cross_bilateral, cross_bilateral_reference):
        out = fn(d, img, lab, SMALL)
        valid = np.isfinite(d) & (d > 0)
        assert np.isfinite(out[valid]).all()
        assert np.isnan(out[~valid]).all()
        # a normalised average never leaves the input's range
        assert out[valid].min() >= 0.1 * (1 - 1e-5) and out[valid].max() <= 1000.0 * (1 + 1e-5)


@pytest.mark.parametrize("shape", [(1, 1), (2, 3), (5, 7)])
def test_tiny_images(shape):
    d = np.arange(1, np.prod(shape) + 1, dtype=np.float32).reshape(shape)
    img = np.zeros((*shape, 3), np.uint8)
    lab = np.full(shape, 26, np.uint8)
    ref = cross_bilateral_reference(d, img, lab)
    fast = cross_bilateral(d, img, lab)
    assert np.isfinite(fast).all()
    np.testing.assert_allclose(fast, ref, rtol=0.02)


def test_all_invalid_and_uniform_and_single_class():
    img = np.full((16, 16, 3), 200, np.uint8)
    lab = np.full((16, 16), 23, np.uint8)
    assert np.isnan(cross_bilateral(np.full((16, 16), np.nan, np.float32), img, lab)).all()
    d = np.linspace(1, 50, 256, dtype=np.float32).reshape(16, 16)
    out = cross_bilateral(d, img, lab)
    ref = cross_bilateral_reference(d, img, lab)
    np.testing.assert_allclose(out, ref, rtol=5e-3)


def test_float16_noncontiguous_and_float_image():
    d, img, lab = blocks_scene(seed=4)
    ref = cross_bilateral(d, img, lab, SMALL)
    d16 = np.asfortranarray(d.astype(np.float16))
    img_f = (img.astype(np.float64) / 255.0)[:, ::-1][:, ::-1]  # non-contiguous float view
    out = cross_bilateral(d16, img_f, np.asfortranarray(lab), SMALL)
    valid = np.isfinite(d)
    assert np.isfinite(out[valid]).all()
    assert np.nanmax(np.abs(out - ref) / ref) < 2e-3  # float16 rounding of the input only


def test_bad_inputs_raise_clear_errors():
    d, img, lab = blocks_scene()
    with pytest.raises(NpsimInputError, match="depth"):
        cross_bilateral(d[None], img, lab)
    with pytest.raises(NpsimInputError, match="labels"):
        cross_bilateral(d, img, lab[:-1])
    with pytest.raises(NpsimInputError, match="image"):
        cross_bilateral(d, img[..., :2], lab)
    with pytest.raises(NpsimInputError, match="labels"):
        cross_bilateral(d, img, lab.astype(np.float32))
    with pytest.raises(NpsimInputError, match="sigma_s"):
        cross_bilateral(d, img, lab, FilterParams(sigma_s=0))
    with pytest.raises(NpsimInputError, match="depth"):
        cross_bilateral(d.astype(complex), img, lab)


def test_inverse_domain_is_exact_on_a_ground_plane_rows():
    # depth of a ground plane: 1/d linear in the row -> averaging 1/d along rows is unbiased
    H, W = 40, 30
    v = np.arange(H, dtype=np.float64)[:, None] + 5.0
    d = np.broadcast_to(100.0 / v, (H, W)).astype(np.float32)
    img = np.full((H, W, 3), 90, np.uint8)
    lab = np.full((H, W), 7, np.uint8)
    p_inv = FilterParams(sigma_s=3.0, domain="inverse", scale_width=0)
    out_inv = cross_bilateral_reference(d, img, lab, p_inv)
    inner = (slice(10, 30), slice(None))
    np.testing.assert_allclose(out_inv[inner], d[inner], rtol=1e-5)
    out_dep = cross_bilateral_reference(d, img, lab, FilterParams(sigma_s=3.0, domain="depth", scale_width=0))
    assert np.all(out_dep[inner] > d[inner])  # Jensen: averaging the convex depth biases it up
    np.testing.assert_allclose(cross_bilateral(d, img, lab, p_inv), out_inv, rtol=1e-4)
    with pytest.raises(NpsimInputError, match="domain"):
        cross_bilateral(d, img, lab, FilterParams(domain="log"))


def test_fast_filter_is_deterministic_across_calls_and_threads():
    """The guide colours come from cv2.kmeans seeded per call: OpenCV's (per-thread) RNG state never leaks in."""
    from concurrent.futures import ThreadPoolExecutor

    import cv2

    d, img, lab = blocks_scene(seed=5)
    first = cross_bilateral(d, img, lab, SMALL)
    cv2.setRNGSeed(12345)
    cv2.randu(np.empty(64, np.float32), 0.0, 1.0)  # someone else used OpenCV's RNG in between
    np.testing.assert_array_equal(cross_bilateral(d, img, lab, SMALL), first)
    with ThreadPoolExecutor(2) as ex:
        for out in ex.map(lambda _: cross_bilateral(d, img, lab, SMALL), range(4)):
            np.testing.assert_array_equal(out, first)


def test_guide_colour_clusters():
    from npsim_core.refine.bilateral import _kmeans

    rng = np.random.default_rng(0)
    blobs = np.array([[20, 0, 0], [50, 40, -30], [80, -20, 60]], np.float32)
    x = np.concatenate([b + rng.normal(0, 1.0, (300, 3)) for b in blobs]).astype(np.float32)
    C = _kmeans(x, 3)
    assert C.shape == (3, 3) and C.dtype == np.float32
    np.testing.assert_allclose(C[np.argsort(C[:, 0])], blobs, atol=0.5)  # one centre per blob
    few = np.repeat(blobs[:2], 10, axis=0)  # fewer distinct colours than clusters: returned as they are
    np.testing.assert_array_equal(_kmeans(few, 16), np.unique(few, axis=0))
