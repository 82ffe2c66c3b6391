"""Run a study's independent jobs on every core: a spawned process pool, one BLAS thread
per worker (the fitter holds the GIL, so processes, not threads, give parallelism; see
docs/batch.md), or in this process when one worker is asked for (CI, the GUI).

Results come back in the order they finish (every result carries what it measured, so a
caller groups by its tags); between results `cancelled` is polled, and a cancelled run
returns the results it has (fits still running are dropped).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from multiprocessing import get_context

# one BLAS/OpenMP thread per worker process (the batch's Dask workers too): a worker runs one
# fit at a time, the processes share the cores
ONE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def core_count() -> int:
    """The cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


@contextmanager
def _one_blas_thread():
    """Spawned workers copy the environment at start: give them one BLAS thread each."""
    saved = {k: os.environ.get(k) for k in ONE_THREAD}
    os.environ.update(ONE_THREAD)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def run_jobs(fn: Callable, jobs: Sequence, workers: int, progress: Callable[[int, int], None],
             cancelled: Callable[[], bool], on_result: Callable[[object], None] | None = None) -> list:
    """fn(job) for every job (fn importable at module level); `on_result(result)`, then
    `progress(done, total)` after each. Stops early (returning what is done) once
    `cancelled()` is true."""
    results = []
    if cancelled():
        return results
    if workers <= 1 or len(jobs) <= 1:
        for job in jobs:
            if cancelled():
                break
            results.append(fn(job))
            if on_result is not None:
                on_result(results[-1])
            progress(len(results), len(jobs))
        return results
    with _one_blas_thread():
        pool = get_context("spawn").Pool(min(workers, len(jobs)))
    try:
        for row in pool.imap_unordered(fn, jobs, chunksize=1):
            results.append(row)
            if on_result is not None:
                on_result(row)
            progress(len(results), len(jobs))
            if cancelled():
                break
    finally:
        pool.terminate()
        pool.join()
    return results
