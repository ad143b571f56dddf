"""Dataset scale: the batch runner (in process, local workers, Ray), its resumable manifest,
the λ sweep with its contact sheet, and the HTML report."""

from __future__ import annotations

import json
import os

import pytest

from npsim_cli.main import main
from npsim_core.chain import ChainParams, iter_frames, verify_frame
from npsim_core.chain import batch as batch_mod
from npsim_core.io import read_image
from npsim_core.synthetic.cityscapes import fixture_image

W, H = 96, 48
QUICK = ChainParams().with_value("refine", "steps", 8).with_value("night", "final_spp", 1)
FAST = ["--set", "refine.steps=8", "--spp", "1"]


@pytest.fixture(scope="module")
def dataset(cityscapes_layout):
    return cityscapes_layout(frames=3, size=(W, H), corrupt=0)


def _mtimes(folder):
    return {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}


def test_interrupted_batch_resumes_without_recomputing(dataset, tmp_path, monkeypatch):
    root, stems = dataset
    out = tmp_path / "out"
    real = batch_mod.run_frame
    calls = []

    def interrupted(src, *a, **k):
        calls.append(src.name)
        if len(calls) == 2:
            raise KeyboardInterrupt  # the user stops the batch while the second frame runs
        return real(src, *a, **k)

    monkeypatch.setattr(batch_mod, "run_frame", interrupted)
    with pytest.raises(KeyboardInterrupt):
        batch_mod.run_batch(iter_frames(root), QUICK, out, nights=1, workers=1)
    doc = json.loads((out / "batch.json").read_text())
    assert list(doc["frames"]) == [stems[0]] and doc["frames"][stems[0]]["status"] == "done"
    assert verify_frame(out / stems[0]) is None and not (out / stems[1]).exists()
    first = _mtimes(out / stems[0])
    monkeypatch.setattr(batch_mod, "run_frame", real)
    res = batch_mod.run_batch(iter_frames(root), QUICK, out, nights=1, workers=1)
    assert [o.status for o in res.outcomes] == ["skipped", "done", "done"]
    assert _mtimes(out / stems[0]) == first  # nothing of the finished frame was touched
    doc = json.loads((out / "batch.json").read_text())
    assert all(doc["frames"][s]["status"] == "done" for s in stems)  # the first frame's record is kept

    def must_not_run(*a, **k):
        raise AssertionError("a complete frame was recomputed")

    monkeypatch.setattr(batch_mod, "run_frame", must_not_run)
    res = batch_mod.run_batch(iter_frames(root), QUICK, out, nights=1, workers=1)
    assert [o.status for o in res.outcomes] == ["skipped"] * 3
    # other parameters: the frames are recomputed, not silently kept (a stand-in for the frame's
    # computation: what is checked is that the batch runs it, not the export again)
    ran = []

    def recompute(src, *a, **k):
        ran.append(src.name)
        return batch_mod.FrameOutcome(src.name, "done", 0.0)

    monkeypatch.setattr(batch_mod, "run_frame", recompute)
    res = batch_mod.run_batch(iter_frames(root)[:1], QUICK.with_value("night", "seed", 7), out, nights=1, workers=1)
    assert ran == [stems[0]] and [o.status for o in res.outcomes] == ["done"]


def test_local_worker_processes_and_cityscapes_layout(dataset, tmp_path, capsys):
    root, stems = dataset
    out = tmp_path / "out"
    assert main(["batch", str(root), "-o", str(out), "--workers", "2", "--nights", "1", "--layout", "cityscapes"]
                + FAST) == 0
    err = capsys.readouterr().err
    assert "2 local workers" in err and "3 frames done" in err and "min left" in err
    for s in stems:
        assert verify_frame(out / s) is None
        night = out / "cityscapes" / "leftImg8bit" / "val" / "synthcity" / f"{s}_night0_leftImg8bit.png"
        label = out / "cityscapes" / "gtFine" / "val" / "synthcity" / f"{s}_night0_gtFine_labelIds.png"
        assert read_image(night).shape == (H, W, 3) and label.exists()
    doc = json.loads((out / "batch.json").read_text())
    assert doc["workers"] == 2 and all(f["peak_rss_mb"] > 0 for f in doc["frames"].values())
    # each worker holds its share of the cores in every library (torch, OpenCV, Dr.Jit)
    assert {f["threads"] for f in doc["frames"].values()} == {max(1, (os.cpu_count() or 1) // 2)}
    assert all(f["depth_source"].startswith("stereo") for f in doc["frames"].values())


def test_ray_tasks_on_a_local_instance(dataset, tmp_path, capsys):
    import ray  # noqa: F401  -- a dev dependency: missing is a failure, not a skip
    root, stems = dataset
    out = tmp_path / "out"
    assert main(["batch", str(root), "-o", str(out), "--ray", "local", "--nights", "0", "--limit", "2"] + FAST) == 0
    assert "Ray (local)" in capsys.readouterr().err
    for s in stems[:2]:
        assert verify_frame(out / s) is None
    doc = json.loads((out / "batch.json").read_text())
    assert doc["ray"] == "local"
    # a task reserves one CPU, so its frame's libraries run one thread each (Ray's workers set only
    # OMP_NUM_THREADS: OpenCV and Dr.Jit would take every core)
    assert {f["threads"] for f in doc["frames"].values()} == {batch_mod.RAY_TASK_CPUS}


def test_bad_dataset_folders_get_a_clear_message(tmp_path, capsys):
    assert main(["batch", str(tmp_path / "nope"), "-o", str(tmp_path / "o")]) == 2
    assert "not found" in capsys.readouterr().err
    (tmp_path / "empty").mkdir()
    assert main(["batch", str(tmp_path / "empty"), "-o", str(tmp_path / "o")]) == 2
    assert "no labelled images found" in capsys.readouterr().err
    assert main(["batch", str(tmp_path / "empty"), "-o", str(tmp_path / "o"), "--ray", "127.0.0.1:1"]) == 2
    assert main(["report", str(tmp_path / "empty")]) == 2
    assert "neither batch.json nor sweep.json" in capsys.readouterr().err


def test_sweep_contact_sheet_table_and_report(dataset, tmp_path, capsys):
    root, stems = dataset
    img = fixture_image(root, stems[0])
    out = tmp_path / "sweep"
    assert main(["sweep", str(img), "--lambda2", "0.1,5", "--lambda3", "1,10", "-o", str(out), "--workers", "1",
                 "--set", "refine.steps=8"]) == 0
    table = capsys.readouterr().out.strip().splitlines()
    assert len(table) == 5  # header + 2x2 cells
    doc = json.loads((out / "sweep.json").read_text())
    assert len(doc["cells"]) == 4 and doc["reference"].startswith("stereo")
    assert {"loss_normal", "loss_continuity", "loss_depth", "normal_rmse_deg", "abs_rel"} <= set(doc["cells"][0])
    sheet = read_image(out / "contact_sheet.png")
    assert sheet.shape[0] > 2 * 2 * 40 and sheet.shape[1] > 2 * 100
    page = (tmp_path / "sweep" / "report.html")
    assert main(["report", str(out)]) == 0
    text = page.read_text()
    assert "contact_sheet.png" in text and text.count("<tr") == 5


def test_batch_report_has_frames_failures_and_light_statistics(tmp_path, capsys):
    from npsim_core.scene import save_scene
    from npsim_core.synthetic import street_scene

    root = tmp_path / "ds"
    save_scene(street_scene(W, H), root / "lit")            # the synthetic street carries a light annotation
    (root / "broken").mkdir()
    (root / "broken" / "scene.json").write_text("{")
    out = tmp_path / "out"
    assert main(["batch", str(root), "-o", str(out), "--nights", "1"] + FAST) == 1
    assert main(["report", str(out)]) == 0
    text = (out / "report.html").read_text()
    assert "lit" in text and "broken" in text and "Failed frames" in text
    assert "<svg" in text and "window_building" in text          # instances and pixels per class
    assert "_night_0.png" in text and "_depth_refined_vis.png" in text
