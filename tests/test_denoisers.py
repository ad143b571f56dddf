"""Monte Carlo denoisers (OIDN, the guided filter, none), the error-bounded render mesh, the
denoiser's way into the manifest, and the bloom option (docs/relight.md)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from npsim_core.chain import Chain, ChainParams
from npsim_core.errors import NpsimInputError
from npsim_core.render.camera_post import CameraParams, add_noise, apply_camera, bloom, linear_to_srgb
from npsim_core.render.denoise import DenoiseGuides, denoise_night
from npsim_core.synthetic import street_scene

SCALAR = ["night.variant=scalar_rgb"]


def _srgb_rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((linear_to_srgb(a) * 255.0 - linear_to_srgb(b) * 255.0) ** 2)))


@pytest.fixture(scope="module")
def night():
    """A 128x64 street night (the size other tests use, so the scene is cached once): the built scene (the chain's reduced render mesh), both kinds of guides,
    a 1-spp render and a 128-spp reference of the same lights (scalar_rgb: deterministic). Much
    smaller frames hold too little noise per pixel for a denoiser to matter (at 96x48 and 4 spp
    neither helps)."""
    from npsim_core.render.denoise import denoise_guides
    from npsim_core.render.render import render_final, render_guides

    s = street_scene(128, 64)
    chain = Chain(s)
    params = ChainParams().with_sets(SCALAR + ["night.seed=1", "refine.steps=30"])
    res = chain.compute(params)
    built, _, mats, _ = chain.night_inputs(params)
    built.apply_lights(chain.activate(params))
    prot = mats.light_classes > 0
    mesh_guides = denoise_guides(res.mesh, res.intrinsics, mats.materials.albedo, s.labels, prot)
    aov_guides = render_guides(built, s.labels, prot)
    raw = render_final(built, spp=1, seed=3)
    ref = render_final(built, spp=128, seed=11, passes=2)
    return {"scene": s, "chain": chain, "res": res, "built": built, "prot": prot, "mesh": mesh_guides,
            "aov": aov_guides, "raw": raw, "ref": ref, "params": params}


@pytest.mark.parametrize("denoiser", ["oidn", "guided"])
def test_denoiser_finite_and_closer_to_reference_than_raw(night, denoiser):
    guides = night["aov"] if denoiser == "oidn" else night["mesh"]
    out = denoise_night(night["raw"], guides, ChainParams().denoise, night["prot"], denoiser=denoiser)
    assert out.shape == night["raw"].shape and out.dtype == np.float32
    assert np.isfinite(out).all() and (out >= 0).all()
    raw_err, err = _srgb_rmse(night["raw"], night["ref"]), _srgb_rmse(out, night["ref"])
    assert err < 0.9 * raw_err, (denoiser, err, raw_err)   # measured: oidn 0.72, guided 0.80


def test_oidn_runs_without_guides_and_with_guides_of_another_size(night):
    raw = night["raw"]
    plain = denoise_night(raw, None, ChainParams().denoise, denoiser="oidn")
    assert np.isfinite(plain).all() and _srgb_rmse(plain, night["ref"]) < _srgb_rmse(raw, night["ref"])
    half = raw[::2, ::2].copy()                     # a preview at half the size: guides area-averaged
    g = night["aov"].at(*half.shape[:2])
    assert g.albedo.shape == half.shape and g.kind == "aov"
    assert np.isfinite(denoise_night(half, night["aov"], ChainParams().denoise, denoiser="oidn")).all()


def test_none_only_removes_fireflies(night):
    raw = night["raw"]
    out = denoise_night(raw, None, ChainParams().denoise, night["prot"], denoiser="none")
    changed = (out != raw).any(axis=2)
    assert np.isfinite(out).all() and changed.mean() < 0.05
    assert not changed[night["prot"]].any()         # light-source pixels are never fireflies
    with pytest.raises(NpsimInputError):
        denoise_night(raw, None, denoiser="bilateral")


def test_aov_guides_match_the_mesh_guides(night):
    """Mitsuba's AOVs are the same surfaces as the rasterised mesh (camera frame, z depth)."""
    a, m = night["aov"], night["mesh"]
    both = np.isfinite(a.depth) & np.isfinite(m.depth)
    assert both.mean() > 0.8
    rel = np.abs(a.depth[both] - m.depth[both]) / m.depth[both]
    assert np.median(rel) < 0.01
    cos = (a.normals[both] * np.nan_to_num(m.normals[both])).sum(1)
    assert np.median(cos) > 0.98
    sky = night["scene"].labels == 23
    assert np.all(a.normals[sky & ~np.isfinite(a.depth)] == 0)


def test_lit_mesh_is_error_bounded_and_keeps_the_labels():
    """The mesh the nights are rendered from: fewer faces, every pixel within 1 % of the full
    mesh's depth, and its label render still reproduces the day labels."""
    from npsim_core.chain.stages import lit_mesh
    from npsim_core.mesh.quality import rasterize
    from npsim_core.render.render import render_labels
    from npsim_core.render.scene_builder import build_label_scene

    s = street_scene(256, 128)
    res = Chain(s).compute(ChainParams().with_value("refine", "steps", 30))
    mesh, what = lit_mesh(res.mesh_result, s.lights, 0.01)
    assert mesh.n_faces < 0.8 * res.mesh.n_faces and "1 %" in what
    full, red = rasterize(res.mesh, res.intrinsics).depth, rasterize(mesh, res.intrinsics).depth
    both = np.isfinite(full) & np.isfinite(red)
    assert np.mean(np.isfinite(full) == np.isfinite(red)) > 0.999
    assert np.max(np.abs(red[both] - full[both]) / full[both]) <= 0.0101
    got = render_labels(build_label_scene(mesh, s.intrinsics, s.labels, variant="scalar_rgb"))
    assert (np.where(got < 0, 23, got) == s.labels).mean() >= 0.995
    assert lit_mesh(res.mesh_result, None, 0.0)[0].n_faces == res.mesh.n_faces


def test_params_denoiser_and_old_json():
    assert ChainParams().night.denoiser_used == "oidn"
    assert ChainParams.from_json({"night": {"denoise": False}}).night.denoiser_used == "none"
    assert ChainParams.from_json({"night": {"denoise": True}}).night.denoiser_used == "oidn"
    p = ChainParams().with_sets(["night.denoiser=none"])           # JSON null from --set
    assert p.night.denoiser == "none"
    assert ChainParams().with_sets(["night.denoiser=guided"]).night.denoiser_used == "guided"
    for bad in (["night.denoiser=bm3d"], ["mesh.render_tolerance=-0.1"], ["night.bloom=2"],
                ["denoise.oidn_quality=best"]):
        with pytest.raises(NpsimInputError):
            ChainParams().with_sets(bad)
    doc = ChainParams().to_json()
    assert doc["night"]["denoiser"] == "oidn" and doc["mesh"]["render_tolerance"] == 0.0
    assert ChainParams.from_json(doc) == ChainParams()


def test_chain_night_records_its_denoiser(night):
    chain, res = night["chain"], night["res"]
    for d in ("guided", "none", "oidn"):
        p = night["params"].with_sets([f"night.denoiser={d}", "night.final_spp=2", "night.spp=2"])
        f = chain.night_final(res, p, seed=1)
        assert f.denoiser == d and np.isfinite(f.linear).all() and f.faces == night["built"].n_faces
        assert [fr.denoiser for fr in chain.night_preview(res, p)] == [d]
    off = night["params"].with_sets(["night.denoise=false", "night.final_spp=2"])
    assert chain.night_final(res, off).denoiser == "none"


@pytest.mark.parametrize("flags,expected", [([], "oidn"), (["--denoiser", "guided"], "guided"),
                                            (["--denoiser", "oidn", "--no-denoise"], "none")])
def test_denoiser_reaches_the_manifest(tmp_path, flags, expected):
    from npsim_cli.main import main
    from npsim_core.scene import save_scene

    s = street_scene(64, 32)
    save_scene(s, tmp_path / "scene")
    out = tmp_path / "out"
    assert main(["night", str(tmp_path / "scene"), "-o", str(out), "--variants", "1", "--spp", "2",
                 "--variant", "scalar_rgb", "--mesh", "grid"] + flags) == 0
    man = json.loads((out / f"{s.name}_export.json").read_text())
    assert man["nights"][0]["denoiser"] == expected
    assert man["params"]["night"]["denoiser"] == ("none" if expected == "none" else expected) or \
        not man["params"]["night"]["denoise"]
    assert man["nights"][0]["render_faces"] > 0


def test_denoiser_option_on_run_and_batch():
    from npsim_cli.main import build_parser
    from npsim_cli.options import params_from_args

    parser = build_parser()
    for cmd in (["run", "SCENE", "-o", "OUT"], ["batch", "ROOT", "-o", "OUT"]):
        args = parser.parse_args(cmd + ["--denoiser", "guided"])
        assert params_from_args(args).night.denoiser_used == "guided"
    with pytest.raises(SystemExit):
        parser.parse_args(["run", "SCENE", "-o", "OUT", "--denoiser", "fancy"])


def test_bloom_off_is_identical_to_the_camera_without_it():
    """With bloom 0 (the default) the camera is bit-identical to exposure -> noise -> white
    balance -> sRGB -> 8 bit, as before the option existed."""
    rng = np.random.default_rng(0)
    lin = (rng.random((40, 60, 3)) ** 3 * 0.3).astype(np.float32)
    lin[10:13, 20:23] = 8.0                                        # a lamp far above sensor white
    cam = CameraParams(exposure_ev=0.5, iso=1600, seed=4)
    assert CameraParams().bloom == 0 and ChainParams().night.bloom == 0
    srgb, noisy = apply_camera(lin, cam)
    x = add_noise(lin * np.float32(2.0 ** 0.5), *cam.betas(), np.random.default_rng(4))
    np.testing.assert_array_equal(noisy, x)
    np.testing.assert_array_equal(srgb, np.floor(linear_to_srgb(x) * 255.0 + 0.5).astype(np.uint8))
    assert bloom(lin, 0.0) is not None and np.array_equal(bloom(lin, 0.0), lin)


def test_bloom_spreads_only_what_exceeds_white_and_keeps_energy():
    lin = np.full((64, 128, 3), 0.05, np.float32)
    lin[30:33, 60:63] = 20.0
    out = bloom(lin, 0.3, threshold=1.0, radius=0.01)
    assert abs(out.sum() - lin.sum()) < 1e-3 * lin.sum()           # energy conserved
    assert out[31, 70].mean() > lin[31, 70].mean() + 0.01           # a halo next to the lamp
    assert out[31, 61].mean() < lin[31, 61].mean()                  # the lamp gave some of it away
    dim = np.full((16, 16, 3), 0.5, np.float32)
    np.testing.assert_array_equal(bloom(dim, 0.5), dim)             # nothing above white: unchanged
    srgb_on, _ = apply_camera(lin, CameraParams(iso=None, bloom=0.3, bloom_radius=0.01))
    srgb_off, _ = apply_camera(lin, CameraParams(iso=None))
    assert (srgb_on != srgb_off).any() and srgb_on[5, 5].tolist() == srgb_off[5, 5].tolist()
    with pytest.raises(NpsimInputError):
        CameraParams(bloom=1.5)


def test_render_panel_denoiser_combo(qtbot):
    from npsim_gui.param_values import with_gui_value
    from npsim_gui.render_panel import RenderPanel

    panel = RenderPanel()
    qtbot.addWidget(panel)
    seen = []
    panel.denoiserChanged.connect(seen.append)
    assert [panel.denoiser.itemData(i) for i in range(panel.denoiser.count())] == ["oidn", "guided", "none"]
    panel.set_denoiser("guided")                                    # showing a value emits nothing
    assert panel.denoiser.currentData() == "guided" and seen == []
    panel.denoiser.setCurrentIndex(panel.denoiser.findData("none"))
    assert seen == ["none"]
    assert with_gui_value(ChainParams(), "night", "denoiser", seen[-1]).night.denoiser_used == "none"


def test_guides_kind_resize_rules():
    H, W = 8, 8
    alb = np.zeros((H, W, 3), np.float32)
    alb[:, ::2] = 1.0                                               # stripes: area-averaging gives 0.5
    g = DenoiseGuides(alb, np.ones((H, W), np.float32), np.zeros((H, W, 3), np.float32),
                      np.zeros((H, W), np.uint8), np.zeros((H, W), bool), kind="aov")
    assert np.allclose(g.at(4, 4).albedo, 0.5)
    m = DenoiseGuides(alb, np.ones((H, W), np.float32), np.zeros((H, W, 3), np.float32),
                      np.zeros((H, W), np.uint8), np.zeros((H, W), bool))
    assert set(np.unique(m.at(4, 4).albedo)) <= {0.0, 1.0}          # mesh guides stay nearest
