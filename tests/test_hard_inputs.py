"""Nothing half-written, nothing silent: each hard or bad input gets a clear error or a warning,
a failed frame never damages an earlier result, and a batch goes on past a bad frame."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from npsim_cli.main import main
from npsim_core.camera import Intrinsics
from npsim_core.chain import Chain, ChainParams, export_frame, frame_errors, verify_frame
from npsim_core.errors import NpsimInputError
from npsim_core.io import read_image, write_image, write_json, write_npy
from npsim_core.scene import Scene, save_scene
from npsim_core.synthetic import street_scene

FAST = ["--set", "refine.steps=10", "--spp", "1"]
QUICK = ChainParams().with_value("refine", "steps", 10).with_value("night", "final_spp", 1)


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


# 1 -------------------------------------------------------------------------------------------------------
def test_empty_scene_leaves_an_earlier_result_untouched(street, scene_dir, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(scene_dir), "-o", str(out), "--nights", "1"] + FAST) == 0
    assert verify_frame(out) is None
    before = _snapshot(out)
    sky = street.with_(labels=np.full_like(street.labels, 23), depth=None, normals=None, lights=None)
    save_scene(sky, tmp_path / "sky")
    capsys.readouterr()
    assert main(["run", str(tmp_path / "sky"), "-o", str(out)] + FAST) == 2
    err = capsys.readouterr().err
    assert "no valid depth" in err and "Traceback" not in err
    assert _snapshot(out) == before and verify_frame(out) is None
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no staging folder left behind


def test_failed_export_midway_keeps_the_previous_result(street, tmp_path, monkeypatch):
    chain = Chain(street)
    files = export_frame(chain, QUICK, tmp_path, nights=0)
    before = _snapshot(tmp_path)
    import npsim_core.mesh.export as mesh_export

    def broken(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(mesh_export, "export_glb", broken)
    with pytest.raises(OSError):
        export_frame(chain, QUICK.with_lambdas(1, 2, 3), tmp_path, nights=0)
    assert _snapshot(tmp_path) == before and verify_frame(tmp_path) is None
    assert files[-1].name.endswith("_export.json")


def test_a_new_result_replaces_all_of_the_old_one(street, tmp_path):
    chain = Chain(street)
    export_frame(chain, QUICK, tmp_path, nights=2)
    assert (tmp_path / f"{street.name}_night_1.png").exists()
    export_frame(chain, QUICK, tmp_path, nights=1)
    assert not (tmp_path / f"{street.name}_night_1.png").exists()  # a stale night is not left behind
    assert verify_frame(tmp_path) is None


# 2 -------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("cmd", ["run", "night", "mesh", "estimate"])
def test_output_path_that_is_a_file_is_refused_first(cmd, scene_dir, tmp_path, capsys):
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    for out in (blocker, blocker / "sub"):
        assert main([cmd, str(scene_dir), "-o", str(out)]) == 2
        err = capsys.readouterr().err
        assert str(blocker) in err and "Traceback" not in err
        assert "choose another output" in err


def test_sweep_and_batch_output_checks(scene_dir, tmp_path, capsys):
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    (tmp_path / "t.csv").mkdir()
    assert main(["sweep", str(scene_dir), "-o", str(tmp_path / "t.csv")]) == 2
    assert "is a folder" in capsys.readouterr().err
    assert main(["sweep", str(scene_dir), "-o", str(blocker)]) == 2
    assert "not a folder" in capsys.readouterr().err
    assert main(["sweep", str(scene_dir), "-o", str(blocker / "t.csv")]) == 2
    assert main(["batch", str(scene_dir.parent), "-o", str(blocker)]) == 2
    assert "not a folder" in capsys.readouterr().err


# 3 -------------------------------------------------------------------------------------------------------
def test_huge_sky_depths_are_invalid_not_pulling_the_refinement(street):
    base = Chain(street).compute(QUICK, until="refine")
    sky = street.labels == 23
    for far in (1e6, 1e30):
        d = street.depth.copy()
        d[sky] = far
        r = Chain(street.with_(depth=d)).compute(QUICK, until="refine")
        a = frame_errors(Chain(street), base)["refined"]["abs_rel"]
        b = frame_errors(Chain(street), r)["refined"]["abs_rel"]
        assert b == pytest.approx(a, rel=1e-3)
        assert np.nanmax(r.depth) <= QUICK.mesh.far_limit


def test_mesh_command_has_a_far_limit(street, tmp_path):
    import trimesh

    d = street.depth.copy()
    d[street.labels == 23] = 1e30
    save_scene(street.with_(depth=d), tmp_path / "s")
    assert main(["mesh", str(tmp_path / "s"), "-o", str(tmp_path / "m"), "--format", "ply", "--set",
                 "refine.steps=5"]) == 0
    v = trimesh.load(next((tmp_path / "m").glob("*.ply")), process=False).vertices
    assert np.isfinite(v).all() and v[:, 2].max() <= 300.0 * 1.01


# 4 -------------------------------------------------------------------------------------------------------
def test_trainids_saved_as_labelids_are_refused_with_the_fix(street, tmp_path, capsys):
    from npsim_core.io import read_label_image
    from npsim_core.labels import cityscapes

    lut = np.full(256, 255, np.uint8)
    for c in cityscapes().classes:
        if 0 <= c.train_id < 255:
            lut[c.id] = c.train_id
    train = lut[street.labels]
    train[train == 255] = 10  # no 255 anywhere: passes as labelIds by value alone
    folder = tmp_path / "ds"
    write_image(folder / "frame.png", street.image)
    write_image(folder / "frame_labelIds.png", train)
    with pytest.raises(NpsimInputError, match="--trainids"):
        read_label_image(folder / "frame_labelIds.png")
    assert np.array_equal(read_label_image(folder / "frame_labelIds.png", trainids=True) == 7, street.labels == 7)
    assert main(["run", str(folder / "frame.png"), "-o", str(tmp_path / "o")] + FAST) == 2
    assert "looks like trainIds" in capsys.readouterr().err


# 5 -------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("doc, message", [([1, 2], "JSON object"), ({"refine": {"lamda": 1}}, "refine.lamda"),
                                           ({"nigth": {}}, "unknown parameter sections"),
                                           ({"refine": 3}, "must be a JSON object")])
def test_params_files_are_strict(doc, message, scene_dir, tmp_path, capsys):
    write_json(tmp_path / "p.json", doc)
    assert main(["run", str(scene_dir), "-o", str(tmp_path / "o"), "--params", str(tmp_path / "p.json")]) == 2
    err = capsys.readouterr().err
    assert message in err and str(tmp_path / "p.json") in err


# 6 -------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("args", [["--exposure", "nan"], ["--exposure", "inf"], ["--scale", "nan"],
                                  ["--fov", "nan"], ["--set", "filter.sigma_s=NaN"]])
def test_non_finite_numbers_are_refused(args, scene_dir, tmp_path, capsys):
    assert main(["night", str(scene_dir), "-o", str(tmp_path / "o")] + args) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_a_diverging_optimiser_is_reported_and_its_result_not_used(street):
    chain = Chain(street)
    p = QUICK.with_value("refine", "optimizer", "adam_faithful").with_value("refine", "lr", 10.0) \
             .with_value("refine", "steps", 60)
    r = chain.compute(p, until="refine")
    assert r.refine.diverged and "diverged" in r.refine.message
    np.testing.assert_array_equal(np.nan_to_num(r.refine.depth), np.nan_to_num(r.filtered))
    ok = chain.compute(QUICK.with_value("refine", "steps", 30), until="refine")
    assert not ok.refine.diverged


# 7 -------------------------------------------------------------------------------------------------------
def test_empty_results_are_errors(scene_dir, street, tmp_path, capsys):
    write_npy(tmp_path / "nan.npy", np.full(street.labels.shape, np.nan, np.float32))
    assert main(["estimate", str(scene_dir), "--method", "files", "--depth", str(tmp_path / "nan.npy"),
                 "-o", str(tmp_path / "e")]) == 2
    assert "no valid pixel" in capsys.readouterr().err
    assert main(["mesh", str(scene_dir), "-o", str(tmp_path / "m"), "--far", "0.5"]) == 2
    assert "no valid depth within 0.5 m" in capsys.readouterr().err


# 8 -------------------------------------------------------------------------------------------------------
def test_every_stage_reports_its_progress(scene_dir, tmp_path, capsys):
    assert main(["mesh", str(scene_dir), "-o", str(tmp_path / "m"), "--format", "ply", "--set", "refine.steps=5"]) == 0
    out = capsys.readouterr()
    for stage in ("geometry", "lights", "filter", "uncertain", "refine", "mesh"):
        assert f"{stage} " in out.out  # per-stage seconds
        assert f"{stage}…" in out.err  # logged when it starts
    events = []
    Chain(street_scene(64, 32)).compute(QUICK, progress=events.append)
    started = [e["stage"] for e in events if set(e) == {"stage"}]
    assert started == ["geometry", "filter", "uncertain", "refine", "mesh", "lights"]
    assert any("step" in e for e in events)


# 9 -------------------------------------------------------------------------------------------------------
def test_skip_existing_verifies_files_and_checksums(scene_dir, tmp_path, capsys):
    root = tmp_path / "ds"
    save_scene(street_scene(64, 32), root / "a")
    out = tmp_path / "out"
    args = ["batch", str(root), "-o", str(out), "--nights", "0", "--skip-existing"] + FAST
    assert main(args) == 0
    frame = out / "a"
    assert verify_frame(frame) is None
    capsys.readouterr()
    assert main(args) == 0
    assert "skipped" in capsys.readouterr().err
    mesh = next(frame.glob("*_mesh.glb"))
    mesh.unlink()
    assert main(args) == 0
    assert "is missing" in capsys.readouterr().err and mesh.exists()
    png = next(frame.glob("*_depth_refined_vis.png"))
    png.write_bytes(png.read_bytes()[:-10])
    assert main(args) == 0
    assert "checksum" in capsys.readouterr().err and verify_frame(frame) is None


def test_batch_goes_on_past_bad_frames(street, tmp_path, capsys):
    root = tmp_path / "ds"
    save_scene(street, root / "a_good")
    save_scene(street.with_(labels=np.full_like(street.labels, 23), depth=None, normals=None, lights=None),
               root / "b_sky")
    save_scene(street, root / "c_corrupt")
    (root / "c_corrupt" / next(p.name for p in (root / "c_corrupt").glob("*_rgb.png"))).write_bytes(b"not a png")
    save_scene(street, root / "d_good")
    assert main(["batch", str(root), "-o", str(tmp_path / "out"), "--nights", "0"] + FAST) == 1
    err = capsys.readouterr().err
    assert "failed: b_sky" in err and "failed: c_corrupt" in err and "Traceback" not in err
    assert "2 frames done" in err
    for ok in ("a_good", "d_good"):
        assert verify_frame(tmp_path / "out" / ok) is None


# 10 ------------------------------------------------------------------------------------------------------
def test_pytest_without_a_display_skips_gui_tests_with_the_reason(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    root = Path(__file__).resolve().parents[1]
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider",
                        str(root / "tests" / "test_editor.py")], env=env, cwd=root, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "no display" in r.stdout and "skipped" in r.stdout and "Fatal" not in r.stdout + r.stderr


# the hard-case list as properties ------------------------------------------------------------------------
LABELS = (7, 8, 11, 21, 23, 26)  # road, sidewalk, building, vegetation, sky, car


@st.composite
def frames(draw):
    h = draw(st.integers(1, 20))
    w = draw(st.integers(1, 24))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    labels = rng.choice(LABELS, size=(h, w)).astype(np.uint8)
    scale = draw(st.sampled_from([0.1, 1.0, 30.0, 1e3, 1e6]))
    depth = (scale * rng.uniform(0.5, 2.0, (h, w))).astype(np.float32)
    for value in draw(st.lists(st.sampled_from([np.nan, np.inf, -np.inf, 0.0, -1.0, 1e30]), max_size=3)):
        depth[rng.random((h, w)) < 0.3] = value
    kind = draw(st.sampled_from(["depth", "prior"]))
    image = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    intr = Intrinsics.from_fov(w, h, 60.0)
    return Scene("hard", image, labels, intr, depth=depth if kind == "depth" else None)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(frame=frames())
def test_hard_frames_end_in_outputs_or_a_clear_error(frame, tmp_path_factory):
    out = tmp_path_factory.mktemp("hard")
    try:
        files = export_frame(Chain(frame), QUICK.with_value("export", "extras", True), out, nights=0,
                             mesh_formats=("ply",))  # extras: the refined depth as float32 .npy
    except NpsimInputError as exc:
        assert str(exc)
        assert not any(out.iterdir())  # nothing half-written
        return
    assert verify_frame(out) is None
    for p in files:
        if p.suffix == ".png":
            assert read_image(p).size > 0
    man = json.loads(files[-1].read_text())
    assert man["mesh"]["faces"] > 0
    d = np.load(out / "hard_depth_refined.npy")
    assert d.shape == frame.labels.shape and not np.isinf(d).any()
    finite = d[np.isfinite(d)]
    assert finite.size and finite.min() > 0
    import trimesh

    v = trimesh.load(out / "hard_mesh.ply", process=False).vertices
    assert np.isfinite(v).all() and v[:, 2].max() <= QUICK.mesh.far_limit * 1.001
