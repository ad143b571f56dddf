"""The synthetic street scene: determinism, ground-truth consistency, lights, prediction, CLI, cache."""

from __future__ import annotations

import numpy as np
import pytest

from npsim_core.annotation import class_of
from npsim_core.camera import backproject, normals_from_depth
from npsim_cli.main import main as cli_main
from npsim_core.labels import cityscapes
from npsim_core.metrics import angular_error_deg, depth_metrics, normal_metrics
from npsim_core.scene import load_scene
from npsim_core.synthetic import (PredictionErrors, make_street_scene, street_ground_truth, street_scene,
                                  simulate_prediction)

W, H = 128, 64
SPP = 2  # RGB quality is irrelevant to these tests; keep them fast


@pytest.fixture(scope="module")
def scene():
    return make_street_scene(W, H, seed=0, spp=SPP)


def _arrays(s):
    return {"image": s.image, "labels": s.labels, "depth_gt": s.depth_gt, "normals_gt": s.normals_gt,
            "depth": s.depth, "normals": s.normals, "lights": s.lights.instance_map, "albedo": s.albedo,
            "roughness": s.roughness}


def test_same_seed_gives_identical_arrays(scene):
    again = make_street_scene(W, H, seed=0, spp=SPP)
    for k, a in _arrays(scene).items():
        b = _arrays(again)[k]
        assert a.dtype == b.dtype and a.shape == b.shape, k
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), k
    assert {g.id: g.members for g in scene.lights.groups.values()} == \
           {g.id: g.members for g in again.lights.groups.values()}


def test_different_seeds_differ(scene):
    other = make_street_scene(W, H, seed=1, spp=SPP)
    assert not np.array_equal(scene.labels, other.labels)
    assert not np.array_equal(scene.depth_gt, other.depth_gt, equal_nan=True)
    assert not np.array_equal(scene.image, other.image)


def test_camera_and_shapes(scene):
    assert scene.intrinsics.width == W and scene.intrinsics.height == H
    assert scene.camera_height == pytest.approx(1.22) and scene.camera_pitch == pytest.approx(0.038)
    assert scene.image.dtype == np.uint8 and scene.image.shape == (H, W, 3)
    assert scene.albedo.shape == (H, W, 3) and 0 <= scene.albedo.min() and scene.albedo.max() <= 1
    assert scene.roughness.shape == (H, W) and np.all((scene.roughness > 0) & (scene.roughness <= 1))
    # The road is flat ground: its GT depth matches the camera-height/pitch ground plane exactly.
    road = scene.labels == 7
    P = backproject(scene.depth_gt, scene.intrinsics)[road]
    s, c = np.sin(0.038), np.cos(0.038)
    height_above_ground = 1.22 - c * P[:, 1] - s * P[:, 2]  # world y: camera y axis is (0, -cos p, -sin p)
    assert np.abs(height_above_ground).max() < 5e-3  # markings sit 2 mm proud


def test_labels_cover_every_pixel_with_known_ids(scene):
    known = set(int(i) for i in cityscapes().ids)
    present = set(int(i) for i in np.unique(scene.labels))
    assert present <= known
    assert 0 not in present  # nothing left 'unlabeled'
    assert {7, 8, 11, 17, 21, 23, 26} <= present


@pytest.mark.parametrize("seed", [0, 5])
def test_all_classes_present_at_moderate_size(seed):
    layout, _, _, gt = street_ground_truth(512, 256, seed=seed)
    labels = np.where(gt.prim >= 0, layout.prims.label[np.maximum(gt.prim, 0)], 23)
    assert {7, 8, 11, 17, 19, 20, 21, 23, 26} <= set(int(i) for i in np.unique(labels))
    for lab in (8, 19, 20):  # sidewalk, traffic light, sign: visible, not just a stray pixel
        assert (labels == lab).sum() >= 30, lab
    lights = np.where(gt.prim >= 0, layout.prims.light[np.maximum(gt.prim, 0)], 0)
    assert {1, 2, 3, 4, 8, 10, 12} <= set(int(i) // 1000 for i in np.unique(lights) if i)


def test_sky_is_the_only_nan(scene):
    sky = scene.labels == 23
    assert sky.any() and not sky.all()
    assert np.array_equal(np.isnan(scene.depth_gt), sky)
    assert np.array_equal(np.isnan(scene.normals_gt).any(axis=-1), sky)
    assert np.array_equal(np.isnan(scene.depth), sky)
    assert np.array_equal(np.isnan(scene.normals).any(axis=-1), sky)
    assert np.nanmin(scene.depth_gt) > 0
    # Sky is only above: every sky pixel lies above the horizon row.
    horizon = scene.intrinsics.cy - scene.intrinsics.fy * np.tan(0.038)
    rows = np.nonzero(sky)[0]
    assert rows.max() < horizon


def test_gt_normals_are_unit_and_face_the_camera(scene):
    valid = ~(scene.labels == 23)
    n = scene.normals_gt[valid]
    assert np.allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-5)
    P = backproject(scene.depth_gt, scene.intrinsics)[valid]
    assert np.all(np.sum(n * P, axis=-1) < 0)


def test_normals_from_gt_depth_agree_with_gt_normals_on_planar_regions(scene):
    n_est = normals_from_depth(scene.depth_gt, scene.intrinsics)
    # Planar interior: same label and same GT normal in the whole 3x3 neighbourhood.
    lab = scene.labels
    same = np.ones_like(lab, dtype=bool)
    nk = np.round(np.nan_to_num(scene.normals_gt) * 1000).astype(np.int32)
    key = (lab.astype(np.int64) * 7919 + nk[..., 0] * 31 + nk[..., 1] * 17 + nk[..., 2])
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            same &= np.roll(np.roll(key, dy, 0), dx, 1) == key
    same[[0, -1], :] = False
    same[:, [0, -1]] = False
    same &= lab != 23
    err = angular_error_deg(n_est, scene.normals_gt)[same]
    assert same.sum() > 0.3 * lab.size
    assert np.median(err) < 2.0
    assert np.mean(err < 5.0) > 0.8


def test_every_light_instance_lies_on_its_host_surface(scene):
    ann = scene.lights
    ann.validate()
    ids = ann.instance_ids()
    assert len(ids) >= 10
    classes = {class_of(i) for i in ids}
    assert {1, 2, 8} <= classes and (3 in classes or 4 in classes)
    # Host surfaces: the same scene cast without the light panes.
    _, intr, _, host = street_ground_truth(W, H, seed=0, include_lights=False)
    on = ann.instance_map > 0
    P_light = backproject(scene.depth_gt, intr)[on]
    P_host = backproject(host.depth, intr)[on]
    n_host = host.normals[on]
    assert np.isfinite(P_host).all(), "a light hangs in the sky"
    dist = np.abs(np.sum((P_light - P_host) * n_host, axis=-1))
    assert dist.max() < 1e-3  # lights are flush with their host face
    assert angular_error_deg(scene.normals_gt[on], n_host).max() < 0.5
    # Lights do not change the semantic label of their host.
    host_prim = host.prim[on]
    assert (host_prim >= 0).all()
    stats = ann.stats()
    for i in ids:
        assert stats[i]["area"] >= 1


def test_groups_reference_existing_lights(scene):
    ann = scene.lights
    ids = set(ann.instance_ids())
    gclasses = {g.class_id for g in ann.groups.values()}
    assert {13, 14} <= gclasses
    for g in ann.groups.values():
        assert g.members and set(g.members) <= ids
        if g.class_id == 13:
            assert all(class_of(m) == 1 for m in g.members)
        if g.class_id == 14:
            assert all(class_of(m) in (2, 3, 4) for m in g.members)
    # Windows of one floor share a group: every building window is in exactly one windows_group.
    wins = [i for i in ids if class_of(i) == 1]
    for w in wins:
        assert sum(w in g.members for g in ann.groups.values()) == 1


def test_traffic_light_group_at_moderate_size():
    s_layout, intr, _, gt = street_ground_truth(512, 256, seed=0)
    lights = np.where(gt.prim >= 0, s_layout.prims.light[np.maximum(gt.prim, 0)], 0)
    tl = [g for g, m in s_layout.groups.items() if class_of(g) == 20]
    assert len(tl) == 1
    visible = set(np.unique(lights).tolist())
    assert all(m in visible and class_of(m) == 12 for m in s_layout.groups[tl[0]])


def test_prediction_is_worse_than_gt_but_sane(scene):
    dm = depth_metrics(scene.depth, scene.depth_gt)
    assert 0.02 < dm.abs_rel < 0.3
    assert dm.delta1 > 0.8
    nm = normal_metrics(scene.normals, scene.normals_gt)
    assert 0.5 < nm.median_deg < 15.0
    assert np.allclose(np.linalg.norm(scene.normals[scene.labels != 23], axis=-1), 1.0, atol=1e-4)


def test_prediction_parameters_act():
    _, _, _, gt = street_ground_truth(W, H, seed=0)
    exact = PredictionErrors(scale=1.0, blur_frac=0.0, blur_min_px=0.3, warp_sigma=0.0, noise_sigma=0.0,
                             normal_noise=0.0)
    d0, n0 = simulate_prediction(gt.depth, gt.normals, exact, seed=0)
    assert depth_metrics(d0, gt.depth).abs_rel < 0.01
    d1, _ = simulate_prediction(gt.depth, gt.normals, PredictionErrors(scale=1.2, blur_frac=0.0, blur_min_px=0.3,
                                                                        warp_sigma=0.0, noise_sigma=0.0), seed=0)
    assert np.nanmedian(d1 / gt.depth) == pytest.approx(1.2, rel=0.01)


def test_mitsuba_render_is_pixel_aligned_with_the_ray_caster():
    from npsim_core.synthetic.render import RENDER_LIFT, render_depth_aov

    layout, intr, pose, gt = street_ground_truth(97, 45, seed=3)  # odd size on purpose
    z = render_depth_aov(layout.prims, intr, pose)
    covered = np.isfinite(gt.depth)
    assert np.array_equal(covered, z > 0)
    light = np.zeros_like(covered)
    light[covered] = layout.prims.light[gt.prim[covered]] > 0
    plain = covered & ~light
    rel = np.abs(z[plain] - gt.depth[plain]) / gt.depth[plain]
    assert np.percentile(rel, 99.5) < 1e-4
    # Lights are lifted off their host by RENDER_LIFT in the render only (no z-fighting).
    assert np.abs(z[light] - gt.depth[light]).max() < 0.2
    assert np.median(np.abs(z[light] - gt.depth[light])) < 10 * RENDER_LIFT


def test_odd_tiny_size():
    s = make_street_scene(33, 17, seed=2, spp=1)
    assert s.image.shape == (17, 33, 3)
    assert np.isnan(s.depth_gt).any() and np.isfinite(s.depth_gt).any()


def test_cli_round_trip(tmp_path, capsys):
    out = tmp_path / "scene"
    assert cli_main(["sample", "--size", "96x48", "-o", str(out), "--seed", "1", "--spp", "2"]) == 0
    err = capsys.readouterr().err
    assert "generating 96x48" in err
    for f in ("street_s1_rgb.png", "street_s1_labelIds.png", "depth_gt.npy", "normals_gt.npy", "depth_pred.npy",
              "normals_pred.npy", "intrinsics.json", "scene.json", "street_s1_lights_instanceIds.png",
              "street_s1_lights.json", "overview.png"):
        assert (out / f).exists(), f
    loaded = load_scene(out)
    ref = make_street_scene(96, 48, seed=1, spp=2)
    for k in ("image", "labels", "depth_gt", "depth", "roughness"):
        assert np.array_equal(getattr(loaded, k), getattr(ref, k), equal_nan=True), k
    for k in ("normals_gt", "normals"):  # the normals reader renormalises (last-bit differences)
        np.testing.assert_allclose(getattr(loaded, k), getattr(ref, k), atol=1e-6)
    assert np.array_equal(loaded.lights.instance_map, ref.lights.instance_map)
    assert loaded.lights.groups == ref.lights.groups
    assert loaded.intrinsics == ref.intrinsics


@pytest.mark.parametrize("size", ["0x5", "abc", "12", "-4x3", "20000x10", "5x1"])
def test_cli_rejects_bad_size(tmp_path, capsys, size):
    assert cli_main(["sample", f"--size={size}", "-o", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "--size" in err
    assert "WIDTHxHEIGHT" in err or "between 2 and 16384" in err
    assert not (tmp_path / "x").exists()


def test_street_scene_cache(tmp_path, monkeypatch):
    import npsim_core.synthetic as syn

    monkeypatch.setenv("NPSIM_CACHE", str(tmp_path))
    monkeypatch.setattr(syn, "auto_spp", lambda w, h: 1)
    stale = tmp_path / f"street_40x20_s0_v{syn.SCENE_VERSION - 1}"   # an older version's entry ...
    other = tmp_path / f"street_40x21_s0_v{syn.SCENE_VERSION - 1}"   # ... and another size's
    for f in (stale, other):
        f.mkdir()
        (f / "scene.json").write_text("{}")
    first = street_scene(40, 20, seed=0)
    folder = tmp_path / f"street_40x20_s0_v{syn.SCENE_VERSION}"
    assert (folder / "scene.json").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp folder left behind
    assert not stale.exists() and other.exists()      # superseded entries of this size are pruned

    def boom(*a, **k):
        raise AssertionError("cache miss")

    monkeypatch.setattr(syn, "make_street_scene", boom)
    second = street_scene(40, 20, seed=0)
    assert np.array_equal(first.depth_gt, second.depth_gt, equal_nan=True)
    assert np.array_equal(first.image, second.image)


def test_suite_uses_a_private_cache():
    """tests/conftest.py points the caches at a per-session folder, so tests never touch ~/.cache/npsim."""
    import os
    from pathlib import Path

    from npsim_core.render.variant import CACHE_FILE
    from npsim_core.synthetic import cache_dir

    user = (Path.home() / ".cache" / "npsim").resolve()
    assert os.environ.get("NPSIM_CACHE")
    assert cache_dir().resolve() != user
    assert user not in CACHE_FILE.resolve().parents  # the Mitsuba variant probe's cache too


def test_import_is_cheap():
    import subprocess
    import sys

    code = "import sys, npsim_core.synthetic, npsim_cli.commands.sample; print('mitsuba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_albedo_texture_is_consistent_with_image(scene):
    # Textured albedo stays in [0, 1], varies on the road; lamps are uniform per light, building panes
    # (scene version 5) vary inside: reflection gradient, frames, curtains (texture.light_factor).
    road = (scene.labels == 7) & (scene.lights.instance_map == 0)
    assert scene.albedo[road].std(axis=0).max() > 0.005
    on = scene.lights.instance_map > 0
    assert (scene.albedo[on] >= 0).all() and (scene.albedo[on] <= 1).all()
    lamps = [i for i in scene.lights.instance_ids() if i // 1000 in (3, 4, 8, 10, 12)]
    for i in lamps[:20]:
        m = scene.lights.instance_map == i
        assert np.ptp(scene.albedo[m], axis=0).max() < 1e-6
    panes = [i for i in scene.lights.instance_ids() if i // 1000 == 1 and (scene.lights.instance_map == i).sum() > 30]
    assert any(np.ptp(scene.albedo[scene.lights.instance_map == i], axis=0).max() > 0.01 for i in panes)
    assert on.any() and lamps
    # Brighter albedo -> brighter pixels on sunlit road (rank correlation is positive).
    lum = scene.image[road].astype(np.float32).mean(axis=1)
    alb = scene.albedo[road].mean(axis=1)
    assert np.corrcoef(lum, alb)[0, 1] > 0.0


_CHILD_VS_IN_PROCESS = """
import numpy as np
from npsim_core.synthetic import street_ground_truth
from npsim_core.synthetic.render import render_rgba
layout, intr, pose, _ = street_ground_truth(48, 24, seed=0)
a = render_rgba(layout.prims, intr, pose, kind="sun", spp=4, seed=0, subprocess=False)
b = render_rgba(layout.prims, intr, pose, kind="sun", spp=4, seed=0, subprocess=True)
assert a.shape == (24, 48, 4)
# Same pixels up to float rounding: the LLVM backend's threads may sum in another order.
np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)
"""


def test_render_in_child_process_matches_in_process():
    """Used when the caller's process runs another Mitsuba variant; must give the same pixels. Compared in a
    fresh interpreter: a test before this one in the same process may have set another variant (the
    in-process render then refuses, below; it used to render with that variant's sampler, other pixels)."""
    import subprocess
    import sys

    run = subprocess.run([sys.executable, "-c", _CHILD_VS_IN_PROCESS], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]


def test_an_in_process_sun_render_under_another_mitsuba_variant_is_refused():
    import subprocess
    import sys

    code = ("import mitsuba as mi; mi.set_variant('llvm_ad_rgb')\n"
            "from npsim_core.synthetic import street_ground_truth\n"
            "from npsim_core.synthetic.render import render_rgba\n"
            "layout, intr, pose, _ = street_ground_truth(48, 24, seed=0)\n"
            "try:\n"
            "    render_rgba(layout.prims, intr, pose, kind='sun', spp=4, seed=0, subprocess=False)\n"
            "except ValueError as exc:\n"
            "    assert 'scalar_rgb' in str(exc); print('refused')\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and run.stdout.strip() == "refused", run.stderr[-2000:]


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 7])
def test_ground_truth_invariants_across_seeds(seed):
    """Layout-level invariants for several seeds (ray casting only, no render)."""
    layout, intr, _, gt = street_ground_truth(160, 80, seed=seed)
    sky = gt.prim < 0
    horizon = intr.cy - intr.fy * np.tan(0.038)
    assert sky.any() and np.nonzero(sky)[0].max() < horizon  # sky only above the horizon
    assert np.array_equal(np.isnan(gt.depth), sky)
    _, _, _, host = street_ground_truth(160, 80, seed=seed, include_lights=False)
    lights = np.where(sky, 0, layout.prims.light[np.maximum(gt.prim, 0)])
    on = lights > 0
    assert on.sum() > 50
    P_l = backproject(gt.depth, intr)[on]
    P_h = backproject(host.depth, intr)[on]
    dist = np.abs(np.sum((P_l - P_h) * host.normals[on], axis=-1))
    assert dist.max() < 1e-3
    assert angular_error_deg(gt.normals[on], host.normals[on]).max() < 0.5
    # A light never changes the semantic class of its host surface.
    host_prims = layout.prims.subset(layout.prims.light == 0)
    assert np.array_equal(layout.prims.label[gt.prim[on]], host_prims.label[host.prim[on]])


def test_street_scene_unwritable_cache_still_returns_a_scene(tmp_path, monkeypatch):
    import npsim_core.synthetic as syn

    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("NPSIM_CACHE", str(blocker / "cache"))
    monkeypatch.setattr(syn, "auto_spp", lambda w, h: 1)
    with pytest.warns(RuntimeWarning, match="NPSIM_CACHE"):
        s = street_scene(24, 12, seed=0)
    assert s.image.shape == (12, 24, 3)


def test_bad_seed_and_size_rejected(tmp_path, capsys):
    from npsim_core.errors import NpsimInputError

    with pytest.raises(NpsimInputError, match="seed"):
        make_street_scene(32, 16, seed=-1)
    with pytest.raises(NpsimInputError, match="size"):
        make_street_scene(0, 16)
    assert cli_main(["sample", "--size", "32x16", "--seed", "-3", "-o", str(tmp_path / "x")]) == 2
    assert "seed" in capsys.readouterr().err


# --------------------------------------------------------------------------- hard variants (docs/synthetic.md)
HARD = ["receding", "occluded_base", "corner", "clutter", "hard"]
#: The layouts that defeat the prior on real frames without stereo (docs/synthetic.md, docs/geometry.md).
HIDDEN = ["canopy", "square", "shopfront", "hard2"]


def _labels(layout, gt):
    return np.where(gt.prim >= 0, layout.prims.label[np.maximum(gt.prim, 0)], 23)


@pytest.mark.parametrize("variant", HARD + HIDDEN)
def test_street_variants_keep_the_ground_truth_invariants(variant):
    """Ray casting only (no render): deterministic, differ from the default, sky only above the horizon,
    every light on its host surface, unit normals facing the camera."""
    layout, intr, _, gt = street_ground_truth(160, 80, seed=0, variant=variant)
    again = street_ground_truth(160, 80, seed=0, variant=variant)[3]
    assert np.array_equal(gt.depth, again.depth, equal_nan=True) and np.array_equal(gt.prim, again.prim)
    default = street_ground_truth(160, 80, seed=0)[3]
    assert not np.array_equal(gt.depth, default.depth, equal_nan=True)
    assert layout.info["variant"] == variant
    sky = gt.prim < 0
    horizon = intr.cy - intr.fy * np.tan(0.038)
    assert sky.any() and np.nonzero(sky)[0].max() < horizon
    assert np.array_equal(np.isnan(gt.depth), sky)
    n = gt.normals[~sky]
    assert np.allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-5)
    P = backproject(gt.depth, intr)[~sky]
    assert (np.sum(P * n, axis=-1) < 0).all()
    _, _, _, host = street_ground_truth(160, 80, seed=0, variant=variant, include_lights=False)
    on = ~sky & (layout.prims.light[np.maximum(gt.prim, 0)] > 0)
    dist = np.abs(np.sum((backproject(gt.depth, intr)[on] - backproject(host.depth, intr)[on]) * host.normals[on],
                         axis=-1))
    assert on.sum() > 20 and dist.max() < 1e-3


def test_street_variants_have_their_hard_features():
    def world_normals(gt):
        from npsim_core.synthetic import CameraPose

        return gt.normals @ CameraPose().R_cw  # camera -> world (x right, y up, z along the street)

    # receding: a longer street, longer blocks, more building in view
    d_layout = street_ground_truth(256, 128, seed=0)[0]
    r_layout = street_ground_truth(256, 128, seed=0, variant="receding")[0]
    assert r_layout.far_z >= 150 > d_layout.far_z

    def block_lengths(layout):  # street-side building boxes (facade blocks along z)
        pr = layout.prims
        ext = pr.hi - pr.lo
        side = (pr.label == 11) & (ext.min(axis=1) > 1.0) & (ext[:, 2] < 100) & (np.abs(pr.lo[:, 0]) < 40)
        return ext[side, 2]

    assert np.median(block_lengths(r_layout)) >= 40 > np.median(block_lengths(d_layout))
    # occluded_base: people (labelId 24) and hedges; facade feet mostly hidden
    o_layout, _, _, o_gt = street_ground_truth(512, 256, seed=0, variant="occluded_base")
    lab = _labels(o_layout, o_gt)
    assert (o_layout.prims.label == 24).sum() >= 6 and (lab == 24).any()

    def visible_feet(lab):
        b = lab == 11
        below = np.zeros_like(b)
        below[:-1] = b[:-1] & ~b[1:] & np.isin(lab[1:], (7, 8))
        return below.sum()

    assert visible_feet(lab) < 0.5 * visible_feet(_labels(d_layout, street_ground_truth(512, 256, seed=0)[3]))
    # corner: a building facade facing the camera (world normal -z) beside the street facades (+-x)
    c_layout, _, _, c_gt = street_ground_truth(256, 128, seed=0, variant="corner")
    lab = _labels(c_layout, c_gt)
    nw = world_normals(c_gt)[lab == 11]
    assert (nw[:, 2] < -0.99).sum() > 200 and (np.abs(nw[:, 0]) > 0.99).sum() > 200
    assert set(c_layout.info["cross_streets"]) == {"left", "right"}
    # clutter: more poles and vegetation than the default street
    k_layout = street_ground_truth(256, 128, seed=0, variant="clutter")[0]
    assert (k_layout.prims.label == 17).sum() > (d_layout.prims.label == 17).sum() + 5
    assert (k_layout.prims.label == 21).sum() > (d_layout.prims.label == 21).sum()


def test_hidden_contact_variants_have_their_features():
    """canopy: wide crowns over the sidewalk whose trunks mostly own no pixel; square: the street ends and
    buildings stand 40-150 m away across it, seen beside the near blocks; shopfront: glazed ground floors,
    awnings and crowds hiding most facade feet; hard2: all of them on the hard street."""
    d_layout, _, _, d_gt = street_ground_truth(256, 128, seed=0, include_lights=False)
    # canopy: >= 8 big trees; most of their trunks hidden (by people, shelters, vans, sign boards)
    layout, _, _, gt = street_ground_truth(256, 128, seed=0, variant="canopy", include_lights=False)
    pr = layout.prims.subset(layout.prims.light == 0)
    crowns = np.nonzero((pr.label == 21) & (pr.lo[:, 1] >= 2.0) & (pr.lo[:, 1] < 3.0)
                        & (pr.hi[:, 0] - pr.lo[:, 0] >= 4.3))[0]
    assert layout.info["canopy_trees"] == crowns.size >= 8
    seen = [(gt.prim == c).sum() > 0 for c in crowns]
    trunk_seen = [(gt.prim == c - 1).sum() > 0 for c in crowns]
    assert sum(seen) >= 6 and sum(t for s, t in zip(seen, trunk_seen) if s) <= 0.5 * sum(seen)
    # square: no far building closing the street; buildings across the square 40-150 m away, in view
    layout, _, _, gt = street_ground_truth(256, 128, seed=0, variant="square", include_lights=False)
    pr = layout.prims.subset(layout.prims.light == 0)
    zs = layout.info["square_z"]
    assert 28.0 <= zs <= 45.0 and layout.far_z == pytest.approx(zs, abs=0.01)
    lab = np.where(gt.prim >= 0, pr.label[np.maximum(gt.prim, 0)], 23)
    far = (lab == 11) & (pr.lo[np.maximum(gt.prim, 0), 2] > zs + 10.0)
    assert far.sum() > 2000 and 40.0 <= np.median(gt.depth[far]) <= 150.0
    # shopfront: crowds (person boxes) and awnings; fewer visible facade feet than the default street
    layout, _, _, gt = street_ground_truth(512, 256, seed=0, variant="shopfront")
    assert layout.info["shop_people"] >= 50
    d512 = street_ground_truth(512, 256, seed=0)

    def visible_feet(layout, gt):
        lab = _labels(layout, gt)
        b = lab == 11
        return (b[:-1] & ~b[1:] & np.isin(lab[1:], (7, 8))).sum()

    assert visible_feet(layout, gt) < 0.6 * visible_feet(d512[0], d512[3])
    # hard2: the hard street's features plus these
    h = street_ground_truth(160, 80, seed=0, variant="hard2")[0].info
    assert h["cross_streets"] and h["people"] > 0 and h["canopy_trees"] > 0 and h["shop_people"] > 0
    assert h["square_z"] >= max(b for _, b in h["cross_streets"].values()) + 6.0


def test_variant_api_names_and_cache(tmp_path, monkeypatch):
    import npsim_core.synthetic as syn
    from npsim_core.errors import NpsimInputError

    monkeypatch.setenv("NPSIM_CACHE", str(tmp_path))
    monkeypatch.setattr(syn, "auto_spp", lambda w, h: 1)
    s = make_street_scene(48, 24, seed=0, spp=1, variant="corner")
    assert s.name == "street_corner_s0" and s.provenance["variant"] == "corner"
    assert s.provenance["layout"]["variant"] == "corner"
    d = street_scene(48, 24, seed=0)
    assert d.name == "street_s0" and "variant" not in d.provenance and "variant" not in d.provenance["layout"]
    h = street_scene(48, 24, seed=0, variant="hard")
    assert h.provenance["variant"] == "hard"
    assert (tmp_path / f"street_48x24_s0_v{syn.SCENE_VERSION}").is_dir()
    assert (tmp_path / f"street_48x24_s0_hard_v{syn.SCENE_VERSION}").is_dir()
    assert not np.array_equal(d.labels, h.labels)
    for bad in ("nope", "Default", ""):
        with pytest.raises(NpsimInputError, match="street variant"):
            make_street_scene(16, 8, variant=bad)
        with pytest.raises(NpsimInputError, match="street variant"):
            street_scene(16, 8, variant=bad)


def test_busy_variant_is_the_default_street_plus_its_objects():
    """The busy street (docs/synthetic.md) adds people, riders, a truck or bus and the ego hood
    after every default draw: its first primitives are the default street's, bit for bit."""
    from npsim_core.synthetic.street import EGO_VEHICLE, build_street, frame_border_labels

    for seed in (0, 1):
        base, busy = build_street(seed), build_street(seed, "busy")
        n = len(base.prims)
        assert len(busy.prims) > n and base.groups == busy.groups and base.sun == busy.sun
        for name in ("lo", "hi", "label", "light", "color", "material", "out"):
            assert np.array_equal(getattr(busy.prims, name)[:n], getattr(base.prims, name)), name
        extra = set(busy.prims.label[n:].tolist())
        assert {24, 25, 33, EGO_VEHICLE} <= extra and extra & {27, 28}
    border = frame_border_labels(200, 100)
    assert set(np.unique(border).tolist()) == {0, 2, 3} and border[50, 0] == 3 and border[0, 0] == 2
