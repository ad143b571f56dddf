"""What a frame writes by default (issue: ≤ 25 MB a 2048x1024 frame): every default output loads
back, the manifest's checksums cover every file, the input depth and float32 maps only with
``--full-outputs``, the refined depth as a 16-bit PNG and the mesh as a Draco-compressed GLB
within its stated position error."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
import trimesh

from npsim_core.annotation import load_annotation
from npsim_core.chain.chain import Chain
from npsim_core.chain.export import export_frame, file_checksum, verify_frame
from npsim_core.chain.params import ChainParams
from npsim_core.chain.stages import lit_mesh
from npsim_core.io import read_depth, read_image, read_json, read_label_image
from npsim_core.mesh.export import GLB_MAX_ERROR_M, export_glb, read_glb
from npsim_core.synthetic import street_scene

QUICK = ChainParams().with_value("refine", "steps", 8).with_value("night", "final_spp", 1)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    scene = street_scene(128, 64)
    chain = Chain(scene)
    out = tmp_path_factory.mktemp("frame")
    files = export_frame(chain, QUICK, out, nights=1)
    return chain, out, files


def _load(path):
    """Load one output by its kind; raises when it does not load."""
    name = path.name
    if name.endswith(".json"):
        return read_json(path)
    if name.endswith("_depth_refined.png"):
        return read_depth(path)
    if name.endswith("_lights_instanceIds.png") or name.endswith("_lights_classIds.png"):
        return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if name.endswith("labelIds.png"):
        return read_label_image(path)
    if name.endswith(".png"):
        return read_image(path, color=not name.endswith("_uncertain.png"))
    if name.endswith(".glb"):
        return read_glb(path)
    if name.endswith(".npy"):
        return np.load(path)
    raise AssertionError(f"an output of unknown kind: {name}")


def test_every_default_output_loads_back_and_is_checksummed(exported, tmp_path):
    chain, out, files = exported
    man = json.loads(files[-1].read_text())
    on_disk = {p.name for p in out.iterdir()}
    # the manifest covers every file in the folder (itself aside), each with its checksum
    assert on_disk - {files[-1].name} == set(man["files"])
    assert all(man["checksums"][n] == file_checksum(out / n) for n in man["files"])
    assert verify_frame(out) is None
    for f in man["files"]:
        assert _load(out / f) is not None
    n = chain.scene.name
    ann = load_annotation(out, n)  # the light annotation as a whole, as the editor reads it
    assert ann.instance_ids() == chain.annotation.instance_ids()
    # no copy of the input depth, no float32 maps by default
    assert not any("depth_input" in f or f.endswith(".npy") for f in man["files"])
    res = chain.compute(QUICK, until="mesh")
    d = read_depth(out / f"{n}_depth_refined.png")
    ref = res.depth
    valid = np.isfinite(ref) & (ref > 0)
    assert np.array_equal(np.isfinite(d), valid)  # 0 = invalid, exactly where the depth is
    assert np.abs(d[valid] - ref[valid]).max() <= 0.5 / 256 + 1e-6  # steps of 1/256 m
    assert man["depth"]["clipped_beyond_255.99_m"] == 0
    # --full-outputs (export.extras) adds the input depth and the float32 maps
    full = export_frame(chain, QUICK.with_value("export", "extras", True), tmp_path, nights=0)
    names = {p.name for p in full}
    assert {f"{n}_depth_input.npy", f"{n}_depth_refined.npy", f"{n}_depth_input.png"} <= names
    assert verify_frame(tmp_path) is None



def test_compressed_glb_round_trip_within_its_error(exported, tmp_path):
    chain, out, _ = exported
    n = chain.scene.name
    res = chain.compute(QUICK, until="mesh")
    small, _ = lit_mesh(res.mesh_result, chain.lights(QUICK).annotation, QUICK.export.mesh_tolerance,
                        QUICK.mesh.far_limit)
    plain = export_glb(small, tmp_path / "plain.glb", chain.scene.image)
    packed = out / f"{n}_mesh.glb"
    assert packed.stat().st_size < plain.stat().st_size / 3
    back = read_glb(packed)
    assert (back.width, back.height) == (small.width, small.height)
    want = [p for p in small.parts if p.n_faces]
    assert [p.name for p in back.parts] == [p.name for p in want]
    from scipy.spatial import cKDTree

    for a, b in zip(want, back.parts):
        assert b.n_faces == a.n_faces and b.foreground == a.foreground
        # every written vertex lies within the stated error of one of the mesh's own vertices,
        # with its label, light id and uv (draco reorders vertices, so matched by position)
        dist, idx = cKDTree(a.vertices).query(b.vertices)
        assert dist.max() <= GLB_MAX_ERROR_M
        assert np.array_equal(a.label[idx], b.label) and np.array_equal(a.light_id[idx], b.light_id)
        assert np.abs(a.uv[idx] - b.uv).max() * max(small.width, small.height) <= 0.125
        # face labels and light ids follow from the vertices (ties of three labels aside)
        np.testing.assert_array_equal(np.sort(a.face_light_id()), np.sort(b.face_light_id()))
        la = a.label[a.faces]
        tie = (la[:, 0] != la[:, 1]) & (la[:, 1] != la[:, 2]) & (la[:, 0] != la[:, 2])
        if not tie.any():
            np.testing.assert_array_equal(np.sort(a.face_label()), np.sort(b.face_label()))
    # a maintained third-party reader (trimesh with DracoPy) loads it too, labels included
    g = trimesh.load(packed, process=False)
    assert sum(len(x.faces) for x in g.geometry.values()) == small.n_faces
    assert "_LABEL" in g.geometry[want[0].name].vertex_attributes
    # and the plain GLB reads back through the same reader
    assert read_glb(plain).n_faces == small.n_faces


def test_ply_is_streamed_in_blocks(tmp_path, monkeypatch):
    """The PLY is written block by block (4000x3000 `npsim mesh`: 28 M faces): any block size
    gives the same bytes, and the records in memory at once stay within a block."""
    import tracemalloc

    import npsim_core.mesh.export as mesh_export
    from npsim_core.camera import Intrinsics
    from npsim_core.mesh.export import export_ply
    from npsim_core.mesh.grid import grid_mesh

    W, H = 256, 128
    intr = Intrinsics.from_fov(W, H, 90)
    d = np.full((H, W), 10.0, np.float32) + np.linspace(0, 1, W, dtype=np.float32)
    lab = np.full((H, W), 11, np.uint8)  # building
    lab[:, W // 2:] = 7  # road
    lights = np.zeros((H, W), np.int32)
    lights[10:20, 10:30] = 4001
    m = grid_mesh(d, intr, lab, lights)
    whole = export_ply(m, tmp_path / "whole.ply").read_bytes()
    monkeypatch.setattr(mesh_export, "PLY_BLOCK", 1000)
    tracemalloc.start()
    export_ply(m, tmp_path / "blocks.ply")
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert (tmp_path / "blocks.ply").read_bytes() == whole
    records = m.n_faces * 22 + m.n_vertices * 29  # the face and vertex records of the whole mesh
    assert peak < records / 4
    t = trimesh.load(tmp_path / "blocks.ply", process=False)
    assert len(t.faces) == m.n_faces
    face = t.metadata["_ply_raw"]["face"]["data"]
    np.testing.assert_array_equal(np.asarray(face["light_id"]).ravel(), m.parts[0].face_light_id())


def test_manifest_says_how_much_of_the_depth_was_guessed(exported, tmp_path):
    """The pop-up prior's confidence reaches the manifest as a structured field (share of pixels below
    0.5); a frame with its own depth has none (docs/geometry.md "Confidence in the chain")."""
    chain, out, files = exported
    man = read_json(files[-1])
    assert man["depth_confidence"] is None  # the synthetic street carries its own depth
    prior = QUICK.with_value("depth", "source", "prior")
    written = export_frame(Chain(chain.scene), prior, tmp_path, nights=0, kinds=("masks",))
    conf = read_json(written[-1])["depth_confidence"]
    assert conf is not None and 0.05 < conf["low_share"] < 0.6 and conf["threshold"] == 0.5


def test_the_last_night_is_denoised_without_the_scene(exported):
    """A frame's last night drops the cached Mitsuba scene before denoising (the worker's memory peak
    came with the scene held through the denoiser: issue #30), and the manifest still has the night
    stages' times and the render mesh it read from the scene."""
    chain, out, files = exported
    man = read_json(files[-1])
    assert {"night_scene", "materials", "guides"} <= set(man["timings"])
    # the night's own time still counts the scene it built (read before the night, then dropped)
    assert man["nights"][0]["timings"]["night_inputs"] >= 0.9 * man["timings"]["night_scene"]
    assert man["nights"][0]["render_mesh"] == "the chain's mesh" and man["nights"][0]["render_faces"] > 0
    assert "night_scene" in chain.engine.run(("night_scene",), QUICK).recomputed
