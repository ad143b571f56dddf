"""Many frames: the batch runner, local processes or Ray tasks, with a resumable manifest.

Each frame is one job: load it, run the chain, export it (atomically, :mod:`.export`). Jobs
run in ``workers`` local processes (``concurrent.futures``; 1 = in this process) or as Ray
tasks (``ray_address``: ``"local"`` starts a local instance, anything else is the address
of a running cluster whose workers see the same paths). The dataset manifest
``<out>/batch.json`` is rewritten atomically as every frame finishes: a crash loses at
most the frames in flight, and a rerun skips every frame whose folder verifies
(manifest, files and checksums, :func:`.export.verify_frame`) -- it recomputes nothing.
"""

from __future__ import annotations

import os
import shutil
import signal
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable

from ..errors import NpsimCancelled, NpsimInputError
from .params import ChainParams
from .session import FrameSource

__all__ = ["FrameOutcome", "BatchResult", "run_frame", "run_batch", "BATCH_MANIFEST"]

BATCH_MANIFEST = "batch.json"


@dataclass
class FrameOutcome:
    """What one frame's job returned: ``status`` is ``done``, ``skipped`` (already complete) or
    ``failed`` (``error`` says why); the rest comes from its export manifest."""

    name: str
    status: str
    seconds: float = 0.0
    error: str = ""
    depth_source: str = ""
    scores: dict = field(default_factory=dict)
    nights: list = field(default_factory=list)
    files: int = 0
    peak_rss_mb: float = 0.0
    warnings: list = field(default_factory=list)
    #: The most CPU threads one of torch, OpenCV and Dr.Jit was allowed in the frame's process
    #: (:func:`thread_counts`): with several workers on one machine each should hold its share.
    threads: int = 0

    def to_json(self) -> dict:
        return {k: v for k, v in self.__dict__.items()}


@dataclass
class BatchResult:
    outcomes: list[FrameOutcome]
    seconds: float
    manifest: Path

    def count(self, status: str) -> int:
        return sum(o.status == status for o in self.outcomes)


def _peak_rss_mb() -> float:
    try:
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    except (ImportError, OSError):  # not on this platform
        return 0.0


def _cityscapes_copy(folder: Path, out_root: Path, src: FrameSource, nights: int) -> None:
    """The frame's nights and labels also in the Cityscapes layout under ``out_root/cityscapes``."""
    split, city = src.split or "unknown", src.group or "unknown"
    for k in range(nights):
        night = folder / f"{src.name}_night_{k}.png"
        if not night.exists():
            continue
        img_dir = out_root / "cityscapes" / "leftImg8bit" / split / city
        lab_dir = out_root / "cityscapes" / "gtFine" / split / city
        img_dir.mkdir(parents=True, exist_ok=True)
        lab_dir.mkdir(parents=True, exist_ok=True)
        stem = f"{src.name}_night{k}"
        shutil.copyfile(night, img_dir / f"{stem}_leftImg8bit.png")
        shutil.copyfile(folder / f"{src.name}_night_{k}_labelIds.png", lab_dir / f"{stem}_gtFine_labelIds.png")


def run_frame(src: FrameSource, params: ChainParams, out_root: str | Path, nights: int,
              layout: str = "npsim", log: Callable[[str], None] | None = None) -> FrameOutcome:
    """Load, compute and export one frame into ``out_root/<name>``; never raises for a bad frame
    (its outcome is ``failed`` with the reason), so a batch goes on."""
    import json

    from .chain import Chain
    from .export import export_frame

    global _IN_FRAME
    t0 = time.perf_counter()
    folder = Path(out_root) / src.name
    _IN_FRAME = True
    try:
        scene = src.load()
        chain = Chain(scene)
        files = export_frame(chain, params, folder, nights=nights, inputs={"frame": str(src.path)},
                             progress=(lambda f, text: log(f"{src.name}: {100 * f:3.0f}% {text}")) if log else None)
        man = json.loads(files[-1].read_text())
        if layout == "cityscapes":
            _cityscapes_copy(folder, Path(out_root), src, nights)
        return FrameOutcome(src.name, "done", time.perf_counter() - t0, depth_source=man["depth_source"],
                            scores=man["errors"], nights=man["nights"], files=len(files),
                            peak_rss_mb=_peak_rss_mb(), warnings=list(man.get("warnings", [])),
                            threads=max(thread_counts().values()))
    except (NpsimInputError, OSError) as exc:
        return FrameOutcome(src.name, "failed", time.perf_counter() - t0, error=str(exc))
    except NpsimCancelled:
        if _STOPPING:  # a worker told to stop: its export cleaned up; end without taking another frame
            os._exit(130)
        raise
    except Exception as exc:  # noqa: BLE001 -- an unforeseen failure is that frame's, not the batch's
        return FrameOutcome(src.name, "failed", time.perf_counter() - t0,
                            error=f"internal error {type(exc).__name__}: {exc} (please report it with this frame)")
    finally:
        _IN_FRAME = False


#: In a worker process: a frame is being computed (its export must be cancelled, not killed), and
#: the parent asked the worker to stop.
_IN_FRAME = False
_STOPPING = False


def _stop_worker(signum, frame) -> None:
    """A worker's SIGTERM: cancel the frame in flight (its export's ``finally`` removes the staging
    folder; :func:`run_frame` then ends the process), or end at once when idle -- quietly either way."""
    global _STOPPING
    _STOPPING = True
    if _IN_FRAME:
        raise NpsimCancelled(f"worker stopped by signal {signum}")
    os._exit(128 + signum)


#: The signals that stop a batch (Ctrl-C, ``kill``).
_STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextmanager
def _stop_signals_held():
    """Hold SIGINT/SIGTERM in the parent while it spawns worker processes, and deliver them after.

    A stop that cut a spawn short closed the pipe the new worker reads its start-up data from, and
    that worker printed an ``EOFError`` traceback into the batch's stderr. Within this block a stop
    signal is only recorded; on leaving it the handlers in place before are restored and each recorded
    signal raised again. Handlers can only be set from the main thread; elsewhere nothing is held (a
    signal's Python handler runs in the main thread anyway)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    previous = {s: signal.signal(s, lambda signum, frame: held.append(signum)) for s in _STOP_SIGNALS}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        for s in dict.fromkeys(held):
            signal.raise_signal(s)


def share_threads(threads: int) -> None:
    """Allow torch, OpenCV and Dr.Jit ``threads`` CPU threads each in this process (each defaults to
    every core, so two workers on a 2-core machine would run 2 x 3 x 2 threads)."""
    os.environ["OMP_NUM_THREADS"] = str(threads)
    try:
        import cv2

        cv2.setNumThreads(threads)
        import torch

        torch.set_num_threads(threads)
    except ImportError:  # pragma: no cover - both are dependencies
        pass
    try:
        import drjit

        drjit.set_thread_count(threads)
    except (ImportError, AttributeError):  # older Dr.Jit: keeps its default
        pass


def thread_counts() -> dict[str, int]:
    """The CPU threads torch, OpenCV and Dr.Jit may use in this process (Dr.Jit's where it says)."""
    import cv2
    import torch

    counts = {"torch": torch.get_num_threads(), "opencv": max(1, cv2.getNumThreads())}
    try:
        import drjit

        counts["drjit"] = drjit.thread_count()
    except (ImportError, AttributeError):  # older Dr.Jit: no way to ask
        pass
    return counts


def _worker_init(threads: int) -> None:
    """A local worker process: its share of the cores (:func:`share_threads`); then a SIGTERM from
    the parent stops it cleanly (:func:`_stop_worker`; before that its default action ends it, with
    nothing written yet)."""
    share_threads(threads)
    signal.signal(signal.SIGTERM, _stop_worker)


def _same_run(manifest: Path, params: ChainParams, nights: int) -> bool:
    """Whether a frame's export manifest was made with ``params`` and ``nights`` nights."""
    import json

    try:
        doc = json.loads(manifest.read_text())
    except (OSError, ValueError):
        return False
    return doc.get("params") == json.loads(json.dumps(params.to_json())) and len(doc.get("nights", [])) == nights


def _write_manifest(path: Path, doc: dict) -> None:
    from ..io import write_json

    doc["updated"] = time.strftime("%Y-%m-%d %H:%M:%S")
    write_json(path, doc)


def run_batch(sources: list[FrameSource], params: ChainParams, out_root: str | Path, *, nights: int = 1,
              workers: int = 1, ray_address: str | None = None, skip_existing: bool = True,
              layout: str = "npsim", inputs: dict | None = None,
              log: Callable[[str], None] = lambda m: None) -> BatchResult:
    """Run every frame of ``sources`` (module doc); returns the outcomes in the sources' order."""
    from .export import check_output_folder, versions, verify_frame

    if workers < 1:
        raise NpsimInputError(f"workers must be >= 1, got {workers}")
    if layout not in ("npsim", "cityscapes"):
        raise NpsimInputError(f"layout must be 'npsim' or 'cityscapes', got {layout!r}")
    out_root = check_output_folder(out_root)
    manifest_path = out_root / BATCH_MANIFEST
    doc = {"format": "npsim-batch", "inputs": inputs or {}, "params": params.to_json(), "nights": nights,
           "workers": workers, "ray": ray_address or "", "versions": versions(), "frames": {}}
    outcomes: dict[str, FrameOutcome] = {}
    todo: list[FrameSource] = []
    for src in sources:
        folder = out_root / src.name
        # the frame's folder is named after its source; the files inside after the scene
        why = verify_frame(folder) if folder.is_dir() else "no output yet"
        if why is None and not _same_run(next(folder.glob("*_export.json")), params, nights):
            why = "made with other parameters or nights"
        if skip_existing and why is None:
            outcomes[src.name] = FrameOutcome(src.name, "skipped")
            log(f"{src.name}: complete (manifest and checksums verified), skipped")
            continue
        if skip_existing and why != "no output yet":
            log(f"{src.name}: previous output incomplete ({why}), recomputing")
        todo.append(src)
    if manifest_path.is_file():  # keep what earlier runs recorded for the skipped frames
        try:
            import json

            old = json.loads(manifest_path.read_text()).get("frames", {})
            doc["frames"].update({k: v for k, v in old.items() if k in outcomes})
        except (OSError, ValueError, AttributeError):
            pass
    _write_manifest(manifest_path, doc)
    t0 = time.perf_counter()
    done: list[float] = []

    def finished(o: FrameOutcome) -> None:
        outcomes[o.name] = o
        doc["frames"][o.name] = o.to_json()
        _write_manifest(manifest_path, doc)
        if o.status == "done":
            done.append(o.seconds)
        n = sum(1 for x in outcomes.values() if x.status != "skipped")
        left = len(todo) - n
        eta = ""
        if left and done:
            eta = f"; about {left * (time.perf_counter() - t0) / n / 60:.1f} min left"
        what = f"done in {o.seconds:.1f} s" if o.status == "done" else f"FAILED: {o.error}"
        log(f"[{n}/{len(todo)}] {o.name}: {what}{eta}")
        for w in o.warnings:
            log(f"{o.name}: WARNING: {w}")

    if ray_address:
        _run_ray(todo, params, out_root, nights, layout, ray_address, finished)
    elif workers == 1:
        for src in todo:
            log(f"{src.name}: started")
            finished(run_frame(src, params, out_root, nights, layout, log=log))
    else:
        threads = max(1, (os.cpu_count() or 1) // workers)
        import multiprocessing

        pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_worker_init, initargs=(threads,))
        try:
            with _stop_signals_held():  # submit spawns the workers: a stop must not cut one's start-up
                pending = {pool.submit(run_frame, src, params, out_root, nights, layout): src for src in todo}
            for src in todo:
                log(f"{src.name}: queued")
            while pending:
                ready, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in ready:
                    src = pending.pop(fut)
                    try:
                        finished(fut.result())
                    except Exception as exc:  # noqa: BLE001 -- a worker that died takes only its frame
                        finished(FrameOutcome(src.name, "failed", error=f"worker died: {type(exc).__name__}: {exc}"))
        except BaseException:  # SIGINT/SIGTERM (or any error) in the parent: the workers must not outlive it
            stopped = stop_workers(pool)
            # A worker killed inside native code (a first render's kernel compile under load outlasts
            # the grace period) could not remove its staging folder: its pid is gone now, so remove it.
            from ..io import remove_stale_staging

            remove_stale_staging(out_root, depth=1)
            log(f"interrupted: {stopped} worker process{'es' if stopped != 1 else ''} stopped; frames in flight "
                "were not written (their staging folders are removed)")
            raise
        pool.shutdown(wait=True)
    return BatchResult([outcomes[s.name] for s in sources if s.name in outcomes], time.perf_counter() - t0,
                       manifest_path)


def stop_workers(pool: ProcessPoolExecutor, grace_s: float = 10.0) -> int:
    """Cancel the queued frames and end ``pool``'s worker processes: SIGTERM (a worker cancels its
    frame, its export removes its staging folder), SIGKILL after ``grace_s`` for one stuck in native
    code. Returns how many were running. ProcessPoolExecutor has no public way to do this."""
    procs = [p for p in (getattr(pool, "_processes", None) or {}).values() if p.is_alive()]
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        p.terminate()
    deadline = time.monotonic() + grace_s
    for p in procs:
        p.join(max(0.0, deadline - time.monotonic()))
        if p.is_alive():
            p.kill()
            p.join(2.0)
    return len(procs)


#: The CPUs a Ray task reserves for one frame; the frame's libraries get as many threads.
RAY_TASK_CPUS = 1


def _ray_frame(src: FrameSource, params: ChainParams, out_root: str, nights: int, layout: str,
               threads: int) -> FrameOutcome:
    """One frame as a Ray task: Ray runs its tasks in long-lived worker processes that set only
    ``OMP_NUM_THREADS``, so OpenCV and Dr.Jit would take every core of the node each."""
    share_threads(threads)
    return run_frame(src, params, out_root, nights, layout)


def _run_ray(todo: Iterable[FrameSource], params: ChainParams, out_root: Path, nights: int, layout: str,
             address: str, finished: Callable[[FrameOutcome], None]) -> None:
    """The same jobs as Ray tasks (``address`` ``local`` starts a local instance)."""
    try:
        import ray
    except ImportError:
        raise NpsimInputError("--ray needs the 'ray' package: pip install 'npsim[cluster]'") from None
    started = False
    if not ray.is_initialized():
        kw = {"include_dashboard": False, "log_to_driver": False}
        try:
            if address == "local":
                ray.init(num_cpus=os.cpu_count() or 1, **kw)
            else:
                ray.init(address=address, **kw)
        except Exception as exc:  # noqa: BLE001 -- Ray raises many kinds; all mean "no cluster there"
            raise NpsimInputError(f"--ray {address}: cannot connect ({type(exc).__name__}: {exc}); give the "
                                  "address of a running Ray cluster (ray start --head) or 'local'") from None
        started = True
    try:
        task = ray.remote(num_cpus=RAY_TASK_CPUS)(_ray_frame)
        refs = {task.remote(src, params, str(out_root), nights, layout, RAY_TASK_CPUS): src for src in todo}
        while refs:
            ready, _ = ray.wait(list(refs), num_returns=1)
            for ref in ready:
                src = refs.pop(ref)
                try:
                    finished(ray.get(ref))
                except Exception as exc:  # noqa: BLE001 -- a lost task takes only its frame
                    finished(FrameOutcome(src.name, "failed", error=f"Ray task failed: {type(exc).__name__}: {exc}"))
    finally:
        if started:
            ray.shutdown()
