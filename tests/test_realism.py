"""Nights of real-layout frames (SGM stereo, no true albedo) and their realism measures.

The SGM car test renders the same 256x128 fixture frame (OpenCV semi-global matching on a
rendered stereo pair) twice -- from its stereo and from its exact depth, same lights (none but
the ego headlights), seed and spp -- and holds the car's structure ratio of the stereo night
at most 10 % above the exact one's. Before the surface fits (``depth.stereo_surfaces``) it was
23 % above (docs/relight.md).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from npsim_core.realism import REAL_NIGHT, global_stats, night_realism, structure_ratio


def _street_like(h: int = 128, w: int = 256, seed: int = 0):
    rng = np.random.default_rng(seed)
    day = np.clip(120 + 40 * rng.standard_normal((h, w, 3)), 0, 255).astype(np.uint8)
    day = np.asarray(__import__("cv2").GaussianBlur(day, (0, 0), 1.5))
    labels = np.full((h, w), 7, np.uint8)
    labels[: h // 3] = 11
    labels[h // 2:, w // 3: w // 2] = 26
    return day, labels


def test_structure_ratio_is_one_for_the_day_and_grows_with_streaks():
    day, labels = _street_like()
    same = structure_ratio(day, labels, day)
    assert same["whole"] == pytest.approx(1.0)
    assert same["classes"]["road"] == pytest.approx(1.0)
    streaked = day.astype(np.int16)
    streaked[::3] += 60  # row streaks, as SGM geometry lit by a lamp gives
    r = structure_ratio(day, labels, np.clip(streaked, 0, 255).astype(np.uint8))
    assert r["whole"] > 1.3 and r["classes"]["car"] > 1.3


def test_global_stats_match_the_shared_tool_definition():
    img = np.zeros((100, 200, 3), np.uint8)
    img[:, :100] = (200, 100, 50)  # warm lit half
    s = global_stats(img)
    assert s["median"] == pytest.approx(0.0, abs=1) or s["median"] > 0
    assert s["lit_rb"] == pytest.approx(4.0, rel=0.02)  # R/B of the brightest 10 %: 200/50
    assert s["pct_over_240"] == 0.0
    out = night_realism(img, np.full((100, 200), 7, np.uint8), img)
    assert set(out["stats"]) == set(REAL_NIGHT) and out["real_night"] == REAL_NIGHT


@pytest.fixture(scope="module")
def sgm_frame(tmp_path_factory):
    from npsim_core.datasets import open_dataset
    from npsim_core.synthetic.cityscapes import write_cityscapes_fixture

    root = tmp_path_factory.mktemp("sgm")
    truth = tmp_path_factory.mktemp("truth")
    stem = write_cityscapes_fixture(root, frames=1, size=(256, 128), corrupt=0, truth=truth)[0]
    scene = open_dataset(root)[0].load()
    return scene, np.load(truth / f"{stem}_depth.npy")


def _night(scene, params):
    from npsim_core.chain import Chain

    chain = Chain(scene)
    return chain.night_final(chain.compute(params), params).image


def test_a_car_on_sgm_stereo_renders_without_streaks(sgm_frame):
    from npsim_core.camera import normals_from_depth
    from npsim_core.chain import ChainParams

    scene, truth = sgm_frame
    assert scene.depth_stereo is not None and scene.albedo is None and scene.roughness is None
    p = ChainParams().with_sets(["night.final_spp=4", "night.exposure_mode=manual", "night.exposure=1"])
    p = replace(p, lights=replace(p.lights, source="none"))
    stereo = _night(scene, p)
    exact_scene = scene.with_(depth=truth, normals=normals_from_depth(truth, scene.intrinsics), depth_stereo=None)
    exact = _night(exact_scene, replace(p, depth=replace(p.depth, source="files")))
    car_sgm = structure_ratio(scene.image, scene.labels, stereo)["classes"]["car"]
    car_exact = structure_ratio(scene.image, scene.labels, exact)["classes"]["car"]
    assert car_sgm is not None and car_exact is not None
    # Streaks raise the ratio: at most 10 % above the exact night's (before the fits: +23 %). A car
    # fitted smoother than the exact boxes (at 256 px a car is ~30 px wide) may fall below it, but
    # not so far that it is washed out.
    assert 0.8 <= car_sgm / car_exact <= 1.10, (car_sgm, car_exact)


def test_a_plate_is_not_lit():
    """A white number plate on a car (a small bright detail of the day photo) does not become a
    glowing rectangle: its albedo stays within 2x its car's median and it is no emitter."""
    from npsim_core.render.materials import estimate_materials

    h, w = 64, 128
    image = np.full((h, w, 3), 90, np.uint8)
    labels = np.full((h, w), 7, np.uint8)
    labels[20:50, 30:90] = 26
    image[20:50, 30:90] = (60, 20, 20)                # dark red car
    image[40:44, 52:68] = (235, 235, 228)             # its plate
    inst = np.where(labels == 26, 26000, labels).astype(np.int32)
    mats = estimate_materials(image, labels, instances=inst)
    lum = mats.albedo @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    body = np.median(lum[labels == 26])
    assert lum[40:44, 52:68].max() <= 2.0 * body * 1.001
    assert mats.source.startswith("fallback")
