"""Work that must not run on the GUI thread, coalesced to the latest request.

NumPy holds the GIL for long stretches, so a thread would still freeze the window: the work
runs in a worker process (spawned, so it shares nothing with Qt). While a job runs, new
requests replace each other; only the newest is run next, and a stale result is dropped.
"""

from __future__ import annotations

import io
import multiprocessing
import os
import pickle
import threading
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import shared_memory
from typing import Any, Callable

import numpy as np
from PySide6.QtCore import QObject, QTimer, Signal

_NOTHING = object()
WORKER_NICENESS = 5  # workers yield the CPU to the window (and its GL threads) on a busy machine


def lower_priority() -> None:
    """Run this worker process at a lower priority than the window (where the OS allows)."""
    if hasattr(os, "nice"):
        try:
            os.nice(WORKER_NICENESS)
        except OSError:
            pass


# arrays this large reach a worker through shared memory: what is left of a job's arguments
# then fits a pipe's buffer (64 KiB), and starting a worker never waits for it to read them
SHARED_BYTES = 1 << 15


class _SharingPickler(pickle.Pickler):
    """Pickles large arrays as the name of a shared-memory copy: a measured table (35 MB)
    or an environment map pickled into a worker's pipe held the GUI thread 0.3–0.5 s, and
    a 200 KB slice 0.15 s (the write waits for the new process to start reading)."""

    def __init__(self, file, segments: list) -> None:
        super().__init__(file, protocol=pickle.HIGHEST_PROTOCOL)
        self._segments = segments

    def reducer_override(self, obj):
        if type(obj) is not np.ndarray or obj.nbytes < SHARED_BYTES or obj.dtype.hasobject or not _room_for(obj.nbytes):
            return NotImplemented
        segment = shared_memory.SharedMemory(create=True, size=obj.nbytes)
        self._segments.append(segment)
        np.ndarray(obj.shape, obj.dtype, buffer=segment.buf)[...] = obj
        return _attached_copy, (segment.name, obj.shape, obj.dtype.str)


def _room_for(nbytes: int) -> bool:
    """Whether shared memory has room for twice `nbytes`: writing past a full /dev/shm (64 MB
    in a default container) kills the writer with SIGBUS instead of raising; such arrays go
    through the pipe as before."""
    try:
        fs = os.statvfs("/dev/shm")
    except (OSError, AttributeError):  # no /dev/shm (macOS) or no statvfs (Windows)
        return True
    return fs.f_bavail * fs.f_frsize > 2 * nbytes


def _attached_copy(name: str, shape: tuple, dtype: str) -> np.ndarray:
    """In the worker: a private copy of a shared array."""
    segment = shared_memory.SharedMemory(name=name)
    view = np.ndarray(shape, np.dtype(dtype), buffer=segment.buf)
    copy = view.copy()
    del view
    segment.close()
    return copy


class Packed:
    """A worker's arguments, pickled with their large arrays in shared memory; `release` once
    the worker has them (it unpickles them first thing)."""

    def __init__(self, args: tuple) -> None:
        self.segments: list = []
        buffer = io.BytesIO()
        try:
            _SharingPickler(buffer, self.segments).dump(args)
        except BaseException:
            self.release()
            raise
        self.payload = buffer.getvalue()

    def release(self, *_) -> None:
        """Free the shared copies (from any thread, any number of times)."""
        segments, self.segments = self.segments, []
        for segment in segments:
            segment.close()
            try:
                segment.unlink()
            except FileNotFoundError:
                pass


def _run_packed(fn, payload: bytes):
    return fn(*pickle.loads(payload))


def _lowered(target, payload: bytes, *args) -> None:
    lower_priority()
    target(*pickle.loads(payload), *args)


def worker_pool() -> ProcessPoolExecutor:
    """One spawned worker process (it shares nothing with Qt), at a lower priority."""
    return ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"), initializer=lower_priority)


def submit(pool: ProcessPoolExecutor, fn, *args) -> Future:
    """`pool.submit(fn, *args)`, the large arrays of args in shared memory until it is done."""
    packed = Packed(args)
    try:
        future = pool.submit(_run_packed, fn, packed.payload)
    except BaseException:
        packed.release()
        raise
    future.add_done_callback(packed.release)
    return future


def stop_pool(pool: ProcessPoolExecutor | None) -> None:
    """Shut a worker pool down without waiting: queued work is dropped; a job already running
    finishes in its process, which then exits. (Terminating the process instead can cut a
    result in half in the pool's pipe, and the pool's manager thread then waits for the rest
    forever: Python's exit hung on it.)"""
    if pool is not None:
        pool.shutdown(wait=False, cancel_futures=True)


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
            self._pool = worker_pool()
        try:
            self._future = submit(self._pool, self._fn, arg)
        except BrokenProcessPool:  # the worker died (killed, out of memory): start a new one once
            self._pool = worker_pool()
            self._future = submit(self._pool, self._fn, arg)
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
        stop_pool(self._pool)
        self._pool = None
        self._future, self._pending = None, _NOTHING


def _run_fit(start, source, sampling: dict, options, messages, cancel) -> None:
    """The child's side of FitProcess: samples, the fit, and its reports through `messages`
    (progress at most every 50 ms, always the newest)."""
    import time

    from brdflab.errors import BRDFLabError
    from brdflab.fitting.image_metric import VIEW, fit_target
    from brdflab.fitting.lm import STOPPED, fit
    from brdflab.fitting.second_error import second_error

    last = [0.0]

    def progress(p) -> None:
        now = time.monotonic()
        if now - last[0] >= 0.05:
            last[0] = now
            messages.put(("progress", p))

    try:
        sampling = dict(sampling)
        samples = fit_target(source, options.metric, sampling, sampling.pop("maps", None), sampling.pop("view", VIEW))
        messages.put(("started", samples.size))
        result = fit(start, samples, options, progress=progress, cancel=cancel)
        if result.status not in STOPPED:  # stopped: Stop answers now, without a render
            result.second = second_error(result.material, source, samples)
        messages.put(("finished", result))
    except BRDFLabError as e:
        messages.put(("failed", str(e)))
    except Exception as e:  # a bug in the worker must not take the window down
        messages.put(("failed", f"the fit failed: {type(e).__name__}: {e}"))


class ChildJob(QObject):
    """`target(*args, messages, cancel)` in a spawned worker process (NumPy loops hold the GIL:
    in a thread they froze the window). The child puts ("started", n), ("progress", x),
    then ("finished", result) or ("failed", message) on `messages`; they come back as signals
    on the GUI thread, progress at most once per poll and always the newest. `cancel.set()`
    asks the child to stop early (it still reports what it has as `finished`)."""

    started = Signal(int)
    progress = Signal(object)
    finished = Signal(object)
    failed = Signal(str)
    what = "job"  # named in the message when the child dies

    def __init__(self, target, args: tuple, parent: QObject | None = None) -> None:
        super().__init__(parent)
        context = multiprocessing.get_context("spawn")
        self.cancel = context.Event()
        self._messages = context.Queue()
        self._packed = Packed(args)
        self._process = context.Process(target=_lowered, daemon=True,
                                        args=(target, self._packed.payload, self._messages, self.cancel))
        self._poll = QTimer(self, interval=30)
        self._poll.timeout.connect(self._check)

    def start(self) -> None:
        self._process.start()
        self._poll.start()

    @property
    def running(self) -> bool:
        return self._poll.isActive()

    def _check(self) -> None:
        import queue

        latest = None
        while True:
            try:
                kind, value = self._messages.get_nowait()
            except queue.Empty:
                break
            if kind == "progress":
                latest = value  # only the newest report is shown
                continue
            if latest is not None:
                self.progress.emit(latest)
                latest = None
            if kind == "started":
                self.started.emit(value)
            else:
                self._end()
                (self.finished if kind == "finished" else self.failed).emit(value)
                return
        if latest is not None:
            self.progress.emit(latest)
        if not self._process.is_alive() and self._messages.empty():
            self._end()
            self.failed.emit(f"the {self.what}'s worker process ended unexpectedly (exit code {self._process.exitcode})")

    def _end(self) -> None:
        """The child has said its last: let it exit and be reaped off the GUI thread (its
        exit takes tens of ms)."""
        self._poll.stop()
        threading.Thread(target=self._reap, daemon=True).start()

    def _reap(self) -> None:
        self._process.join()
        self._packed.release()

    def kill(self) -> None:
        """The window is closing: no result is wanted."""
        self._poll.stop()
        if self._process.is_alive():
            self._process.kill()
            self._process.join(timeout=5)
        self._packed.release()


class FitProcess(ChildJob):
    """One fit: `started` gives the samples to fit, `finished` the FitResult (the best so far
    when cancelled)."""

    what = "fit"

    def __init__(self, start, source, sampling: dict, options, parent: QObject | None = None) -> None:
        super().__init__(_run_fit, (start, source, sampling, options), parent)
        self.options = options


def _run_auto(source, settings: dict, messages, cancel) -> None:
    """The child's side of AutoFitProcess: the source's samples as the command line takes
    them, then the ladder (fitting/auto.py), reporting after every screen and full fit."""
    from brdflab.errors import BRDFLabError
    from brdflab.fitting.auto import auto_fit
    from brdflab.fitting.image_metric import VIEW, SceneImages
    from brdflab.fitting.samples import samples_of
    from brdflab.fitting.scene_auto import scene_auto
    from brdflab.fitting.second_error import second_error

    report = lambda p: messages.put(("progress", p))
    try:
        if settings["metric"] == "image":  # scene-Auto: judged by renders under the window's map
            scene = SceneImages.of_source(source, settings["maps"], settings.get("view", VIEW))
            messages.put(("started", scene.size))
            ladder = scene_auto(scene, settings["tolerance"], settings["combination"], settings["models"],
                                progress=report, cancel=cancel)
        else:
            samples = samples_of(source)
            messages.put(("started", samples.size))
            keys = ("tolerance", "metric", "combination", "split", "models")
            ladder = auto_fit(samples, progress=report, cancel=cancel, **{k: settings[k] for k in keys})
        if ladder.chosen.result is not None and not cancel.is_set():  # the pick reports both numbers
            ladder.chosen.result.second = second_error(ladder.chosen.result.material, source,
                                                       scene if settings["metric"] == "image" else samples)
        messages.put(("finished", ladder))
    except BRDFLabError as e:
        messages.put(("failed", str(e)))
    except Exception as e:  # a bug in the worker must not take the window down
        messages.put(("failed", f"Auto failed: {type(e).__name__}: {e}"))


class AutoFitProcess(ChildJob):
    """One Auto run: `progress` gives AutoProgress after each candidate, `finished` the
    Ladder (the ladder so far, and its pick among the fully fitted, when cancelled).
    `settings`: auto_fit's keyword arguments (tolerance, metric, combination, split, models) and
    `maps`, the environment maps scene-Auto renders under when the metric is the image metric."""

    what = "Auto fit"

    def __init__(self, source, settings: dict, parent: QObject | None = None) -> None:
        super().__init__(_run_auto, (source, settings), parent)
        self.settings = settings

def _run_study(out_dir: str, part: str, scene: dict, messages, cancel) -> None:
    """The child's side of StudyProcess: one study part on the window's scene, quick sizes."""
    from pathlib import Path

    from brdflab.errors import BRDFLabError
    from brdflab.study.framework import StudyContext, run_study

    try:
        context = StudyContext(quick=True, progress=lambda text: messages.put(("progress", text)),
                               cancelled=cancel.is_set, **scene)
        result = run_study(Path(out_dir), context, [part])
        messages.put(("finished", {"charts": result.charts[part], "numbers": result.numbers[part],
                                   "seconds": result.seconds[part], "stopped": cancel.is_set()}))
    except BRDFLabError as e:
        messages.put(("failed", str(e)))
    except Exception as e:  # a failed study is reported in the panel, never raised in the window
        messages.put(("failed", f"{type(e).__name__}: {e}"))


class StudyProcess(ChildJob):
    """One study part (brdflab/study) measured in a worker process: progress lines, then the
    chart files written into `out_dir`."""

    what = "study"

    def __init__(self, out_dir: str, part: str, scene: dict, parent: QObject | None = None) -> None:
        super().__init__(_run_study, (out_dir, part, scene), parent)
