"""Night rendering: pixel alignment, determinism, emitter colour, darkness, camera noise, variant choice, CLI."""

from __future__ import annotations

import dataclasses
import json
import threading

import numpy as np
import pytest

from npsim_core.annotation import LightAnnotation
from npsim_core.camera import Intrinsics
from npsim_core.errors import NpsimCancelled, NpsimInputError
from npsim_core.io import read_image, read_label_image
from npsim_core.mesh.grid import grid_mesh
from npsim_core.render import variant as variant_mod
from npsim_core.render.camera_post import CameraParams, add_noise, apply_camera, iso_noise
from npsim_core.render.lights import activate_lights, load_light_table
from npsim_core.render.materials import estimate_materials
from npsim_core.render.render import PreviewParams, render_final, render_labels, render_linear, render_preview
from npsim_core.render.scene_builder import BuildParams, build_label_scene, build_scene
from npsim_core.synthetic import street_scene

SCALAR = "scalar_rgb"


def _miou(pred: np.ndarray, gt: np.ndarray) -> tuple[float, dict]:
    ious = {}
    for c in np.unique(gt):
        a, b = gt == c, pred == c
        ious[int(c)] = (a & b).sum() / (a | b).sum()
    return float(np.mean(list(ious.values()))), ious


@pytest.fixture(scope="module")
def street():
    s = street_scene(128, 64)
    mesh = grid_mesh(s.depth_gt, s.intrinsics, s.labels, s.lights.instance_map)
    return s, mesh


@pytest.mark.parametrize("variant", ["scalar_rgb", "llvm_ad_rgb"])
def test_label_render_reproduces_labels(variant):
    """THE key test: the day labels fit the rendered night pixel for pixel (IoU >= 0.99)."""
    s = street_scene(256, 128)
    # The synthetic camera has cx off-centre by ~9 px and fx != fy: a wrong principal-point
    # sign or a missing fy/fx correction would shift the image and fail this.
    assert abs(s.intrinsics.cx - (s.width - 1) / 2) > 5 and s.intrinsics.fx != s.intrinsics.fy
    mesh = grid_mesh(s.depth_gt, s.intrinsics, s.labels, s.lights.instance_map)
    got = render_labels(build_label_scene(mesh, s.intrinsics, s.labels, variant=variant))
    got = np.where(got < 0, 23, got)  # no surface = sky
    miou, ious = _miou(got, s.labels)
    assert miou >= 0.99, ious
    assert (got == s.labels).mean() >= 0.995
    assert min(ious.values()) >= 0.95, ious


def test_camera_matches_intrinsics_on_a_point():
    """A small emissive square at a known 3-D point lands on the pixel K predicts."""
    intr = Intrinsics(50.0, 53.0, 20.3, 9.7, 48, 24)
    depth = np.full((24, 48), np.nan, np.float32)
    depth[5:8, 30:33] = 4.0  # a 3x3 patch of pixels -> 2x2 quads centred on pixel (31, 6)
    labels = np.full((24, 48), 23, np.uint8)
    labels[5:8, 30:33] = 20
    mesh = grid_mesh(depth, intr, labels)
    got = render_labels(build_label_scene(mesh, intr, labels, variant=SCALAR), passes=16)
    ys, xs = np.nonzero(got == 20)
    assert len(xs) > 0
    assert xs.mean() == pytest.approx(31.0, abs=0.3) and ys.mean() == pytest.approx(6.0, abs=0.3)


def _build(s, mesh, active, **kw):
    table = kw.pop("table", load_light_table())
    mats = estimate_materials(s.image, s.labels, albedo=s.albedo, roughness=s.roughness,
                              light_classes=s.lights.class_map())
    return build_scene(mesh, s.intrinsics, mats, table, s.lights, active,
                       BuildParams(**kw), variant=SCALAR), table


def test_same_seed_identical_night_and_toggle_in_place(street):
    s, mesh = street
    table = load_light_table()
    a = activate_lights(s.lights, table, 3, image=s.image)
    built, _ = _build(s, mesh, a, max_depth=2)
    img1 = render_final(built, spp=4, seed=3)
    img2 = render_final(built, spp=4, seed=3)
    assert np.array_equal(img1, img2)
    # switch every light off in place: same Mitsuba scene object, darker image, then back on
    scene_obj = built.scene
    off = activate_lights(s.lights, table, 3, image=s.image, force={i: False for i in s.lights.instance_ids()})
    built.apply_lights(off)
    dark = render_final(built, spp=4, seed=3)
    assert built.scene is scene_obj
    lit = np.isin(s.lights.instance_map, a.on_ids)
    assert lit.sum() > 20
    assert dark[lit].mean() < 0.5 * img1[lit].mean() and dark.mean() < img1.mean()
    built.apply_lights(a)
    assert np.array_equal(render_final(built, spp=4, seed=3), img1)


def test_different_seeds_different_active_sets(street):
    s, _ = street
    table = load_light_table()
    sets = {tuple(activate_lights(s.lights, table, k).on_ids) for k in range(6)}
    assert len(sets) == 6


def test_emitter_colour_matches_table(tmp_path):
    """A lit sodium street light's pixels have the table's chromaticity (r/g, b/g)."""
    H, W = 24, 32
    intr = Intrinsics.from_fov(W, H, 60)
    depth = np.full((H, W), 5.0, np.float32)
    labels = np.full((H, W), 11, np.uint8)
    ann = LightAnnotation(np.zeros((H, W), np.int32))
    ann.instance_map[8:16, 10:22] = 9001  # street_light_LT (sodium)
    user = tmp_path / "t.json"
    user.write_text(json.dumps({"classes": {"9": {"spread": 0.0}}}))
    table = load_light_table(user)
    mesh = grid_mesh(depth, intr, labels, ann.instance_map)
    image = np.full((H, W, 3), 128, np.uint8)
    mats = estimate_materials(image, labels, light_classes=ann.class_map())
    act = activate_lights(ann, table, 0)
    assert act.lights[9001].on
    built = build_scene(mesh, intr, mats, table, ann, act,
                        BuildParams(ego_headlights=False, sky=False, throw_spots=False), variant=SCALAR)
    img = render_final(built, spp=8)
    patch = img[10:14, 12:20].reshape(-1, 3).mean(0)
    rg, bg = table.spec(9).chromaticity
    assert patch[0] / patch[1] == pytest.approx(rg, rel=0.03)
    assert patch[2] / patch[1] == pytest.approx(bg, rel=0.1, abs=0.005)
    assert patch[1] == pytest.approx(table.unit_scale * act.lights[9001].strength, rel=0.05)


def test_no_lights_only_dim_sky(street):
    s, mesh = street
    table = load_light_table()
    off = activate_lights(s.lights, table, 0, force={i: False for i in s.lights.instance_ids()})
    built, _ = _build(s, mesh, off, ego_headlights=False)
    img = render_final(built, spp=4)
    sky = s.labels == 23
    assert img.mean() < 0.01 and img.max() < 0.1
    # sky pixels show exactly the night sky's constant radiance
    assert img[sky].mean(0) == pytest.approx(np.array(table.sky_radiance), rel=1e-3)
    assert 0 < img[~sky].mean() < img[sky].mean()
    # and the ego headlights light the road when switched on in place
    built.set_ego_headlights(True)
    lit = render_final(built, spp=4)
    road = s.labels == 7
    assert lit[road].mean() > 5 * img[road].mean()


def test_preview_progressive_and_cancellable(street):
    s, mesh = street
    built, _ = _build(s, mesh, activate_lights(s.lights, load_light_table(), 1), max_depth=2)
    frames = list(render_preview(built, PreviewParams(scale=0.5, spp_per_pass=2, passes=3, max_depth=2)))
    assert [f.spp for f in frames] == [2, 4, 6]
    assert frames[-1].image.shape == (32, 64, 3) and frames[-1].image.dtype == np.float32
    ev = threading.Event()
    gen = render_preview(built, PreviewParams(scale=0.5, spp_per_pass=1, passes=5), cancel=ev)
    next(gen)
    ev.set()
    with pytest.raises(NpsimCancelled):
        next(gen)
    # also renders from a worker thread
    out = {}
    t = threading.Thread(target=lambda: out.setdefault("img", render_linear(built, spp=1, scale=0.25)))
    t.start()
    t.join()
    assert out["img"].shape == (16, 32, 3)


def test_noise_statistics_match_betas():
    rng = np.random.default_rng(0)
    flat = np.full((256, 256, 3), 0.2, np.float32)
    b1, b2 = 4e-3, 1e-4
    noisy = add_noise(flat, b1, b2, rng)
    assert noisy.mean() == pytest.approx(0.2, abs=1e-3)
    assert noisy.var() == pytest.approx(b1 * 0.2 + b2, rel=0.03)
    # through the camera pipeline with an ISO preset (exposure 0, neutral white balance)
    _, lin = apply_camera(np.full((256, 256, 3), 0.05, np.float32), CameraParams(iso=3200, seed=1))
    e1, e2 = iso_noise(3200)
    assert lin.var() == pytest.approx(e1 * 0.05 + e2, rel=0.03)
    assert iso_noise(400)[0] < e1 and iso_noise(400)[1] < e2
    srgb, _ = apply_camera(np.full((4, 4, 3), 0.2159, np.float32), CameraParams(iso=None))
    assert srgb.dtype == np.uint8 and (srgb == 128).all()  # sRGB(0.2159) = 128/255
    with pytest.raises(NpsimInputError):
        apply_camera(np.full((4, 4, 3), np.nan, np.float32))


def test_motion_blur_only_on_moving_vehicles():
    lin = np.zeros((20, 40, 3), np.float32)
    lin[5:15, 18:22] = 1.0
    labels = np.full((20, 40), 7, np.uint8)
    labels[4:16, 10:30] = 26
    lc = np.zeros((20, 40), np.uint8)
    lc[6:8, 18:22] = 5  # moving_front light on the car
    _, blurred = apply_camera(lin, CameraParams(iso=None, motion_blur_px=9), labels=labels, light_classes=lc)
    _, still = apply_camera(lin, CameraParams(iso=None, motion_blur_px=9), labels=labels, light_classes=lc * 0)
    assert np.array_equal(still, lin)
    assert blurred[10, 15:25, 0].min() > 0 and blurred[10, 20, 0] < 1.0
    assert (blurred[0:3] == 0).all()


def test_variant_override_and_probe_cache(monkeypatch, tmp_path):
    monkeypatch.setenv("NPSIM_MITSUBA_VARIANT", "scalar_rgb")
    assert variant_mod.choose_variant().name == "scalar_rgb"
    monkeypatch.setenv("NPSIM_MITSUBA_VARIANT", "cuda_rgb")
    with pytest.raises(NpsimInputError):
        variant_mod.choose_variant()
    monkeypatch.delenv("NPSIM_MITSUBA_VARIANT")
    monkeypatch.setattr(variant_mod, "CACHE_FILE", tmp_path / "v.json")
    calls = []
    monkeypatch.setattr(variant_mod, "probe_llvm", lambda: (calls.append(1), (False, "fake failure"))[1])
    assert variant_mod.choose_variant().name == "scalar_rgb"
    assert variant_mod.choose_variant().name == "scalar_rgb"
    assert len(calls) == 1  # second answer came from the cache
    assert variant_mod.choose_variant(refresh=True).reason == "fake failure" and len(calls) == 2


def test_night_cli(tmp_path):
    from npsim_cli.main import main
    from npsim_core.scene import save_scene

    s = street_scene(64, 32)
    save_scene(s, tmp_path / "scene")
    rc = main(["night", str(tmp_path / "scene"), "-o", str(tmp_path / "out"), "--variants", "2", "--seed", "5",
               "--spp", "2", "--variant", "scalar_rgb", "--mesh", "grid", "--full-outputs"])
    assert rc == 0
    for k in range(2):
        stem = tmp_path / "out" / f"{s.name}_night_{k}"
        img = read_image(f"{stem}.png")
        assert img.shape == (32, 64, 3)
        assert np.array_equal(read_label_image(f"{stem}_labelIds.png"), s.labels)
        assert np.load(f"{stem}_linear.npy").shape == (32, 64, 3)
        lights = json.loads(open(f"{stem}_lights.json").read())
        night = json.loads((tmp_path / "out" / f"{s.name}_export.json").read_text())["nights"][k]
        assert lights["seed"] == 5 + k and night["seed"] == 5 + k and night["variant"] == "scalar_rgb"
        assert img.mean() < 100  # a night, not a day
    assert main(["night", str(tmp_path / "nope"), "-o", str(tmp_path / "o2")]) == 2


def test_bad_inputs(street):
    s, mesh = street
    table = load_light_table()
    mats = estimate_materials(s.image, s.labels)
    with pytest.raises(NpsimInputError):
        build_scene(mesh, s.intrinsics.resized(64, 32), mats, table, variant=SCALAR)
    bad = dataclasses.replace(mesh.parts[0], vertices=mesh.parts[0].vertices.copy())
    bad.vertices[0] = np.nan
    with pytest.raises(NpsimInputError):
        build_scene(dataclasses.replace(mesh, parts=[bad]), s.intrinsics, mats, table, variant=SCALAR)


def test_visible_background_vertices_get_their_own_texture():
    """Completed-but-visible background vertices (post-processing) must show their own pixel, hidden ones not."""
    from npsim_core.mesh.types import MeshPart, SceneMesh
    from npsim_core.render.scene_builder import _visible_background_repair

    H, W = 4, 4
    vv, uu = np.mgrid[0:H, 0:W]
    pix = np.stack([uu.ravel(), vv.ravel()], 1).astype(np.float32)
    verts = np.concatenate([pix, np.ones((H * W, 1), np.float32)], 1)
    wrong_uv = np.tile(np.array([[0.5 / W, 1 - 0.5 / H]], np.float32), (H * W, 1))  # all point at pixel (0, 0)
    bg = MeshPart("background", verts, np.array([[0, 4, 1]]), wrong_uv, pix, np.full(H * W, 11, np.uint8),
                  np.zeros(H * W, np.int32))
    fg_pix = pix[pix[:, 0] == 3]
    fg = MeshPart("car_1", np.concatenate([fg_pix, np.ones((len(fg_pix), 1), np.float32)], 1),
                  np.array([[0, 1, 2]]), np.zeros((len(fg_pix), 2), np.float32), fg_pix,
                  np.full(len(fg_pix), 26, np.uint8), np.zeros(len(fg_pix), np.int32), foreground=True)
    labels = np.full((H, W), 7, np.uint8)
    labels[:, 3] = 26
    lights = np.zeros((H, W), np.int32)
    lights[1, 1] = 1005
    (uv, lab, lid), _ = _visible_background_repair(SceneMesh([bg, fg], W, H), labels, lights)
    own = np.stack([(pix[:, 0] + 0.5) / W, 1 - (pix[:, 1] + 0.5) / H], 1)
    vis = pix[:, 0] < 3
    assert np.allclose(uv[vis], own[vis]) and np.allclose(uv[~vis], wrong_uv[~vis])
    assert (lab[vis] == 7).all() and (lab[~vis] == 11).all()
    assert lid[1 * W + 1] == 1005 and lid.sum() == 1005


def test_fireflies_removed_but_lights_kept():
    from npsim_core.render.camera_post import remove_fireflies

    img = np.full((9, 9, 3), 0.02, np.float32)
    img[2, 2] = 5.0          # a Monte Carlo firefly on a dark wall
    img[6, 6] = 5.0          # a one-pixel lamp (protected)
    protect = np.zeros((9, 9), bool)
    protect[6, 6] = True
    out, n = remove_fireflies(img, 4.0, 0.01, protect)
    assert n == 1
    assert np.allclose(out[2, 2], 0.02) and np.allclose(out[6, 6], 5.0)
    assert np.array_equal(np.delete(out.reshape(-1, 3), [20, 60], axis=0), np.delete(img.reshape(-1, 3), [20, 60], axis=0))
    flat, n0 = remove_fireflies(np.full((5, 5, 3), 0.3, np.float32))
    assert n0 == 0 and np.all(flat == 0.3)


def test_night_cli_fast_final_settings(tmp_path):
    """Direct-light-only path length and a reduced mesh (the fast full-resolution setting)."""
    from npsim_cli.main import main
    from npsim_core.scene import save_scene

    s = street_scene(96, 48)
    save_scene(s, tmp_path / "scene")
    args = ["night", str(tmp_path / "scene"), "--variants", "1", "--spp", "4", "--variant", "scalar_rgb",
            "--iso", "0", "--full-outputs", "--set", "refine.steps=8"]  # the night settings are under test
    assert main(args + ["-o", str(tmp_path / "one"), "--max-depth", "3"]) == 0
    assert main(args + ["-o", str(tmp_path / "fast"), "--max-depth", "2", "--face-budget", "4000"]) == 0
    full = json.loads((tmp_path / "one" / f"{s.name}_export.json").read_text())
    fast = json.loads((tmp_path / "fast" / f"{s.name}_export.json").read_text())
    assert full["params"]["night"]["final_max_depth"] == 3 and fast["params"]["night"]["final_max_depth"] == 2
    assert fast["mesh"]["faces"] < full["mesh"]["faces"]
    lin_fast = np.load(tmp_path / "fast" / f"{s.name}_night_0_linear.npy")
    assert lin_fast.shape == (48, 96, 3) and np.isfinite(lin_fast).all()
    assert read_image(tmp_path / "fast" / f"{s.name}_night_0.png").mean() < 100  # a night
    assert np.array_equal(read_label_image(tmp_path / "fast" / f"{s.name}_night_0_labelIds.png"), s.labels)
    assert main(args + ["-o", str(tmp_path / "bad"), "--face-budget", "-5"]) == 2


def test_label_render_of_the_postprocessed_mesh_matches_labels():
    """The whole chain's mesh (filtered depth, U, post-processing kernel) rendered with label colours:
    every sheet ends half a pixel beyond its border pixels, so even 1-3 px poles keep their outline."""
    from npsim_core.chain import Chain, ChainParams
    from npsim_core.mesh.postprocess import PostprocessParams, postprocess_mesh

    s = street_scene(256, 128)
    st = Chain(s).compute(ChainParams(), until="uncertain")
    ious = {}
    for ext in (True, False):
        r = postprocess_mesh(st.filtered, s.intrinsics, s.labels, st.uncertain, s.lights.instance_map,
                             normals=s.normals, params=PostprocessParams(extend_edges=ext))
        got = render_labels(build_label_scene(r.mesh, s.intrinsics, s.labels, variant=SCALAR))
        got = np.where(got < 0, 23, got)
        miou, ious[ext] = _miou(got, s.labels)
        if ext:
            assert (got == s.labels).mean() >= 0.995 and miou >= 0.99, ious[ext]
            assert min(ious[ext].values()) >= 0.97, ious[ext]
    assert min(ious[False].values()) < 0.9       # without it thin poles lose their outer half-pixels


def test_denoise_removes_noise_but_keeps_edges_and_lights():
    from npsim_core.render.denoise import DenoiseGuides, DenoiseParams, denoise

    H, W = 48, 96
    rng = np.random.default_rng(0)
    clean = np.full((H, W, 3), 0.02, np.float32)
    clean[:, W // 2:] = 0.2                           # a lit wall beside a dark road: a sharp edge
    clean[10:14, 10:14] = 5.0                         # a lamp
    depth = np.where(np.arange(W)[None, :] < W // 2, 10.0, 20.0) * np.ones((H, 1))
    labels = np.where(np.arange(W)[None, :] < W // 2, 7, 11) * np.ones((H, 1), np.uint8)
    normals = np.zeros((H, W, 3), np.float32)
    normals[..., 2] = -1.0
    protect = np.zeros((H, W), bool)
    protect[10:14, 10:14] = True
    noisy = clean * rng.gamma(4.0, 0.25, (H, W, 1)).astype(np.float32)      # MC-like multiplicative noise
    noisy[protect] = clean[protect]
    g = DenoiseGuides(np.full((H, W, 3), 0.5, np.float32), depth.astype(np.float32), normals,
                      labels.astype(np.uint8), protect)
    out = denoise(noisy, g)
    err = lambda a: float(np.sqrt(np.mean((a - clean)[~protect] ** 2)))
    assert err(out) < 0.4 * err(noisy)
    np.testing.assert_array_equal(out[protect], noisy[protect])             # lights untouched
    # Nothing of the lit wall leaks across the label/depth edge onto the road.
    assert out[:, W // 2 - 3:W // 2].mean() < 0.05
    assert np.isfinite(out).all() and out.dtype == np.float32
    # Guides at full resolution serve a half-size preview; 0 iterations is a no-op.
    small = noisy[::2, ::2].copy()
    assert denoise(small, g).shape == small.shape
    np.testing.assert_array_equal(denoise(noisy, g, DenoiseParams(iterations=0)), noisy)
    with pytest.raises(NpsimInputError):
        DenoiseParams(sigma_depth=0)


def test_denoise_guides_from_the_mesh():
    from npsim_core.render.denoise import denoise_guides

    s = street_scene(64, 32)
    mesh = grid_mesh(s.depth_gt, s.intrinsics, s.labels)
    g = denoise_guides(mesh, s.intrinsics, s.albedo, s.labels, s.lights.class_map() > 0)
    ok = np.isfinite(s.depth_gt) & (s.labels != 23)
    np.testing.assert_allclose(g.depth[ok], s.depth_gt[ok], rtol=1e-3)
    assert (np.abs(np.linalg.norm(g.normals[ok], axis=1) - 1) < 1e-3).mean() > 0.95
    with pytest.raises(NpsimInputError):
        denoise_guides(mesh, s.intrinsics, s.albedo[:10], s.labels)


def test_low_beam_pattern_cuts_off_below_the_horizon_and_rises_on_the_kerb_side():
    """The ego lamps' texture (docs/relight.md, "People in the headlights"): row 0 = down, column 0 =
    the kerb side (image right); full light just under -0.57 deg, 2 % above the line."""
    import math

    from npsim_core.render.scene_builder import LOW_BEAM_ABOVE, low_beam_pattern

    cutoff, rows, cols = 35.0, 1024, 128
    pat = low_beam_pattern(cutoff, rows, cols)
    assert pat.shape == (rows, cols, 3) and pat.dtype == np.float32
    t = math.tan(math.radians(cutoff))

    def row_of(elev_deg):   # the row looking at this elevation straight ahead
        return int((math.tan(math.radians(elev_deg)) / t * 0.5 + 0.5) * rows)

    oncoming, kerb = cols - 1 - cols // 2 + 2, cols // 2 - 12  # a few degrees either side of straight ahead
    assert pat[row_of(-2.0), oncoming, 0] > 0.9 and pat[row_of(0.5), oncoming, 0] == pytest.approx(LOW_BEAM_ABOVE)
    assert pat[row_of(0.5), kerb, 0] > 0.9        # the kerb side's line has risen above 0.5 deg
    assert pat[row_of(-20.0), oncoming, 0] >= 0.25


def test_oidn_bounded_memory_gives_the_same_image():
    """The per-image OIDN filter with a scratch-memory bound (tiles) denoises exactly as the
    unbounded convenience call."""
    import pyoidn

    from npsim_core.render.denoise import DenoiseParams, denoise_oidn

    rng = np.random.default_rng(3)
    x = (rng.random((96, 160, 3)) ** 4).astype(np.float32)
    ref = np.maximum(pyoidn.denoise(x, hdr=True, quality="fast"), 0)
    np.testing.assert_array_equal(denoise_oidn(x, params=DenoiseParams(oidn_max_memory_mb=16)), ref)
    np.testing.assert_array_equal(denoise_oidn(x), ref)
    assert not np.array_equal(denoise_oidn(x, params=DenoiseParams(oidn_quality="balanced")), ref)
    with pytest.raises(NpsimInputError, match="oidn_max_memory_mb"):
        DenoiseParams(oidn_max_memory_mb=1)


def test_multijitter_sampler_lowers_the_noise(street):
    """The nights' default sampler (``RENDER_SAMPLER``, multi-jittered): at the same spp its renders
    differ from one seed to the next far less than the independent sampler's (fewer
    samples for the same error; 128x64: mean |difference| 0.6x); an unknown sampler is refused."""
    from npsim_core.render.scene_builder import RENDER_SAMPLER

    s, mesh = street
    table = load_light_table()
    a = activate_lights(s.lights, table, 3, image=s.image)
    built, _ = _build(s, mesh, a)
    assert RENDER_SAMPLER == "multijitter" and built.sampler == RENDER_SAMPLER

    def seed_spread(sampler):
        # mean, not RMS: a single firefly would decide an RMS at this size
        x, y = (render_linear(built, spp=8, seed=k, sampler=sampler) for k in (11, 12))
        return float(np.mean(np.abs(x - y)))

    ind, mj = seed_spread("independent"), seed_spread("multijitter")
    assert mj < 0.75 * ind, (mj, ind)
    with pytest.raises(NpsimInputError, match="sampler"):
        BuildParams(sampler="sobol")


def test_onebounce_integrator_agrees_with_path(street):
    """The nights' path tracer at one bounce without the path's last BSDF ray (render/integrator.py,
    27 % less render CPU at 2048x1024): by default in a JIT variant at max_depth 3, and its image is
    Mitsuba's ``path`` one up to the dropped glossy share (here 0.5-1 % darker) and the Monte Carlo
    noise (means over 16x16-pixel blocks: its distance to a path render 1.3-2.2x that between two
    path seeds over four seed sets); scalar scenes keep ``path``."""
    from npsim_core.render.integrator import NAME

    s, mesh = street
    table = load_light_table()
    a = activate_lights(s.lights, table, 3, image=s.image)
    mats = estimate_materials(s.image, s.labels, albedo=s.albedo, roughness=s.roughness,
                              light_classes=s.lights.class_map())
    assert _build(s, mesh, a)[0].info["integrator"] == "path"  # scalar_rgb (before the LLVM scenes: it sets the variant)
    one = build_scene(mesh, s.intrinsics, mats, table, s.lights, a, BuildParams(), variant="llvm_ad_rgb")
    path = build_scene(mesh, s.intrinsics, mats, table, s.lights, a, BuildParams(integrator="path"),
                       variant="llvm_ad_rgb")
    assert one.info["integrator"] == NAME and path.info["integrator"] == "path"

    def blocks(img):
        return img.reshape(4, 16, 8, 16, 3).mean(axis=(1, 3))

    x = blocks(render_linear(one, spp=64, seed=1))
    y, z = (blocks(render_linear(path, spp=64, seed=k)) for k in (2, 3))
    assert abs(x.mean() / y.mean() - 1) < 0.03, (x.mean(), y.mean())
    assert np.abs(x - y).mean() < 2.5 * np.abs(y - z).mean() + 1e-4, (np.abs(x - y).mean(), np.abs(y - z).mean())
    with pytest.raises(NpsimInputError, match="integrator"):
        BuildParams(integrator="bdpt")
