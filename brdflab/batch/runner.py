"""Run a batch: find the pairs still to fit, send them to Dask workers, and record each
result (XML of the source, then the table) atomically as it arrives."""

from __future__ import annotations

import logging
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from brdflab.batch.charts import write_charts
from brdflab.batch.progress import Progress
from brdflab.batch.store import FitStore
from brdflab.batch.table import CSV_NAME, PARQUET_NAME, ResultsTable
from brdflab.batch.tasks import (FitTask, TaskOutcome, base_row, discover_sources, make_tasks, one_line,
                                 options_dict, run_task)
from brdflab.errors import BRDFLabError
from brdflab.io.atomic import ensure_folder, folder_lock
from brdflab.fitting.auto import DEFAULT_SPLIT, DEFAULT_TOLERANCE, validate_models, validate_tolerance
from brdflab.models import get_model
from brdflab.study.workers import ONE_THREAD, core_count  # one BLAS thread per worker; the cores we may use


@dataclass
class BatchSettings:
    sources: list[Path]
    lobe_sets: list[tuple[str, ...]]
    out: Path
    metric: str = "L2"
    combination: str = "Linear"
    max_iterations: int = 200
    scheduler: str | None = None  # tcp://host:port of an existing cluster; None: a LocalCluster
    workers: int | None = None  # LocalCluster size; None: one per core
    auto: bool = False  # also one Auto task per source (the ladder of `brdflab fit --auto`)
    auto_tolerance: float = DEFAULT_TOLERANCE
    auto_split: int = DEFAULT_SPLIT
    auto_models: tuple[str, ...] = ()  # the models Auto's ladder tries; () = every registry model

    def auto_settings(self) -> tuple[tuple[str, object], ...] | None:
        if not self.auto:
            return None
        return (("models", ",".join(self.auto_models)), ("split", self.auto_split), ("tolerance", self.auto_tolerance))


@dataclass
class BatchSummary:
    tasks: int
    skipped: int
    ran: int = 0
    failed: int = 0
    seconds: float = 0.0
    workers: int = 0
    dashboard: str | None = None
    files: list[str] = field(default_factory=list)


def validate(settings: BatchSettings) -> None:
    """Bad options fail before any cluster starts."""
    from brdflab.fitting.lm import material_from_lobes

    if not settings.lobe_sets and not settings.auto:
        raise BRDFLabError("name at least one lobe set (--lobes A,B,...) or --auto")
    if settings.auto:
        validate_tolerance(settings.auto_tolerance)
        validate_models(settings.auto_models)
        for name in settings.auto_models:
            get_model(name)  # an unknown model fails before any cluster starts
    elif settings.auto_models:
        raise BRDFLabError("--models applies to --auto")
    for lobes in settings.lobe_sets:
        if not lobes:
            raise BRDFLabError("an empty --lobes")
        material_from_lobes(list(lobes), settings.combination, 3)  # unknown models raise here
    if settings.workers is not None and settings.workers < 1:
        raise BRDFLabError("--workers must be at least 1")
    if settings.workers is not None and settings.scheduler:
        raise BRDFLabError("--workers sizes the local cluster; an existing cluster (--scheduler) has its own workers")
    if settings.out.exists() and not settings.out.is_dir():
        raise BRDFLabError("--out must be a folder", settings.out)


def open_client(settings: BatchSettings):
    """A client of the named scheduler, or of a new LocalCluster of single-threaded worker processes."""
    from distributed import Client

    if settings.scheduler:
        try:
            return Client(settings.scheduler, timeout="10s"), None
        except (OSError, TimeoutError, ValueError) as e:
            raise BRDFLabError(f"cannot reach the scheduler: {one_line(e)}", settings.scheduler) from None
    cluster = local_cluster(settings.workers or core_count())
    return Client(cluster), cluster


# A fit holds the GIL in the worker's task thread; every wake-up of the worker's event loop
# takes it away (a loop tick every 20 ms, the sampling profiler every 10 ms, monitors), which
# costs most on a busy machine, where the fit's thread then waits for a core to get it back.
# The nanny also starts each worker with MALLOC_TRIM_THRESHOLD_=65536 (Dask's default), which
# turns off glibc's adaptive mmap threshold: every temporary array over 128 KB is then mapped
# and unmapped at each use, and a fit runs 30 % slower (measured: docs/batch.md). Not set here
# (None removes it); on other clusters `tasks.restore_malloc_reuse` undoes most of it.
QUIET_WORKERS = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
}


def local_cluster(workers: int):
    """Single-threaded worker processes with one BLAS thread each and a quiet event loop."""
    import dask
    from distributed import LocalCluster

    with dask.config.set(QUIET_WORKERS):
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                            env=ONE_THREAD, silence_logs=logging.CRITICAL)


def failed_outcome(task: FitTask, error: BaseException) -> TaskOutcome:
    """The row of a task that never returned (its worker died too often, or it was lost)."""
    return TaskOutcome({**base_row(task), "error": float("nan"), "parameters": "", "seconds": 0.0, "iterations": 0,
                        "evaluations": 0, "status": "failed", "message": one_line(error), "worker": "", "pid": 0})


class Recorder:
    """Stores outcomes as they arrive: the sources' XML files first, then the table (the record).

    Every write replaces whole files atomically. Writes are spaced so that they cost at most
    about a fifth of the main process's time (a big table takes longer to rewrite), and what
    has not been flushed when the process dies is simply fitted again by a rerun.
    """

    def __init__(self, out: Path, tasks: list[FitTask], warn) -> None:
        self.table = ResultsTable.load(out)
        self.store = FitStore(ensure_folder(out / "fits"), sorted({t.source for t in tasks}))
        self.warn = warn
        self.store.load_existing(warn)
        self.sha = {t.source: t.sha256 for t in tasks}
        self.dirty: set[str] = set()
        self.unsaved = 0
        self.last_flush = time.monotonic()
        self.interval = 0.5

    def add(self, outcomes: list[TaskOutcome]) -> None:
        self.table.update([o.row for o in outcomes])
        for o in outcomes:
            if o.fitting is not None:
                self.store.add(o.row["key"], o.row["source"], o.fitting, o.source_type)
                self.dirty.add(o.row["source"])
        self.unsaved += len(outcomes)

    def due(self) -> bool:
        return self.unsaved > 0 and time.monotonic() - self.last_flush >= self.interval

    def flush(self) -> None:
        """Write what arrived, under the output folder's lock, with what a batch running beside
        this one (into the same --out) saved meanwhile."""
        t0 = time.monotonic()
        with folder_lock(self.table.folder):
            self.table.merge_saved()
            if self.dirty:
                self.store.load_existing(self.warn)
            for source in sorted(self.dirty):
                rows = sorted((r for r in self.table.rows.values() if r["source"] == source),
                              key=lambda r: (r["lobes"], r["options"]))
                self.store.write(source, rows, self.sha[source])
            self.table.save()
        self.dirty.clear()
        self.unsaved = 0
        self.last_flush = time.monotonic()
        self.interval = max(0.5, 4.0 * (self.last_flush - t0))


def run_batch(settings: BatchSettings, stream=None) -> BatchSummary:
    """Fit every (source, lobe set) pair not already in the table with the same inputs."""
    stream = stream or sys.stderr
    validate(settings)
    t0 = time.perf_counter()
    options = options_dict(settings.metric, settings.max_iterations)
    lobe_sets = list(dict.fromkeys(settings.lobe_sets))  # a set named twice is one task per source
    tasks = make_tasks(discover_sources(settings.sources), lobe_sets, settings.combination, options,
                       settings.auto_settings())
    ensure_folder(settings.out)  # a read-only or missing place fails here, in one line
    recorder = Recorder(settings.out, tasks, lambda text: print(f"brdflab batch: warning: {text}", file=stream))
    pending = [t for t in tasks if not recorder.table.is_done(t.key, t.sha256)]
    summary = BatchSummary(tasks=len(tasks), skipped=len(tasks) - len(pending))
    if pending:
        _run(pending, settings, recorder, summary, stream)
    elif not (settings.out / CSV_NAME).exists():
        recorder.flush()
    charts = write_charts(recorder.table.frame(), settings.metric, settings.out)
    summary.files = [CSV_NAME, PARQUET_NAME, *(c.name for c in charts)]
    summary.seconds = time.perf_counter() - t0
    return summary


def _run(pending: list[FitTask], settings: BatchSettings, recorder: Recorder, summary: BatchSummary, stream) -> None:
    from distributed import as_completed

    client, cluster = open_client(settings)
    try:
        summary.workers = len(client.scheduler_info()["workers"])
        summary.dashboard = client.dashboard_link
        print(f"brdflab batch: {len(pending)} tasks on {summary.workers} workers "
              f"({summary.skipped} already done); dashboard {summary.dashboard}", file=stream, flush=True)
        by_key = {}
        futures = []
        for task in pending:
            future = client.submit(run_task, task, key=f"fit-{task.key}-{task.sha256[:8]}", pure=False)
            by_key[future.key] = task
            futures.append(future)
        progress = Progress(len(pending), stream)
        arrivals = as_completed(futures, with_results=True, raise_errors=False)
        while not arrivals.is_empty() or recorder.unsaved:
            batch = arrivals.next_batch(block=False) if not arrivals.is_empty() else []
            outcomes = [result if isinstance(result, TaskOutcome) else failed_outcome(by_key[future.key], result)
                        for future, result in batch]
            if outcomes:
                recorder.add(outcomes)
                failed = sum(o.row["status"] == "failed" for o in outcomes)
                summary.ran += len(outcomes)
                summary.failed += failed
                progress.update(len(outcomes), failed)
            if recorder.due() or (arrivals.is_empty() and recorder.unsaved):
                recorder.flush()
            elif not outcomes:
                progress.update(0, 0)  # the clock moves on while a long fit runs
                time.sleep(0.02)
        progress.close()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
