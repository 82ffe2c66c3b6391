"""Auto fitting: model no more than a source needs (issue 13).

A ladder of candidate materials, climbed in order of cost: the Lambertian alone; the
Lambertian + each one-lobe model; then the Lambertian + the best one-lobe result's lobe
+ each model; then three lobes the same way. Every candidate is fitted on one half of a
seeded random split of the source's samples and scored on the other half, the HELD-BACK
samples it never saw, so that fitting noise does not pay.

Within a rung, the candidates are fitted in order of parameters, then evaluation time;
the rung's pick is, of those whose held-back error is within the tolerance T of the
rung's best, one with the fewest parameters (of them the lowest error). The climb stops
when the next rung's best held-back error does not improve on the current pick by more
than T (relative).

To cost less than fitting everything, Auto screens the first rung: every one-lobe
candidate is fitted quickly (a quarter of the fitted samples, from its start alone, few
steps), and only those near the screening's best (see `screen_margin`), at least the
SCREEN_KEEP best, or whose screen is inconclusive (no better than the Lambertian refitted the
same quick way), are fitted fully, from the same start as without screening. Later rungs are
fitted fully: there a quick fit of one lobe added to a fitted base ranks the candidates no
better than chance (violet-acrylic, rung 2: the worst screen was the best full fit; brass and
ss440 lost their best rung-2 base to the screen), and every candidate was kept anyway on the
slices where each rung paid, so the screens only added their cost (docs/benchmarks.md).
`exhaustive=True` fully fits every candidate of every rung, past the stop too: the
reference Auto is checked against (`benchmarks/fit_auto.py`).

A window runs Auto in a worker process: `progress` hears of every screen and full fit, and
`cancel` (an Event) stops the climb within one sample chunk of the running fit; the ladder
so far comes back, with the pick among the candidates fully fitted.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Callable, Protocol

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.fitting.defaults import DEFAULT_METRIC
from brdflab.fitting.lm import FitOptions, FitResult, fit, material_from_lobes, parameter_count
from brdflab.fitting.metrics import SAMPLE_METRICS, metric_errors
from brdflab.fitting.samples import ArraySampleSet, SampleSet
from brdflab.fitting.stored import fitting_of
from brdflab.io.xmlio import Fitting
from brdflab.material.analytic import AnalyticMaterial
from brdflab.models import get_model, model_names

DEFAULT_TOLERANCE = 0.05
DEFAULT_SPLIT = 20_000  # samples fitted, and as many held back
MAX_LOBES = 3  # after the Lambertian
MAX_AUTO_MODELS = 32  # the models a ladder tries (each at each rung); more than the registry's built-ins
SPLIT_SEED = 13
SCREENED_RUNGS = 1  # rungs screened before their full fits (see the module doc)
SCREEN_KEEP = 4  # Auto fully fits at least this many of a screened rung's candidates (with 3, the
# specular phenolics lost Cook–Torrance GGX, 4th of 15 by 0.1 % of its screen, their best lobe)
SCREEN_MIN_MARGIN = 0.15
SCREEN_MIN_SAMPLES = 500
SCREEN_ITERATIONS = 25  # a screening fit: from the start alone (no restarts), this many LM steps at most


@dataclass
class Candidate:
    """One rung's candidate: its lobes, cost, errors and time."""

    rung: int
    lobes: tuple[str, ...]
    parameters: int
    evaluation_ns: float  # per sample pair, of the lobes after the Lambertian
    error_fitted: float = math.nan
    error_held_back: float = math.nan
    seconds: float = 0.0  # wall time of the fit and its held-back scoring
    cpu_seconds: float = 0.0  # this process's CPU time for the same (robust on a shared machine)
    status: str = ""
    screen_error: float = math.nan  # held-back error of the screening fit (Auto, rungs ≥ 1)
    result: FitResult | None = field(default=None, repr=False)

    @property
    def fitted(self) -> bool:
        """Fully fitted (a fit cancelled half-way keeps its best parameters, but is not)."""
        return self.result is not None and self.status != "cancelled"

    def as_dict(self) -> dict:
        return {"rung": self.rung, "lobes": list(self.lobes), "parameters": self.parameters,
                "evaluation_ns": round(self.evaluation_ns, 2), "error_fitted": _number(self.error_fitted),
                "error_held_back": _number(self.error_held_back), "screen_error": _number(self.screen_error),
                "seconds": round(self.seconds, 4), "cpu_seconds": round(self.cpu_seconds, 4), "status": self.status,
                "fitted": self.result.material.describe()["lobes"] if self.result is not None else None}


@dataclass
class Ladder:
    """What an Auto run did: every candidate fitted, the pick and why."""

    candidates: list[Candidate]
    chosen: Candidate
    reason: str
    tolerance: float
    metric: str
    fitted_samples: int
    held_back_samples: int
    seconds: float
    cpu_seconds: float
    error: float = math.nan  # the pick's error over every sample of the source (the whole hemisphere)
    samples: int = 0  # how many that is
    seen: str = ""  # scene-Auto: what its pixels show (the sphere, or a mesh by name)

    def as_dict(self) -> dict:
        return {"tolerance": self.tolerance, "metric": self.metric, **({"seen": self.seen} if self.seen else {}),
                "fitted_samples": self.fitted_samples,
                "held_back_samples": self.held_back_samples, "error": _number(self.error), "samples": self.samples,
                "seconds": round(self.seconds, 4),
                "cpu_seconds": round(self.cpu_seconds, 4), "chosen": self.candidates.index(self.chosen), "reason": self.reason,
                "candidates": [c.as_dict() for c in self.candidates]}


class Cancel(Protocol):
    """What asks a run to stop: a threading or multiprocessing Event."""

    def is_set(self) -> bool: ...


@dataclass(frozen=True)
class AutoProgress:
    """A report after each screen and full fit: how far the climb is and its best so far."""

    step: int  # screens and full fits done
    expected: int  # about how many in all (the climb may stop sooner; a screen may keep more)
    stage: str  # "screened" | "fitted"
    candidate: str  # the candidate just done, e.g. "Lambertian+CookTorrance"
    error: float  # its held-back error (of its quick fit when screened)
    best: str  # the lowest held-back error fully fitted so far
    best_error: float
    rung: int = 0  # the candidate's rung: lobes after the Lambertian
    measure: str = "held back"  # what `error` is: the held-back error, or (scene-Auto) the image error

    def describe(self) -> str:
        return (f"rung {self.rung}, candidate {self.step} of about {self.expected}: {self.stage} {self.candidate} "
                f"({self.measure} {self.error:.4g}); best so far {self.best} {self.best_error:.4g}")


class _Cancelled(Exception):
    """The climb was asked to stop; `candidate` is the one whose fit it interrupted (if any)."""

    def __init__(self, candidate: Candidate | None) -> None:
        super().__init__("cancelled")
        self.candidate = candidate


class _Climb:
    """An Auto run's reporting and stopping: every fit gets `cancel`; after every screen and
    full fit `progress` hears how far the climb is."""

    def __init__(self, progress: Callable[[AutoProgress], None] | None, cancel: Cancel | None,
                 rungs: int, models: int, exhaustive: bool, measure: str = "held back") -> None:
        self.progress, self.cancel, self.measure = progress, cancel, measure
        self.models = models
        self.screened_rungs = 0 if exhaustive else min(rungs, SCREENED_RUNGS)
        self.rungs_left = rungs
        self.step = 0
        self.expected = 1 + self.screened_rungs * (models + min(models, SCREEN_KEEP)) + (rungs - self.screened_rungs) * models
        self.best: Candidate | None = None

    def stop_if_cancelled(self, candidate: Candidate, result: FitResult) -> None:
        """After a fit of `candidate`: stop if it was cancelled half-way."""
        if result.status == "cancelled":
            raise _Cancelled(candidate)

    def screened(self, kept: int) -> None:
        """A rung's screening (if any) is done and keeps `kept` to fit fully: the estimate follows."""
        self.rungs_left -= 1
        self.expected = self.step + kept + self.rungs_left * self.models

    def report(self, candidate: Candidate, stage: str) -> None:
        self.step += 1
        if stage == "fitted" and (self.best is None or candidate.error_held_back < self.best.error_held_back):
            self.best = candidate
        if self.progress is not None and self.best is not None:
            error = candidate.error_held_back if stage == "fitted" else candidate.screen_error
            self.progress(AutoProgress(self.step, max(self.expected, self.step), stage, _label(candidate), error,
                                       _label(self.best), self.best.error_held_back, candidate.rung, self.measure))


def _number(x: float) -> float | None:
    return x if math.isfinite(x) else None


def improves(current: float, new: float, tolerance: float) -> bool:
    """Whether `new` is lower than `current` by more than `tolerance` of `current`."""
    return new < current * (1.0 - tolerance)


def validate_tolerance(tolerance: float) -> None:
    if not (math.isfinite(tolerance) and 0.0 <= tolerance < 1.0):
        raise BRDFLabError(f"--tolerance {tolerance:g}: must be a relative error in [0, 1), e.g. 0.05")


def validate_models(models: list[str] | tuple[str, ...]) -> None:
    """Auto fits every listed model at every rung: a model listed twice, or more than
    MAX_AUTO_MODELS of them (1,000 entries ran for minutes), is refused before any fit."""
    if len(models) > MAX_AUTO_MODELS:
        raise BRDFLabError(f"--models lists {len(models):,} models; Auto tries at most {MAX_AUTO_MODELS}")
    repeated = sorted(name for name, n in Counter(models).items() if n > 1)
    if repeated:
        raise BRDFLabError(f"--models names {', '.join(repeated)} more than once")


def split_samples(samples: SampleSet, size: int = DEFAULT_SPLIT, seed: int = SPLIT_SEED
                  ) -> tuple[ArraySampleSet, ArraySampleSet]:
    """A stratified subset of 2·size samples (all, if fewer), shuffled with `seed` and cut
    in two: (fitted, held back). Each half's weights stand for the whole measure."""
    pool = samples.subset(2 * size, seed=seed)
    if not isinstance(pool, ArraySampleSet):
        pool = ArraySampleSet(*(np.concatenate(x) for x in zip(*pool.chunks())))
    if pool.size < 2:
        raise BRDFLabError("Auto needs at least 2 samples to hold some back")
    order = np.random.default_rng(seed).permutation(pool.size)
    halves = np.array_split(order, 2)

    def part(idx: np.ndarray) -> ArraySampleSet:
        return ArraySampleSet(pool.wi[idx], pool.wo[idx], pool.values[idx], pool.weight[idx] * (pool.size / idx.size))

    return part(np.sort(halves[0])), part(np.sort(halves[1]))


@lru_cache(maxsize=None)
def evaluation_ns(model: str, pairs: int = 20_000) -> float:
    """A model's evaluation time per sample pair at its defaults (best of 3; ns)."""
    rng = np.random.default_rng(0)
    v = rng.normal(size=(2, pairs, 3))
    v[..., 2] = np.abs(v[..., 2])
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    m = get_model(model)
    params = m.defaults()
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        m.evaluate(v[0], v[1], params)
        best = min(best, time.perf_counter() - t0)
    return best / pairs * 1e9


def _candidate(rung: int, lobes: tuple[str, ...], combination: str, n_channels: int) -> Candidate:
    material = material_from_lobes(["Lambertian", *lobes], combination, n_channels)
    return Candidate(rung, lobes, parameter_count(material), sum(evaluation_ns(m) for m in lobes))


def _start(candidate: Candidate, base: Candidate | None, combination: str, n_channels: int) -> AnalyticMaterial:
    """The candidate's start: model defaults, with the inherited lobes at their fitted values."""
    material = material_from_lobes(["Lambertian", *candidate.lobes], combination, n_channels)
    if base is not None and base.result is not None:
        for old, new in zip(base.result.material.lobes, material.lobes[:len(base.result.material.lobes)]):
            new.params = dict(old.params)
            new.scale = list(old.scale)
    return material


def _fit(candidate: Candidate, base: Candidate | None, fitted: SampleSet, held_back: SampleSet,
         combination: str, options: FitOptions, climb: _Climb) -> tuple[FitResult, float]:
    """Fit the candidate (from its start) and score it on the held-back samples; its
    times grow by what this took."""
    t0, c0 = time.perf_counter(), time.process_time()
    start = _start(candidate, base, combination, fitted.n_channels)
    result = fit(start, fitted, options, cancel=climb.cancel)
    (held,) = metric_errors([result.material], held_back, options.metric)
    candidate.seconds += time.perf_counter() - t0
    candidate.cpu_seconds += time.process_time() - c0
    return result, held


def _fit_fully(candidate: Candidate, base: Candidate | None, fitted: SampleSet, held_back: SampleSet,
               combination: str, options: FitOptions, climb: _Climb) -> None:
    candidate.result, candidate.error_held_back = _fit(candidate, base, fitted, held_back, combination, options, climb)
    candidate.status, candidate.error_fitted = candidate.result.status, candidate.result.error
    climb.stop_if_cancelled(candidate, candidate.result)
    climb.report(candidate, "fitted")


def screen_margin(tolerance: float) -> float:
    """How far (relative) behind the screening's best a candidate may be and still be fully
    fitted: three tolerances, at least 15 % (a quarter of the samples ranks fits roughly)."""
    return max(3.0 * tolerance, SCREEN_MIN_MARGIN)


def _screen(rung: list[Candidate], base: Candidate, fitted: SampleSet, held_back: SampleSet, combination: str,
            options: FitOptions, tolerance: float, climb: _Climb, share: int = 4,
            smallest: int = SCREEN_MIN_SAMPLES) -> list[Candidate]:
    """Fit every candidate quickly (1/`share` of the fitted samples, no restarts, few
    steps: fit time is mostly restarts and steps, not samples); the ones worth a full fit:
    those whose held-back error there is within `screen_margin` of the best, at least
    the SCREEN_KEEP best, and every one whose screen is inconclusive (no better than the
    base's own quick refit)."""
    small = fitted.subset(max(smallest, fitted.size // share), seed=SPLIT_SEED)
    quick = replace(options, restarts=False, max_iterations=min(options.max_iterations, SCREEN_ITERATIONS))
    for c in rung:
        result, held = _fit(c, base, small, held_back, combination, quick, climb)
        climb.stop_if_cancelled(c, result)
        c.screen_error = held
        climb.report(c, "screened")
    # the base screened the same way: a candidate whose screen does not beat it learnt nothing
    # from its quick fit (its new lobe stuck at the start, or the small set misled it), so
    # its screen cannot rank it: it is fully fitted rather than dropped
    base_again = Candidate(base.rung, base.lobes, base.parameters, base.evaluation_ns)
    result, base_screen = _fit(base_again, base, small, held_back, combination, quick, climb)
    if result.status == "cancelled":
        raise _Cancelled(None)
    for c in rung:
        c.seconds += base_again.seconds / len(rung)
        c.cpu_seconds += base_again.cpu_seconds / len(rung)
    ranked = sorted(rung, key=lambda c: (c.screen_error, c.lobes))
    keep = {id(c) for c in ranked[:SCREEN_KEEP]}
    keep |= {id(c) for c in rung if not improves(c.screen_error, ranked[0].screen_error, screen_margin(tolerance))}
    keep |= {id(c) for c in rung if not c.screen_error < base_screen}
    for c in rung:
        if id(c) not in keep:
            c.status = "screened out"
    return [c for c in rung if id(c) in keep]


def _label(candidate: Candidate) -> str:
    return "+".join(("Lambertian", *candidate.lobes))


def _pick(rung: list[Candidate], tolerance: float) -> Candidate:
    """Among the candidates within `tolerance` of the rung's best held-back error, those
    with the fewest parameters; of them the lowest error (not the fastest: measured times
    of near-equal models can swap between runs, and the pick must be deterministic)."""
    best = min(c.error_held_back for c in rung)
    near = [c for c in rung if not improves(c.error_held_back, best, tolerance)]
    fewest = min(c.parameters for c in near)
    return min((c for c in near if c.parameters == fewest), key=lambda c: (c.error_held_back, c.lobes))


def _improved(rung_index: int, full: list[Candidate], chosen: Candidate, tolerance: float,
              metric: str) -> tuple[Candidate, str] | None:
    """The rung's pick and why, when its best beats the current pick by more than the tolerance."""
    best = min(full, key=lambda c: c.error_held_back)
    if not improves(chosen.error_held_back, best.error_held_back, tolerance):
        return None
    gain = 1.0 - best.error_held_back / chosen.error_held_back if chosen.error_held_back > 0 else 0.0
    pick = _pick(full, tolerance)
    return pick, (f"rung {rung_index} improved the held-back {metric} error by {gain:.1%} (> {tolerance:.1%}); "
                  f"{_label(pick)} has the fewest parameters within the tolerance of its best ({_label(best)})")


def mark_cancelled(stop: _Cancelled, rung: list[Candidate], done: list[Candidate]) -> None:
    """A climb stopped in `rung`: the fit it interrupted is cancelled, the rung's others not
    reached, and the rung joins the candidates `done`."""
    if stop.candidate is not None:
        stop.candidate.status = "cancelled"
    for c in rung:
        c.status = c.status or "not reached"
    done += rung


def _cancelled(rung: list[Candidate], chosen: Candidate, stopped: bool, tolerance: float,
               metric: str) -> tuple[Candidate, str]:
    """The pick of a cancelled climb, among the candidates fully fitted, and why; `rung` is
    the rung it was stopped in (empty: the Lambertian's fit)."""
    if not chosen.fitted:
        return chosen, ("cancelled during the Lambertian's fit: nothing was fully fitted, so its best "
                        "parameters so far are kept")
    fully = [c for c in rung if c.fitted]
    where = f"cancelled in rung {rung[0].rung} ({len(fully)} of its {len(rung)} candidates fully fitted)"
    better = None if stopped or not fully else _improved(rung[0].rung, fully, chosen, tolerance, metric)
    if better is not None:
        return better[0], f"{where}; of those fully fitted: {better[1]}"
    return chosen, f"{where}; {_label(chosen)}, the pick of the rungs climbed before, is kept"


def auto_fit(samples: SampleSet, tolerance: float = DEFAULT_TOLERANCE, metric: str = DEFAULT_METRIC,
             combination: str = "Linear", split: int = DEFAULT_SPLIT, models: list[str] | None = None,
             max_lobes: int = MAX_LOBES, exhaustive: bool = False, options: FitOptions | None = None,
             progress: Callable[[AutoProgress], None] | None = None, cancel: Cancel | None = None) -> Ladder:
    """Climb the ladder on `samples` (see the module doc); returns every candidate fitted
    and the pick. `models`: the lobe models tried (default: every registry model).
    `progress` is called after every screen and full fit; once `cancel` is set, the running
    fit stops within a sample chunk and the ladder so far is returned (its `reason` says so)."""
    validate_tolerance(tolerance)
    validate_models(models or [])
    if metric not in SAMPLE_METRICS:
        raise BRDFLabError(f"Auto judges its rungs on held-back samples: it takes a sample metric "
                           f"({', '.join(SAMPLE_METRICS)}), not {metric}")
    t0, c0 = time.perf_counter(), time.process_time()
    options = replace(options or FitOptions(), metric=metric, diagnose=False)
    options.validate()
    fitted, held_back = split_samples(samples, split)
    names = [m for m in (models or model_names()) if m != "Lambertian"]
    channels = samples.n_channels
    climb = _Climb(progress, cancel, max_lobes if names else 0, len(names), exhaustive)
    lambertian = _candidate(0, (), combination, channels)
    done, chosen, base, stopped = [lambertian], lambertian, lambertian, False
    rung: list[Candidate] = []
    try:
        _fit_fully(lambertian, None, fitted, held_back, combination, options, climb)
        reason = f"no lobe model to add: the Lambertian alone ({metric} {chosen.error_held_back:.4g} held back)"
        for rung_index in range(1, max_lobes + 1):
            if not names or (stopped and not exhaustive):
                break
            rung = sorted((_candidate(rung_index, (*base.lobes, m), combination, channels) for m in names),
                          key=lambda c: (c.parameters, c.evaluation_ns, c.lobes))
            screened = not exhaustive and rung_index <= SCREENED_RUNGS
            full = _screen(rung, base, fitted, held_back, combination, options, tolerance, climb) if screened else rung
            climb.screened(len(full))
            for c in full:
                _fit_fully(c, base, fitted, held_back, combination, options, climb)
            done += rung
            rung = []  # climbed: a cancel from here on is in the next rung
            best = min(full, key=lambda c: c.error_held_back)
            base = best
            if stopped:
                continue  # exhaustive: past the stop, climbed for the reference only
            better = _improved(rung_index, full, chosen, tolerance, metric)
            if better is not None:
                chosen, reason = better[0], better[1] + ", and the ladder ends there"
            else:
                stopped = True
                gain = 1.0 - best.error_held_back / chosen.error_held_back if chosen.error_held_back > 0 else 0.0
                reason = (f"rung {rung_index} improves the held-back {metric} error by {gain:.1%} at best "
                          f"({_label(best)}), not more than the tolerance {tolerance:.1%}: {_label(chosen)} is enough")
    except _Cancelled as stop:
        mark_cancelled(stop, rung, done)
        chosen, reason = _cancelled(rung, chosen, stopped, tolerance, metric)
    if exhaustive:
        reason = "exhaustive run (every rung climbed, every candidate fully fitted): " + reason
    if chosen.status == "max-iterations" and not (cancel is not None and cancel.is_set()):
        reason += _finish(chosen, fitted, held_back, options, cancel)
    error = metric_errors([chosen.result.material], samples, metric)[0] if chosen.result is not None else math.nan
    return Ladder(done, chosen, reason, tolerance, metric, fitted.size, held_back.size, time.perf_counter() - t0,
                  time.process_time() - c0, error, samples.size)


def _finish(chosen: Candidate, fitted: SampleSet, held_back: SampleSet, options: FitOptions,
            cancel: Cancel | None) -> str:
    """A pick whose fit stopped at the iteration cap goes on from where it stopped (as many
    iterations again); what the reason adds: that it converged then, or that it did not."""
    again = fit(chosen.result.material, fitted, replace(options, restarts=False, coarse_size=0), cancel=cancel)
    if again.status == "cancelled":
        return "; its fit stopped at the iteration cap, and continuing it was cancelled"
    again.iterations += chosen.result.iterations  # never worse than its start, the pick
    (chosen.error_held_back,) = metric_errors([again.material], held_back, options.metric)
    chosen.result, chosen.status, chosen.error_fitted = again, again.status, again.error
    if chosen.status == "converged":
        return "; its fit, stopped at the iteration cap, was continued until it converged"
    return (f"; its fit stopped at the iteration cap ({options.max_iterations} iterations) twice and has not "
            "converged: more iterations (--max-iterations) may lower its error")


def chosen_fit(ladder: Ladder) -> FitResult:
    """The pick's fit, its error over every sample of the source (not only the ones Auto fitted);
    scene-Auto's (metric image) as fitted, over the scene's renders."""
    if ladder.metric == "image":
        return ladder.chosen.result
    result = replace(ladder.chosen.result, error=ladder.error)
    result.scored_on = f"{ladder.samples} samples (all of the source; Auto fitted {ladder.fitted_samples})"
    return result


def chosen_fitting(ladder: Ladder) -> Fitting:
    """The <Fitting> that stores Auto's pick (the command line's --out and the window store
    the same): its fit, plus its error on the held-back samples and the tolerance."""
    fitting = fitting_of(chosen_fit(ladder))
    if ladder.metric == "image":
        fitting.statistics.update({"autoTolerance": ladder.tolerance, "autoScene": "image error within the tolerance"})
        return fitting
    fitting.statistics.update({"heldBackError": ladder.chosen.error_held_back,
                               "heldBackSamples": ladder.held_back_samples, "autoTolerance": ladder.tolerance})
    return fitting
