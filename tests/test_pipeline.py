"""Staged pipeline with caching: generic engine and the depth refinement chain."""

import threading
from dataclasses import dataclass

import numpy as np
import pytest

from npsim_core.camera import Intrinsics
from npsim_core.errors import NpsimCancelled, NpsimInputError
from npsim_core.pipeline import Pipeline, content_key, refinement_pipeline
from npsim_core.refine import FilterParams, RefineParams, RefineResult, UncertaintyParams
from npsim_core.scene import Scene


@dataclass(frozen=True)
class Add:
    k: float = 1.0


def _counting_pipeline():
    calls = []

    def stage(name):
        def f(inputs, p, ctx):
            calls.append(name)
            return sum(inputs.values()) + p.k
        return f

    pipe = Pipeline()
    pipe.add_source("x", 1.0)
    pipe.add_stage("a", stage("a"), ("x",), Add(1))
    pipe.add_stage("b", stage("b"), ("a",), Add(10))
    pipe.add_stage("c", stage("c"), ("b", "x"), Add(100))
    pipe.add_stage("side", stage("side"), ("x",), Add(0))
    return pipe, calls


def test_generic_engine_recomputes_only_downstream():
    pipe, calls = _counting_pipeline()
    r = pipe.run("c")
    assert r.results["c"] == 1 + 1 + 10 + 100 + 1 and r.recomputed == ["a", "b", "c"] and calls == ["a", "b", "c"]
    assert pipe.run("c").recomputed == []
    assert pipe.run("c", params={"b": Add(20)}).recomputed == ["b", "c"]
    assert pipe.run("c", params={"c": Add(5)}).recomputed == ["c"]
    assert pipe.run("c").recomputed == []  # defaults again: still cached
    assert pipe.run("side").recomputed == ["side"]
    pipe.add_source("x", 2.0)  # a new input invalidates everything that reads it
    assert pipe.run("c").recomputed == ["a", "b", "c"]
    assert set(pipe.run("c").timings) == {"a", "b", "c"}


def test_registration_errors():
    pipe, _ = _counting_pipeline()
    with pytest.raises(NpsimInputError, match="neither a source"):
        pipe.add_stage("d", lambda i, p, c: 0, ("nope",), Add())
    with pytest.raises(NpsimInputError, match="frozen dataclass"):
        pipe.add_stage("d", lambda i, p, c: 0, ("a",), {"k": 1})
    with pytest.raises(NpsimInputError, match="already exists"):
        pipe.add_stage("a", lambda i, p, c: 0, ("x",), Add())
    with pytest.raises(NpsimInputError, match="unknown stage"):
        pipe.run("zzz")
    with pytest.raises(NpsimInputError, match="unknown stage"):
        pipe.run("c", params={"zzz": Add()})


def test_content_key_tracks_array_content():
    a = np.zeros((3, 3), np.float32)
    k0 = content_key(a)
    a2 = a.copy()
    a2[1, 1] = 1
    assert content_key(a.copy()) == k0 != content_key(a2)
    assert content_key(FilterParams()) == content_key(FilterParams()) != content_key(FilterParams(sigma_s=9))


def test_cancellation_passes_through():
    pipe, calls = _counting_pipeline()
    ev = threading.Event()
    ev.set()
    with pytest.raises(NpsimCancelled):
        pipe.run("c", cancel=ev)
    assert calls == []


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


def test_refinement_chain_caching():
    scene = small_scene()
    pipe = refinement_pipeline(scene, refine_params=RefineParams(steps=5))
    r = pipe.run("refine")
    assert r.recomputed == ["filter", "uncertain", "refine"]
    assert isinstance(r.results["refine"], RefineResult)
    assert r.results["filter"].shape == scene.depth.shape and r.results["uncertain"].dtype == bool
    assert r.results["uncertain"].any()
    assert pipe.run("refine", params={"refine": RefineParams(steps=5, lambdas=(1, 1, 5))}).recomputed == ["refine"]
    assert pipe.run("refine", params={"uncertain": UncertaintyParams(l=4)}).recomputed == ["uncertain", "refine"]
    assert pipe.run("refine", params={"filter": FilterParams(sigma_s=4)}).recomputed == ["filter", "uncertain",
                                                                                         "refine"]
    assert pipe.run("uncertain").recomputed == []
    progress = []
    pipe.run("refine", params={"refine": RefineParams(steps=3, lambdas=(1, 2, 3))},
             progress=lambda stage, f, text: progress.append(stage))
    assert "refine" in progress


def test_refinement_chain_cancel_inside_refine():
    scene = small_scene()
    pipe = refinement_pipeline(scene)
    pipe.run("uncertain")
    state = {"n": 0}

    def cancel():
        state["n"] += 1
        return state["n"] > 3  # let the pipeline start the refine stage, then stop it mid-run

    with pytest.raises(NpsimCancelled):
        pipe.run("refine", params={"refine": RefineParams(optimizer="adam_faithful", steps=10000)}, cancel=cancel)
