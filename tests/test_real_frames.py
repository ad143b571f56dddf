"""Real dataset frames end to end, on the Cityscapes-layout fixture (no ground truth; stereo,
camera JSON, instanceIds, a corrupt frame): depth sources, scoring, run and batch."""

from __future__ import annotations

import json

import numpy as np
import pytest

from npsim_cli.main import main
from npsim_core.chain import Chain, ChainParams, iter_frames, verify_frame
from npsim_core.errors import NpsimInputError
from npsim_core.scoring import reference_of, score_depth
from npsim_core.synthetic import street_scene
from npsim_core.synthetic.cityscapes import fixture_image, fixture_seed

W, H = 128, 64
FAST = ["--set", "refine.steps=10", "--spp", "1"]


@pytest.fixture(scope="module")
def dataset(cityscapes_layout):
    return cityscapes_layout(frames=3, size=(W, H), corrupt=1)



def test_auto_takes_the_stereo_and_fills_its_holes(dataset):
    root, stems = dataset
    frame = iter_frames(root)[0].load()
    assert frame.depth is None and frame.depth_gt is None and frame.depth_stereo is not None
    res = Chain(frame).compute(ChainParams().with_value("depth", "stereo_surfaces", False), until="geometry")
    assert res.depth_source.startswith("stereo:")
    holes = ~np.isfinite(frame.depth_stereo) & ~np.isin(frame.labels, (1, 23))
    assert holes.any() and np.isfinite(res.depth_in[holes]).mean() > 0.9  # filled from the aligned prior
    assert np.isnan(res.depth_in[np.isin(frame.labels, (1, 23))]).all()    # sky and ego hood stay invalid
    # The input is the stereo where it has one (the SGM fixture's stereo is 10 % off the truth at
    # 128x64, the prior 1 %: closeness to the truth no longer tells them apart).
    st = frame.depth_stereo
    ok = np.isfinite(res.depth_in) & np.isfinite(st) & (st < 80) & (frame.labels != 1)
    rel = np.abs(res.depth_in[ok] - st[ok]) / st[ok]
    assert np.median(rel) < 1e-6


def test_depth_sources_are_chosen_or_refused_by_name(dataset):
    root, _ = dataset
    frame = iter_frames(root)[0].load()
    chain = Chain(frame)
    prior = chain.compute(ChainParams().with_value("depth", "source", "prior"), until="geometry")
    assert prior.depth_source.startswith("prior")
    with pytest.raises(NpsimInputError, match="no depth of its own"):
        chain.compute(ChainParams().with_value("depth", "source", "files"), until="geometry")
    with pytest.raises(NpsimInputError, match="checkpoint"):
        ChainParams().with_value("depth", "source", "network")
    with pytest.raises(NpsimInputError, match="no stereo depth"):
        Chain(street_scene(W, H)).compute(ChainParams().with_value("depth", "source", "stereo"), until="geometry")


def test_scoring_uses_whatever_reference_a_frame_has(dataset):
    root, _ = dataset
    frame = iter_frames(root)[0].load()
    ref = reference_of(frame)
    assert ref.kind.startswith("stereo") and np.nanmax(ref.depth) <= 80.0
    assert ref.normals is not None and np.isfinite(ref.normals).any()
    sc = score_depth(frame.depth_stereo, frame.intrinsics, frame.labels, ref)
    assert sc["abs_rel"] == 0.0 and sc["delta1"] == 1.0 and set(sc["classes"]) >= {"road", "building", "car"}
    assert reference_of(frame.with_(depth_stereo=None)) is None  # no reference: not scored, no error
    synthetic = street_scene(W, H)
    assert reference_of(synthetic).kind == "ground truth"


def test_run_on_a_real_layout_frame(dataset, tmp_path, capsys):
    root, stems = dataset
    out = tmp_path / "out"
    assert main(["run", str(fixture_image(root, stems[0])), "-o", str(out), "--nights", "1"] + FAST) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and "depth from stereo" in err and "vs stereo" in err
    man = json.loads((out / f"{stems[0]}_export.json").read_text())
    assert man["depth_source"].startswith("stereo") and man["errors"]["reference"].startswith("stereo")
    assert np.isfinite(man["errors"]["refined"]["abs_rel"]) and "building" in man["errors"]["refined"]["classes"]
    names = set(man["files"])
    assert not any("depth_input" in n for n in names)  # the dataset's stereo, not copied by default
    for must in (f"{stems[0]}_depth_refined.png", f"{stems[0]}_night_0.png", f"{stems[0]}_night_0_labelIds.png",
                 f"{stems[0]}_mesh.glb"):
        assert must in names
    assert not any(n.endswith("_linear.npy") for n in names)  # only what a frame needs by default
    assert man["mesh"]["written"]["faces"] <= man["mesh"]["faces"]
    assert verify_frame(out) is None


def test_batch_reports_the_corrupt_frame_and_finishes_the_others(dataset, tmp_path, capsys):
    root, stems = dataset
    out = tmp_path / "out"
    assert main(["batch", str(root), "-o", str(out), "--nights", "0"] + FAST) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert f"failed: {stems[2]}" in err and (("not a readable image" in err or "truncated PNG" in err) or "truncated PNG" in err)
    assert "2 frames done" in err and "2 frames vs stereo" in err  # the dataset summary
    for stem in stems[:2]:
        assert verify_frame(out / stem) is None
    # resumed: the finished frames are verified and skipped, the corrupt one tried again
    assert main(["batch", str(root), "-o", str(out), "--nights", "0", "--skip-existing"] + FAST) == 1
    err = capsys.readouterr().err
    assert err.count("skipped") >= 2 and f"failed: {stems[2]}" in err


def test_a_frame_copied_side_by_side_opens_by_folder_and_by_image(dataset, tmp_path):
    import shutil

    from npsim_core.chain import load_frame

    root, stems = dataset
    one = tmp_path / "one"
    one.mkdir()
    for p in root.rglob(f"{stems[0]}_*"):
        shutil.copy(p, one / p.name)
    by_folder = load_frame(one)
    by_image = load_frame(one / f"{stems[0]}_leftImg8bit.png")
    for s in (by_folder, by_image):
        assert s.name == stems[0] and s.depth_stereo is not None
        assert "camera json" in s.provenance["intrinsics"]
    for p in root.rglob(f"{stems[1]}_*"):
        shutil.copy(p, one / p.name)
    with pytest.raises(NpsimInputError, match="holds 2 frames"):
        load_frame(one)
