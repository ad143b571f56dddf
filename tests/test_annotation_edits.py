"""An annotation edit rebuilds only what it touched: never the mesh, and in the night scene only
the bands and lights whose faces changed -- with the same night as a scene built from scratch."""

from __future__ import annotations

import numpy as np
import pytest

from npsim_core.chain import Chain, ChainParams
from npsim_core.chain.engine import Engine, Stage
from npsim_core.render.render import render_final
from npsim_core.synthetic import street_scene

W, H = 128, 64


def _edited(ann):
    """``ann`` with one ungrouped light removed and a new window painted on a facade."""
    ann = ann.copy()
    grouped = {m for g in ann.groups.values() for m in g.members}
    gone = next(i for i in ann.instance_ids() if i not in grouped)
    ann.instance_map[ann.instance_map == gone] = 0
    ann.instance_map[H // 4:H // 4 + 4, W // 3:W // 3 + 5] = 4999  # class 4: a window
    return ann, gone


def test_incremental_stage_gets_its_previous_result_and_keeps_one():
    seen = []

    def run(inputs, params, ctx):
        seen.append(None if ctx.previous is None else (ctx.previous.value, dict(ctx.previous.input_keys)))
        return inputs["x"] * 10

    eng = Engine((Stage("y", run, ("x",), incremental=True),))
    eng.set_source("x", 1)
    assert eng.run("y", None).results["y"] == 10 and seen == [None]
    eng.set_source("x", 2)
    assert eng.run("y", None).results["y"] == 20
    assert seen[1][0] == 10 and set(seen[1][1]) == {"x"}  # the last result and the keys it came from
    eng.set_source("x", 1)
    eng.run("y", None)
    assert len(seen) == 3 and seen[2][0] == 20  # one result kept: going back recomputes


@pytest.fixture(scope="module")
def edit():
    scene = street_scene(W, H)
    p = ChainParams().with_value("refine", "steps", 5).with_value("night", "variant", "scalar_rgb")
    chain = Chain(scene)
    before = chain.compute(p)
    first = chain.night_inputs(p)[0]
    faces_before = first.n_faces
    ann, gone = _edited(scene.lights)
    chain.set_annotation(ann)
    after = chain.compute(p)
    built, _, _, run = chain.night_inputs(p)
    return dict(scene=scene, p=p, chain=chain, before=before, after=after, built=built, run=run, ann=ann,
                gone=gone, faces_before=faces_before)


def test_an_edit_reruns_the_lights_not_the_mesh(edit):
    assert edit["after"].recomputed == ["lights"] and edit["after"].mesh is edit["before"].mesh
    assert "mesh" not in edit["run"].recomputed and "night_scene" in edit["run"].recomputed


def test_an_edit_rebuilds_only_the_shapes_it_touched(edit):
    built = edit["built"]
    n, total = (int(x) for x in built.info["rebuilt"].split(" shapes")[0].split(" of "))
    assert 0 < n <= 8 < total  # the new window, the bands around it and the removed light's band
    assert built.n_faces == edit["faces_before"]
    assert 4999 in built.area_keys and edit["gone"] not in built.area_keys
    x0, y0, x1, y1 = built.changed_box  # covers the new window
    assert x0 <= W // 3 and y0 <= H // 4 and x1 >= W // 3 + 5 and y1 >= H // 4 + 4


def test_the_edited_scene_renders_like_one_built_from_scratch(edit):
    chain, p = edit["chain"], edit["p"]
    built = edit["built"]
    built.apply_lights(chain.activate(p))
    got = render_final(built, spp=4, seed=2)
    fresh = Chain(edit["scene"].with_(lights=edit["ann"]))
    ref = fresh.night_inputs(p)[0]
    assert ref.info["rebuilt"] == "all"
    ref.apply_lights(fresh.activate(p))
    want = render_final(ref, spp=4, seed=2)
    assert np.array_equal(got, want)
