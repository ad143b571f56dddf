"""Where a frame's lights come from (``lights.source``, ``--lights``): the hand annotation, the
automatic proposals, a file or none; dataset frames pick up the annotation saved beside their image."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np
import pytest

from npsim_cli.main import main
from npsim_core.annotation import annotation_paths, annotation_stem, save_annotation, save_coco
from npsim_core.chain import Chain, ChainParams, iter_frames, load_frame
from npsim_core.chain.stages import lit_mesh
from npsim_core.errors import NpsimInputError
from npsim_core.synthetic import street_scene
from npsim_core.synthetic.cityscapes import fixture_image

W, H = 128, 64
FAST = ["--set", "refine.steps=5", "--spp", "1"]


@pytest.fixture(scope="module")
def dataset(cityscapes_layout):
    return cityscapes_layout(frames=2, size=(W, H), corrupt=0)



def test_each_source_gives_its_annotation_and_says_so(tmp_path):
    scene = street_scene(W, H)
    assert scene.lights is not None and scene.lights.instance_ids()
    chain = Chain(scene)
    p = ChainParams().with_value("refine", "steps", 5)
    auto = chain.lights(p)
    assert auto.source == "annotation" and auto.annotation is scene.lights
    assert chain.lights(p.with_value("lights", "source", "none")).annotation is None
    from npsim_core.annotation import LightAnnotation

    chain.set_annotation(LightAnnotation.empty(H, W))  # an editor on an unlabelled frame: still proposed
    assert chain.lights(p).source == "proposed"
    assert chain.lights(p.with_value("lights", "source", "annotation")).annotation.instance_ids() == []
    chain.set_annotation(scene.lights)
    proposed = chain.lights(p.with_value("lights", "source", "proposed"))
    assert proposed.source == "proposed" and "proposed lights" in proposed.note
    if proposed.annotation is not None:
        assert all(proposed.confidence[i] >= 0.5 for i in proposed.annotation.instance_ids())
    # a file: the editor's format and COCO give the same annotation
    save_annotation(scene.lights, tmp_path, "frame")
    save_coco(scene.lights, tmp_path / "frame_coco.json")
    for path in (annotation_paths(tmp_path, "frame")["json"], tmp_path / "frame_coco.json"):
        got = Chain(scene.with_(lights=None)).lights(p.with_value("lights", "source", "file")
                                                     .with_value("lights", "file", str(path)))
        assert got.source == "file" and np.array_equal(got.annotation.instance_map, scene.lights.instance_map)


def test_lights_feed_the_mesh_and_the_nights():
    scene = street_scene(W, H)
    chain = Chain(scene)
    p = ChainParams().with_value("refine", "steps", 5)
    lit = chain.compute(p)
    dark = chain.compute(p.with_value("lights", "source", "none"))
    assert dark.recomputed == ["lights"] and dark.mesh is lit.mesh  # the lights do not change the geometry
    assert any(part.light_id.any() for part in lit_mesh(lit.mesh_result, lit.lights.annotation)[0].parts)
    assert not any(part.light_id.any() for part in lit_mesh(dark.mesh_result, dark.lights.annotation)[0].parts)
    built = chain.night_inputs(p)[0]
    assert 0 < built.info["lights"] <= len(scene.lights.instance_ids())  # a light under a pixel may get no face
    assert chain.night_inputs(p.with_value("lights", "source", "none"))[0].info["lights"] == 0
    assert chain.activate(p.with_value("lights", "source", "none")).lights == {}
    assert chain.activate(p).lights  # the annotated lights get states


def test_bad_light_files_are_named():
    with pytest.raises(NpsimInputError, match="lights.file"):
        Chain(street_scene(W, H)).lights(ChainParams().with_value("lights", "source", "file"))
    with pytest.raises(NpsimInputError, match="lights.source must be one of"):
        ChainParams().with_value("lights", "source", "sometimes")
    scene = street_scene(W, H)
    other = street_scene(2 * W, 2 * H)
    with tempfile.TemporaryDirectory() as d:
        save_annotation(other.lights, d, "big")
        path = str(annotation_paths(d, "big")["json"])
        p = ChainParams().with_value("lights", "source", "file").with_value("lights", "file", path)
        with pytest.raises(NpsimInputError, match=r"big_lights.json: the light annotation is 256x128"):
            Chain(scene).lights(p)
        (Path(d) / "x.json").write_text(json.dumps({"hello": 1}))
        with pytest.raises(NpsimInputError, match="neither an NPSim light annotation .* nor a COCO"):
            Chain(scene).lights(p.with_value("lights", "file", str(Path(d) / "x.json")))


def test_dataset_frames_use_the_annotation_saved_beside_their_image(dataset):
    root, stems = dataset
    image = fixture_image(root, stems[0])
    assert annotation_stem(image) == stems[0]
    assert load_frame(image).lights is None
    lights = street_scene(W, H).lights
    save_annotation(lights, image.parent, annotation_stem(image))
    try:
        for scene in (load_frame(image), iter_frames(root)[0].load()):
            assert np.array_equal(scene.lights.instance_map, lights.instance_map)
            assert scene.provenance["lights"].endswith(f"{stems[0]}_lights.json")
        assert iter_frames(root)[1].load().lights is None
    finally:
        for p in annotation_paths(image.parent, stems[0]).values():
            p.unlink(missing_ok=True)


def test_cli_lights_option(dataset, tmp_path, capsys):
    root, stems = dataset
    image = str(fixture_image(root, stems[0]))
    out = tmp_path / "none"
    assert main(["run", image, "-o", str(out), "--lights", "none", *FAST]) == 0
    assert "lights: no light sources" in capsys.readouterr().err
    manifest = json.loads((out / f"{stems[0]}_export.json").read_text())
    assert manifest["lights"]["source"] == "none" and manifest["lights"]["count"] == 0
    assert main(["run", image, "-o", str(tmp_path / "x"), "--lights", str(tmp_path / "missing.json")]) == 2
    assert "neither auto" in capsys.readouterr().err
    save_annotation(street_scene(W, H).lights, tmp_path, "f")
    assert main(["batch", str(root), "-o", str(tmp_path / "b"), "--lights",
                 str(annotation_paths(tmp_path, "f")["json"])]) == 2
    assert "cannot light every frame of a batch" in capsys.readouterr().err


def test_a_batch_of_unannotated_frames_lights_its_nights_with_proposals(dataset, tmp_path):
    root, stems = dataset
    out = tmp_path / "batch"
    assert main(["batch", str(root), "-o", str(out), "--workers", "1", *FAST]) == 0
    for stem in stems:
        manifest = json.loads(next(out.rglob(f"{stem}_export.json")).read_text())
        assert manifest["lights"]["source"] == "proposed" and manifest["lights"]["count"] > 0
        assert all(0.5 <= c <= 1 for c in manifest["lights"]["confidence"].values())
        night = manifest["nights"][0]
        assert night["lights"] == manifest["lights"]["count"]  # every proposed light got a state
