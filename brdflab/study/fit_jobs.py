"""One fit of the study, as a picklable job: what to fit (a MERL slice or an in-memory
source, lobes, combination, sample subset, start) and the row it measures.

Both fitting parts of `brdflab study` use it: `fitting` (error against time over models,
combinations and subset sizes) and `stability` (LM from many starts). A job runs in the
calling process or in a worker of `study.workers`; a slice is read and its sample set
built once per process.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.fitting.diagnosis import at_bound
from brdflab.fitting.lm import FIT_NAME, FitOptions, fit, material_from_lobes, parameter_count
from brdflab.fitting.metrics import metric_errors
from brdflab.fitting.samples import SampleSet, samples_of
from brdflab.material.analytic import AnalyticMaterial, Lobe

METRIC = "Ngan"


@dataclass(frozen=True)
class FitJob:
    """`lobes` after a Lambertian (empty: the Lambertian alone); `size` None: all samples;
    `start`: parameter values for the non-Lambertian lobes (None: `material_from_lobes`'
    start); `restarts`, `coarse`: the fitter's multi-start stage and its coarse subset
    (both on: what `brdflab fit` does)."""

    source: str  # a slice path (read in the worker) or a key of `register_source`
    lobes: tuple[str, ...]
    combination: str = "Linear"
    size: int | None = None
    seed: int = 1
    start: tuple[tuple[str, float], ...] | None = None
    restarts: bool = True
    coarse: bool = True
    score_all: bool = True  # also measure the result on every sample of the source
    clock: str = "cpu"  # "cpu" in a one-thread worker; "wall" in a process with other threads
    tag: dict = field(default_factory=dict, compare=False, hash=False)


_IN_MEMORY: dict[str, object] = {}


def register_source(key: str, source) -> str:
    """Make an in-memory source (the GUI's current material) reachable by jobs run in
    this process; returns the key to put in `FitJob.source`."""
    _IN_MEMORY[key] = source
    _samples.cache_clear()
    return key


@lru_cache(maxsize=4)
def _samples(source: str) -> SampleSet:
    if source in _IN_MEMORY:
        return samples_of(_IN_MEMORY[source])
    from brdflab.sources.measured import read_slice

    return samples_of(read_slice(source))


def start_material(job: FitJob) -> AnalyticMaterial:
    """The material the fit starts from: `material_from_lobes`' start, with `job.start`
    (if given) set on every non-Lambertian lobe."""
    material = material_from_lobes(["Lambertian", *job.lobes], job.combination, 3)
    if job.start is not None:
        for lobe in material.lobes:
            if lobe.model.name != "Lambertian":
                lobe.params.update(dict(job.start))
    return material


def bounds_hit(material: AnalyticMaterial) -> list[str]:
    """'name side' of every lobe parameter that ended on a bound of its range (scale-
    invariant directions excluded), as the fitter's diagnosis finds them."""
    return [f"{p.name} {side}" for lobe in material.lobes for p in lobe.model.parameters
            if p.name not in lobe.model.scale_invariant
            and (side := at_bound(lobe.params[p.name], p.lower, p.upper, p.log)) is not None]


def run_job(job: FitJob) -> dict:
    """Fit, and the row: the fit's time, its error on the samples it fitted, and (if
    `score_all`) the error of the result on every sample of the source. A fit that
    cannot run (BRDFLabError) gives a row with status "failed: …" and no errors.

    `seconds` is the fit's CPU time (`clock` "cpu"): the fit is single-threaded in a study
    worker (one BLAS thread), so on an idle core it equals the wall time, and unlike the
    wall time (`wall_seconds`, also kept) it does not count the time other jobs of a
    shared machine hold the core. In a process whose BLAS or GUI threads would add their
    own CPU time (a scoped run in the window's process), `clock` "wall" takes wall time."""
    full = _samples(job.source)
    samples = full if job.size is None or job.size >= full.size else full.subset(job.size, seed=job.seed)
    start = start_material(job)
    options = FitOptions(metric=METRIC, restarts=job.restarts, coarse_size=60_000 if job.coarse else 0,
                         diagnose=False)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        result = fit(start, samples, options)
    except BRDFLabError as e:  # e.g. a random start where the lobe is not finite: LM cannot begin
        return {**job.tag, "lobes": "+".join(["Lambertian", *job.lobes]), "combination": job.combination,
                "samples": int(samples.size), "seconds": time.process_time() - c0,
                "wall_seconds": time.perf_counter() - t0, "error_fitted": None, "error": None,
                "iterations": 0, "status": f"failed: {e}", "on_bound": []}
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    row = {**job.tag, "lobes": "+".join(["Lambertian", *job.lobes]), "combination": job.combination,
           "samples": int(samples.size), "seconds": cpu if job.clock == "cpu" else wall, "wall_seconds": wall, "error_fitted": result.error,
           "iterations": result.iterations, "status": result.status, "parameters": parameter_count(start),
           "on_bound": bounds_hit(result.material), "fitted": result.material.describe()["lobes"]}
    if job.score_all:
        error_all, zero_all = metric_errors([result.material, None], full, METRIC)
        row.update(error=error_all, zero_error=zero_all)
    return row


def random_start(model, rng: np.random.Generator) -> tuple[tuple[str, float], ...]:
    """Parameter values drawn in the model's bounds: log-uniform on log-scale parameters
    (from max(lower, 1e-3)), uniform otherwise."""
    values = []
    for p in model.parameters:
        if p.log:
            v = float(np.exp(rng.uniform(np.log(max(p.lower, 1e-3)), np.log(p.upper))))
        else:
            v = float(rng.uniform(p.lower, p.upper))
        values.append((p.name, v))
    return tuple(values)


def material_of(row: dict) -> AnalyticMaterial:
    """The fitted material of a row (its `fitted` lobes), e.g. to check its error."""
    lobes = [Lobe.create(l["model"], l["scale"], l["channel"], **l["parameters"]) for l in row["fitted"]]
    return AnalyticMaterial(FIT_NAME, row["combination"], 3, lobes)
