"""The one chain: the engine's cache and invalidation, the chain's stages, the one export writer."""

import json
import threading
from dataclasses import dataclass, replace

import numpy as np
import pytest

from npsim_core.annotation import LightAnnotation

from npsim_core.camera import Intrinsics
from npsim_core.chain import Chain, ChainParams, export_frame
from npsim_core.chain.engine import Engine, Stage, content_key
from npsim_core.errors import NpsimCancelled, NpsimInputError
from npsim_core.refine import FilterParams, RefineParams, RefineResult
from npsim_core.scene import Scene


@dataclass(frozen=True)
class Add:
    k: float = 1.0


@dataclass(frozen=True)
class P:
    a: Add = Add(1)
    b: Add = Add(10)
    c: Add = Add(100)
    use_b: bool = True


def _counting_engine():
    calls = []

    def stage(name):
        def f(inputs, p, ctx):
            calls.append(name)
            return sum(inputs.values()) + p.k
        return f

    eng = Engine((
        Stage("a", stage("a"), ("x",), lambda p: p.a),
        Stage("b", stage("b"), ("a",), lambda p: p.b),
        Stage("c", stage("c"), ("b", "x"), lambda p: p.c, needs=lambda p: ("b", "x") if p.use_b else ("x",)),
        Stage("side", stage("side"), ("x",), lambda p: Add(0)),
    ))
    eng.set_source("x", 1.0)
    return eng, calls


def test_engine_recomputes_only_downstream():
    eng, calls = _counting_engine()
    p = P()
    r = eng.run("c", p)
    assert r.results["c"] == 1 + 1 + 10 + 100 + 1 and r.recomputed == ["a", "b", "c"] and calls == ["a", "b", "c"]
    assert eng.run("c", p).recomputed == []
    assert eng.run("c", replace(p, b=Add(20))).recomputed == ["b", "c"]
    assert eng.run("c", replace(p, c=Add(5))).recomputed == ["c"]
    assert eng.run("c", p).recomputed == []  # the defaults again: still cached
    assert eng.run("side", p).recomputed == ["side"]
    eng.set_source("x", 2.0)  # a new input invalidates everything that reads it
    assert eng.run("c", p).recomputed == ["a", "b", "c"]


def test_engine_lazy_inputs_and_real_timings():
    eng, calls = _counting_engine()
    p = P(use_b=False)
    r = eng.run("c", p)
    assert r.recomputed == ["c"] and r.results["c"] == 1 + 100 and "b" not in r.results
    # a parameter of a stage that is not read does not invalidate the result
    assert eng.run("c", replace(p, b=Add(99))).recomputed == []
    # timings of cached results are the seconds they took when computed, never 0 by caching
    r1 = eng.run(("a", "b"), P())
    r2 = eng.run(("a", "b"), P())
    assert r2.recomputed == [] and r2.timings == r1.timings and all(t > 0 for t in r2.timings.values())


def test_engine_errors_and_cancel():
    eng, calls = _counting_engine()
    with pytest.raises(NpsimInputError, match="unknown stage"):
        eng.run("zzz", P())
    with pytest.raises(NpsimInputError, match="already exists"):
        eng.add_stage(Stage("a", lambda i, p, c: 0, ("x",)))
    bad = Engine((Stage("d", lambda i, p, c: 0, ("nope",)),))
    with pytest.raises(NpsimInputError, match="neither sources"):
        bad.run("d", P())
    ev = threading.Event()
    ev.set()
    with pytest.raises(NpsimCancelled):
        eng.run("c", P(), cancel=ev)
    assert calls == []


def test_content_key_tracks_array_content():
    a = np.zeros((3, 3), np.float32)
    k0 = content_key(a)
    a2 = a.copy()
    a2[1, 1] = 1
    assert content_key(a.copy()) == k0 != content_key(a2)
    assert content_key(FilterParams()) == content_key(FilterParams()) != content_key(FilterParams(sigma_s=9))


def small_scene(H=24, W=40):
    rng = np.random.default_rng(0)
    intr = Intrinsics.from_fov(W, H, 60.0)
    rays = intr.pixel_rays(np.float64)
    n = np.array([0.0, -0.6, -1.0])
    n /= np.linalg.norm(n)
    d = (-5.0 / (rays @ n)).astype(np.float32)
    labels = np.full((H, W), 7, np.uint8)
    labels[8:16, 10:22] = 26
    d[8:16, 10:22] = 3.0
    image = rng.integers(0, 255, (H, W, 3), dtype=np.uint8)
    normals = np.broadcast_to(n, (H, W, 3)).astype(np.float32).copy()
    normals[8:16, 10:22] = (0, 0, -1)
    dn = (d * (1 + 0.01 * rng.standard_normal(d.shape))).astype(np.float32)
    return Scene(name="tiny", image=image, labels=labels, intrinsics=intr, depth=dn, normals=normals)


def test_chain_caching_follows_the_parameters():
    chain = Chain(small_scene())
    p = ChainParams().with_value("refine", "steps", 5)
    r = chain.compute(p, until="refine")
    assert r.recomputed == ["geometry", "filter", "uncertain", "refine"]
    assert isinstance(r.refine, RefineResult) and r.filtered.shape == (24, 40) and r.uncertain.dtype == bool
    assert r.uncertain.any() and r.depth_source == "files: the frame's depth and normals"
    assert chain.compute(p.with_lambdas(1, 1, 5), until="refine").recomputed == ["refine"]
    assert chain.compute(p.with_value("uncertainty", "l", 4), until="refine").recomputed == ["uncertain", "refine"]
    assert chain.compute(p.with_value("filter", "sigma_s", 4.0), until="refine").recomputed == [
        "filter", "uncertain", "refine"]
    m = chain.compute(p)
    # no hand annotation: the lights are proposed (lights.source auto); the mesh's geometry does
    # not read them, so an annotation edit never rebuilds it
    assert m.recomputed == ["mesh", "lights"] and m.mesh.n_faces > 0 and m.lights.source == "proposed"
    chain.set_annotation(LightAnnotation.empty(24, 40))
    assert chain.compute(p).recomputed == ["lights"]
    assert chain.compute(p.with_value("night", "seed", 3)).recomputed == []  # nights do not touch the mesh
    # a mesh of the input depth reads neither the refinement nor its parameters
    grid = p.with_value("mesh", "depth", "input").with_value("mesh", "postprocess", False)
    g = chain.compute(grid)
    assert g.recomputed == ["mesh"] and g.refine is None
    assert chain.compute(grid.with_lambdas(3, 3, 3)).recomputed == []
    progress = []
    chain.compute(p.with_lambdas(1, 2, 3), until="refine", progress=progress.append)
    assert {"stage": "refine"} in progress and any("history" in x for x in progress)


def test_chain_cancel_inside_refine():
    chain = Chain(small_scene())
    chain.compute(ChainParams(), until="uncertain")
    state = {"n": 0}

    def cancel():
        state["n"] += 1
        return state["n"] > 3  # let the chain start the refine stage, then stop it mid-run

    with pytest.raises(NpsimCancelled):
        chain.compute(ChainParams().with_value("refine", "optimizer", "adam_faithful")
                      .with_value("refine", "steps", 10000), until="refine", cancel=cancel)


def test_params_json_rejects_unknown_and_wrong_types():
    p = ChainParams().with_sets(["refine.lambdas=[1,5,1]", "night.iso=800", "mesh.depth=filtered"])
    assert p.refine.lambdas == (1, 5, 1) and p.night.iso == 800 and p.mesh.depth == "filtered"
    assert ChainParams.from_json(json.loads(json.dumps(p.to_json()))) == p
    with pytest.raises(NpsimInputError, match="JSON object"):
        ChainParams.from_json([1, 2], "p.json")
    with pytest.raises(NpsimInputError, match="unknown parameter sections"):
        ChainParams.from_json({"refin": {}}, "p.json")
    with pytest.raises(NpsimInputError, match="p.json: unknown parameter refine.lambda"):
        ChainParams.from_json({"refine": {"lambda": 1}}, "p.json")
    with pytest.raises(NpsimInputError, match="mesh.depth"):
        ChainParams().with_value("mesh", "depth", "gt")


@pytest.fixture(scope="module")
def street():
    from npsim_core.synthetic import street_scene

    return street_scene(96, 48)


def test_export_manifest_has_the_real_stage_timings(street, tmp_path):
    chain = Chain(street)
    p = ChainParams().with_value("refine", "steps", 20).with_value("night", "final_spp", 2)
    first = chain.compute(p)
    files = export_frame(chain, p, tmp_path, nights=1, mesh_formats=("ply",))
    assert not any(f.name.endswith(("_linear.npy", "_normals_refined.npy")) for f in files)  # extras only
    man = json.loads(files[-1].read_text())
    assert files[-1].name == f"{street.name}_export.json"
    for stage in ("geometry", "filter", "uncertain", "refine", "mesh"):
        # the export found these cached; the manifest still holds what they cost
        assert man["timings"][stage] == pytest.approx(first.timings[stage], abs=1e-4)
    assert man["timings"]["refine"] > 0 and man["timings"]["night_scene"] > 0
    assert man["depth_source"] and man["nights"][0]["seed"] == 0 and man["nights"][0]["timings"]["render"] > 0
    assert set(man["files"]) == {f.name for f in files[:-1]}
    err = man["errors"]
    assert err["reference"] == "ground truth" and "normal_rmse_deg" in err["refined"]
    assert set(err["refined"]["classes"]) == {"road", "sidewalk", "building", "vegetation", "car"}


def test_night_command_and_run_write_identical_nights(street, tmp_path):
    """`npsim night` and `npsim run` go through the same chain and writer: same bytes."""
    from npsim_cli.main import main
    from npsim_core.scene import save_scene

    save_scene(street, tmp_path / "scene")
    common = ["--spp", "2", "--seed", "5", "--set", "refine.steps=10", "--set", "export.extras=true"]
    assert main(["night", str(tmp_path / "scene"), "-o", str(tmp_path / "night"), "--variants", "1"] + common) == 0
    assert main(["run", str(tmp_path / "scene"), "-o", str(tmp_path / "run"), "--nights", "1"] + common) == 0
    stem = f"{street.name}_night_0"
    for suffix in (".png", "_linear.npy", "_labelIds.png", "_lights.json"):
        a = (tmp_path / "night" / f"{stem}{suffix}").read_bytes()
        b = (tmp_path / "run" / f"{stem}{suffix}").read_bytes()
        assert a == b, suffix
    man = json.loads((tmp_path / "night" / f"{street.name}_export.json").read_text())
    assert man["nights"][0]["seed"] == 5 and man["params"]["night"]["final_spp"] == 2


def test_empty_mesh_is_a_clear_error_before_any_file(tmp_path):
    s = small_scene()
    sky = s.with_(labels=np.full_like(s.labels, 23), depth=np.full_like(s.depth, np.nan))
    with pytest.raises(NpsimInputError, match="no valid depth"):
        export_frame(Chain(sky), ChainParams().with_value("refine", "steps", 2), tmp_path / "out")
    assert not any((tmp_path / "out").iterdir())


def test_display_mesh_falls_back_to_a_coarser_kernel_when_the_reduction_cannot_reach_the_budget():
    from npsim_core.mesh.quality import project
    from npsim_core.mesh.reduce import ReduceParams, reduce_mesh
    from npsim_core.synthetic import street_scene

    scene = street_scene(256, 128)
    chain = Chain(scene)
    p = ChainParams().with_value("refine", "steps", 5)
    r = chain.compute(p)
    # the display keeps the light borders (the viewer shows the emitters)
    floor = reduce_mesh(r.layers.with_lights(scene.lights.instance_map), r.intrinsics,
                        ReduceParams(budget=8000)).mesh.n_faces
    assert floor > 1.5 * 8000  # step, silhouette and light-border quads stay at pixel resolution
    shown = chain.display_mesh(r, max_faces=8000, params=p)
    assert any((q.face_light_id() > 0).any() for q in shown.parts)
    assert shown.n_faces < floor and shown.info["display_scale"] == 0.5
    assert (shown.width, shown.height) == (256, 128)
    # vertices sit on their full-resolution pixels (within the coarse grid's pixel)
    v = np.concatenate([q.vertices for q in shown.parts])
    pix = np.concatenate([q.pixel for q in shown.parts])
    assert np.abs(project(v, r.intrinsics) - pix).max() < 2.0
    assert chain.display_mesh(r, max_faces=30000, params=p).info.get("display_scale") is None
