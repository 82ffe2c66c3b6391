"""Fits made once: a fit of the same lobes to the same samples with the same options, by the
same fitter, is read back from the user's cache instead of run again (issue 35: every export
of a measured source refitted Principled from scratch, 2–6 minutes each).

The key is a SHA-256 of what decides the result: the samples' content (`SampleSet.digest`),
the start (its lobes, parameters and scales), the options, and the code a fit runs (the
source of the fitting, models, material and geometry packages), so a changed fitter or model
never returns an old answer. An entry is one small JSON file written atomically; one that cannot be read, or
whose parameters a material may not hold, is fitted again and rewritten. Only fits that ran
to their end are kept (not a cancelled one, nor one cut by a time limit).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable

from brdflab.errors import BRDFLabError
from brdflab.fitting.lm import STOPPED, FitOptions, FitResult, fit
from brdflab.fitting.samples import SampleSet
from brdflab.io.user_cache import code_digest, entry_key, read_entry, write_entry
from brdflab.material.analytic import AnalyticMaterial

KIND = "fits"
VERSION = 1  # of the entry's layout
CODE = ("fitting", "models", "material", "geometry")  # the packages whose code decides a fit's result


def fit_key(start: AnalyticMaterial, samples: SampleSet, options: FitOptions) -> str:
    """The cache key of fitting `start` to `samples` with `options`."""
    described = {
        "version": VERSION,
        # a model read from a file is its file's content (origin.sha256), not its name
        "start": [[l.model.name, getattr(getattr(l.model, "origin", None), "sha256", None), sorted(l.params.items()),
                   list(l.scale), l.channel] for l in start.lobes],
        "combination": start.combination,
        "channels": start.n_channels,
        "options": {k: v for k, v in dataclasses.asdict(options).items() if k not in ("workers", "time_limit")},
        "samples": samples.digest(),
        "code": code_digest(*CODE),
    }
    return entry_key(described)


def _read(start: AnalyticMaterial, options: FitOptions, key: str) -> FitResult | None:
    """The cached result for `key`, or None when there is none or it cannot be used."""
    entry = read_entry(KIND, key)
    if entry is None:
        return None
    try:
        material = start.copy()
        if len(entry["lobes"]) != len(material.lobes):
            return None
        for lobe, stored in zip(material.lobes, entry["lobes"]):
            lobe.params = {k: float(stored["params"][k]) for k in lobe.params}
            lobe.scale = [float(s) for s in stored["scale"]]
        material.validate()
        error, zero = float(entry["error"]), float(entry["zero_error"])
        if not (math.isfinite(error) and math.isfinite(zero)):
            return None
        second = {str(k): (float(v) if isinstance(v, (int, float)) else str(v)) for k, v in entry.get("second", {}).items()}
        return FitResult(material, error, options.metric, 0.0, int(entry["iterations"]), 0, str(entry["status"]),
                         str(entry["message"]), [], list(entry["warnings"]), zero, str(entry["scored_on"]), second)
    except (ValueError, KeyError, TypeError, AttributeError, BRDFLabError):
        return None


def _write(key: str, result: FitResult) -> None:
    entry = {"lobes": [{"model": l.model.name, "params": l.params, "scale": list(l.scale)} for l in result.material.lobes],
             "error": result.error, "zero_error": result.zero_error, "iterations": result.iterations,
             "status": result.status, "message": result.message, "warnings": result.warnings,
             "scored_on": result.scored_on, "seconds": result.seconds, "second": result.second}
    write_entry(KIND, key, entry)


def fit_once(start: AnalyticMaterial, samples: SampleSet, options: FitOptions | None = None,
             cancel=None, second: Callable[[FitResult], dict] | None = None) -> tuple[FitResult, bool]:
    """`fit(start, samples, options)`, from the cache when the same fit ran before; and whether
    it came from the cache. `second`: the fit's other number (second_error.py), kept with it
    (an entry written before without it gets it once)."""
    options = options or FitOptions()
    key = fit_key(start, samples, options)
    cached = _read(start, options, key)
    if cached is not None:
        if second is not None and not cached.second:
            cached.second = second(cached)
            _write(key, cached)
        return cached, True
    result = fit(start, samples, options, cancel=cancel)
    if second is not None:
        result.second = second(result)
    if result.status not in STOPPED:
        _write(key, result)
    return result, False
