"""Nights on the busy synthetic street (people, riders, a truck or bus, the ego hood, the frame
borders): the ego rule, people in the headlights, speckle after denoising and auto exposure
(docs/relight.md, "The ego vehicle", "People in the headlights", "Speckle", "Exposure")."""

from __future__ import annotations

import numpy as np
import pytest

from npsim_core.camera import backproject
from npsim_core.chain import Chain, ChainParams
from npsim_core.errors import NpsimInputError
from npsim_core.render.camera_post import auto_exposure
from npsim_core.render.denoise import denoise_night, isolated_outliers
from npsim_core.render.ego import composite_ego, road_band_above
from npsim_core.render.lights import srgb_to_linear
from npsim_core.synthetic import street_scene
from npsim_core.synthetic.primitives import CameraPose

W, H = 256, 128
Y = np.array([0.2126, 0.7152, 0.0722])


@pytest.fixture(scope="module")
def busy():
    return street_scene(W, H, 0, variant="busy")


@pytest.fixture(scope="module")
def night(busy):
    """One night at the defaults, camera noise off (so the picture can be compared with the render),
    parked cars' headlamps all on (p 1; the light table has 0.02-0.06), so that a tenth of the busy
    street is lit for the speckle test whatever the night's draw (p 0.2 did it by the draw's luck
    until each light's draw was keyed to its id)."""
    p = ChainParams().with_value("night", "noise", False).with_value("night", "probabilities", ((3, 1.0),))
    chain = Chain(busy)
    res = chain.compute(p)
    frame = chain.night_final(res, p)
    _, guides, mats, _ = chain.night_inputs(p)
    lights = mats.light_classes > 0
    clean = denoise_night(frame.linear, guides, p.denoise, lights, denoiser=p.night.denoiser_used)
    clean, _ = composite_ego(clean, busy.image, busy.labels, lights)
    return {"chain": chain, "res": res, "frame": frame, "guides": guides, "clean": clean, "params": p}


def test_busy_street_has_people_riders_a_big_vehicle_and_the_ego_labels(busy):
    present = set(np.unique(busy.labels).tolist())
    assert {1, 2, 3, 24, 25, 33} <= present and present & {27, 28}
    hood = busy.labels == 1
    assert np.isin(busy.labels[-1], (1, 2, 3)).all() and hood[-1].mean() > 0.8  # the bottom rows,
    assert not hood[: int(0.85 * H)].any()                                     # like Cityscapes
    assert np.isfinite(busy.depth_gt[hood]).all() and (busy.depth_gt[hood] < 1.1).all()  # a real 3D bonnet
    n = busy.normals_gt[hood]
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)
    assert (busy.image[busy.labels == 2] == 0).all()                    # no data on the rectification border
    layout = busy.provenance["layout"]
    assert layout["crossing"] == 2 and layout["riders"] >= 1 and layout["ego_hood"]


def test_ego_and_border_pixels_get_no_geometry(busy, night):
    mesh = night["res"].mesh
    for part in mesh.parts:
        if part.n_vertices:
            on_pixel = (part.pixel == np.rint(part.pixel)).all(1)   # (sheet borders reach half a pixel out)
            px = part.pixel[on_pixel].astype(int)
            assert not np.isin(busy.labels[px[:, 1], px[:, 0]], (1, 2, 3)).any(), part.name


def test_hood_is_no_brighter_than_the_lit_road_above_it_and_has_no_row_streaks(busy, night):
    lin = srgb_to_linear(night["frame"].image.astype(np.float32) / 255.0) @ Y
    hood, band = busy.labels == 1, road_band_above(busy.labels)
    assert band.sum() > 50
    road = float(np.median(lin[band]))
    assert road > 0.01                                                  # lit by the headlights
    assert np.percentile(lin[hood], 99) <= road
    # Row streaks: the mean of each hood row (central columns, fully hood) against its neighbours.
    cols = hood[-int(0.03 * H):].all(0) & hood[H - int(0.05 * H)]
    rows = np.nonzero(hood[:, cols].all(1))[0]
    means = lin[np.ix_(rows, np.nonzero(cols)[0])].mean(1)
    jump = np.abs(np.diff(means)) / max(float(means.mean()), 1e-4)
    assert jump.max() < 0.3
    # The road's last rows are not lifted into the headlights (no bright line along the bonnet).
    edge = np.zeros_like(hood)
    edge[:-1] = hood[1:] & ~hood[:-1] & (busy.labels[:-1] == 7)
    assert np.median(lin[edge]) < 2.0 * road


def test_pedestrians_saturate_only_where_the_rendered_radiance_does(busy, night):
    ev = night["frame"].exposure["exposure_ev"]
    exposed = night["clean"] * 2.0 ** ev
    ped = np.isin(busy.labels, (24, 25))
    saturated = ped[..., None] & (night["frame"].image == 255)
    assert (exposed[saturated] >= 0.98).all()


def test_headlights_light_the_legs_not_the_body_of_people_ahead(busy, night):
    """The cause of the white pedestrians: a plain cone puts full intensity on their bodies
    (torso/road irradiance 18 measured); the low beam's cut-off keeps it below about 0.6 m."""
    lin, alb = night["frame"].linear @ Y, np.maximum(busy.albedo @ Y, 1e-3)
    pose = CameraPose(busy.camera_height, busy.camera_pitch)
    world = backproject(busy.depth_gt, busy.intrinsics) @ pose.R_cw + pose.center
    near = (busy.depth_gt > 8) & (busy.depth_gt < 15)
    ped = (busy.labels == 24) & near & (np.abs(world[..., 0]) < 3.0)   # the two crossing ahead
    road = (busy.labels == 7) & near
    torso, legs = ped & (world[..., 1] > 0.9), ped & (world[..., 1] < 0.5)
    assert torso.sum() > 10 and legs.sum() > 10
    e_road = np.median(lin[road] / alb[road])
    assert np.median(lin[torso] / alb[torso]) < 2.0 * e_road
    assert np.median(lin[legs] / alb[legs]) > 4.0 * e_road               # facing the lamps, lit


def test_denoising_leaves_no_isolated_outliers_in_lit_regions(night):
    bad, lit = isolated_outliers(night["clean"], night["guides"])
    assert lit.sum() > 0.1 * W * H
    assert bad.sum() / lit.sum() < 0.001
    raw_bad, raw_lit = isolated_outliers(night["frame"].linear, night["guides"])
    assert raw_bad.sum() / raw_lit.sum() > 0.01                        # the test sees the render's speckle


def test_same_seed_same_exposure_and_manual_override(busy, night):
    p = night["params"]
    again = Chain(busy)
    f2 = again.night_final(again.compute(p), p)
    e1, e2 = night["frame"].exposure, f2.exposure
    assert e1["exposure_mode"] == "auto" and e1["exposure_ev"] == e2["exposure_ev"]
    assert p.night.exposure_min <= e1["exposure_auto_ev"] <= p.night.exposure_max
    manual = p.with_value("night", "exposure_mode", "manual").with_value("night", "exposure", 1.25)
    f3 = night["chain"].night_final(night["res"], manual)
    assert f3.exposure["exposure_ev"] == 1.25 and "meter" not in f3.exposure
    with pytest.raises(NpsimInputError, match="exposure_mode"):
        ChainParams().with_value("night", "exposure_mode", "programme")


def test_auto_exposure_meters_lit_pixels_within_its_bounds():
    rng = np.random.default_rng(0)
    lin = rng.uniform(0.01, 0.05, (32, 64, 3)).astype(np.float32)
    labels = np.full((32, 64), 7, np.uint8)
    labels[:4] = 23
    lin[:4] = 5.0                                                        # a bright sky is not metered
    ev, info = auto_exposure(lin, labels, target=0.1, bounds=(-3, 4))
    ev2, _ = auto_exposure(lin * 2, labels, target=0.1, bounds=(-3, 4))
    assert abs(ev - ev2 - 1.0) < 1e-6 and abs(info["meter"] * 2 ** ev - 0.1) < 1e-6
    assert auto_exposure(lin, labels, target=100.0, bounds=(-3, 4))[0] == 4.0          # clipped
    assert auto_exposure(lin, labels, target=1e-4, bounds=(-3, 4))[0] == -3.0
    assert auto_exposure(lin, labels, target=0.1, bounds=(-3, 4), compensation=-1)[0] == pytest.approx(ev - 1)
    assert auto_exposure(np.zeros_like(lin), labels, compensation=0.5)[0] == 0.5      # nothing lit


def test_the_exposure_is_written_in_the_night_manifest(tmp_path):
    import json

    from npsim_core.chain import export_frame

    scene = street_scene(128, 64, 0, variant="busy")
    p = (ChainParams().with_value("refine", "steps", 5).with_value("night", "final_spp", 4)
         .with_value("night", "exposure", -0.5))
    export_frame(Chain(scene), p, tmp_path, nights=1, kinds=("nights",))
    manifest = json.loads(next(tmp_path.glob("*_export.json")).read_text())
    ex = manifest["nights"][0]["exposure"]
    assert ex["exposure_mode"] == "auto" and ex["ego_pixels"] > 0
    assert ex["exposure_ev"] == pytest.approx(ex["exposure_auto_ev"] - 0.5, abs=1e-5)   # -0.5 = compensation
    assert manifest["params"]["night"]["exposure_mode"] == "auto"
