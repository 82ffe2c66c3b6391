"""Work that must not run on the GUI thread, coalesced to the latest request.

NumPy holds the GIL for long stretches, so a thread would still freeze the window: the work
runs in a worker process (spawned, so it shares nothing with Qt). While a job runs, new
requests replace each other; only the newest is run next, and a stale result is dropped.
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable

from PySide6.QtCore import QObject, QTimer, Signal

_NOTHING = object()


def _worker_pool() -> ProcessPoolExecutor:
    return ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))


class LatestOnly(QObject):
    """Runs `fn(arg)` in a worker process for the latest `request(arg)`; emits `done(result)`
    or `failed(message)` on the GUI thread."""

    done = Signal(object)
    failed = Signal(str)

    def __init__(self, fn: Callable[[Any], Any], parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._fn = fn
        self._pool: ProcessPoolExecutor | None = None
        self._future: Future | None = None
        self._pending: Any = _NOTHING
        self._poll = QTimer(self, interval=20)
        self._poll.timeout.connect(self._check)

    @property
    def busy(self) -> bool:
        return self._future is not None

    def request(self, arg: Any) -> None:
        if self._future is not None:
            self._pending = arg  # coalesce: only the newest waiting request survives
            return
        self._submit(arg)

    def _submit(self, arg: Any) -> None:
        if self._pool is None:
            self._pool = _worker_pool()
        try:
            self._future = self._pool.submit(self._fn, arg)
        except BrokenProcessPool:  # the worker died (killed, out of memory): start a new one once
            self._pool = _worker_pool()
            self._future = self._pool.submit(self._fn, arg)
        self._poll.start()

    def _check(self) -> None:
        if self._future is None or not self._future.done():
            return
        future, self._future = self._future, None
        pending, self._pending = self._pending, _NOTHING
        if pending is not _NOTHING:  # the result is stale: run the newest request instead
            self._submit(pending)
            return
        self._poll.stop()
        try:
            result = future.result()
        except Exception as e:  # a failed job is reported, never raised into the event loop
            self.failed.emit(f"{type(e).__name__}: {e}")
            return
        self.done.emit(result)

    def shutdown(self) -> None:
        self._poll.stop()
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
        self._future, self._pending = None, _NOTHING
