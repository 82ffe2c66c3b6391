"""The error metrics of fits, evaluated directly for any material and sample set."""

from __future__ import annotations

import math

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.fitting.samples import SampleSet

NGAN_MAX_COS = math.cos(math.radians(80.0))


def sample_weight(metric: str, wi: np.ndarray, wo: np.ndarray, measure: np.ndarray, cosine: bool = True) -> np.ndarray:
    """Per-sample weight of squared differences under `metric` (cosine=False: the
    normalising weight)."""
    if metric == "L2":
        return np.ones(wi.shape[0])
    if metric == "cosL2":
        return wi[:, 2] ** 2 if cosine else np.ones(wi.shape[0])
    if metric == "Ngan":
        ok = (wi[:, 2] >= NGAN_MAX_COS) & (wo[:, 2] >= NGAN_MAX_COS)
        return np.where(ok, measure * (wi[:, 2] ** 2 if cosine else 1.0), 0.0)
    raise BRDFLabError(f"unknown metric {metric!r}")


def metric_error(material, samples: SampleSet, metric: str) -> float:
    """sqrt(Σ w (f − y)² / (Σ w_norm · C)): the number a fit with `metric` reports."""
    num = 0.0
    den = 0.0
    for wi, wo, y, measure in samples.chunks():
        f = material.evaluate(wi, wo)
        num += float(sample_weight(metric, wi, wo, measure) @ ((f - y) ** 2).sum(axis=1))
        den += float(sample_weight(metric, wi, wo, measure, cosine=False).sum())
    return math.sqrt(num / max(den * y.shape[1], 1e-300))
