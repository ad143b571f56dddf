"""The last silent paths: every depth limited at its entrance, no ignored parameter, a
report that verifies, clean stops, a CLI that starts light, honest stereo scores, a refinement
that never spoils an exact input, and messages that name the real cause."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from npsim_cli.main import main
from npsim_core.chain import Chain, ChainParams
from npsim_core.errors import NpsimInputError
from npsim_core.io import write_npy
from npsim_core.scene import save_scene
from npsim_core.synthetic import street_scene

FAST = ["--set", "refine.steps=5", "--spp", "1"]


# 7 ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [["--help"], ["run", "--help"], ["mesh", "scene"], ["batch", "d", "-o", "o",
                                                                                     "--workers", "x"]])
def test_help_and_argument_errors_import_nothing_heavy(argv):
    """``npsim --help`` took 4.5 s and 300 MB: every command module imported the chain (torch,
    Mitsuba, OpenCV) to build its parser. Time is measured by benchmarks/cli_start.py."""
    code = ("import sys\nfrom npsim_cli.main import main\ntry:\n    main(%r)\nexcept SystemExit:\n    pass\n"
            "print('HEAVY:' + ','.join(m for m in ('torch', 'mitsuba', 'PySide6', 'ray', 'pyoidn', 'cv2', "
            "'numpy') if m in sys.modules))" % (argv,))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("HEAVY:")]
    assert line and line[-1] == "HEAVY:", out.stdout[-300:] + out.stderr[-300:]


# 1 ------------------------------------------------------------------------------------------------------
def _with_extremes(street):
    d = street.depth.copy()
    d[5, 5:15] = 1e-30
    d[20, 5:12] = 1e30
    return street.with_(depth=d)


def test_depths_outside_the_limits_are_dropped_and_counted(street):
    """1e-30 m built vertices on the camera centre (and overflowed the filter), 1e30 m passed as
    valid; both are invalid now, at the chain's entrance, with the count in the depth source."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = Chain(_with_extremes(street)).compute(ChainParams().with_value("refine", "steps", 3), until="mesh")
    assert np.isnan(res.depth_in[5, 5:15]).all() and np.isnan(res.depth_in[20, 5:12]).all()
    assert "17 pixels dropped as invalid (10 nearer than 0.1 m, 7 beyond 300 m)" in res.depth_source
    assert float(np.nanmin(res.depth)) >= 0.1
    z = np.concatenate([p.vertices[:, 2] for p in res.mesh.parts if len(p.vertices)])
    assert float(z.min()) >= 0.1 - 1e-6  # no vertex on the camera centre
    near = Chain(_with_extremes(street)).compute(ChainParams().with_value("depth", "near_limit", 3.0),
                                                 until="geometry")
    assert "nearer than 3 m" in near.depth_source and np.nanmin(near.depth_in) >= 3.0


def test_estimate_from_files_drops_absurd_depths_and_says_so(street, scene_dir, tmp_path, capsys):
    d = street.depth_gt.copy()
    d[10, 10:20] = 1e30
    d[12, 10:14] = 1e-30
    write_npy(tmp_path / "d.npy", d)
    assert main(["estimate", str(scene_dir), "--method", "files", "--depth", str(tmp_path / "d.npy"),
                 "-o", str(tmp_path / "e")]) == 0
    out = capsys.readouterr().out
    assert "14 pixels dropped as invalid (4 nearer than 0.1 m, 10 beyond 300 m)" in out
    absrel = float(out.split("AbsRel ")[1].split(",")[0])
    assert absrel < 0.01


def test_the_filter_treats_subnanometre_depth_as_invalid(street):
    import warnings

    from npsim_core.refine.bilateral import cross_bilateral

    d = street.depth.copy()
    d[:4] = 1e-30
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = cross_bilateral(d, street.image, street.labels)
    assert np.isfinite(out[8:]).any() and np.nanmax(out) < 1e4


# 5 ------------------------------------------------------------------------------------------------------
def test_estimate_in_place_keeps_the_previous_prediction(street, tmp_path, capsys):
    folder = save_scene(street, tmp_path / "s")
    first = np.load(folder / "depth_pred.npy")
    assert main(["estimate", str(folder), "--method", "popup"]) == 0
    assert "kept" in capsys.readouterr().out
    np.testing.assert_array_equal(np.load(folder / "depth_pred.prev.npy"), first)
    assert (folder / "normals_pred.prev.npy").is_file() and (folder / "scene.prev.json").is_file()
    popup = np.load(folder / "depth_pred.npy")
    write_npy(tmp_path / "d.npy", street.depth_gt)
    assert main(["estimate", str(folder), "--method", "files", "--depth", str(tmp_path / "d.npy")]) == 0
    np.testing.assert_array_equal(np.load(folder / "depth_pred.prev.npy"), first)  # never overwritten
    np.testing.assert_array_equal(np.load(folder / "depth_pred.prev2.npy"), popup)


# 6, 11 --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("gone,said", [("depth_pred.npy", "input depth falls back"),
                                       ("albedo.png", "albedo fallback"),
                                       ("roughness.npy", "roughness fallback")])
def test_a_file_scene_json_names_but_lost_is_said_in_log_and_manifest(street, tmp_path, capsys, gone, said):
    s = street.with_(albedo=np.full(street.image.shape, 0.5, np.float32),
                     roughness=np.full(street.labels.shape, 0.5, np.float32))
    folder = save_scene(s, tmp_path / "s")
    (folder / gone).unlink()
    out = tmp_path / "out"
    assert main(["run", str(folder), "-o", str(out), "--nights", "0"] + FAST) == 0
    err = capsys.readouterr().err
    assert f"WARNING: {folder / 'scene.json'} names {gone}, which is missing" in err and said in err
    man = json.loads(next(out.glob("*_export.json")).read_text())
    assert any(gone in w and said in w for w in man["warnings"])


@pytest.mark.parametrize("cut", ["truncate", "crc"])
def test_a_damaged_png_is_named_by_the_program_not_by_libpng(scene_dir, tmp_path, cut):
    """'libpng error: Read Error' reached stderr (from the C library, before the program's own line)."""
    import shutil

    folder = Path(shutil.copytree(scene_dir, tmp_path / "s"))
    png = next(folder.glob("*_rgb.png"))
    data = bytearray(png.read_bytes())
    if cut == "truncate":
        data = data[: len(data) // 2]
    else:
        data[60] ^= 0xFF  # inside the first data chunk
    png.write_bytes(bytes(data))
    code = f"from npsim_cli.main import main; raise SystemExit(main(['info', {str(folder)!r}]))"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert "libpng" not in r.stderr and ("truncated PNG" in r.stderr or "corrupt PNG" in r.stderr), r.stderr
    assert r.stderr.count("\n") == 1  # one line


def test_an_all_zero_label_file_is_called_unlabelled_not_trainids(tmp_path):
    from npsim_core.io import read_label_image, write_image

    write_image(tmp_path / "x_labelIds.png", np.zeros((32, 64), np.uint8))
    with pytest.raises(NpsimInputError) as exc:
        read_label_image(tmp_path / "x_labelIds.png")
    assert "unlabelled frame" in str(exc.value) and "trainIds" not in str(exc.value)


# 2 ------------------------------------------------------------------------------------------------------
def test_a_parameter_the_chosen_method_does_not_read_is_named(scene_dir, tmp_path, capsys):
    """``--set refine.lr=10`` with the default Gauss-Newton solver changed nothing and said nothing."""
    args = ["mesh", str(scene_dir), "-o", str(tmp_path / "m"), "--format", "ply", "--set", "refine.steps=2"]
    assert main(args + ["--set", "refine.lr=10", "--set", "denoise.sigma_depth=0.1"]) == 0
    err = capsys.readouterr().err
    assert "--set refine.lr changes nothing: refine.lr is read only by the lbfgs and adam_faithful" in err
    assert "refine.optimizer is 'fast'" in err
    assert "--set denoise.sigma_depth changes nothing: denoise.sigma_depth is read only by the guided" in err
    assert main(args + ["--set", "refine.optimizer=adam_faithful", "--set", "refine.lr=1e-4"]) == 0
    assert "changes nothing" not in capsys.readouterr().err
    doc = ChainParams().with_value("refine", "cg_iters", 3).with_value("refine", "optimizer", "lbfgs").to_json()
    (tmp_path / "p.json").write_text(json.dumps(doc))
    assert main(args + ["--params", str(tmp_path / "p.json")]) == 0
    assert f"--params {tmp_path / 'p.json'} changes nothing: refine.cg_iters is read only by the fast" \
        in capsys.readouterr().err


# 3 ------------------------------------------------------------------------------------------------------
def test_report_verifies_each_frame_and_says_what_lit_it(street, tmp_path, capsys):
    root = tmp_path / "ds"
    save_scene(street.with_(lights=None), root / "a")
    save_scene(street, root / "b")
    save_scene(street.with_(lights=None), root / "c")
    save_scene(street.with_(lights=None), root / "d")
    out = tmp_path / "out"
    assert main(["batch", str(root), "-o", str(out), "--nights", "0", "--workers", "1"] + FAST) == 0
    import shutil

    shutil.rmtree(out / "c")                                   # the whole frame folder lost
    next((out / "d").glob("*_export.json")).unlink()            # its manifest lost
    png = next((out / "b").glob("*_depth_refined_vis.png"))
    png.write_bytes(png.read_bytes()[:-7])                      # a file changed
    capsys.readouterr()
    assert main(["report", str(out)]) == 0
    said = capsys.readouterr().out
    assert "4 frames: 1 corrupt, 1 done, 2 missing" in said
    assert "c: missing: the frame's folder is gone" in said and "d: missing: no manifest" in said
    assert "b: corrupt:" in said and "checksum" in said
    page = (out / "report.html").read_text()
    assert "1 done (files and checksums verified), 2 missing, 1 corrupt" in page
    assert "proposals (" in page and "lit by the ego headlights and the sky only" not in page


# 8 ------------------------------------------------------------------------------------------------------
def test_a_stereo_input_is_scored_on_held_out_pixels_only(cityscapes_layout, tmp_path, capsys):
    """'AbsRel 0.000 -> 0.027' compared the result with its own input when the input was the stereo."""
    from npsim_core.chain import frame_errors, iter_frames
    from npsim_core.geometry.stereo import holdout_mask, stereo_valid

    root, _ = cityscapes_layout(frames=1, size=(128, 64), corrupt=0)
    frame = iter_frames(root)[0].load()
    params = ChainParams().with_value("refine", "steps", 3).with_value("depth", "stereo_surfaces", False)
    chain = Chain(frame)
    res = chain.compute(params, until="refine")
    held = holdout_mask(frame, 80.0)
    valid = stereo_valid(frame, 80.0)
    assert abs(held.sum() - 0.1 * valid.sum()) <= 1 and np.array_equal(held, holdout_mask(frame, 80.0))
    # none of the held-out stereo reached the input: there it is the prior's fill, not the stereo (a fill
    # can equal a quantised stereo value by chance: the prior's scale is the median stereo/prior ratio,
    # i.e. one ground pixel's, so along that row the scaled prior equals the stereo where it is the same)
    same = np.isclose(res.depth_in[held], frame.depth_stereo[held], rtol=1e-6)
    assert same.mean() < 0.01, int(same.sum())
    assert "held out of the input" in res.depth_source
    err = frame_errors(chain, res, 80.0, 0.1)
    assert "held out of the input" in err["reference"]
    assert err["input"]["pixels"] == int(held.sum())
    assert err["input"]["abs_rel"] > 0.001  # the input is no copy of its reference any more
    out = tmp_path / "out"
    assert main(["run", str(next(root.rglob("*_leftImg8bit.png"))), "-o", str(out), "--nights", "0"] + FAST) == 0
    assert "held out of the input" in capsys.readouterr().err
    man = json.loads(next(out.glob("*_export.json")).read_text())
    assert "held out of the input" in man["errors"]["reference"] and "held out" in man["depth_source"]


# 10 -----------------------------------------------------------------------------------------------------
def test_the_default_refinement_keeps_an_exact_input_depth():
    """Fed the synthetic street's exact depth, the default refinement took AbsRel from 0 to 0.0053 and
    the normal RMSE from 12.1 to 21.8 degrees."""
    from npsim_core.chain import frame_errors

    s = street_scene(128, 64)
    exact = s.with_(depth=s.depth_gt, normals=None)  # as 'npsim estimate --method files --depth depth_gt.npy'
    chain = Chain(exact)
    res = chain.compute(ChainParams(), until="refine")
    e = frame_errors(chain, res)
    assert res.refine.kept_input and "kept the input depth" in res.refine.message
    assert e["refined"]["abs_rel"] == 0.0
    assert e["refined"]["normal_rmse_deg"] == pytest.approx(e["input"]["normal_rmse_deg"], abs=1e-6)
    off = Chain(exact).compute(ChainParams().with_value("refine", "keep_input", False), until="refine")
    assert not off.refine.kept_input and frame_errors(Chain(exact), off)["refined"]["abs_rel"] > 1e-3
    pred = Chain(s).compute(ChainParams(), until="refine")  # a noisy prediction is still refined
    assert not pred.refine.kept_input


# 4 ------------------------------------------------------------------------------------------------------
def _children(pid: int) -> list[int]:
    try:
        return [int(x) for x in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        return []


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] not in ("Z", "X")
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads worker pids from Linux /proc")
@pytest.mark.parametrize("when", ["starting", "exporting"])
def test_sigterm_to_batch_ends_its_workers_and_leaves_no_half_frame(street, tmp_path, when):
    """Workers kept running after the parent exited; a killed export left its staging folder."""
    import signal
    import time

    from npsim_core.chain import verify_frame

    root = tmp_path / "ds"
    for k in range(4):
        save_scene(street, root / f"f{k}")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "npsim_cli", "batch", str(root), "-o", str(out), "--workers", "2", "--nights", "2",
           "--spp", "4"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    workers: set[int] = set()
    t0 = time.monotonic()
    while time.monotonic() - t0 < 90 and proc.poll() is None:  # until a worker is inside an export
        workers |= set(_children(proc.pid))
        if (when == "starting" and len(workers) >= 2) or list(out.glob("*/.*.partial-*")):
            break
        time.sleep(0.05)
    assert proc.poll() is None, proc.stderr.read()[-2000:]
    workers |= set(_children(proc.pid))
    proc.send_signal(signal.SIGTERM)
    err = proc.communicate(timeout=60)[1]
    assert proc.returncode == 130, err[-2000:]
    assert "stopped; frames in flight were not written" in err and "Traceback" not in err
    time.sleep(0.5)
    assert workers and not [p for p in workers if _alive(p)]
    assert not list(out.rglob(".*.partial-*"))  # no staging folder left behind
    for frame in out.iterdir():
        if frame.is_dir():
            assert verify_frame(frame) is None or not any(frame.iterdir())  # whole or nothing


def _stuck_export(out_root: str, name: str):
    """A worker's frame that is inside an export (its staging folder made) and stuck in native code:
    SIGTERM is blocked, as it is while a render's kernels compile, so only the SIGKILL ends it."""
    import signal
    import tempfile
    import time

    from npsim_core.io import staging_prefix

    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})
    folder = Path(out_root) / name
    folder.mkdir(parents=True, exist_ok=True)
    tempfile.mkdtemp(prefix=staging_prefix(name), dir=folder)
    time.sleep(120)


def test_a_batch_stopped_while_a_worker_is_stuck_removes_that_workers_staging(tmp_path, monkeypatch):
    """CI: a SIGTERM'd batch left '.street_s0.partial-*' behind -- its worker, under load, was still
    in native code when the grace period ended, was killed, and never reached its cleanup."""
    import functools
    import time

    from npsim_core.chain import batch
    from npsim_core.chain.session import FrameSource

    out = tmp_path / "out"
    monkeypatch.setattr(batch, "stop_workers", functools.partial(batch.stop_workers, grace_s=0.5))
    src = FrameSource("f0", tmp_path / "f0.png", functools.partial(_stuck_export, str(out), "f0"))

    def log(msg: str) -> None:  # the parent is interrupted once the worker is inside its export
        if msg.endswith("queued"):
            t0 = time.monotonic()
            while time.monotonic() - t0 < 60 and not list(out.glob("*/.*.partial-*")):
                time.sleep(0.05)
            assert list(out.glob("*/.*.partial-*"))
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        batch.run_batch([src, FrameSource("f1", src.path, functools.partial(_stuck_export, str(out), "f1"))],
                        ChainParams(), out, workers=2, log=log)
    assert not list(out.rglob(".*.partial-*"))


def test_a_stop_during_worker_start_up_is_delivered_after_the_spawn():
    """CI: a SIGTERM'd batch printed a worker's 'EOFError: Ran out of input' traceback -- the stop cut
    the parent's spawn short, closing the pipe the new worker was reading its start-up data from."""
    import os
    import signal

    from npsim_core.chain import batch

    got: list[int] = []
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: got.append(signum))
    try:
        with batch._stop_signals_held():
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(1000):  # give the handler every chance to run here
                sum(range(100))
            assert not got  # held while workers spawn ...
        assert got == [signal.SIGTERM]  # ... and delivered right after, to the handler in place before
    finally:
        signal.signal(signal.SIGTERM, previous)


def test_leftover_staging_folders_are_removed_by_the_next_run_and_said(scene_dir, tmp_path, capsys):
    out = tmp_path / "m"
    junk = out / ".street.partial-999999999-abc"  # a pid that cannot be alive
    junk.mkdir(parents=True)
    (junk / "street_mesh.ply").write_bytes(b"x" * 1000)
    old = out / ".street.partial-xyz"  # an older version's name, without a pid
    old.mkdir()
    live = out / f".street.partial-{__import__('os').getpid()}-abc"  # in use by a live process: kept
    live.mkdir()
    assert main(["mesh", str(scene_dir), "-o", str(out), "--format", "ply", "--set", "refine.steps=2"]) == 0
    err = capsys.readouterr().err
    assert f"removed {junk}" in err and "interrupted run" in err and f"removed {old}" in err
    assert not junk.exists() and not old.exists() and live.exists()
    live.rmdir()
    frame = tmp_path / "b" / "street"
    (frame / ".street.partial-999999999-x").mkdir(parents=True)
    assert main(["batch", str(scene_dir.parent), "-o", str(tmp_path / "b"), "--nights", "0", "--workers", "1"]
                + FAST) == 0
    assert "removed" in capsys.readouterr().err and not (frame / ".street.partial-999999999-x").exists()
