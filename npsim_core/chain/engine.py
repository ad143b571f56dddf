"""The staged cache the chain runs on: stages, keys, invalidation, cancel, progress, timings.

A :class:`Stage` is a pure function ``run(inputs, params, ctx) -> result`` with the
names of the stages (or sources) it may read, a function that picks its own
parameter object out of the whole parameter set, and a ``version`` to bump when its
code changes what it returns. A result's key is a hash of (stage name, version,
its parameters, the keys of its inputs); a changed parameter therefore changes the
key of its stage and of every stage downstream, and only those are recomputed.

Inputs are resolved lazily: a stage whose ``needs(params)`` names a subset of its
inputs (e.g. the mesh built from the input depth skips the refinement) never
triggers the others. Every cached result keeps the seconds it took to compute,
so :attr:`EngineRun.timings` is the real cost of each result, cached or not.

An *incremental* stage (``Stage.incremental``) keeps one result and, when its key
changes, is handed that result to update (:attr:`StageContext.previous`): the night
scene rebuilds only the shapes an annotation edit touched. The previous result leaves
the cache before the stage runs, since the stage may reuse (and change) parts of it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from ..errors import NpsimCancelled, NpsimInputError
from ..memory import release_free_memory

__all__ = ["Stage", "StageContext", "PreviousResult", "Engine", "EngineRun", "content_key"]

ProgressFn = Callable[[str, float, Any], None]


@dataclass(frozen=True)
class Stage:
    """One stage of the chain.

    name : result name. run : ``run(inputs: dict, params, ctx) -> result``.
    inputs : names of sources or earlier stages the stage may read.
    params_of : picks the stage's (hashable, frozen) parameters out of the whole set.
    needs : ``needs(params) -> names``, the inputs actually read (default: all).
    version : bump when the stage's output changes for the same inputs and parameters.
    incremental : keep one result and hand it to the next run (:attr:`StageContext.previous`).
    """

    name: str
    run: Callable[[dict, Any, "StageContext"], Any]
    inputs: tuple[str, ...]
    params_of: Callable[[Any], Any] = lambda params: ()
    needs: Callable[[Any], tuple[str, ...]] | None = None
    version: int = 1
    incremental: bool = False


@dataclass(frozen=True)
class PreviousResult:
    """An incremental stage's last result, with the cache keys of the inputs and of the
    parameters it was computed from (compare them with :attr:`StageContext.input_keys`)."""

    value: Any
    input_keys: Mapping[str, str]
    params_key: str


@dataclass
class StageContext:
    """What a running stage may use besides its inputs and parameters."""

    name: str
    cancel_flag: Any = None
    progress_cb: ProgressFn | None = None
    #: Cache keys of the inputs this run reads, and of the stage's parameters.
    input_keys: Mapping[str, str] = field(default_factory=dict)
    params_key: str = ""
    #: For an incremental stage: its previous result (None the first time).
    previous: PreviousResult | None = None

    def cancelled(self) -> bool:
        c = self.cancel_flag
        if c is None:
            return False
        return bool(c.is_set()) if hasattr(c, "is_set") else bool(c())

    def cancel(self) -> None:
        """Raise :class:`NpsimCancelled` when the caller asked to stop (call it in long loops)."""
        if self.cancelled():
            raise NpsimCancelled(f"cancelled during stage {self.name!r}")

    def progress(self, fraction: float, info: Any = "") -> None:
        if self.progress_cb is not None:
            self.progress_cb(self.name, float(fraction), info)


@dataclass
class EngineRun:
    """What :meth:`Engine.run` resolved.

    results : stage/source name -> result, for every stage resolved.
    timings : stage name -> seconds its result took to compute (in this run or when cached).
    recomputed : stages computed in this run, in order.
    keys : name -> cache key.
    """

    results: dict[str, Any]
    timings: dict[str, float]
    recomputed: list[str]
    keys: dict[str, str] = field(default_factory=dict)


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


class Engine:
    """Sources and stages with cached results (see the module docstring).

    Parameters
    ----------
    cache_size : int
        Results kept per stage, most recent last; a few let a slider go back and forth.
    """

    def __init__(self, stages: tuple[Stage, ...] = (), cache_size: int = 4):
        self._stages: OrderedDict[str, Stage] = OrderedDict()
        self._sources: dict[str, tuple[str, Any]] = {}
        self._cache: dict[str, OrderedDict[str, tuple[Any, float]]] = {}
        self._cache_size = max(1, int(cache_size))
        self._lock = threading.RLock()
        for st in stages:
            self.add_stage(st)

    # ------------------------------------------------------------------ registration
    def set_source(self, name: str, value: Any, key: str | None = None) -> None:
        """Set (or replace) an input value; ``key`` defaults to its content hash."""
        with self._lock:
            if name in self._stages:
                raise NpsimInputError(f"{name!r} is a stage, not a source")
            self._sources[name] = (key or content_key(value), value)

    def add_stage(self, stage: Stage) -> None:
        """Append a stage; every input must be a source name or an earlier stage."""
        with self._lock:
            if stage.name in self._stages:
                raise NpsimInputError(f"a stage named {stage.name!r} already exists")
            self._stages[stage.name] = stage
            self._cache[stage.name] = OrderedDict()

    @property
    def stages(self) -> tuple[str, ...]:
        return tuple(self._stages)

    def source(self, name: str) -> Any:
        return self._sources[name][1]

    def clear_cache(self, *names: str) -> None:
        """Forget the cached results of the stages ``names`` (all stages when none is given)."""
        with self._lock:
            for name, c in self._cache.items():
                if not names or name in names:
                    c.clear()

    # ------------------------------------------------------------------ running
    def keys(self, params: Any) -> dict[str, str]:
        """Cache key of every source and stage for ``params`` (nothing is computed)."""
        with self._lock:
            keys = {n: k for n, (k, _) in self._sources.items()}
            for name, st in self._stages.items():
                missing = [i for i in st.inputs if i not in keys]
                if missing:
                    raise NpsimInputError(f"stage {name!r} reads {missing}, neither sources nor earlier stages")
                needed = st.needs(params) if st.needs is not None else st.inputs
                keys[name] = content_key((name, st.version, st.params_of(params),
                                          tuple(keys[i] for i in st.inputs if i in needed)))
        return keys

    def run(self, until: str | tuple[str, ...], params: Any, *, cancel=None,
            progress: ProgressFn | None = None) -> EngineRun:
        """Compute (or fetch) ``until`` (one name or several) and what it needs.

        ``cancel`` (``threading.Event`` or callable) is checked before every stage and
        handed to stages; :class:`NpsimCancelled` leaves finished stages cached.
        ``progress(stage, fraction, info)`` reports; every stage starts with fraction 0.
        """
        targets = (until,) if isinstance(until, str) else tuple(until)
        for t in targets:
            if t not in self._stages:
                raise NpsimInputError(f"unknown stage {t!r}; stages are {list(self._stages)}")
        keys = self.keys(params)
        run = EngineRun(results={}, timings={}, recomputed=[], keys=keys)
        with self._lock:
            for name, (_, value) in self._sources.items():
                run.results[name] = value
        for t in targets:
            self._resolve(t, params, run, cancel, progress)
        return run

    def _resolve(self, name: str, params: Any, run: EngineRun, cancel, progress) -> Any:
        if name in run.results:
            return run.results[name]
        st = self._stages[name]
        key = run.keys[name]
        with self._lock:
            cache = self._cache[name]
            if key in cache:
                cache.move_to_end(key)
                value, seconds = cache[key][:2]
                run.results[name], run.timings[name] = value, seconds
                return value
        needed = st.needs(params) if st.needs is not None else st.inputs
        inputs = {i: self._resolve(i, params, run, cancel, progress) for i in st.inputs if i in needed}
        pkey = content_key(st.params_of(params))
        ctx = StageContext(name, cancel, progress, input_keys={i: run.keys[i] for i in inputs}, params_key=pkey)
        if st.incremental:
            with self._lock:
                if cache:
                    _, (value, _, prev_inputs, prev_pkey) = cache.popitem(last=True)
                    ctx.previous = PreviousResult(value, prev_inputs, prev_pkey)
                    del value
        ctx.cancel()
        ctx.progress(0.0, {"stage": name})
        t0 = time.perf_counter()
        value = st.run(inputs, st.params_of(params), ctx)
        seconds = time.perf_counter() - t0
        with self._lock:
            cache[key] = (value, seconds, dict(ctx.input_keys), pkey)
            while len(cache) > (1 if st.incremental else self._cache_size):
                cache.popitem(last=False)
        run.results[name], run.timings[name] = value, seconds
        run.recomputed.append(name)
        release_free_memory()  # the stage's temporaries are gone: their pages go back (see npsim_core.memory)
        ctx.progress(1.0, {"stage": name, "done": True, "seconds": seconds})
        return value
