"""Foundation: camera, scene model and its validation, file formats, atomic writes, metrics (docs/method.md §1, §2, §9)."""

from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

from npsim_core import io as nio
from npsim_core.annotation import GroupInstance, LightAnnotation
from npsim_core.camera import Intrinsics, backproject, normals_from_depth, valid_depth_mask
from npsim_core.errors import NpsimInputError
from npsim_core.labels import cityscapes
from npsim_core.metrics import angular_error_deg, depth_metrics, normal_metrics
from npsim_core.scene import Scene, load_scene, save_scene


def _scene(W=32, H=16, **kw) -> Scene:
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    labels = np.full((H, W), 7, np.uint8)
    labels[: H // 2] = 23
    labels[H // 2 - 2: H // 2, 3:9] = 26
    args = dict(name="t", image=img, labels=labels, intrinsics=Intrinsics.from_fov(W, H, 90.0))
    args.update(kw)
    return Scene(**args)


# --------------------------------------------------------------------------- camera
def test_intrinsics_from_fov_matrix_and_resize():
    intr = Intrinsics.from_fov(640, 480, 90.0)
    assert intr.fx == pytest.approx(320.0) and intr.fy == pytest.approx(320.0)
    assert (intr.cx, intr.cy) == (319.5, 239.5)
    assert intr.hfov_deg == pytest.approx(90.0)
    K = np.array([[500.0, 0, 300], [0, 510, 200], [0, 0, 1]])
    k2 = Intrinsics.from_matrix(K, 600, 400)
    np.testing.assert_array_equal(k2.matrix, K)
    assert Intrinsics.from_dict(k2.to_dict()) == k2
    cs = Intrinsics.cityscapes(1024, 512)
    assert cs.fx == pytest.approx(2262.52 / 2) and cs.fy == pytest.approx(2265.30 / 2)
    assert cs.cx == pytest.approx((1096.98 + 0.5) / 2 - 0.5) and cs.cy == pytest.approx((513.14 + 0.5) / 2 - 0.5)
    # Resizing is invertible and keeps the pixel-centre convention: the image centre stays the centre.
    c = Intrinsics.from_fov(100, 50, 60.0).resized(200, 100)
    assert (c.cx, c.cy) == (99.5, 49.5)
    assert cs.resized(2048, 1024).cx == pytest.approx(1096.98)
    with pytest.raises(NpsimInputError, match="3x3"):
        Intrinsics.from_matrix(np.eye(2), 10, 10)
    with pytest.raises(NpsimInputError, match="field of view"):
        Intrinsics.from_fov(10, 10, 180.0)
    with pytest.raises(NpsimInputError, match="missing 'cy'"):
        Intrinsics.from_dict({"fx": 1, "fy": 1, "cx": 1, "width": 2, "height": 2})


@pytest.mark.parametrize("bad", [dict(fx=float("nan")), dict(cy=float("inf")), dict(fx=-1.0), dict(width=0)])
def test_intrinsics_reject_bad_values(bad):
    args = dict(fx=100.0, fy=100.0, cx=10.0, cy=5.0, width=20, height=10)
    args.update(bad)
    with pytest.raises(NpsimInputError, match="finite|> 0|>= 1x1"):
        Intrinsics(**args)


def test_backprojection_of_known_planes():
    intr = Intrinsics(fx=50.0, fy=40.0, cx=15.5, cy=7.5, width=32, height=16)
    P = backproject(np.full((16, 32), 4.0, np.float32), intr)
    assert P.shape == (16, 32, 3)
    np.testing.assert_allclose(P[..., 2], 4.0)
    np.testing.assert_allclose(P[3, 20], [4.0 * (20 - 15.5) / 50, 4.0 * (3 - 7.5) / 40, 4.0], rtol=1e-6)
    # Ground 1.5 m below a level camera: depth 1.5 fy / (v - cy) puts every point at y = 1.5.
    v = np.arange(16, dtype=np.float64)[:, None]
    d = np.where(v > intr.cy, 1.5 * intr.fy / np.maximum(v - intr.cy, 1e-9), np.nan) * np.ones((1, 32))
    P = backproject(d, intr)
    np.testing.assert_allclose(P[8:, :, 1], 1.5, rtol=1e-6)
    assert np.isnan(P[:8]).all()  # invalid depth -> NaN points, never silently zero
    d[0, 0], d[15, 0] = -1.0, np.inf
    assert not valid_depth_mask(d)[0, 0] and not valid_depth_mask(d)[15, 0]
    with pytest.raises(NpsimInputError, match="Intrinsics.resized"):
        backproject(np.ones((8, 8)), intr)


def test_normals_from_depth_orientation():
    intr = Intrinsics.from_fov(32, 16, 70.0)
    wall = normals_from_depth(np.full((16, 32), 7.0), intr)
    np.testing.assert_allclose(wall.reshape(-1, 3), np.tile([0, 0, -1.0], (16 * 32, 1)), atol=1e-6)
    # Flat ground 1.2 m below a level camera.
    v = np.arange(16, dtype=np.float64)[:, None]
    d = np.where(v > intr.cy, 1.2 * intr.fy / np.maximum(v - intr.cy, 1e-9), np.nan) * np.ones((1, 32))
    n = normals_from_depth(d, intr)
    np.testing.assert_allclose(n[9:].reshape(-1, 3), np.tile([0, -1.0, 0], (7 * 32, 1)), atol=1e-5)
    assert np.isnan(n[:8]).all()
    # Toward the camera: n . P < 0.
    P = backproject(d, intr)
    assert (np.einsum("hwc,hwc->hw", P[9:], n[9:]) < 0).all()
    # A wall facing the camera's left side (plane x = -3, seen to the left): n = (1, 0, 0).
    u = np.arange(32, dtype=np.float64)[None, :]
    x = (u - intr.cx) / intr.fx
    side = np.where(x < -0.05, -3.0 / np.minimum(x, -1e-9), np.nan) * np.ones((16, 1))
    ns = normals_from_depth(side, intr)
    ok = np.isfinite(ns).all(-1)
    assert ok.sum() > 50
    np.testing.assert_allclose(ns[ok], np.tile([1.0, 0, 0], (ok.sum(), 1)), atol=1e-5)


# --------------------------------------------------------------------------- scene
def test_scene_validation_names_the_problem():
    s = _scene()
    with pytest.raises(NpsimInputError, match=r"labels are \(20, 16\).*image is 32x16"):
        _scene(labels=np.zeros((16, 20), np.uint8))
    with pytest.raises(NpsimInputError, match="uint8 sRGB, got float32"):
        _scene(image=s.image.astype(np.float32))
    with pytest.raises(NpsimInputError, match="labels must be uint8"):
        _scene(labels=s.labels.astype(np.int32))
    bad = s.labels.copy()
    bad[0, 0] = 40
    with pytest.raises(NpsimInputError, match=r"\[40\].*trainids"):
        _scene(labels=bad)
    with pytest.raises(NpsimInputError, match="intrinsics are for 64x32"):
        _scene(intrinsics=Intrinsics.from_fov(64, 32, 90.0))
    with pytest.raises(NpsimInputError, match="finite"):
        _scene(intrinsics=Intrinsics(float("nan"), 1.0, 1.0, 1.0, 32, 16))
    with pytest.raises(NpsimInputError, match="depth has shape"):
        _scene(depth=np.ones((8, 8), np.float32))
    with pytest.raises(NpsimInputError, match="depth must be floating"):
        _scene(depth=np.ones((16, 32), np.int32))
    with pytest.raises(NpsimInputError, match="normals has shape"):
        _scene(normals=np.ones((16, 32), np.float32))
    with pytest.raises(NpsimInputError, match="camera_height"):
        _scene(camera_height=float("nan"))
    with pytest.raises(NpsimInputError, match="light annotation"):
        _scene(lights=LightAnnotation.empty(8, 8))


def test_scene_folder_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    H, W = 16, 32
    depth = rng.uniform(1, 50, (H, W)).astype(np.float32)
    depth[0, :4] = np.nan
    n = rng.normal(size=(H, W, 3)).astype(np.float32)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    inst = np.zeros((H, W), np.int32)
    inst[10:12, 3:6] = 3001
    inst[10:12, 7:9] = 3002
    lights = LightAnnotation(inst, groups={14001: GroupInstance(14001, (3001, 3002))})
    s = _scene(depth=depth, normals=n, depth_gt=depth * 1.1, normals_gt=n, lights=lights,
               roughness=rng.random((H, W)).astype(np.float32), camera_height=1.5, camera_pitch=0.02,
               provenance={"source": "test"})
    save_scene(s, tmp_path / "sc")
    assert (tmp_path / "sc" / "depth_pred.npy").exists() and (tmp_path / "sc" / "t_labelIds.png").exists()
    back = load_scene(tmp_path / "sc")
    np.testing.assert_array_equal(back.image, s.image)
    np.testing.assert_array_equal(back.labels, s.labels)
    assert back.intrinsics == s.intrinsics
    for attr in ("depth", "depth_gt", "roughness"):
        np.testing.assert_array_equal(getattr(back, attr), getattr(s, attr))
    for attr in ("normals", "normals_gt"):  # re-normalised on reading: float32 rounding only
        np.testing.assert_allclose(getattr(back, attr), getattr(s, attr), atol=1e-6)
    np.testing.assert_array_equal(back.lights.instance_map, inst)
    assert back.lights.groups[14001].members == (3001, 3002)
    assert (back.camera_height, back.camera_pitch) == (1.5, 0.02)
    assert back.provenance["source"] == "test"
    assert load_scene(tmp_path / "sc", with_ground_truth=False).depth_gt is None
    with pytest.raises(NpsimInputError, match="scene folder not found"):
        load_scene(tmp_path / "nope")


def test_scene_folder_with_nan_intrinsics_is_rejected_naming_the_file(tmp_path):
    save_scene(_scene(), tmp_path / "sc")
    p = tmp_path / "sc" / "intrinsics.json"
    doc = json.loads(p.read_text())
    doc["fx"] = float("nan")
    p.write_text(json.dumps(doc))  # Python's json writes NaN, and reads it back
    with pytest.raises(NpsimInputError, match=r"intrinsics\.json.*finite"):
        load_scene(tmp_path / "sc")
    p.unlink()
    with pytest.raises(NpsimInputError, match="intrinsics.json is missing"):
        load_scene(tmp_path / "sc")


# --------------------------------------------------------------------------- readers / writers
def _depth(H=12, W=20):
    rng = np.random.default_rng(1)
    d = rng.uniform(0.5, 200.0, (H, W)).astype(np.float32)
    d[0, 0] = np.nan
    return d


def test_depth_npy_pfm_round_trip(tmp_path):
    d = _depth()
    nio.write_npy(tmp_path / "d.npy", d)
    np.testing.assert_array_equal(nio.read_depth(tmp_path / "d.npy"), d)
    nio.write_pfm(tmp_path / "d.pfm", d)
    np.testing.assert_array_equal(nio.read_depth(tmp_path / "d.pfm"), d)
    rgb = np.random.default_rng(2).random((5, 7, 3)).astype(np.float32)
    nio.write_pfm(tmp_path / "c.pfm", rgb)
    np.testing.assert_array_equal(nio.read_pfm(tmp_path / "c.pfm"), rgb)
    # Invalid values (<= 0, inf) become NaN.
    nio.write_npy(tmp_path / "e.npy", np.array([[0.0, -1.0], [np.inf, 2.0]], np.float32))
    e = nio.read_depth(tmp_path / "e.npy")
    assert np.isnan(e[0]).all() and np.isnan(e[1, 0]) and e[1, 1] == 2.0


def test_depth_png_round_trip_and_range(tmp_path):
    d = _depth()
    d[1, 1] = 300.0  # beyond 65535/256 m: clipped
    nio.write_depth_png(tmp_path / "d.png", d)
    raw = cv2.imread(str(tmp_path / "d.png"), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint16 and raw[0, 0] == 0
    back = nio.read_depth(tmp_path / "d.png")
    assert np.isnan(back[0, 0])
    assert back[1, 1] == pytest.approx(65535 / 256)
    ok = np.isfinite(d) & (d < 255)
    assert np.max(np.abs(back[ok] - d[ok])) <= 0.5 / 256 + 1e-6


def test_cityscapes_disparity_png(tmp_path):
    disp = np.array([[10.0, 20.5], [0.0, 100.0]])
    raw = np.where(disp > 0, disp * 256 + 1, 0).astype(np.uint16)
    raw[1, 0] = 0  # 0 = invalid
    nio.write_image(tmp_path / "x_disparity.png", raw)
    d = nio.read_depth(tmp_path / "x_disparity.png", disparity_baseline=0.209313, disparity_focal=2262.52)
    expect = 0.209313 * 2262.52 / disp[disp > 0]
    np.testing.assert_allclose(d[disp > 0], expect, rtol=1e-6)
    assert np.isnan(d[1, 0])
    with pytest.raises(NpsimInputError, match="both baseline"):
        nio.read_depth(tmp_path / "x_disparity.png", disparity_baseline=0.2)


def test_exr_round_trip_or_clear_error(tmp_path):
    d = _depth()
    have_exr = cv2.haveImageWriter(str(tmp_path / "probe.exr"))
    p = tmp_path / "d.exr"
    if have_exr:
        cv2.imwrite(str(p), np.nan_to_num(d, nan=0.0))
        np.testing.assert_allclose(nio.read_depth(p), d, equal_nan=True)
    else:
        p.write_bytes(b"v/1\x01" + b"\0" * 64)
        with pytest.raises(NpsimInputError, match=r"d\.exr.*EXR.*\.npy or \.pfm"):
            nio.read_depth(p)


def test_normals_npy_and_png_round_trips(tmp_path):
    rng = np.random.default_rng(4)
    n = rng.normal(size=(12, 20, 3)).astype(np.float32)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    n[0, 0] = np.nan
    nio.write_npy(tmp_path / "n.npy", n)
    np.testing.assert_allclose(nio.read_normals(tmp_path / "n.npy"), n, atol=1e-6, equal_nan=True)
    for bits, tol_deg in ((16, 0.01), (8, 0.6)):
        nio.write_normals_png(tmp_path / f"n{bits}.png", n, bits=bits)
        raw = cv2.imread(str(tmp_path / f"n{bits}.png"), cv2.IMREAD_UNCHANGED)
        assert raw.dtype == (np.uint16 if bits == 16 else np.uint8)
        back = nio.read_normals(tmp_path / f"n{bits}.png")
        err = angular_error_deg(back, n)
        assert np.nanmax(err) < tol_deg, bits
        # n = 2c/(2^b - 1) - 1 exactly (docs/method.md §2.2): check one encoded pixel.
        c = raw[3, 4][::-1].astype(np.float64)  # BGR on disk
        v = 2 * c / (2 ** bits - 1) - 1
        np.testing.assert_allclose(back[3, 4], v / np.linalg.norm(v), atol=1e-6)


def test_label_png_round_trip_and_trainids(tmp_path):
    labels = np.array([[7, 8, 26], [23, 11, 0]], np.uint8)
    nio.write_image(tmp_path / "l.png", labels)
    np.testing.assert_array_equal(nio.read_label_image(tmp_path / "l.png"), labels)
    train = np.array([[0, 1, 13], [10, 2, 255]], np.uint8)
    nio.write_image(tmp_path / "t.png", train)
    np.testing.assert_array_equal(nio.read_label_image(tmp_path / "t.png", trainids=True), labels)
    # trainIds read as labelIds fail loudly when they hold unknown ids (255).
    with pytest.raises(NpsimInputError, match=r"t\.png.*\[255\].*trainids"):
        nio.read_label_image(tmp_path / "t.png")
    # Grey stored as 3 equal channels is accepted.
    nio.write_image(tmp_path / "g.png", np.repeat(labels[..., None], 3, axis=2))
    np.testing.assert_array_equal(nio.read_label_image(tmp_path / "g.png"), labels)


def test_image_round_trip_rgb_order(tmp_path):
    img = np.zeros((4, 6, 3), np.uint8)
    img[..., 0] = 200  # red
    nio.write_image(tmp_path / "i.png", img)
    np.testing.assert_array_equal(nio.read_image(tmp_path / "i.png"), img)
    nio.write_json(tmp_path / "j.json", {"a": np.float32(1.5), "b": np.arange(3)})
    assert nio.read_json(tmp_path / "j.json") == {"a": 1.5, "b": [0, 1, 2]}


def test_bad_inputs_are_rejected_naming_the_file(tmp_path):
    missing = tmp_path / "missing.png"
    for reader in (nio.read_image, nio.read_label_image, nio.read_depth, nio.read_normals, nio.read_array,
                   nio.read_json, nio.read_pfm):
        with pytest.raises(NpsimInputError, match=r"missing\.png: file not found"):
            reader(missing)
    corrupt = tmp_path / "corrupt.png"
    corrupt.write_bytes(b"\x89PNG\r\n\x1a\n" + b"garbage" * 10)
    for reader in (nio.read_image, nio.read_label_image, nio.read_depth, nio.read_normals):
        with pytest.raises(NpsimInputError, match=r"corrupt\.png"):
            reader(corrupt)
    # Depth PNG with 3 channels / 8 bits.
    nio.write_image(tmp_path / "rgb_depth.png", np.zeros((4, 4, 3), np.uint16))
    with pytest.raises(NpsimInputError, match=r"rgb_depth\.png.*single-channel 16-bit"):
        nio.read_depth(tmp_path / "rgb_depth.png")
    nio.write_image(tmp_path / "d8.png", np.ones((4, 4), np.uint8))
    with pytest.raises(NpsimInputError, match=r"d8\.png.*16-bit"):
        nio.read_depth(tmp_path / "d8.png")
    # Normals PNG with one channel; normals .npy with the wrong shape.
    nio.write_image(tmp_path / "n1.png", np.ones((4, 4), np.uint8))
    with pytest.raises(NpsimInputError, match=r"n1\.png.*3-channel"):
        nio.read_normals(tmp_path / "n1.png")
    nio.write_npy(tmp_path / "n2.npy", np.ones((4, 4), np.float32))
    with pytest.raises(NpsimInputError, match=r"n2\.npy.*HxWx3"):
        nio.read_normals(tmp_path / "n2.npy")
    # A colour label visualisation instead of labelIds.
    col = cityscapes().colorize(np.array([[7, 26], [23, 11]], np.uint8))
    nio.write_image(tmp_path / "x_color.png", col)
    with pytest.raises(NpsimInputError, match=r"x_color\.png.*colour"):
        nio.read_label_image(tmp_path / "x_color.png")
    # Depth of the wrong dimensionality; unknown suffixes; truncated .npy; bad PFM / JSON.
    nio.write_npy(tmp_path / "d3.npy", np.ones((2, 3, 4), np.float32))
    with pytest.raises(NpsimInputError, match=r"d3\.npy.*2-D"):
        nio.read_depth(tmp_path / "d3.npy")
    (tmp_path / "d.tiff").write_bytes(b"x")
    with pytest.raises(NpsimInputError, match=r"d\.tiff.*unsupported depth format"):
        nio.read_depth(tmp_path / "d.tiff")
    (tmp_path / "t.npy").write_bytes(b"\x93NUMPY\x01\x00")
    with pytest.raises(NpsimInputError, match=r"t\.npy"):
        nio.read_depth(tmp_path / "t.npy")
    (tmp_path / "b.pfm").write_bytes(b"P6\n1 1\n-1\n")
    with pytest.raises(NpsimInputError, match=r"b\.pfm.*not a PFM"):
        nio.read_pfm(tmp_path / "b.pfm")
    (tmp_path / "s.pfm").write_bytes(b"Pf\n4 4\n-1.0\n" + b"\0" * 12)
    with pytest.raises(NpsimInputError, match=r"s\.pfm.*header says 4x4"):
        nio.read_pfm(tmp_path / "s.pfm")
    (tmp_path / "b.json").write_text("{nope")
    with pytest.raises(NpsimInputError, match=r"b\.json.*not valid JSON"):
        nio.read_json(tmp_path / "b.json")
    with pytest.raises(NpsimInputError, match="is a folder"):
        nio.read_image(tmp_path)


def test_atomic_writes_keep_the_old_file_when_the_write_fails(tmp_path):
    target = tmp_path / "d.npy"
    nio.write_npy(target, np.arange(4.0))
    with pytest.raises(ValueError):
        nio.write_npy(target, np.array([object()]))  # np.save refuses pickles mid-write
    np.testing.assert_array_equal(np.load(target), np.arange(4.0))
    j = tmp_path / "a.json"
    nio.write_json(j, {"v": 1})
    with pytest.raises(TypeError):
        nio.write_json(j, {"v": object()})
    assert nio.read_json(j) == {"v": 1}
    p = tmp_path / "x.bin"
    p.write_bytes(b"old")
    with pytest.raises(RuntimeError):
        with nio.atomic_path(p) as tmp:
            tmp.write_bytes(b"half")
            raise RuntimeError("crash mid-write")
    assert p.read_bytes() == b"old"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.json", "d.npy", "x.bin"]  # no temp files left


# --------------------------------------------------------------------------- metrics
def test_depth_metrics_hand_computed():
    gt = np.array([[1.0, 2.0], [4.0, np.nan]])
    pred = np.array([[1.1, 1.0], [4.0, 3.0]])
    m = depth_metrics(pred, gt)
    # |0.1|/1, |1|/2, 0/4 -> mean 0.2; squared errors 0.01, 1, 0 -> sqrt(1.01/3); ratios 1.1, 2, 1 -> 2/3 < 1.25
    assert m.n == 3
    assert m.abs_rel == pytest.approx((0.1 + 0.5 + 0.0) / 3)
    assert m.rmse == pytest.approx(math.sqrt(1.01 / 3))
    assert m.delta1 == pytest.approx(2 / 3)
    mask = np.array([[True, False], [True, True]])
    m2 = depth_metrics(pred, gt, mask)
    assert m2.n == 2 and m2.abs_rel == pytest.approx(0.05) and m2.delta1 == 1.0
    empty = depth_metrics(pred, gt, np.zeros((2, 2), bool))
    assert empty.n == 0 and math.isnan(empty.abs_rel)
    assert set(m.as_dict()) == {"abs_rel", "rmse", "delta1", "n", "rmse_log"}
    assert m.rmse_log == pytest.approx(math.sqrt((math.log(1.1) ** 2 + math.log(2.0) ** 2) / 3))


def test_normal_metrics_hand_computed():
    def rot(deg):  # unit vector at ``deg`` from (0, 0, -1) in the x-z plane
        r = math.radians(deg)
        return [math.sin(r), 0.0, -math.cos(r)]

    gt = np.array([[[0, 0, -1.0]] * 4], dtype=np.float64)
    errs = [0.0, 10.0, 20.0, 40.0]
    pred = np.array([[rot(e) for e in errs]])
    pred[0, 2] *= 3.0  # length does not matter
    np.testing.assert_allclose(angular_error_deg(pred, gt)[0], errs, atol=1e-6)
    m = normal_metrics(pred, gt)
    assert m.n == 4
    assert m.rmse_deg == pytest.approx(math.sqrt((0 + 100 + 400 + 1600) / 4))
    assert m.mean_deg == pytest.approx(17.5) and m.median_deg == pytest.approx(15.0)
    assert (m.within_5, m.within_11_25, m.within_22_5, m.within_30) == (0.25, 0.5, 0.75, 0.75)
    pred[0, 3] = np.nan  # invalid pixels are left out
    m = normal_metrics(pred, gt)
    assert m.n == 3 and m.within_30 == 1.0
    zero = pred.copy()
    zero[0, 0] = 0.0
    assert np.isnan(angular_error_deg(zero, gt)[0, 0])


def test_atomic_writes_give_normal_file_permissions(tmp_path):
    import os

    umask = os.umask(0o022)
    os.umask(umask)
    p = tmp_path / "new.json"
    nio.write_json(p, {"a": 1})
    assert p.stat().st_mode & 0o777 == 0o666 & ~umask  # not mkstemp's private 0600
    os.chmod(p, 0o640)
    nio.write_json(p, {"a": 2})
    assert p.stat().st_mode & 0o777 == 0o640  # replacing keeps the file's mode
