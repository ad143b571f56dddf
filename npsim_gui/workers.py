"""Background jobs for the GUI: debounced, cancellable, stale results dropped.

A job is a plain callable ``fn(cancel: threading.Event, progress: Callable[[object], None])``
that runs in a worker thread. Submitting a new job on a *channel* cancels the
previous one on that channel (its event is set; the core functions raise
``NpsimCancelled`` at their next check) and any result it still delivers is
ignored, so the UI only ever shows the newest state and never blocks.
"""

from __future__ import annotations

import threading
import traceback
from typing import Any, Callable

from PySide6.QtCore import QObject, QRunnable, QThreadPool, QTimer, Signal

from npsim_core.errors import NpsimCancelled
from npsim_core.memory import release_free_memory


class _Signals(QObject):
    done = Signal(int, object)
    failed = Signal(int, str, str)
    progress = Signal(int, object)


class _Job(QRunnable):
    def __init__(self, serial: int, fn: Callable, cancel: threading.Event, signals: _Signals):
        super().__init__()
        self.serial, self.fn, self.cancel, self.signals = serial, fn, cancel, signals
        self.setAutoDelete(True)

    def run(self) -> None:
        try:
            result = self.fn(self.cancel, lambda info: self._emit(self.signals.progress, self.serial, info))
        except NpsimCancelled:
            return
        except Exception as exc:  # shown to the user as a readable message, never a crash
            self._emit(self.signals.failed, self.serial, f"{type(exc).__name__}: {exc}", traceback.format_exc())
            return
        if not self.cancel.is_set():
            self._emit(self.signals.done, self.serial, result)

    def _emit(self, signal, *args) -> None:
        try:
            signal.emit(*args)
        except RuntimeError:  # the window (and its signal object) is gone: nobody to tell
            self.cancel.set()


class JobChannel(QObject):
    """One stream of jobs where only the newest matters (e.g. 'pipeline', 'render')."""

    finished = Signal(object)
    failed = Signal(str, str)
    progress = Signal(object)
    busy = Signal(bool)

    def __init__(self, name: str, pool: QThreadPool | None = None, debounce_ms: int = 0,
                 parent: QObject | None = None, *, one_at_a_time: bool = False):
        super().__init__(parent)
        self.name = name
        #: Start a job only once the cancelled one has stopped (it stops at its next cancellation
        #: check): two night renders at once shared the 2 cores and Mitsuba calls that hold the GIL.
        self.one_at_a_time = one_at_a_time
        self.pool = pool or QThreadPool.globalInstance()
        self._serial = 0
        self._cancel: threading.Event | None = None
        self._running = 0
        self._signals = _Signals()
        self._signals.done.connect(self._on_done)
        self._signals.failed.connect(self._on_failed)
        self._signals.progress.connect(self._on_progress)
        self._pending: Callable | None = None
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(debounce_ms)
        self._timer.timeout.connect(self._start_pending)

    @property
    def is_busy(self) -> bool:
        return self._running > 0 or self._timer.isActive() or self._pending is not None

    def submit(self, fn: Callable[[threading.Event, Callable[[Any], None]], Any]) -> None:
        """Run ``fn`` after the debounce interval, cancelling whatever ran before."""
        self.cancel()
        self._pending = fn
        self._timer.start()
        self.busy.emit(True)

    def cancel(self) -> None:
        """Drop the pending job and ask the running one to stop; :attr:`busy` turns False when
        it has stopped (at once when nothing runs)."""
        self._timer.stop()
        self._pending = None
        if self._cancel is not None:
            self._cancel.set()
        self._serial += 1
        if self._running == 0:
            self.busy.emit(False)

    def shutdown(self, timeout_ms: int = 5000) -> None:
        """Cancel and wait (bounded) for running jobs, e.g. before the window closes."""
        self.cancel()
        self.pool.waitForDone(timeout_ms)

    def _start_pending(self) -> None:
        if self.one_at_a_time and self._running > 0:
            return  # started when the running (cancelled) job has ended: _on_progress
        fn, self._pending = self._pending, None
        if fn is None:
            return
        self._serial += 1
        self._cancel = threading.Event()
        self._running += 1
        self.pool.start(_Job(self._serial, self._wrap(fn), self._cancel, self._signals))

    def _wrap(self, fn: Callable) -> Callable:
        def run(cancel: threading.Event, progress: Callable) -> Any:
            try:
                return fn(cancel, progress)
            finally:
                release_free_memory()  # the job's temporaries are freed: hand their pages back (off the GUI thread)
                try:
                    self._signals.progress.emit(-1, "ended")  # marks 'a job ended' for the busy counter
                except RuntimeError:  # channel already deleted (window closed)
                    pass
        return run

    def _on_progress(self, serial: int, info: object) -> None:
        if serial == -1:
            self._running = max(0, self._running - 1)
            if self._pending is not None and not self._timer.isActive():
                self._start_pending()  # a job held back by one_at_a_time
            if not self.is_busy:
                self.busy.emit(False)
            return
        if serial == self._serial:
            self.progress.emit(info)

    def _on_done(self, serial: int, result: object) -> None:
        if serial == self._serial:
            self.finished.emit(result)

    def _on_failed(self, serial: int, message: str, tb: str) -> None:
        if serial == self._serial:
            self.failed.emit(message, tb)
