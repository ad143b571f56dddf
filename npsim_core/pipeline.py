"""A small staged pipeline with per-stage caching (SPEC §7).

Each *stage* is a pure function of its upstream results and its own frozen
parameter dataclass. The pipeline keys every stage result on a hash of
(stage name, its parameters, the keys of its inputs), so changing one
parameter recomputes exactly that stage and the stages downstream of it;
everything upstream comes from the cache. The GUI's live sliders stand on this.

Stage registration API
----------------------
::

    pipe = Pipeline()
    pipe.add_source("scene", scene)                 # inputs with no parameters
    pipe.add_stage("filter", run_filter, inputs=("scene",), params=FilterParams())
    pipe.add_stage("mesh", build_mesh, inputs=("scene", "refine"), params=MeshParams())
    run = pipe.run(until="mesh", params={"filter": FilterParams(sigma_s=5)})
    run.results["mesh"], run.timings, run.recomputed

A stage function has the signature::

    func(inputs: dict[str, Any], params: P, ctx: StageContext) -> Any

``inputs`` maps each name in ``inputs=`` to its upstream result (or source
value); ``ctx.cancel()`` raises :class:`~npsim_core.errors.NpsimCancelled` when
the caller's cancel flag is set (check it in long loops), ``ctx.cancel_flag``
is the raw flag to pass on (e.g. to :func:`refine_depth`), and
``ctx.progress(fraction, text)`` reports progress. Stages must not mutate their
inputs. Stages are appended in dependency order (inputs must already exist);
parameters must be frozen dataclasses (hashable, with a deterministic repr).

:func:`refinement_pipeline` builds the depth refinement chain of SPEC §2::

    scene -> filter (cross-bilateral, on the predicted depth)
          -> uncertain (variance filter, on the *filtered* depth: thesis eq. 3.3
             writes d(·), the output of eq. 3.2)
          -> refine (normal-guided refinement, initial depth and anchor = filtered
             depth, normals = the scene's predicted normals, U = uncertain)

so changing λ reruns only ``refine``; changing σs reruns ``filter``,
``uncertain`` and ``refine``; changing ``l`` reruns ``uncertain`` and ``refine``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from .errors import NpsimCancelled, NpsimInputError


@dataclass(frozen=True)
class Stage:
    """A registered stage: name, function, upstream names, default parameters."""

    name: str
    func: Callable[[dict, Any, "StageContext"], Any]
    inputs: tuple[str, ...]
    params: Any


@dataclass
class StageContext:
    """What a running stage may use besides its inputs and parameters."""

    name: str
    cancel_flag: Any = None
    progress_cb: Callable[[str, float, str], None] | None = None

    def cancelled(self) -> bool:
        c = self.cancel_flag
        if c is None:
            return False
        return bool(c.is_set()) if hasattr(c, "is_set") else bool(c())

    def cancel(self) -> None:
        """Raise NpsimCancelled if the caller asked to stop."""
        if self.cancelled():
            raise NpsimCancelled(f"pipeline cancelled during stage {self.name!r}")

    def progress(self, fraction: float, text: str = "") -> None:
        if self.progress_cb is not None:
            self.progress_cb(self.name, float(fraction), text)


@dataclass
class PipelineRun:
    """Results of :meth:`Pipeline.run`.

    Attributes
    ----------
    results : dict
        Stage name -> result, for every stage up to ``until`` (and sources).
    timings : dict
        Stage name -> seconds spent computing it in this run (0.0 when cached).
    recomputed : list of str
        Stages actually computed in this run, in order.
    keys : dict
        Stage name -> cache key.
    """

    results: dict[str, Any]
    timings: dict[str, float]
    recomputed: list[str]
    keys: dict[str, str]


def _hash_value(h: "hashlib._Hash", v: Any) -> None:
    """Feed a content hash of ``v`` (arrays by bytes, dataclasses by fields) into ``h``."""
    if isinstance(v, np.ndarray):
        a = np.ascontiguousarray(v)
        h.update(f"nd{a.dtype.str}{a.shape}".encode())
        h.update(a.view(np.uint8).data if a.size else b"")
    elif dataclasses.is_dataclass(v) and not isinstance(v, type):
        h.update(type(v).__qualname__.encode())
        for f in dataclasses.fields(v):
            h.update(f.name.encode())
            _hash_value(h, getattr(v, f.name))
    elif isinstance(v, Mapping):
        h.update(b"map")
        for k in sorted(v, key=repr):
            _hash_value(h, k)
            _hash_value(h, v[k])
    elif isinstance(v, (list, tuple)):
        h.update(f"seq{len(v)}".encode())
        for x in v:
            _hash_value(h, x)
    elif isinstance(v, (set, frozenset)):
        h.update(b"set")
        for x in sorted(v, key=repr):
            _hash_value(h, x)
    else:
        h.update(repr(v).encode())


def content_key(v: Any) -> str:
    """Stable content hash of a value (arrays, dataclasses, containers, scalars)."""
    h = hashlib.blake2b(digest_size=16)
    _hash_value(h, v)
    return h.hexdigest()


class Pipeline:
    """Named stages with cached results; see the module docstring for the API.

    Parameters
    ----------
    cache_size : int
        Results kept per stage (most recent first); a few let a slider go back
        and forth without recomputing.
    """

    def __init__(self, cache_size: int = 4):
        self._stages: OrderedDict[str, Stage] = OrderedDict()
        self._sources: dict[str, tuple[str, Any]] = {}
        self._cache: dict[str, OrderedDict[str, Any]] = {}
        self._cache_size = max(1, int(cache_size))
        self._lock = threading.RLock()

    # -- registration -------------------------------------------------------------------------
    def add_source(self, name: str, value: Any, key: str | None = None) -> None:
        """Set (or replace) an input value; ``key`` defaults to its content hash."""
        with self._lock:
            if name in self._stages:
                raise NpsimInputError(f"{name!r} is a stage, not a source")
            self._sources[name] = (key or content_key(value), value)

    def add_stage(self, name: str, func: Callable, inputs: tuple[str, ...] | list[str], params: Any) -> None:
        """Append a stage; its inputs must be sources or earlier stages."""
        with self._lock:
            if name in self._stages or name in self._sources:
                raise NpsimInputError(f"a stage or source named {name!r} already exists")
            inputs = tuple(inputs)
            for i in inputs:
                if i not in self._stages and i not in self._sources:
                    raise NpsimInputError(f"stage {name!r} reads {i!r}, which is neither a source nor an earlier "
                                          "stage; add it first")
            self._check_params(name, params)
            self._stages[name] = Stage(name, func, inputs, params)
            self._cache[name] = OrderedDict()

    @staticmethod
    def _check_params(name: str, params: Any) -> None:
        if not (dataclasses.is_dataclass(params) and not isinstance(params, type)
                and type(params).__dataclass_params__.frozen):
            raise NpsimInputError(f"parameters of stage {name!r} must be a frozen dataclass instance, "
                                  f"got {type(params).__name__}")

    @property
    def stages(self) -> tuple[str, ...]:
        return tuple(self._stages)

    def default_params(self, name: str) -> Any:
        return self._stages[name].params

    def set_params(self, name: str, params: Any) -> None:
        """Change a stage's default parameters (results stay cached by key)."""
        with self._lock:
            self._check_params(name, params)
            st = self._stages[name]
            self._stages[name] = dataclasses.replace(st, params=params)

    def clear_cache(self) -> None:
        with self._lock:
            for c in self._cache.values():
                c.clear()

    # -- running -----------------------------------------------------------------------------
    def _needed(self, until: str) -> list[str]:
        if until not in self._stages:
            raise NpsimInputError(f"unknown stage {until!r}; stages are {list(self._stages)}")
        need: set[str] = set()
        stack = [until]
        while stack:
            n = stack.pop()
            if n in need or n in self._sources:
                continue
            need.add(n)
            stack.extend(self._stages[n].inputs)
        return [n for n in self._stages if n in need]

    def run(self, until: str | None = None, params: Mapping[str, Any] | None = None, *, cancel=None,
            progress: Callable[[str, float, str], None] | None = None) -> PipelineRun:
        """Compute (or fetch from cache) every stage ``until`` depends on, and ``until`` itself.

        Parameters
        ----------
        until : str, optional
            Last stage to compute (default: the last registered).
        params : dict, optional
            Stage name -> parameters overriding the stage's defaults for this run.
        cancel : threading.Event or callable, optional
            Checked before every stage and passed to stages; raises NpsimCancelled.
        progress : callable(stage, fraction, text), optional
        """
        if not self._stages:
            raise NpsimInputError("the pipeline has no stages")
        until = until or next(reversed(self._stages))
        params = dict(params or {})
        for n in params:
            if n not in self._stages:
                raise NpsimInputError(f"parameters given for unknown stage {n!r}; stages are {list(self._stages)}")
            self._check_params(n, params[n])
        order = self._needed(until)
        results: dict[str, Any] = {}
        keys: dict[str, str] = {}
        timings: dict[str, float] = {}
        recomputed: list[str] = []
        with self._lock:
            for name, (key, value) in self._sources.items():
                results[name] = value
                keys[name] = key
        for name in order:
            st = self._stages[name]
            p = params.get(name, st.params)
            key = content_key((name, p, tuple(keys[i] for i in st.inputs)))
            keys[name] = key
            ctx = StageContext(name, cancel, progress)
            ctx.cancel()
            with self._lock:
                cache = self._cache[name]
                hit = key in cache
                if hit:
                    cache.move_to_end(key)
                    results[name] = cache[key]
            if hit:
                timings[name] = 0.0
                continue
            t0 = time.perf_counter()
            out = st.func({i: results[i] for i in st.inputs}, p, ctx)
            timings[name] = time.perf_counter() - t0
            recomputed.append(name)
            with self._lock:
                cache[key] = out
                while len(cache) > self._cache_size:
                    cache.popitem(last=False)
            results[name] = out
            ctx.progress(1.0, "done")
        return PipelineRun(results=results, timings=timings, recomputed=recomputed, keys=keys)


# --- the depth refinement chain (SPEC §2) ------------------------------------------------------

def _stage_filter(inputs, params, ctx):
    from .refine.bilateral import cross_bilateral

    scene = inputs["scene"]
    if scene.depth is None:
        raise NpsimInputError(f"scene {scene.name!r} has no estimated depth; run 'npsim estimate' first")
    return cross_bilateral(scene.depth, scene.image, scene.labels, params)


def _stage_uncertain(inputs, params, ctx):
    from .refine.uncertainty import uncertain_map

    return uncertain_map(inputs["filter"], inputs["scene"].labels, params)


def _stage_refine(inputs, params, ctx):
    from .refine.optimize import refine_depth

    scene = inputs["scene"]
    if scene.normals is None:
        raise NpsimInputError(f"scene {scene.name!r} has no estimated normals; run 'npsim estimate' first")

    def prog(step, total, losses):
        ctx.progress(step / max(total, 1), f"step {step}/{total} loss {losses['total']:.4g}")

    return refine_depth(inputs["filter"], scene.normals, scene.intrinsics, inputs["uncertain"], params,
                        progress=prog, cancel=ctx.cancel_flag)


def refinement_pipeline(scene, filter_params=None, uncertainty_params=None, refine_params=None,
                        cache_size: int = 4) -> Pipeline:
    """The SPEC §2 chain ``scene -> filter -> uncertain -> refine`` on one scene.

    Results: 'filter' (HxW float32 filtered depth, m), 'uncertain' (HxW bool U),
    'refine' (:class:`~npsim_core.refine.optimize.RefineResult`). Later stages
    (mesh, postprocess, render) are appended with :meth:`Pipeline.add_stage`.
    """
    from .refine.bilateral import FilterParams
    from .refine.optimize import RefineParams
    from .refine.uncertainty import UncertaintyParams

    pipe = Pipeline(cache_size=cache_size)
    pipe.add_source("scene", scene)
    pipe.add_stage("filter", _stage_filter, ("scene",), filter_params or FilterParams())
    pipe.add_stage("uncertain", _stage_uncertain, ("scene", "filter"), uncertainty_params or UncertaintyParams())
    pipe.add_stage("refine", _stage_refine, ("scene", "filter", "uncertain"), refine_params or RefineParams())
    return pipe
