"""Render geometry from SGM stereo: the faults of the surface fits that showed in the nights.

On the 256x128 Cityscapes-layout fixture (OpenCV semi-global matching on a rendered stereo pair,
its exact depth written outside the dataset), the surface fits (``fit_surfaces``) are compared
with the exact geometry where the nights differed (docs/relight.md "Nights of real frames"):

* the kerbs' vertical faces (labelled sidewalk) were part of the sidewalk plane, so the lamps'
  line along them was missing (2048x1024: sidewalk structure ratio 0.71 of the exact night's);
* cars leaned back or sideways (glass and paint matched to the background, edges fattened by the
  nearer car beside them), so their lamps threw their light at the sky or along a façade (the
  row streaks on the left façade: building 1.19 of the exact night's).
"""

from __future__ import annotations

import numpy as np
import pytest

from npsim_core.camera import normals_from_depth
from npsim_core.geometry.surfaces import SurfaceParams, fit_surfaces


@pytest.fixture(scope="module")
def sgm(sgm_frame):
    from npsim_core.chain import Chain, ChainParams
    from npsim_core.geometry.stereo import stereo_valid

    scene, exact = sgm_frame
    # The hole filling the chain hands to the fits (its stereo estimate without the fits).
    filled = Chain(scene).compute(ChainParams().with_sets(["depth.stereo_surfaces=false", "depth.stereo_holdout=0"]),
                                  until="geometry").depth_in
    return scene, exact, filled, stereo_valid(scene, 80.0)


def _fit(sgm, **kw):
    scene, _, filled, valid = sgm
    return fit_surfaces(scene.depth_stereo, valid, filled, scene.labels, scene.intrinsics, scene.instances,
                        SurfaceParams(**kw))


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1.0, 1.0)))


def test_kerbs_get_their_vertical_faces(sgm):
    """Sidewalk pixels whose exact normal is horizontal are the kerbs' faces (up to 3 px tall
    here): the fit gives them a vertical face (old fit: the sidewalk's plane, ~90° off)."""
    scene, exact, _, _ = sgm
    n_true = normals_from_depth(exact, scene.intrinsics)
    up = np.array([0.0, -np.cos(scene.camera_pitch), -np.sin(scene.camera_pitch)])
    kerb = (scene.labels == 8) & (np.abs(n_true @ up) < 0.3)
    kerb[:, :8] = False                                   # the frame's edge column's normals
    assert kerb.sum() >= 20
    depth, normals, info = _fit(sgm)
    assert info["kerb_pixels"] > 0
    err = _angle(normals[kerb], n_true[kerb])
    assert np.nanmedian(err) < 25, np.nanmedian(err)
    _, old_normals, _ = _fit(sgm, kerb_max_m=0.0)
    assert np.nanmedian(_angle(old_normals[kerb], n_true[kerb])) > 60
    # ... and the sidewalk's top keeps its plane.
    top = (scene.labels == 8) & (np.abs(n_true @ up) > 0.9)
    assert np.nanmedian(_angle(normals[top], n_true[top])) < 10


def test_cars_stand_upright(sgm):
    """No fitted car surface faces the sky: at most 2 % of the car pixels' normals are more than
    30° above the horizontal (old fit, local planes: 40 %), and the upright faces' normals are
    near the exact ones (median error 11°, old 31°)."""
    scene, exact, _, _ = sgm
    n_true = normals_from_depth(exact, scene.intrinsics)
    up = np.array([0.0, -np.cos(scene.camera_pitch), -np.sin(scene.camera_pitch)])
    cars = (scene.labels == 26) & np.isfinite(exact)

    def facing_up(n):
        return float(np.mean((n[cars] @ up) > np.sin(np.radians(30))))

    _, normals, _ = _fit(sgm)
    _, old, _ = _fit(sgm, vehicle_upright=False, fattening_px=0.0)
    assert facing_up(normals) < 0.02
    assert facing_up(old) > 0.2                                                  # 40 %
    # Their upright faces (the exact boxes' tops are not fitted as such), all cars and the largest.
    vert = cars & (np.abs(n_true @ up) < 0.5)
    err, err_old = (np.nanmedian(_angle(n[vert], n_true[vert])) for n in (normals, old))
    assert err < 20 and err < 0.75 * err_old, (err, err_old)                     # 256x128: 11° (old 31°)
    big = max(np.unique(scene.instances[cars]), key=lambda i: (scene.instances == i).sum())
    m = vert & (scene.instances == big)
    assert np.nanmedian(_angle(normals[m], n_true[m])) < 15                        # the van: 9° (old 13°)


def test_a_car_beside_a_nearer_one_does_not_lean_toward_it():
    """A car at 60 m whose right columns carry the disparity of a nearer car at 42 m beside it
    (SGM's edge fattening, 10 px at 1024 px wide as on the fixture) is fitted at 60 m and facing
    the camera, not as a surface turning toward the nearer car (its lamp then lit a façade
    sideways)."""
    from npsim_core.camera import Intrinsics

    W, H = 1024, 256
    intr = Intrinsics.cityscapes(W, H)
    labels = np.full((H, W), 11, np.uint8)
    instances = labels.astype(np.int32).copy()
    stereo = np.full((H, W), 70.0)
    labels[100:140, 400:460] = 26
    instances[100:140, 400:460] = 26000
    stereo[100:140, 400:460] = 60.0
    labels[100:140, 460:500] = 26
    instances[100:140, 460:500] = 26001
    stereo[100:140, 460:500] = 42.0
    stereo[100:140, 450:460] = np.linspace(55.0, 42.0, 10)[None, :]   # fattened into the far car
    valid = np.ones((H, W), bool)
    depth, normals, _ = fit_surfaces(stereo, valid, stereo.astype(np.float32), labels, intr, instances)
    far = depth[100:140, 400:460]
    assert np.abs(np.median(far, axis=0) / 60.0 - 1).max() < 0.03
    n = normals[100:140, 400:460].reshape(-1, 3)
    assert np.median(n[:, 2]) < -0.97                    # faces the camera
    old, _, _ = fit_surfaces(stereo, valid, stereo.astype(np.float32), labels, intr, instances,
                             SurfaceParams(fattening_px=0.0))
    assert np.abs(np.median(old[100:140, 400:460], axis=0) / 60.0 - 1).max() > 0.05    # 7 % off


def test_tree_crowns_stand_upright_and_stay_where_they_are(sgm):
    """Local planes on SGM's foliage turned every patch of a crown a different way: a quarter of
    the crowns' surface (from the fitted depth, as meshed) faced more than 30° up and the median
    normal was 60° from the exact one. Fitted locally upright (``vegetation_upright``): 10 %,
    48°, and the depth error does not grow (AbsRel 0.073 -> 0.066)."""
    scene, exact, _, _ = sgm
    up = np.array([0.0, -np.cos(scene.camera_pitch), -np.sin(scene.camera_pitch)])
    veg = (scene.labels == 21) & np.isfinite(exact)
    assert veg.sum() >= 500
    n_true = normals_from_depth(exact, scene.intrinsics)

    def measure(**kw):
        depth, _, _ = _fit(sgm, **kw)
        n = normals_from_depth(depth, scene.intrinsics)
        absrel = float(np.mean(np.abs(depth[veg] - exact[veg]) / exact[veg]))
        return float(np.mean((n[veg] @ up) > 0.5)), float(np.nanmedian(_angle(n[veg], n_true[veg]))), absrel

    up_new, err_new, rel_new = measure()
    up_old, err_old, rel_old = measure(vegetation_upright=False)
    assert up_old > 0.2 and up_new < 0.15, (up_old, up_new)                      # 24 % -> 10 %
    assert err_new < err_old - 6, (err_old, err_new)                             # 60° -> 48°
    assert rel_new <= rel_old * 1.02, (rel_old, rel_new)


def _box_entry(o: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Entry distance of rays (o, d: (..., 3)) into an axis-aligned box, inf if they miss it."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - o) / d, (hi - o) / d
    tmin, tmax = np.nanmax(np.minimum(t1, t2), -1), np.nanmin(np.maximum(t1, t2), -1)
    return np.where((tmax >= tmin) & (tmax > 0), np.maximum(tmin, 0), np.inf)


def _sunny_street(W=256, H=128, el_deg=40.0, az_deg=30.0, height=12.0, x_f=-6.0, cam_h=1.2):
    """A drawn street by day (camera frame, pitch 0): road, a 12 m façade on the left whose near
    part goes on above the frame's top edge, a parked van on the right; sun ``el_deg`` up,
    ``az_deg`` to the left of ahead. (image, labels, normals, depth, intrinsics, unit vector to the sun)."""
    from npsim_core.camera import Intrinsics

    intr = Intrinsics.cityscapes(W, H)
    u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    r = np.stack([(u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy, np.ones_like(u)], -1)
    lo, hi = np.array([1.5, cam_h - 1.6, 10.0]), np.array([3.5, cam_h, 14.5])
    with np.errstate(divide="ignore", invalid="ignore"):
        tg = np.where(r[..., 1] > 0, cam_h / r[..., 1], np.inf)
        tf = np.where(r[..., 0] < 0, x_f / r[..., 0], np.inf)
    tf = np.where((tf >= 2.0) & (tf <= 80.0) & (tf * r[..., 1] >= cam_h - height), tf, np.inf)
    tb = _box_entry(np.zeros_like(r), r, lo, hi)
    tg = np.where(tg <= 120.0, tg, np.inf)
    t = np.minimum(np.minimum(tg, tf), tb)
    labels = np.select([~np.isfinite(t), t == tb, t == tf], [23, 26, 11], 7).astype(np.uint8)
    depth = np.where(np.isfinite(t), t, np.nan).astype(np.float32)
    P = r * np.where(np.isfinite(t), t, 0.0)[..., None]
    normals = np.zeros((H, W, 3))
    normals[labels == 7] = (0.0, -1.0, 0.0)
    normals[labels == 11] = (1.0, 0.0, 0.0)
    box = labels == 26
    rel = (P[box] - 0.5 * (lo + hi)) / (0.5 * (hi - lo))
    ax = np.argmax(np.abs(rel), -1)
    nb = np.zeros((box.sum(), 3))
    nb[np.arange(len(ax)), ax] = np.sign(rel[np.arange(len(ax)), ax])
    normals[box] = nb
    el, az = np.radians(el_deg), np.radians(az_deg)
    s = np.array([-np.cos(el) * np.sin(az), -np.sin(el), np.cos(el) * np.cos(az)])
    q = P + 0.01 * normals
    with np.errstate(divide="ignore", invalid="ignore"):
        tt = (x_f - q[..., 0]) / s[0]
        zf = q[..., 2] + tt * s[2]
        facade = (tt > 0) & (q[..., 1] + tt * s[1] >= cam_h - height) & (zf >= 2.0) & (zf <= 80.0)
    lit = np.isfinite(t) & ~facade & ~np.isfinite(_box_entry(q, np.broadcast_to(s, q.shape), lo, hi))
    cu = -normals[..., 1]
    shade = 2.5 * np.maximum(normals @ s, 0.0) * lit + 0.5 * (1 + cu) + 0.15 * (1 - cu)
    albedo = np.select([labels == 7, labels == 11, labels == 26], [0.12, 0.3, 0.4], 0.0)
    lin = albedo * shade * np.exp(np.random.default_rng(0).normal(0, 0.05, (H, W))) * 0.2
    lin = np.where(labels == 23, 0.8, lin)
    srgb = np.clip(np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * np.abs(lin) ** (1 / 2.4) - 0.055), 0, 1)
    image = np.round(np.repeat(srgb[..., None], 3, -1) * 255).astype(np.uint8)
    return image, labels, normals.astype(np.float32), depth, intr, s


def test_the_sun_is_found_though_the_facade_casting_the_shadow_goes_on_above_the_frame():
    """The façade that shadows the street goes on above the frame's top edge, to a height the frame
    does not show. Taken as unlimited, every high sun shadowed the whole street and a low one won
    (40° off the true sun here; on the 2048x1024 fixture from SGM geometry 35°, whose de-lit cars
    then kept 0.305 of albedo error). With its height fitted to the observed shadows (and thin
    objects thin, margins for fitted geometry) the estimate is within 10° (here 4°)."""
    from npsim_core.render.materials import estimate_daylight

    image, labels, normals, depth, intr, true = _sunny_street()
    light = estimate_daylight(image, labels, normals, depth, intr, 0.0)
    s = np.asarray(light.sun)
    assert np.degrees(np.arccos(np.clip(s @ true, -1, 1))) < 10, (light, true)
    assert 1.5 < light.ratio < 4.0                                              # drawn with 2.5
    assert light.above_height is not None and np.isfinite(light.above_height[labels[0] == 11]).all()


def test_a_delit_car_rear_is_not_lit_as_its_side_though_the_fitted_normals_blur_the_corner():
    """The vehicle fits smooth a car's columns (σ 32 px), so the rear beside a sunlit side took
    part of the side's slope (2048x1024 fixture: rear normals a median 68° off) and its de-lit
    albedo kept the day's step near the corner (car error 0.217, target 0.197). De-lighting now
    fits the car's depth with the two visible faces of an upright box
    (``vehicle_box_normals``, docs/relight.md "Cars as boxes"): one paint on side and rear."""
    from npsim_core.camera import Intrinsics
    from npsim_core.render.materials import DayLight, delit_albedo

    H, W = 128, 256
    K = Intrinsics.cityscapes(W, H)
    sky_c = np.array([0.83, 1.0, 1.35], np.float32)
    labels = np.full((H, W), 7, np.uint8)
    labels[:20] = 23
    depth = np.full((H, W), 30.0, np.float32)
    depth[:20] = np.nan
    normals = np.zeros((H, W, 3), np.float32)
    normals[...] = (0.0, -1.0, 0.0)
    # An upright box right of the camera: its left side at x = 1.2 m from z 8 to 12.5 m, its
    # rear (facing the camera) at z = 8 m, 1.8 m wide. A ray enters it at the farther of the
    # two faces' hits.
    u = np.arange(W)
    t = (u - K.cx) / K.fx
    on = (t > 1.2 / 12.5) & (t < 3.0 / 8.0)
    z = np.where(t > 0, np.maximum(8.0, 1.2 / np.maximum(t, 1e-6)), np.inf)
    side = on & (1.2 / np.maximum(t, 1e-6) > 8.0)
    rows = slice(60, 90)
    labels[rows, on] = 26
    depth[rows, on] = z[on]
    true_n = normals.copy()
    true_n[rows, side] = (-1.0, 0.0, 0.0)
    true_n[rows, on & ~side] = (0.0, 0.0, -1.0)
    # The fitted normals: the corner blurred over ±24 columns (as the upright column fit does).
    corner = int(np.flatnonzero(on & ~side)[0])
    f = np.clip((u - corner + 24) / 48.0, 0.0, 1.0)
    blur = np.stack([-(1 - f), np.zeros(W), -f], -1)
    blur /= np.linalg.norm(blur, axis=-1, keepdims=True)
    normals[rows, on] = blur[on].astype(np.float32)
    sun = np.array([-0.8, -0.6, 0.0])
    paint = np.array([0.4, 0.1, 0.1], np.float32)
    cosv = np.maximum(true_n @ sun.astype(np.float32), 0.0)[..., None]
    cu = (true_n @ np.array([0.0, -1.0, 0.0], np.float32))[..., None]
    amb = 0.5 * (1 + cu) + 0.3 * 0.5 * (1 - cu)
    lin = 0.05 * (2.5 * cosv + amb * sky_c) * np.where(labels[..., None] == 26, paint, 0.12)
    lin[:20] = 0.2 * sky_c
    image = np.round(np.clip(np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055), 0, 1)
                     * 255).astype(np.uint8)
    light = DayLight(sun=tuple(sun), ratio=2.5, score=0.5, shadow_fraction=0.0)
    alb, _ = delit_albedo(image, labels, normals, depth, K, 0.0, light=light)
    a = (alb @ np.array([0.2126, 0.7152, 0.0722], np.float32))[rows]
    rear = np.median(a[:, on & ~side], axis=0)
    sidev = np.median(a[:, side])
    # Old code: the rear's columns near the corner were divided by part of the sun (0.6x darker).
    assert rear.min() / rear.max() > 0.85
    assert sidev / np.median(rear) == pytest.approx(1.0, abs=0.15)



def test_a_sidewalk_beside_a_pole_is_fitted_over_the_poles_fattened_stereo():
    """A small sidewalk patch (smaller than the plane window, so its fit hands over to the patch's
    plane) with a pole standing on it whose disparity SGM spread 5 px onto the sidewalk beside it
    (2048x1024 fixture, seed 1: ~20 px beside a pole and a parked car's wheels): the dropped pixels
    take the sidewalk's plane (old: they kept the pole's stereo, 10-25 % in front of the sidewalk,
    and cast shadow bands across it in the night; sidewalk structure 1.28x the exact night's)."""
    from npsim_core.camera import Intrinsics

    W, H = 512, 256
    intr = Intrinsics.cityscapes(W, H)
    labels = np.zeros((H, W), np.uint8)                       # unlabelled: not fitted
    v = np.arange(H, dtype=np.float64)[:, None].repeat(W, 1)
    ground = intr.fy * 1.05 / np.maximum(v - intr.cy, 1.0)     # a sidewalk 1.05 m below the camera
    depth = np.full((H, W), 30.0)
    side = (slice(150, 160), slice(200, 260))                  # 18-27 m
    labels[side] = 8
    depth[side] = ground[side]
    labels[110:157, 230:233] = 17                              # a pole standing on it
    depth[110:157, 230:233] = ground[157, 231]
    fat = (slice(150, 157), slice(233, 238))
    depth[fat] = ground[157, 231]                              # its disparity spread onto the sidewalk
    valid = labels > 0
    filled = depth.astype(np.float32)                          # the hole filling: the stereo
    z, _, _ = fit_surfaces(depth, valid, filled, labels, intr)
    assert np.abs(z[fat] / ground[fat] - 1).max() < 0.05
    z_old, _, _ = fit_surfaces(depth, valid, filled, labels, intr, params=SurfaceParams(fit_over_dropped=False))
    assert np.abs(z_old[fat] / ground[fat] - 1).max() > 0.15
