"""Dataset readers: Cityscapes, ACDC and plain folders, built as tiny fake trees (docs/method.md §10)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from npsim_core.camera import Intrinsics
from npsim_core.datasets import SceneSource, default_intrinsics, detect_layout, iter_dataset, open_dataset
from npsim_core.errors import NpsimInputError
from npsim_core.io import write_image
from npsim_core.labels import cityscapes

W, H = 64, 32
CAMERA = {"extrinsic": {"baseline": 0.209313, "pitch": 0.05, "roll": 0.0, "x": 1.7, "y": 0.1, "yaw": -0.02,
                        "z": 1.3},
          "intrinsic": {"fx": 2262.52, "fy": 2265.30, "u0": 1096.98, "v0": 513.14}}


def _img(seed: int, w: int = W, h: int = H) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (h, w, 3), dtype=np.uint8)


def _labels(w: int = W, h: int = H) -> np.ndarray:
    lab = np.full((h, w), 7, np.uint8)
    lab[: h // 3] = 23
    lab[h // 3: h // 2] = 11
    lab[h // 2: h // 2 + 3, 5:15] = 26
    return lab


def _trainids(lab: np.ndarray) -> np.ndarray:
    lut = cityscapes().lut("train_id", fill=255)
    return lut[lab].astype(np.uint8)


@pytest.fixture
def cityscapes_root(tmp_path: Path) -> Path:
    root = tmp_path / "cityscapes"
    for split, city, stem, extras in (("val", "frankfurt", "frankfurt_000000_000294", True),
                                      ("val", "lindau", "lindau_000001_000019", False),
                                      ("train", "aachen", "aachen_000002_000019", False)):
        write_image(root / "leftImg8bit" / split / city / f"{stem}_leftImg8bit.png", _img(len(stem)))
        lab = _labels()
        write_image(root / "gtFine" / split / city / f"{stem}_gtFine_labelIds.png", lab)
        write_image(root / "gtFine" / split / city / f"{stem}_gtFine_labelTrainIds.png", _trainids(lab))
        write_image(root / "gtFine" / split / city / f"{stem}_gtFine_color.png", cityscapes().colorize(lab))
        if extras:
            disp = np.zeros((H, W), np.uint16)
            disp[H // 2:] = 20 * 256 + 1  # disparity 20 px at full resolution
            write_image(root / "disparity" / split / city / f"{stem}_disparity.png", disp)
            p = root / "camera" / split / city / f"{stem}_camera.json"
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_text(json.dumps(CAMERA))
    # An image without labels is skipped.
    write_image(root / "leftImg8bit" / "test" / "berlin" / "berlin_000000_000019_leftImg8bit.png", _img(9))
    return root


def test_cityscapes_layout_is_listed_and_loaded(cityscapes_root):
    assert detect_layout(cityscapes_root) == "cityscapes"
    srcs = open_dataset(cityscapes_root)
    assert [s.name for s in srcs] == ["aachen_000002_000019", "frankfurt_000000_000294", "lindau_000001_000019"]
    fr = srcs[1]
    assert isinstance(fr, SceneSource)
    assert (fr.layout, fr.split, fr.group) == ("cityscapes", "val", "frankfurt")
    assert fr.disparity_path is not None and fr.camera_path is not None
    assert srcs[0].camera_path is None and srcs[0].disparity_path is None
    scene = fr.load()
    assert scene.name == "frankfurt_000000_000294" and scene.image.shape == (H, W, 3)
    np.testing.assert_array_equal(scene.labels, _labels())
    # Intrinsics from camera.json (for 2048x1024) rescaled to the 64x32 image; pose from its extrinsic.
    assert scene.intrinsics == Intrinsics(2262.52, 2265.30, 1096.98, 513.14, 2048, 1024).resized(W, H)
    assert (scene.camera_height, scene.camera_pitch) == (1.3, 0.05)
    assert "camera json" in scene.provenance["intrinsics"]
    # Stereo depth B f / disp with the focal of the disparity image's size (here the same 64x32 scaling).
    fx = 2262.52 * W / 2048
    np.testing.assert_allclose(scene.depth_stereo[H // 2:], 0.209313 * fx / 20.0, rtol=1e-5)
    assert np.isnan(scene.depth_stereo[: H // 2]).all() and scene.depth is None and scene.depth_gt is None
    assert fr.load(disparity_as="gt").depth_gt is not None
    as_input = fr.load(disparity_as="input")
    assert as_input.depth is not None and as_input.depth_gt is None
    assert fr.load(disparity_as="none").depth_stereo is None
    with pytest.raises(NpsimInputError, match="disparity_as"):
        fr.load(disparity_as="both")
    # Without a camera file: Cityscapes' typical intrinsics, and the provenance says it was assumed.
    other = srcs[2].load()
    assert other.intrinsics == Intrinsics.cityscapes(W, H)
    assert "assumed" in other.provenance["intrinsics"] and "assumed" in other.provenance["camera_pose"]


def test_cityscapes_subfolder_fov_override_and_trainids(cityscapes_root):
    sub = cityscapes_root / "leftImg8bit" / "val" / "frankfurt"
    assert detect_layout(sub) == "cityscapes"
    srcs = open_dataset(sub, hfov_deg=60.0)
    assert [s.name for s in srcs] == ["frankfurt_000000_000294"]
    scene = srcs[0].load()
    assert scene.intrinsics == Intrinsics.from_fov(W, H, 60.0)  # --fov beats the camera file
    assert "60.0 deg (given)" in scene.provenance["intrinsics"]
    tr = open_dataset(cityscapes_root, trainids=True)
    assert all(s.label_path.name.endswith("_gtFine_labelTrainIds.png") and s.trainids for s in tr)
    t = tr[0].load()
    np.testing.assert_array_equal(t.labels, _labels())  # trainIds mapped back to labelIds
    assert t.provenance["labels_format"] == "trainIds mapped to labelIds"
    with pytest.raises(NpsimInputError, match=r"--fov.*\(0, 180\)"):
        open_dataset(cityscapes_root, hfov_deg=0.0)


def test_cityscapes_disparity_without_camera_is_a_clear_error(cityscapes_root):
    (cityscapes_root / "camera" / "val" / "frankfurt" / "frankfurt_000000_000294_camera.json").unlink()
    src = [s for s in open_dataset(cityscapes_root) if s.name.startswith("frankfurt")][0]
    with pytest.raises(NpsimInputError, match=r"frankfurt_000000_000294_disparity\.png.*baseline.*camera\.json"):
        src.load()
    assert src.load(disparity_as="none").depth_stereo is None


def test_bad_camera_json_names_the_file(cityscapes_root):
    p = cityscapes_root / "camera" / "val" / "frankfurt" / "frankfurt_000000_000294_camera.json"
    p.write_text(json.dumps({"extrinsic": {}, "intrinsic": {"fx": 1}}))
    src = [s for s in open_dataset(cityscapes_root) if s.name.startswith("frankfurt")][0]
    with pytest.raises(NpsimInputError, match=r"_camera\.json: not a Cityscapes camera file"):
        src.load()
    cam = json.loads(json.dumps(CAMERA))
    cam["intrinsic"]["fx"] = float("nan")
    p.write_text(json.dumps(cam))
    with pytest.raises(NpsimInputError, match=r"_camera\.json: camera values must be finite"):
        src.load()


def test_acdc_layout(tmp_path):
    root = tmp_path / "acdc"
    w, h = 48, 27  # ACDC's 16:9
    for cond, seq, stem in (("night", "GOPR0351", "GOPR0351_frame_000159"), ("fog", "GOPR0476", "GOPR0476_frame_000001")):
        write_image(root / "rgb_anon" / cond / "val" / seq / f"{stem}_rgb_anon.png", _img(1, w, h))
        write_image(root / "gt" / cond / "val" / seq / f"{stem}_gt_labelIds.png", _labels(w, h))
    write_image(root / "rgb_anon" / "rain" / "val" / "GOPR0400" / "GOPR0400_frame_000002_rgb_anon.png", _img(2, w, h))
    assert detect_layout(root) == "acdc"
    srcs = open_dataset(root)
    assert [(s.name, s.group) for s in srcs] == [("GOPR0476_frame_000001", "fog/GOPR0476"),
                                                ("GOPR0351_frame_000159", "night/GOPR0351")]
    scene = srcs[1].load()
    assert scene.provenance["dataset"] == "acdc" and scene.provenance["split"] == "val"
    # Not 2:1: Cityscapes' field of view with square pixels instead of a stretched Cityscapes K.
    intr = scene.intrinsics
    assert intr.fx == intr.fy and intr.hfov_deg == pytest.approx(Intrinsics.cityscapes().hfov_deg)
    assert "square pixels" in scene.provenance["intrinsics"]
    assert default_intrinsics(W, H)[0] == Intrinsics.cityscapes(W, H)
    assert [s.name for s in open_dataset(root / "rgb_anon" / "night")] == ["GOPR0351_frame_000159"]


def test_plain_folder_matches_labels_by_stem(tmp_path):
    d = tmp_path / "imgs"
    write_image(d / "a.png", _img(1))
    write_image(d / "a_labelIds.png", _labels())
    write_image(d / "a_color.png", cityscapes().colorize(_labels()))
    write_image(d / "b.jpg", _img(2))
    write_image(d / "labels" / "b.png", _labels())
    write_image(d / "c.png", _img(3))  # no labels: skipped
    write_image(d / "scene_rgb.png", _img(4))  # an NPSim scene folder's naming
    write_image(d / "scene_labelIds.png", _labels())
    assert detect_layout(d) == "folder"
    srcs = open_dataset(d)
    assert [(s.name, s.image_path.name, s.label_path.relative_to(d).as_posix()) for s in srcs] == [
        ("a", "a.png", "a_labelIds.png"), ("b", "b.jpg", "labels/b.png"), ("scene", "scene_rgb.png",
                                                                           "scene_labelIds.png")]
    s = srcs[1].load()
    assert s.image.shape == (H, W, 3) and s.provenance["dataset"] == "folder"
    np.testing.assert_array_equal(s.labels, _labels())
    write_image(d / "t.png", _img(5))
    write_image(d / "t_trainIds.png", _trainids(_labels()))
    tr = open_dataset(d, trainids=True)
    assert [x.name for x in tr] == ["b", "t"]  # labels/b.png is taken as trainIds too (explicit flag)
    np.testing.assert_array_equal(tr[1].load().labels, _labels())


def test_dataset_errors_are_clear(tmp_path):
    with pytest.raises(NpsimInputError, match="dataset folder not found"):
        open_dataset(tmp_path / "nope")
    (tmp_path / "f.txt").write_text("x")
    with pytest.raises(NpsimInputError, match="is a file"):
        open_dataset(tmp_path / "f.txt")
    empty = tmp_path / "empty"
    empty.mkdir()
    write_image(empty / "lonely.png", _img(1))
    with pytest.raises(NpsimInputError, match=r"no labelled images found.*x_labelIds\.png"):
        open_dataset(empty)
    cs = tmp_path / "cs"
    (cs / "leftImg8bit" / "val").mkdir(parents=True)
    with pytest.raises(NpsimInputError, match=r"no labelled images.*cityscapes.*gtFine_labelIds"):
        open_dataset(cs)
    with pytest.raises(NpsimInputError, match="unknown dataset layout"):
        open_dataset(empty, layout="kitti")
    # Label/image size mismatch and a colour label file are named.
    d = tmp_path / "bad"
    write_image(d / "a.png", _img(1))
    write_image(d / "a_labelIds.png", _labels(32, 16))
    with pytest.raises(NpsimInputError, match=r"a_labelIds\.png: labels are 32x16.*a\.png is 64x32"):
        open_dataset(d)[0].load()
    write_image(d / "a_labelIds.png", cityscapes().colorize(_labels()))
    with pytest.raises(NpsimInputError, match=r"a_labelIds\.png.*colour"):
        open_dataset(d)[0].load()


def test_estimate_cli_on_a_dataset_image(cityscapes_root, tmp_path, capsys):
    from npsim_cli.main import main
    from npsim_core.scene import load_scene

    img = cityscapes_root / "leftImg8bit" / "val" / "frankfurt" / "frankfurt_000000_000294_leftImg8bit.png"
    assert main(["estimate", str(img), "-o", str(tmp_path / "out")]) == 0
    s = load_scene(tmp_path / "out")
    assert s.name == "frankfurt_000000_000294" and s.depth is not None and s.depth_stereo is not None
    assert s.provenance["geometry"]["method"] == "popup"
    assert "vs stereo" in capsys.readouterr().out
    assert main(["estimate", str(img)]) == 2
    assert "-o DIR is required" in capsys.readouterr().err
    lonely = tmp_path / "lonely.png"
    write_image(lonely, _img(3))
    assert main(["estimate", str(lonely), "-o", str(tmp_path / "o2")]) == 2
    assert "no labels found" in capsys.readouterr().err
    assert list(iter_dataset(cityscapes_root / "leftImg8bit" / "test"))[:1] == []
