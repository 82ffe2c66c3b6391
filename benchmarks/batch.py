"""Batch fitting throughput: `brdflab batch` on a LocalCluster against the same fits run one
after another in one process, both measured in this one run.

    python benchmarks/batch.py [--workers N] [--json docs/bench/batch.json] [--out DIR]

Tasks: every shared MERL slice × 4 lobe sets (Linear, L2). The serial route calls the fitter
directly (load, samples, fit); the batch route is `run_batch` on a fresh LocalCluster (the
CLI's), timed with and without the cluster's start-up (processes spawned, brdflab imported
in them); writing the results table, the XML files and the charts is included. The
errors of both routes must agree (an independent check that the batch fits the same thing).
For the conditions of the run, the same fits on a plain process pool of the same size (no
Dask) give the parallelism the machine offered at that moment. Also measured: Dask's own per-task overhead (no-op tasks on the same cluster), which the
plan in docs/batch.md uses.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from brdflab.batch.runner import BatchSettings, local_cluster, run_batch
from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
from brdflab.fitting.samples import samples_of
from brdflab.sources.files import load_source

DATA = Path(os.environ.get("BRDFLAB_SHARED", Path(__file__).resolve().parents[2] / "shared")) / "data"
LOBE_SETS = [("Lambertian", "BlinnPhong"), ("Lambertian", "Ward"), ("Lambertian", "CookTorrance"),
             ("Lambertian", "LafortuneIso")]


def serial(slices: list[Path]) -> tuple[float, dict]:
    """The same fits one after another in this process; returns the wall time and the errors."""
    errors = {}
    t0 = time.perf_counter()
    for path in slices:
        for lobes in LOBE_SETS:
            source = load_source(path)
            result = fit(material_from_lobes(list(lobes), "Linear", source.n_channels), samples_of(source),
                         FitOptions(metric="L2"))
            errors[(path.stem, ",".join(lobes))] = result.error
    return time.perf_counter() - t0, errors


def fit_one(job: tuple[Path, tuple[str, ...]]) -> float:
    path, lobes = job
    source = load_source(path)
    return fit(material_from_lobes(list(lobes), "Linear", source.n_channels), samples_of(source),
               FitOptions(metric="L2")).error


def plain_pool(slices: list[Path], workers: int) -> float:
    """The same fits on a multiprocessing pool (spawned, warmed up): the machine's ceiling now."""
    from multiprocessing import get_context

    jobs = [(p, lobes) for p in slices for lobes in LOBE_SETS]
    os.environ.update({"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"})
    with get_context("spawn").Pool(workers) as pool:
        pool.map(fit_one, jobs[:workers], chunksize=1)
        t0 = time.perf_counter()
        list(pool.imap_unordered(fit_one, jobs, chunksize=1))
        return time.perf_counter() - t0


def noop(i: int) -> int:
    return i


def dask_overhead(client, n: int = 400) -> float:
    """Seconds per trivial task, submitted in one go and gathered: the scheduler's cost per task."""
    t0 = time.perf_counter()
    futures = client.map(noop, range(n), pure=False)
    client.gather(futures)
    return (time.perf_counter() - t0) / n


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=len(os.sched_getaffinity(0)))
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--out", type=Path, default=None, help="keep the batch's output here")
    args = parser.parse_args()
    from distributed import Client

    slices = sorted((DATA / "merl_slices").glob("*.slice"))
    tasks = len(slices) * len(LOBE_SETS)
    load_before = os.getloadavg()
    print(f"{tasks} tasks ({len(slices)} slices × {len(LOBE_SETS)} lobe sets); load average {load_before}", flush=True)

    serial_s, serial_errors = serial(slices)
    print(f"serial, one process: {serial_s:.1f} s ({tasks / serial_s:.2f} tasks/s)", flush=True)

    t0 = time.perf_counter()
    cluster = local_cluster(args.workers)  # the CLI's own local cluster
    client = Client(cluster)
    client.run(lambda: __import__("brdflab.batch.tasks") and __import__("brdflab.sources.files"))  # worker imports
    startup_s = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp) / "batch"
        t0 = time.perf_counter()
        summary = run_batch(BatchSettings([DATA / "merl_slices"], LOBE_SETS, out, scheduler=client.scheduler.address),
                            stream=open(os.devnull, "w"))
        batch_s = time.perf_counter() - t0
        table = pd.read_csv(out / "results.csv")
    overhead_s = dask_overhead(client)
    client.close()
    cluster.close()
    pool_s = plain_pool(slices, args.workers)
    print(f"plain process pool, {args.workers} processes: {pool_s:.1f} s ({serial_s / pool_s:.2f}× serial)", flush=True)
    load_after = os.getloadavg()

    batch_errors = {(r.material, r.lobes): r.error for r in table.itertuples()}
    rel = max(abs(batch_errors[k] - e) / e for k, e in serial_errors.items())
    task_s = table["seconds"].to_numpy()
    result = {
        "tasks": tasks, "workers": args.workers, "cpus": os.cpu_count(), "python": platform.python_version(),
        "serial_s": serial_s, "batch_s": batch_s, "cluster_startup_s": startup_s,
        "speedup": serial_s / batch_s, "speedup_with_startup": serial_s / (batch_s + startup_s),
        "plain_pool_s": pool_s, "plain_pool_speedup": serial_s / pool_s,
        "failed": summary.failed, "max_relative_error_difference": rel,
        "task_seconds_mean": float(task_s.mean()), "task_seconds_median": float(np.median(task_s)),
        "task_seconds_by_lobes": table.groupby("lobes")["seconds"].mean().to_dict(),
        "dask_overhead_per_task_s": overhead_s,
        "load_average_before": load_before, "load_average_after": load_after,
    }
    print(f"batch, {args.workers} workers: {batch_s:.1f} s ({tasks / batch_s:.2f} tasks/s) + {startup_s:.1f} s cluster "
          f"start-up; speed-up {result['speedup']:.2f}× ({result['speedup_with_startup']:.2f}× with start-up)")
    print(f"errors: batch vs serial differ by at most {rel:.2e} (relative); {summary.failed} failed")
    print(f"per task: fit {result['task_seconds_mean']:.3f} s mean; Dask overhead {overhead_s * 1e3:.2f} ms")
    print(f"load average before {load_before}, after {load_after}")
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
