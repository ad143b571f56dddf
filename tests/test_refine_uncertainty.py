"""Dual-reference variance filter (uncertain map U): semantics, numerics, stability."""

import cv2
import numpy as np
import pytest

from npsim_core.errors import NpsimInputError
from npsim_core.refine.uncertainty import UncertaintyParams, region_variance, uncertain_map

ROAD, BUILDING, CAR, SKY = 7, 11, 26, 23


def car_on_road(H=40, W=50, near=5.0, far=20.0):
    lab = np.full((H, W), ROAD, np.uint8)
    d = np.full((H, W), far, np.float32)
    lab[10:20, 12:30] = CAR
    d[10:20, 12:30] = near
    return d, lab


def test_region_variance_matches_brute_force():
    rng = np.random.default_rng(0)
    d = rng.uniform(0.1, 1000, (23, 31)).astype(np.float32)
    d[rng.random(d.shape) < 0.2] = np.nan
    n, m, v = region_variance(d, 8)
    for y, x in [(0, 0), (5, 9), (22, 30), (18, 27)]:
        blk = d[y:y + 8, x:x + 8]
        b = blk[np.isfinite(blk)].astype(np.float64)
        assert n[y, x] == len(b)
        assert m[y, x] == pytest.approx(b.mean(), rel=1e-12)
        assert v[y, x] == pytest.approx(b.var(), rel=1e-9, abs=1e-9)


def test_uncertain_band_around_foreground_edges():
    d, lab = car_on_road()
    U = uncertain_map(d, lab, UncertaintyParams(l=8))
    ys, xs = np.nonzero(U)
    # regions start up to l-1 before the car and cover up to l-1 after it
    assert (ys.min(), ys.max(), xs.min(), xs.max()) == (3, 26, 5, 36)
    assert U[10:20, 12:30].any() and U[5, 5] and not U[4, 4]
    assert not U[30:, :].any() and not U[:, 40:].any()


def test_empty_on_single_class_all_sky_and_no_foreground():
    rng = np.random.default_rng(1)
    d = rng.uniform(1, 100, (30, 40)).astype(np.float32)
    assert not uncertain_map(d, np.full((30, 40), CAR, np.uint8)).any()
    assert not uncertain_map(np.full((30, 40), np.nan, np.float32), np.full((30, 40), SKY, np.uint8)).any()
    lab = np.full((30, 40), ROAD, np.uint8)
    lab[:, 20:] = BUILDING  # a change, but not involving a foreground class
    assert not uncertain_map(d, lab).any()


def test_depth_criterion_and_modes():
    d, lab = car_on_road(near=20.0, far=20.0)  # semantic change but no depth change
    assert not uncertain_map(d, lab).any()
    d, lab = car_on_road(near=100.0, far=100.2)  # 0.2 % step: below tau, above mu_v (abs var ~0.01)
    assert not uncertain_map(d, lab, UncertaintyParams(mode="relative")).any()
    assert uncertain_map(d, lab, UncertaintyParams(mode="absolute")).any()
    d, lab = car_on_road(near=0.10, far=0.13)  # 30 % step at 10 cm: relative flags it, absolute cannot
    assert uncertain_map(d, lab, UncertaintyParams(mode="relative")).any()
    assert not uncertain_map(d, lab, UncertaintyParams(mode="absolute")).any()


def test_float32_naive_variance_fails_where_ours_passes():
    rng = np.random.default_rng(2)
    H, W = 32, 32
    d = (500.0 + rng.normal(0, 0.003, (H, W))).astype(np.float32)  # std 3 mm at 500 m: Var ~1e-5 m²
    d64 = d.astype(np.float64)
    true_var = np.array([[d64[y:y + 8, x:x + 8].var() for x in range(W - 7)] for y in range(H - 7)])
    # naive float32 E[d²] − E[d]² over the same windows
    m = cv2.boxFilter(d, cv2.CV_32F, (8, 8), anchor=(0, 0), normalize=True, borderType=cv2.BORDER_CONSTANT)
    m2 = cv2.boxFilter(d * d, cv2.CV_32F, (8, 8), anchor=(0, 0), normalize=True, borderType=cv2.BORDER_CONSTANT)
    naive = (m2 - m * m)[:H - 7, :W - 7]
    _, _, ours = region_variance(d, 8)
    ours = ours[:H - 7, :W - 7]
    assert np.max(np.abs(naive - true_var)) > 1e-3  # garbage at the thesis's mu_v scale
    assert np.max(np.abs(ours - true_var)) < 1e-9
    # and so U: a car at the same 500 m (no real discontinuity) must not be uncertain at mu_v = 1e-3
    lab = np.full((H, W), ROAD, np.uint8)
    lab[8:20, 8:20] = CAR
    assert not uncertain_map(d, lab, UncertaintyParams(mode="absolute", mu_v=1e-3)).any()
    assert (naive > 1e-3).any() or (naive < 0).any()


def test_extreme_depths_invalid_and_tiny():
    rng = np.random.default_rng(3)
    d = np.where(rng.random((21, 33)) < 0.5, 0.1, 1000.0).astype(np.float32)
    d[0, 0], d[1, 1], d[2, 2], d[3, 3] = np.nan, np.inf, 0.0, -1.0
    lab = rng.choice(np.array([ROAD, CAR], np.uint8), d.shape)
    U = uncertain_map(d.astype(np.float16)[:, ::-1], lab[:, ::-1])
    assert U.dtype == bool and U.shape == d.shape and U.any()
    for shape in [(1, 1), (2, 3), (7, 5)]:
        U = uncertain_map(np.ones(shape, np.float32), np.full(shape, CAR, np.uint8))
        assert U.shape == shape and not U.any()
    d2 = np.array([[1.0, 2.0, 3.0], [1.0, 9.0, 3.0]], np.float32)
    lab2 = np.array([[ROAD, CAR, ROAD], [ROAD, ROAD, ROAD]], np.uint8)
    assert uncertain_map(d2, lab2).all()  # the clipped 2x3 region covers everything


def test_bad_inputs():
    d, lab = car_on_road()
    with pytest.raises(NpsimInputError, match="labels"):
        uncertain_map(d, lab[:5])
    with pytest.raises(NpsimInputError, match="depth"):
        uncertain_map(d[None], lab)
    with pytest.raises(NpsimInputError, match="mode"):
        uncertain_map(d, lab, UncertaintyParams(mode="loose"))
    with pytest.raises(NpsimInputError, match="l must"):
        uncertain_map(d, lab, UncertaintyParams(l=0))


def test_fast_map_matches_brute_force_definition():
    """U from the float32 box sums and uint8 morphology equals the definition evaluated region by region
    (float64 statistics), on a 0.1-1000 m scene with invalid pixels and mixed labels."""
    rng = np.random.default_rng(11)
    H, W, l, tau = 29, 37, 6, 1e-3
    d = np.exp(rng.uniform(np.log(0.1), np.log(1000), (H, W))).astype(np.float32)
    d[rng.random(d.shape) < 0.3] *= np.float32(1.0 + 0.01 * rng.random())  # some near-flat regions
    d[:10, :15] = 50.0 + rng.normal(0, 0.5, (10, 15))                      # low-spread block
    d[rng.random(d.shape) < 0.1] = np.nan
    lab = rng.choice(np.array([ROAD, BUILDING, CAR, SKY], np.uint8), (H, W), p=[0.5, 0.3, 0.1, 0.1])
    lab[15:, 20:] = ROAD
    p = UncertaintyParams(l=l, tau=tau, foreground=frozenset({CAR}))
    U = uncertain_map(d, lab, p)
    expect = np.zeros((H, W), bool)
    for y in range(H):
        for x in range(W):
            blk, hb = d[y:y + l, x:x + l], lab[y:y + l, x:x + l]
            v = blk[np.isfinite(blk)].astype(np.float64)
            if len(v) >= 2 and v.var() > tau * v.mean() ** 2 and len(np.unique(hb)) > 1 and (hb == CAR).any():
                expect[y:y + l, x:x + l] = True
    np.testing.assert_array_equal(U, expect)
    assert 0.05 < U.mean() < 0.95


# --------------------------------------------------------------------------- the input's confidence
def test_low_confidence_boundary_is_uncertain_even_without_a_depth_step():
    """A guessed placement (the pop-up prior's crown or facade at a depth its hidden contact allows)
    may show no step against its neighbours where the scene has one: a region holding a pixel of
    confidence below ``confidence_below`` counts as spread, so a foreground boundary there is in U.
    The guessed area away from foreground boundaries is not (the semantic condition still holds)."""
    d, lab = car_on_road()
    d[:] = 12.0  # the car placed at the road's depth: no spread anywhere
    assert not uncertain_map(d, lab).any()
    conf = np.ones(d.shape, np.float32)
    conf[8:22, 10:32] = 0.3  # the car and a rim: guessed
    conf[30:, :] = 0.3       # guessed road far from any foreground
    conf[0, 0] = np.nan      # (NaN: no confidence there)
    U = uncertain_map(d, lab, confidence=conf)
    ys, xs = np.nonzero(U)
    assert (ys.min(), ys.max(), xs.min(), xs.max()) == (3, 26, 5, 36)  # the band around the car, as with a step
    assert not U[30:].any()
    # sure everywhere, the confidence off, or no confidence at all: the thesis's U
    assert not uncertain_map(d, lab, confidence=np.ones(d.shape, np.float32)).any()
    assert not uncertain_map(d, lab, UncertaintyParams(confidence_below=0.0), confidence=conf).any()
    with pytest.raises(NpsimInputError, match="confidence_below"):
        uncertain_map(d, lab, UncertaintyParams(confidence_below=1.5), confidence=conf)
    with pytest.raises(NpsimInputError, match="confidence map has shape"):
        uncertain_map(d, lab, confidence=conf[:-1])


def test_the_chain_reads_the_priors_confidence_and_not_for_other_sources():
    """The geometry stage carries the pop-up prior's confidence (NaN where the depth is invalid), says
    the share of guessed pixels in the depth source sentence and the provenance (the manifest's), and
    the uncertain stage reads it: U grows by the guessed foreground boundaries. A frame with its own
    depth (files; stereo alike) has no confidence and keeps the thesis's U bit for bit (128x64: at
    64x32 the thesis's U already covers three quarters of the frame)."""
    from dataclasses import replace

    from npsim_core.chain.chain import Chain
    from npsim_core.chain.params import ChainParams
    from npsim_core.synthetic import street_scene

    street = street_scene(128, 64)

    p = ChainParams()
    prior = replace(p, depth=replace(p.depth, source="prior"))
    off = replace(prior, uncertainty=replace(p.uncertainty, confidence_below=0.0))
    ch = Chain(street)
    geo = ch.engine.run(("geometry",), prior).results["geometry"]
    assert geo.confidence is not None and geo.confidence.shape == street.labels.shape
    assert np.array_equal(np.isfinite(geo.confidence), np.isfinite(geo.scene.depth))
    share = float(np.mean(geo.confidence[np.isfinite(geo.confidence)] < 0.5))
    assert 0.05 < share < 0.6
    assert "guessed (confidence < 0.5)" in ch.compute(prior, until="uncertain").depth_source
    assert geo.scene.provenance["confidence"]["low_share"] == pytest.approx(share, abs=1e-4)
    U_on = ch.compute(prior, until="uncertain").uncertain
    U_off = ch.compute(off, until="uncertain").uncertain
    assert (U_on >= U_off).all() and U_on.sum() > U_off.sum()
    files = Chain(street.with_(depth=geo.scene.depth, normals=geo.scene.normals))
    fp = replace(p, depth=replace(p.depth, source="files"))
    geo_f = files.engine.run(("geometry",), fp).results["geometry"]
    assert geo_f.confidence is None and "confidence" not in geo_f.scene.provenance
    assert np.array_equal(files.compute(fp, until="uncertain").uncertain, U_off)
