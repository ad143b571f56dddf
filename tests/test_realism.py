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


def _night(scene, params):
    from npsim_core.chain import Chain

    chain = Chain(scene)
    return chain.night_final(chain.compute(params), params).image


def test_a_car_on_sgm_stereo_renders_without_streaks(sgm_frame):
    from npsim_core.camera import normals_from_depth
    from npsim_core.chain import Chain, ChainParams

    scene, truth = sgm_frame
    assert scene.depth_stereo is not None and scene.albedo is None and scene.roughness is None
    p = ChainParams().with_sets(["night.final_spp=4", "night.exposure_mode=manual", "night.exposure=1"])
    p = replace(p, lights=replace(p.lights, source="none"))
    chain = Chain(scene)
    night = chain.night_final(chain.compute(p), p)
    stereo = night.image
    assert set(night.realism["stats"]) == set(REAL_NIGHT)          # every night carries its realism
    assert night.realism["structure"]["whole"] > 0
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


def test_surface_fit_recovers_a_plane_under_sgm_like_errors():
    """A wall and the ground under row streaks, speckle islands and a foreground-fattened edge:
    the fit recovers both planes and their normals (the raw stereo is off by up to 30 %)."""
    from npsim_core.camera import Intrinsics, backproject, normals_from_depth
    from npsim_core.geometry.surfaces import fit_surfaces

    W, H = 256, 128
    intr = Intrinsics.cityscapes(W, H)
    rays = backproject(np.ones((H, W), np.float32), intr)
    # Ground 1.22 m below the camera (y down), a wall 6 m to the left (x = -6).
    with np.errstate(divide="ignore", invalid="ignore"):
        z_ground = np.where(rays[..., 1] > 1e-3, 1.22 / rays[..., 1], np.inf)
        z_wall = np.where(rays[..., 0] < -1e-3, -6.0 / rays[..., 0], np.inf)
    truth = np.minimum(z_ground, z_wall).astype(np.float32)
    labels = np.where(z_wall < z_ground, 11, 7).astype(np.uint8)
    labels[~np.isfinite(truth)] = 23
    rng = np.random.default_rng(0)
    noisy = truth * (1 + 0.04 * rng.standard_normal((H, 1)))          # whole rows off (streaks)
    noisy = noisy * (1 + 0.01 * rng.standard_normal((H, W)))
    for _ in range(12):                                                # speckle islands
        y, x = rng.integers(40, H - 5), rng.integers(5, W - 5)
        noisy[y:y + 3, x:x + 3] *= 0.7
    edge = np.argmax(labels == 7, axis=1)                              # the wall's ground contact
    for v in range(H):                                                 # wall depth bled into the ground
        noisy[v, edge[v]:edge[v] + 3] = noisy[v, max(edge[v] - 1, 0)]
    valid = np.isfinite(truth) & (truth < 80)
    depth, normals, info = fit_surfaces(noisy, valid, np.where(valid, noisy, np.nan).astype(np.float32), labels,
                                        intr)
    inner = valid & (cv2_erode(labels == 7) | cv2_erode(labels == 11)) & (truth < 40)
    raw_err = np.abs(noisy[inner] - truth[inner]) / truth[inner]
    err = np.abs(depth - truth)[inner] / truth[inner]
    assert raw_err.max() > 0.2 and np.median(err) < 0.01 and np.percentile(err, 99) < 0.03
    n_true = normals_from_depth(truth, intr)
    ang = np.degrees(np.arccos(np.clip((normals * n_true).sum(-1), -1, 1)))[inner]
    assert np.median(ang) < 2.0
    assert info["speckle_fraction"] > 0


def cv2_erode(m: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.erode(m.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)


def test_gloss_only_where_the_geometry_is_smooth():
    from npsim_core.render.materials import estimate_materials

    h, w = 32, 64
    labels = np.full((h, w), 26, np.uint8)
    flat = np.zeros((h, w, 3), np.float32)
    flat[..., 2] = -1.0
    rng = np.random.default_rng(1)
    bumpy = flat + 0.5 * rng.standard_normal((h, w, 3)).astype(np.float32)
    bumpy /= np.linalg.norm(bumpy, axis=-1, keepdims=True)
    image = np.full((h, w, 3), 120, np.uint8)
    smooth = estimate_materials(image, labels, normals=flat).roughness
    rough = estimate_materials(image, labels, normals=bumpy).roughness
    assert np.allclose(smooth, 0.25) and rough.mean() > 0.8   # paint stays glossy only when smooth


def test_camera_shoulder_keeps_highlights_below_white_and_lamps_white():
    """A hard clip at sensor white put every lit surface between 1x and 2x white at 255
    (0.5 % of the fixture's night above 240 against real nights' 0.24 %); the camera's
    highlight shoulder keeps their gradation, leaves the shadows and mid-tones bit-identical
    and still puts lamps (far above white) at 255."""
    from npsim_core.render.camera_post import CameraParams, apply_camera, linear_to_srgb

    ramp = np.linspace(0.0, 4.0, 401, dtype=np.float32)
    lin = np.repeat(ramp[None, :, None], 3, axis=2)
    srgb, _ = apply_camera(lin, CameraParams(iso=None))
    g = srgb[0, :, 0].astype(int)
    over = (ramp >= 1.0) & (ramp <= 1.3)
    assert (g[over] < 250).all() and (np.diff(g[(ramp >= 0.9) & (ramp <= 1.5)]) >= 0).all()
    assert len(np.unique(g[over])) > 5                                # gradation, not one flat white
    assert (g[ramp >= 2.0] == 255).all()                              # lamps stay white
    low = ramp <= 0.5
    np.testing.assert_array_equal(g[low], np.floor(linear_to_srgb(ramp[low]) * 255 + 0.5).astype(int))
    hard, _ = apply_camera(lin, CameraParams(iso=None, highlight_knee=1.0))
    assert (hard[0, over, 0] == 255).all()                            # the old camera clipped them


def test_sun_from_shadows_of_buildings_cut_by_the_frame_top(sgm_frame):
    """The street's sun is high (~49°); the façades casting the ground's shadows go on above the
    frame, so shadow rays that left the frame found nothing and the estimate picked a low sun
    (17° elevation, 37° off the true direction, at every size). With what continues above the
    frame's top edge (``above_frame_depth``) it is within 20°, and the sun/sky ratio near the
    street's ~2.6 (was 7.5)."""
    from npsim_core.camera import normals_from_depth
    from npsim_core.render.materials import estimate_daylight
    from npsim_core.synthetic.primitives import CameraPose
    from npsim_core.synthetic.render import sun_direction_camera
    from npsim_core.synthetic.street import build_street

    scene, truth = sgm_frame
    true = -sun_direction_camera(CameraPose(scene.camera_height, scene.camera_pitch), *build_street(0).sun)
    light = estimate_daylight(scene.image, scene.labels, normals_from_depth(truth, scene.intrinsics), truth,
                              scene.intrinsics, float(scene.camera_pitch))
    s = np.asarray(light.sun) / np.linalg.norm(light.sun)
    angle = np.degrees(np.arccos(np.clip(s @ (true / np.linalg.norm(true)), -1, 1)))
    assert angle < 20, (light, true)
    assert 1.5 < light.ratio < 4.0


def test_a_far_lamp_pole_keeps_its_stereo_depth():
    """A pole whose stereo lies beyond the stereo's range (a lamp at a street's end, 100 m)
    took the hole filling's depth (here 55 m: the lamp then lit the near road white, 2048x1024
    fixture); it keeps its own stereo, and a thin pole near range keeps all of it, edges
    included, rather than the few fattened pixels left after edge trimming."""
    from npsim_core.camera import Intrinsics
    from npsim_core.geometry.surfaces import fit_surfaces

    W, H = 256, 128
    intr = Intrinsics.cityscapes(W, H)
    labels = np.full((H, W), 11, np.uint8)
    stereo = np.full((H, W), 60.0)
    labels[20:70, 100:103] = 17                                        # a pole 3 px wide at 100 m
    stereo[20:70, 100:103] = 100.0
    labels[20:70, 200:204] = 17                                        # a pole 4 px wide at 40 m,
    stereo[20:70, 200:204] = 40.0                                      # its inner columns fattened
    stereo[20:70, 201:203] = 25.0
    valid = stereo <= 80.0
    filled = np.where(valid, stereo, 55.0).astype(np.float32)
    depth, _, _ = fit_surfaces(stereo, valid, filled, labels, intr)
    assert abs(float(np.median(depth[20:70, 100:103])) - 100.0) < 1.0
    assert float(np.median(depth[20:70, 200:204])) > 30.0


def _headlit_night(h: int = 64, w: int = 128):
    """A linear night of grey surfaces (albedo 0.3) under the default light table's lamps: the left
    half lit by a car's headlamps (class 5), the right half by the ego low beams, falling off
    toward the top; the top rows sky; plus the sky's faint light everywhere."""
    from npsim_core.render.lights import load_light_table

    t = load_light_table()
    head = np.array([t.spec(5).chromaticity[0], 1.0, t.spec(5).chromaticity[1]], np.float32)
    rg, bg = t.ego_chromaticity()
    ego = np.array([rg, 1.0, bg], np.float32)
    level = np.linspace(0.002, 0.25, h, dtype=np.float32)[:, None, None]      # brighter toward the camera
    lin = np.concatenate([np.repeat(level * head, w // 2, 1), np.repeat(level * ego, w // 2, 1)], axis=1)
    lin = 0.3 * (lin + np.asarray(t.sky_radiance, np.float32))
    labels = np.full((h, w), 7, np.uint8)
    labels[:6] = 23
    lin[:6] = np.asarray(t.sky_radiance, np.float32)
    return lin.astype(np.float32), labels


def test_a_night_lit_by_halogen_headlamps_is_warm_through_the_camera():
    """The brightest 10 % of real night photos are warm (R/B 1.61, sodium and halogen light); the
    light table's headlamps (~4500 K) and ego low beams (5000 K) rendered headlit surfaces
    neutral white (R/B 1.31 here; the fixture's nights 1.30). At halogen colour and through the
    chain's camera (automatic white balance that corrects warm light only partly) the lit R/B
    is warm but not orange."""
    from npsim_core.chain import ChainParams
    from npsim_core.render.camera_post import CameraParams, apply_camera, auto_white_balance

    lin, labels = _headlit_night()
    n = ChainParams().night
    wb, info = auto_white_balance(lin, labels, degree=n.white_balance)
    srgb, _ = apply_camera(lin, CameraParams(iso=None, white_balance=wb, tone_contrast=n.tone_contrast))
    rb = global_stats(srgb)["lit_rb"]
    assert 1.4 <= rb <= 1.9, (rb, info)
    assert wb[0] < 1.0 < wb[2]                                   # the white balance cools a warm night a little


def test_auto_white_balance_corrects_only_part_of_the_way_and_reads_lit_pixels():
    from npsim_core.render.camera_post import auto_white_balance

    lin = np.zeros((40, 60, 3), np.float32)
    lin[10:] = np.array([0.16, 0.1, 0.0625], np.float32)            # warm-lit scene, r/g 1.6, b/g 0.625
    labels = np.full((40, 60), 7, np.uint8)
    labels[:10] = 23
    lin[:10] = (0.0, 0.0, 5.0)                                       # a blue sky: not metered
    exclude = np.zeros((40, 60), bool)
    exclude[30:, :5] = True
    lin[30:, :5] = (0.0, 5.0, 0.0)                                   # a green lamp: excluded
    full, _ = auto_white_balance(lin, labels, exclude, degree=1.0)
    assert full == pytest.approx((0.625, 1.0, 1.6), rel=1e-4)       # grey world over the lit pixels only
    part, info = auto_white_balance(lin, labels, exclude, degree=0.25)
    assert part == pytest.approx((0.625 ** 0.25, 1.0, 1.6 ** 0.25), rel=1e-4)
    assert info["awb_illuminant"] == pytest.approx([1.6, 1.0, 0.625], rel=1e-3)
    lin[10:, :, 2] = 0.01                                            # sodium-like: the gains stay in a camera's range
    assert auto_white_balance(lin, labels, exclude, degree=1.0)[0][2] == pytest.approx(2.0)
    assert auto_white_balance(lin, labels, exclude, degree=0.0)[0] == (1.0, 1.0, 1.0)
    assert auto_white_balance(np.zeros_like(lin), labels)[0] == (1.0, 1.0, 1.0)   # nothing lit


def test_tone_contrast_narrows_the_range_around_mid_grey_and_keeps_hue():
    """Real night photos hold their highlights closer to their median than a linear sensor with
    the sRGB curve (fixture nights: p99/median 5.8 against real 4.7); the camera's tone curve
    (slope < 1 in log luminance around its mid-grey) lifts the dark and compresses the bright,
    leaves mid-grey and colour ratios as they are; 1 is the identity (the neutral camera)."""
    from npsim_core.render.camera_post import CameraParams, apply_camera, tone_contrast

    y = np.array([0.0025, 0.025, 0.25], np.float32)
    w = np.array([0.2126, 0.7152, 0.0722], np.float32)
    warm = np.array([2.0, 1.0, 0.5], np.float32)
    rgb = (y[:, None] * warm / (warm @ w))[None]                         # luminance y, r/b 4
    out = tone_contrast(rgb, 0.9, 0.025)[0]
    ratio = (out @ w) / (rgb[0] @ w)
    assert ratio[0] > 1.2 and ratio[1] == pytest.approx(1.0) and ratio[2] < 0.8
    np.testing.assert_allclose(out[:, 0] / out[:, 2], 4.0, rtol=1e-5)       # hue kept
    np.testing.assert_array_equal(tone_contrast(rgb, 1.0), rgb)
    a, _ = apply_camera(np.repeat(rgb, 4, 0), CameraParams(iso=None, tone_contrast=0.9))
    b, _ = apply_camera(np.repeat(rgb, 4, 0), CameraParams(iso=None))
    assert a[0, 0].mean() > b[0, 0].mean() and a[0, 2].mean() < b[0, 2].mean()
    with pytest.raises(Exception, match="tone_contrast"):
        CameraParams(tone_contrast=0.0)


def test_the_night_sky_glows_warm_not_blue():
    """City sky glow is the city's sodium, halogen and warm-LED light scattered back: brownish in
    night photos (docs/relight.md); the table's sky was bluish (b/r 2)."""
    from npsim_core.render.lights import load_light_table

    r, g, b = load_light_table().sky_radiance
    assert r > g > b


def test_a_delit_facade_in_the_shade_keeps_its_colour_not_the_sky_blue():
    """A façade in the shade is lit by the blue sky alone; divided by a grey shading its de-lit
    albedo kept that blue (the fixture's de-lit façades came out grey-blue and pale: chroma error
    0.21 against the true albedo, 0.05 now). The shading is coloured by the sky seen in the photo
    and the sun found from lit against shadowed ground (``day_light_colours``)."""
    from npsim_core.camera import Intrinsics
    from npsim_core.render.lights import srgb_to_linear
    from npsim_core.render.materials import DayLight, delit_albedo

    H, W = 64, 128
    sky_c = np.array([0.75, 1.0, 1.4], np.float32)
    sun_c = np.array([1.1, 1.0, 0.85], np.float32)
    wall, asphalt = np.array([0.5, 0.4, 0.28], np.float32), np.array([0.12, 0.12, 0.12], np.float32)
    labels = np.full((H, W), 7, np.uint8)
    labels[:12], labels[12:34] = 23, 11
    normals = np.zeros((H, W, 3), np.float32)
    normals[:34] = (0.0, 0.0, -1.0)
    normals[34:] = (0.0, -1.0, 0.0)
    depth = np.full((H, W), 12.0, np.float32)
    depth[:12] = np.nan
    lin = np.zeros((H, W, 3), np.float32)
    lin[:12] = 0.3 * sky_c
    lin[12:34] = 0.1 * wall * sky_c                                  # façade facing away from the sun
    lin[34:] = 0.1 * asphalt * sky_c                                 # road: shade on the left,
    lin[34:, W // 2:] += 0.25 * asphalt * sun_c                       # sun on the right
    image = np.round(np.clip(np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055), 0, 1)
                     * 255).astype(np.uint8)
    assert np.allclose(srgb_to_linear(image[20, 20] / 255.0), lin[20, 20], rtol=0.05)
    light = DayLight(sun=(0.0, -0.8, 0.6), ratio=2.5, score=0.5, shadow_fraction=0.5)
    alb, _ = delit_albedo(image, labels, normals, depth, Intrinsics.cityscapes(W, H), 0.0, light=light)
    a = np.median(alb[16:30, 10:W - 10].reshape(-1, 3), axis=0)
    assert a[0] / a[1] == pytest.approx(wall[0] / wall[1], rel=0.08)
    assert a[2] / a[1] == pytest.approx(wall[2] / wall[1], rel=0.08)


def test_a_delit_car_is_one_paint_on_its_sunlit_and_its_shaded_face():
    """Vehicles kept the prior fallback when de-lit: a car's sunlit side stayed ~2x brighter than
    its shaded rear, as in the day photo. Divided by the day's shading per pixel over its fitted
    surface (``MaterialParams.delit_vehicles``), both faces get the one paint they have (the
    fixture: car albedo error 0.43 -> 0.32 at 1024x512, docs/relight.md "Cars per pixel")."""
    from npsim_core.camera import Intrinsics
    from npsim_core.render.materials import DayLight, delit_albedo

    H, W = 64, 128
    sky_c = np.array([0.83, 1.0, 1.35], np.float32)
    labels = np.full((H, W), 7, np.uint8)
    labels[:10] = 23
    labels[30:50, 30:90] = 26
    normals = np.zeros((H, W, 3), np.float32)
    normals[...] = (0.0, -1.0, 0.0)
    normals[30:50, 30:60] = (-1.0, 0.0, 0.0)                        # the car's side, facing the sun (left)
    normals[30:50, 60:90] = (0.0, 0.0, -1.0)                        # its rear, facing the camera
    depth = np.full((H, W), 10.0, np.float32)
    depth[:10] = np.nan
    sun = np.array([-0.8, -0.6, 0.0])
    paint = np.array([0.4, 0.1, 0.1], np.float32)
    cosv = np.maximum(normals @ sun.astype(np.float32), 0.0)[..., None]
    up = np.array([0.0, -1.0, 0.0], np.float32)
    cu = (normals @ up)[..., None]
    amb = 0.5 * (1 + cu) + 0.3 * 0.5 * (1 - cu)
    lin = 0.05 * (2.5 * cosv + amb * sky_c) * np.where(labels[..., None] == 26, paint, 0.12)
    lin[:10] = 0.2 * sky_c
    image = np.round(np.clip(np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055), 0, 1)
                     * 255).astype(np.uint8)
    y = (lin @ np.array([0.2126, 0.7152, 0.0722], np.float32))
    assert np.median(y[32:48, 32:58]) > 2 * np.median(y[32:48, 62:88])   # the photo: side 2x the rear
    light = DayLight(sun=tuple(sun), ratio=2.5, score=0.5, shadow_fraction=0.0)
    alb, _ = delit_albedo(image, labels, normals, depth, Intrinsics.cityscapes(W, H), 0.0, light=light)
    a = alb @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    assert np.median(a[32:48, 32:58]) / np.median(a[32:48, 62:88]) == pytest.approx(1.0, abs=0.15)


def test_lens_glare_saturates_a_halo_larger_than_the_lamp_and_conserves_energy():
    """A lamp head far above sensor white saturated only its own pixels: the fixture's heads
    cover 0.08 % of the frame against real nights' 0.24 % above 240. The lens's glare PSF
    spreads a share of *all* light: around the head a halo above white several times its area,
    the image's energy unchanged, a broad lit area and a dim lit window (no halo) as they were."""
    from npsim_core.render.camera_post import glare_kernel, lens_glare

    lin = np.full((128, 256, 3), 0.004, np.float32)               # dark street
    lin[80:120, 20:100] = 0.3                                    # a broad lit area
    lin[20:24, 180:184] = 2000.0                                 # a lamp head (16 px) at its radiance
    lin[60:68, 180:188] = 0.5                                    # a lit window, below white
    out = lens_glare(lin, 0.03, 0.01)
    assert out.sum() == pytest.approx(lin.sum(), rel=1e-4)       # energy conserved
    head = (lin[..., 1] > 1).sum()
    assert (out[..., 1] > 1).sum() >= 3 * head                   # saturated core larger than the emitter
    assert out[20:24, 180:184, 1].min() > 1000                   # the head stays far above white
    np.testing.assert_allclose(out[90:110, 40:80], lin[90:110, 40:80], rtol=0.02)  # broad area kept
    ring = np.zeros(lin.shape[:2], bool)
    ring[57:71, 177:191] = True
    ring[60:68, 180:188] = False
    assert out[ring].max() < 0.1                                 # a window gets no visible halo
    k = glare_kernel(3.0)
    assert k.sum() == pytest.approx(1.0) and k[k.shape[0] // 2].argmax() == k.shape[0] // 2
    np.testing.assert_array_equal(lens_glare(lin, 0.0), lin)


def test_visible_head_radiance_is_the_spot_intensity_over_the_head_area():
    """The render caps a throwing lamp's visible head at ``throw.max_visible_radiance`` (2) against
    fireflies, and on stereo geometry the spot can light its own head a hundredfold (the fixture's
    SGM heads reached 278 where the exact ones had 4: the glare drew discs around them). The
    camera's glare takes the head's own radiance, ``throw.gain`` x the table radiance, the same on
    any geometry; lamps without a spot and lights that are off are left alone (NaN)."""
    from npsim_core.render.lights import ActiveLights, LightState, load_light_table, visible_head_radiance

    table = load_light_table()
    inst = np.zeros((8, 8), np.int32)
    head, window, off = 8 * 1000 + 1, 1 * 1000 + 1, 8 * 1000 + 2
    inst[1:3, 1:3], inst[5:7, 5:7], inst[1:3, 5:7] = head, window, off

    def state(lid, cls, on, rad):
        return LightState(lid, cls, on, 1.0, (1.0, 1.0), rad, 0.5, None)

    act = ActiveLights({head: state(head, 8, True, (9.0, 8.0, 6.0)), window: state(window, 1, True, (0.2, 0.1, 0.05)),
                        off: state(off, 8, False, (0.0, 0.0, 0.0))}, 0, False)
    r = visible_head_radiance(inst, act, table, [head, off])
    np.testing.assert_allclose(r[1, 1], float(table.throw["gain"]) * np.array([9.0, 8.0, 6.0]))
    assert np.isfinite(r[..., 0]).sum() == 4 and np.isnan(r[inst != head]).all()
    assert visible_head_radiance(inst, act, table, [off]) is None


def test_a_fixed_night_through_the_default_camera_has_real_night_statistics():
    """The camera inputs of the 2048x1024 fixture's SGM night (seed 0, tree of 2026-11-26 02:06; the
    denoised linear render with the ego vehicle composited, its metered exposure and white balance,
    the light states), area-downsampled to 256x128 (``tests/data/night_camera_inputs_256.npz``,
    docs/relight.md "Glare"). Through the chain's default camera all five global statistics are
    within 15 % of real ACDC nights; the camera before the glare (tone 0.9, lamp heads as rendered)
    gave median 28, p99 201 and 0.09 % above 240 (2 of 5)."""
    from pathlib import Path

    from npsim_core.chain import ChainParams
    from npsim_core.realism import stats_within
    from npsim_core.render.camera_post import CameraParams, apply_camera
    from npsim_core.render.lights import ActiveLights, LightState, load_light_table, visible_head_radiance

    d = np.load(Path(__file__).parent / "data" / "night_camera_inputs_256.npz")
    lights = {int(i): LightState(int(i), int(c), bool(o), 1.0, (1.0, 1.0), tuple(float(v) for v in r), 0.5, None)
              for i, c, o, r in zip(d["light_ids"], d["light_class"], d["light_on"], d["light_radiance"])}
    table = load_light_table()
    spots = [i for i, s in lights.items() if table.spec(s.class_id).throw]
    heads = visible_head_radiance(d["inst"], ActiveLights(lights, 0, False), table, spots)
    n = ChainParams().night
    cam = CameraParams(exposure_ev=float(d["exposure_ev"]), iso=n.iso, seed=n.seed,
                       white_balance=tuple(float(v) for v in d["white_balance"]), tone_contrast=n.tone_contrast,
                       glare=n.glare, glare_radius=n.glare_radius)
    lin = np.where(np.isfinite(heads), heads, d["linear"].astype(np.float32))
    srgb, _ = apply_camera(lin, cam)
    st = global_stats(srgb)
    assert all(stats_within(st).values()), st


def test_a_frame_without_albedo_maps_gets_a_delit_albedo_by_default_and_the_manifest_says_so(sgm_frame, tmp_path):
    """Issue #25: the night's albedo is the day photo with the day's light divided out. It was the
    per-class prior fallback unless ``night.delight`` was set; now de-lighting is the default for a
    frame without albedo maps, and each night's manifest entry names the albedo it used."""
    from npsim_core.chain import Chain, ChainParams
    from npsim_core.chain.export import export_frame
    from npsim_core.io import read_json

    scene, _ = sgm_frame
    assert scene.albedo is None
    p = ChainParams().with_sets(["night.final_spp=1"])
    assert p.night.delight
    p = replace(p, lights=replace(p.lights, source="none"))
    written = export_frame(Chain(scene), p, tmp_path, nights=1, kinds=("nights",))
    night = read_json(written[-1])["nights"][0]
    assert night["materials"].startswith("de-lit (sun "), night["materials"]


def test_a_vehicle_surface_off_its_box_is_not_glossy():
    """Stereo vehicle fits are smooth at the 5-px scale of ``geometry_roughness`` but their normals
    wander from column to column; on glossy paint each column mirrored the street lamps in a white
    vertical strip (the 2048x1024 fixture's seed 1). A car's rear here is flat (its depth a plane
    facing the camera) while its normals swing ±25° across the columns: the paint is rough where
    they are off the car's box, glossy where the normals are the box's."""
    from npsim_core.camera import Intrinsics
    from npsim_core.render.materials import estimate_materials

    H, W = 64, 256
    labels = np.full((H, W), 7, np.uint8)
    labels[30:50, 100:150] = 26                                   # a car's rear, 1.8 m wide at 10 m
    depth = np.full((H, W), 10.0, np.float32)
    normals = np.zeros((H, W, 3), np.float32)
    normals[...] = (0.0, -1.0, 0.0)
    th = np.radians(25.0) * np.sin(2 * np.pi * (np.arange(W) - 100) / 32.0)
    wobble = np.stack([np.sin(th), np.zeros(W), -np.cos(th)], -1).astype(np.float32)
    normals[30:50] = np.where((labels[30:50] == 26)[..., None], wobble[None], normals[30:50])
    flat = normals.copy()
    flat[30:50, 100:150] = (0.0, 0.0, -1.0)
    image = np.full((H, W, 3), 120, np.uint8)
    kw = dict(depth=depth, intrinsics=Intrinsics.cityscapes(W, H), pitch=0.0, delight=False)
    wob = estimate_materials(image, labels, normals=normals, **kw).roughness
    glossy = estimate_materials(image, labels, normals=flat, **kw).roughness
    car = labels == 26
    far_off = car & (np.abs(np.degrees(th))[None, :] > 20)
    assert far_off.sum() > 100 and wob[far_off].min() > 0.9        # strips' columns: rough
    assert wob[car].mean() > 0.5
    assert np.allclose(glossy[car], 0.25)                         # the box's own face keeps its gloss


def test_few_parked_cars_have_their_headlamps_on():
    """A parked car's low beams burn only while its engine runs: a few in a hundred parked cars.
    The light table's 0.1-0.3 (SOLO's) switched on 3-4 parked cars' headlamps in the 2048x1024
    fixture's nights, each with a saturated glare and a white spot on the road; over 400 parked
    cars and four nights, fewer than 8 % are on (0.1-0.3 gave ~20 %), and moving cars' are on."""
    from npsim_core.annotation import LightAnnotation
    from npsim_core.render.lights import activate_lights, load_light_table

    inst = np.zeros((40, 40), np.int32)
    inst.ravel()[:400] = 3 * 1000 + 1 + np.arange(400)                # 400 parked_front lamps, no groups
    inst.ravel()[400:500] = 5 * 1000 + 1 + np.arange(100)             # 100 moving_front lamps
    ann, table = LightAnnotation(inst), load_light_table()
    nights = [activate_lights(ann, table, seed) for seed in range(4)]
    parked = np.mean([s.on for n in nights for i, s in n.lights.items() if i // 1000 == 3])
    moving = np.mean([s.on for n in nights for i, s in n.lights.items() if i // 1000 == 5])
    assert 0.0 < parked < 0.08 and moving > 0.9, (parked, moving)
