"""The Cityscapes-layout fixture (npsim_core.synthetic.cityscapes): real-data paths without ground truth."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from npsim_core.camera import Intrinsics
from npsim_core.datasets import detect_layout, open_dataset
from npsim_core.errors import NpsimInputError
from npsim_core.io import read_label_image
from npsim_core.labels import cityscapes
from npsim_core.synthetic import street_ground_truth, street_scene
from npsim_core.synthetic.cityscapes import (BASELINE, NATIVE_SIZE, camera_json, ego_vehicle_mask, fixture_seed,
                                             fixture_stem, native_intrinsics, simulate_stereo_disparity,
                                             write_cityscapes_fixture)

W, H = 128, 64
SEED = 3
NOISE = 0.02


@pytest.fixture(scope="module")
def fixture_root(tmp_path_factory) -> tuple[Path, list[str]]:
    root = tmp_path_factory.mktemp("cs") / "cityscapes"
    stems = write_cityscapes_fixture(root, frames=3, size=(W, H), seed=SEED, corrupt=1, noise=NOISE, stereo="noise")
    return root, stems


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_layout_is_a_plain_cityscapes_tree(fixture_root):
    root, stems = fixture_root
    assert stems == [fixture_stem("synthcity", i) for i in range(3)] == \
        ["synthcity_000000_000019", "synthcity_000001_000019", "synthcity_000002_000019"]
    assert detect_layout(root) == "cityscapes"
    srcs = open_dataset(root)
    assert [s.name for s in srcs] == stems
    assert all((s.layout, s.split, s.group) == ("cityscapes", "val", "synthcity") for s in srcs)
    assert all(s.disparity_path is not None and s.camera_path is not None for s in srcs)
    # Exactly the Cityscapes files: no depth, normals, arrays, scene files or temporaries.
    expected = set()
    for st in stems:
        expected |= {f"leftImg8bit/val/synthcity/{st}_leftImg8bit.png",
                     f"gtFine/val/synthcity/{st}_gtFine_labelIds.png",
                     f"gtFine/val/synthcity/{st}_gtFine_instanceIds.png",
                     f"gtFine/val/synthcity/{st}_gtFine_color.png",
                     f"disparity/val/synthcity/{st}_disparity.png",
                     f"camera/val/synthcity/{st}_camera.json"}
    assert set(_files(root)) == expected
    # The disparity PNGs are uint16 like real ones; the camera JSON has the Cityscapes keys only.
    disp = cv2.imread(str(srcs[0].disparity_path), cv2.IMREAD_UNCHANGED)
    assert disp.dtype == np.uint16 and disp.shape == (H, W)
    import json
    cam = json.loads(srcs[0].camera_path.read_text())
    assert set(cam) == {"extrinsic", "intrinsic"}
    assert set(cam["extrinsic"]) == {"baseline", "pitch", "roll", "x", "y", "yaw", "z"}
    assert set(cam["intrinsic"]) == {"fx", "fy", "u0", "v0"}
    assert cam["extrinsic"]["baseline"] == BASELINE
    # Intrinsics are for the native 2048x1024 image, as in real files.
    assert (cam["intrinsic"]["fx"], cam["intrinsic"]["u0"]) == (2262.52, 1096.98)


def test_good_frame_loads_image_labels_camera_and_stereo_depth(fixture_root):
    root, stems = fixture_root
    for i, src in enumerate(open_dataset(root)[:2]):
        truth = street_scene(W, H, fixture_seed(SEED, i))
        scene = src.load()
        hood = ego_vehicle_mask(W, H)
        assert 0.04 < hood.mean() < 0.08 and hood[-1].all() and not hood[: int(0.9 * H)].any()
        np.testing.assert_array_equal(scene.image[~hood], truth.image[~hood])
        np.testing.assert_array_equal(scene.labels[~hood], truth.labels[~hood])
        assert (scene.labels[hood] == 1).all()                                 # ego vehicle, labelId 1
        # Camera: the reader's rescaled JSON intrinsics are the synthetic ones bit for bit; pose round-trips.
        assert scene.intrinsics == truth.intrinsics
        assert (scene.camera_height, scene.camera_pitch) == (truth.camera_height, truth.camera_pitch)
        assert "camera json" in scene.provenance["intrinsics"]
        # Stereo depth: real-looking coverage, holes on sky and the hood, values within the noise.
        # It loads as the stereo depth; there is no ground truth (nor any other depth or normals).
        d, gt = scene.depth_stereo, truth.depth_gt
        assert d is not None and scene.provenance["stereo_depth"].endswith("depth_stereo")
        assert scene.depth_gt is None and scene.normals_gt is None and scene.depth is None and scene.normals is None
        np.testing.assert_array_equal(src.load(disparity_as="gt").depth_gt, d)
        ok = np.isfinite(d)
        assert 0.75 <= ok.mean() <= 0.85
        assert not ok[truth.labels == 23].any() and not ok[hood].any()
        assert np.isfinite(gt[ok]).all()
        rel = np.abs(d[ok] / gt[ok] - 1.0)
        # Gaussian multiplicative noise: median |error| = 0.674 sigma (plus 1/256 px quantisation).
        assert 0.5 * NOISE < np.median(rel) < 0.85 * NOISE
        assert np.percentile(rel, 99) < 4 * NOISE
        assert np.nanmax(gt[ok]) < 123.0                                       # far range is a hole
        # Holes are not only sky and hood: occlusion bands, the left border, thin structures, blobs.
        inner = ~hood & (truth.labels != 23)
        assert 0.05 < 1.0 - ok[inner].mean() < 0.2
        assert not ok[int(0.85 * H), :3].any()       # left border: those points are outside the right view


def test_instance_ids_follow_the_cityscapes_convention(fixture_root):
    root, stems = fixture_root
    table = cityscapes()
    inst_classes = {c.id for c in table.classes if c.has_instances}
    for i, st in enumerate(stems):
        gt_dir = root / "gtFine" / "val" / "synthcity"
        labels = read_label_image(gt_dir / f"{st}_gtFine_labelIds.png")
        inst = cv2.imread(str(gt_dir / f"{st}_gtFine_instanceIds.png"), cv2.IMREAD_UNCHANGED)
        assert inst.dtype == np.uint16 and inst.shape == labels.shape
        is_inst = np.isin(labels, list(inst_classes))
        assert is_inst.any()                                                    # the street has cars
        np.testing.assert_array_equal(inst[~is_inst], labels[~is_inst])        # plain labelIds elsewhere
        np.testing.assert_array_equal(inst[is_inst] // 1000, labels[is_inst])  # classId*1000 + k
        for cls in np.unique(labels[is_inst]):
            ks = sorted(int(v) % 1000 for v in np.unique(inst[labels == cls]))
            assert ks == list(range(len(ks)))                                  # k = 0, 1, 2, ...
        # Each car instance is one car: its pixels are within a car's length in depth.
        truth = street_scene(W, H, fixture_seed(SEED, i))
        for v in np.unique(inst[is_inst]):
            dz = truth.depth_gt[inst == v]
            assert np.nanmax(dz) - np.nanmin(dz) < 6.0


def test_instances_separate_overlapping_cars():
    from npsim_core.synthetic.cityscapes import instance_ids

    layout, _, _, gt = street_ground_truth(256, 128, 0)
    labels = np.where(gt.prim >= 0, layout.prims.label[np.maximum(gt.prim, 0)], 23).astype(np.uint8)
    by_object = instance_ids(labels, gt.prim, layout.prims)
    by_component = instance_ids(labels)
    n_obj = len(np.unique(by_object[labels == 26]))
    n_comp = len(np.unique(by_component[labels == 26]))
    assert n_obj > n_comp  # parked cars touch in the image; connected components merge them


def test_corrupt_frame_is_a_clear_input_error(fixture_root):
    root, stems = fixture_root
    bad = open_dataset(root)[-1]
    assert bad.name == stems[-1]
    with pytest.raises(NpsimInputError, match="not a readable image|truncated PNG"):
        bad.load()
    data = bad.image_path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"                                    # looks like a PNG, is cut short
    # Its labels, disparity and camera are intact.
    assert read_label_image(bad.label_path).shape == (H, W)
    assert cv2.imread(str(bad.disparity_path), cv2.IMREAD_UNCHANGED).shape == (H, W)
    assert bad.camera(W, H)[0] == Intrinsics.cityscapes(W, H)


def test_same_arguments_same_bytes(fixture_root, tmp_path):
    root, _ = fixture_root
    again = tmp_path / "again"
    write_cityscapes_fixture(again, frames=3, size=(W, H), seed=SEED, corrupt=1, noise=NOISE, stereo="noise")
    assert _files(again) == _files(root)
    other = tmp_path / "other"
    write_cityscapes_fixture(other, frames=1, size=(W, H), seed=SEED + 7, corrupt=0, color=False,
                             ego_vehicle=False)
    files = _files(other)
    assert len(files) == 5 and not any(k.endswith("_color.png") for k in files)
    st = fixture_stem("synthcity", 0)
    assert files[f"leftImg8bit/val/synthcity/{st}_leftImg8bit.png"] != \
        _files(root)[f"leftImg8bit/val/synthcity/{st}_leftImg8bit.png"]
    assert not (read_label_image(other / f"gtFine/val/synthcity/{st}_gtFine_labelIds.png") == 1).any()


@pytest.mark.parametrize("size", [(128, 64), (256, 128), (250, 125), (97, 45), (333, 167), (2048, 1024)])
def test_camera_json_intrinsics_round_trip_exactly(size):
    intr = Intrinsics.cityscapes(*size)
    nat = native_intrinsics(intr)
    assert (nat.width, nat.height) == NATIVE_SIZE
    assert nat.resized(*size) == intr
    odd = Intrinsics(300.123456789, 301.5, 160.25, 77.75, *size)
    assert native_intrinsics(odd).resized(*size) == odd
    doc = camera_json(intr, 1.22, 0.038)
    assert doc["extrinsic"]["z"] == 1.22 and doc["extrinsic"]["pitch"] == 0.038
    assert abs(doc["intrinsic"]["fx"] - 2262.52) < 1e-9 and abs(doc["intrinsic"]["v0"] - 513.14) < 1e-9


def test_stereo_model_parameters_act():
    layout, intr, _, gt = street_ground_truth(W, H, 1)
    labels = np.where(gt.prim >= 0, layout.prims.label[np.maximum(gt.prim, 0)], 23).astype(np.uint8)
    fx = intr.fx

    def depth_of(p):
        with np.errstate(divide="ignore"):
            return np.where(p > 0, BASELINE * fx / ((p.astype(np.float64) - 1.0) / 256.0), np.nan)

    # No noise, no extra holes: only physical holes, values exact up to the 1/256 px quantisation.
    p, info = simulate_stereo_disparity(gt.depth, labels, fx, seed=0, noise=0.0, hole_fraction=0.0)
    d = depth_of(p)
    ok = np.isfinite(d)
    assert info["blobs"] == 0.0 and info["glass"] == 0.0 and abs(info["coverage"] - ok.mean()) < 1e-12
    assert info["occluded"] > 0 and info["out_of_view"] > 0 and info["thin"] > 0
    disp_gt = BASELINE * fx / gt.depth[ok]
    assert np.abs(BASELINE * fx / d[ok] - disp_gt).max() <= 0.5 / 256 + 1e-9
    # The hole fraction sets the coverage; the noise sets the spread.
    for hf in (0.15, 0.25, 0.35):
        p, info = simulate_stereo_disparity(gt.depth, labels, fx, seed=0, noise=0.05, hole_fraction=hf)
        assert abs((p > 0).mean() - (1 - hf)) < 0.01 and abs(info["coverage"] - (1 - hf)) <= 1 / (H * W)
    d = depth_of(p)
    ok = np.isfinite(d)
    assert 0.5 * 0.05 < np.median(np.abs(d[ok] / gt.depth[ok] - 1)) < 0.85 * 0.05
    with pytest.raises(NpsimInputError):
        simulate_stereo_disparity(gt.depth, labels, fx, noise=0.7)
    with pytest.raises(NpsimInputError):
        simulate_stereo_disparity(gt.depth, labels, fx, hole_fraction=1.0)


@pytest.mark.parametrize("kwargs", [{"corrupt": 4}, {"frames": 0}, {"city": "a/b"}, {"split": ""},
                                    {"seed": -1}, {"size": "big"}])
def test_bad_arguments_are_input_errors(tmp_path, kwargs):
    with pytest.raises(NpsimInputError):
        write_cityscapes_fixture(tmp_path / "x", **kwargs)
    assert not (tmp_path / "x").exists()


def test_sgm_stereo_is_the_default_and_has_structured_errors(tmp_path):
    """``--stereo sgm`` (default): disparity from OpenCV semi-global matching on a rendered right view,
    Cityscapes-encoded, with the exact depth written only outside the dataset (``--truth``)."""
    root, truth = tmp_path / "ds", tmp_path / "truth"
    stem = write_cityscapes_fixture(root, frames=1, size=(256, 128), seed=0, corrupt=0, truth=truth)[0]
    assert not list(root.rglob("*_depth.npy"))
    depth = np.load(truth / f"{stem}_depth.npy")
    p = cv2.imread(str(root / "disparity" / "val" / "synthcity" / f"{stem}_disparity.png"), cv2.IMREAD_UNCHANGED)
    assert p.dtype == np.uint16
    ok = p > 0
    assert 0.6 < ok.mean() < 0.9                          # Cityscapes: 75-85 % valid
    assert not ok[:, :16].any()                           # no match left of the search range
    d = (p[ok].astype(np.float64) - 1) / 256
    assert np.allclose(d * 16, np.rint(d * 16))           # SGBM's 1/16 px sub-pixel steps
    fx = Intrinsics.cityscapes(256, 128).fx
    rel = np.abs(BASELINE * fx / d - depth[ok]) / depth[ok]
    assert 0.01 < np.median(rel) < 0.1                    # errs like stereo, not exact ...
    assert (rel > 0.2).mean() > 0.02                      # ... with gross outliers (streaks, fattening)
    with pytest.raises(NpsimInputError, match="outside"):
        write_cityscapes_fixture(root, frames=1, size=(256, 128), corrupt=0, truth=root / "truth")


def test_sample_command_offers_the_street_variants(tmp_path):
    import argparse

    from npsim_cli.commands import sample
    from npsim_core.synthetic.street import VARIANTS

    ap = argparse.ArgumentParser()
    sample.register(ap.add_subparsers())
    args = ap.parse_args(["sample", "-o", "x", "--variant", "busy"])
    assert args.variant == "busy" and "busy" in VARIANTS
    bad = ap.parse_args(["sample", "-o", str(tmp_path / "x"), "--variant", "nonesuch"])
    with pytest.raises(NpsimInputError, match="busy"):  # the error lists the variants
        bad.func(bad)
