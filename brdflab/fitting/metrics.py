"""The error metrics of fits, over one measure for every source (CONVENTIONS.md "Fit errors").

Every metric weighs squared differences by the (ωi, ωo) solid-angle measure of the
samples: Ngan and L2 over pairs with θi, θo ≤ 80°, cosL2 over the whole hemisphere.
`grid_error` is the independent check: BRDFLab's own 16 θi × 16 θo × 64 φo grid.
"""

from __future__ import annotations

import math

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.fitting.image_metric import SceneImages
from brdflab.fitting.samples import SampleSet
from brdflab.geometry.vec import shared_half_vectors

MAX_THETA = math.radians(80.0)
NGAN_MAX_COS = math.cos(MAX_THETA)
METRICS = {
    "Ngan": "Ngan et al. 2005: RMS of (f − f') cos θi over the solid-angle measure, θi and θo ≤ 80°",
    "L2": "RMS of f − f' (1/sr) over the solid-angle measure, θi and θo ≤ 80°",
    "cosL2": "RMS of (f − f') cos θi over the solid-angle measure of the whole hemisphere",
    "image": "renders of the reference view under three maps, cube-root toned, RMS relative to the source's "
             "(image_metric.py)",
}
SAMPLE_METRICS = tuple(m for m in METRICS if m != "image")


def check_metric(metric: str, samples: SampleSet) -> None:
    """The image metric runs over a scene's renders, every other over samples."""
    if metric not in METRICS:
        raise BRDFLabError(f"unknown metric {metric!r} (known: {', '.join(METRICS)})")
    if (metric == "image") != isinstance(samples, SceneImages):
        raise BRDFLabError("the image metric compares renders of a scene (SceneImages), the others samples"
                           if metric == "image" else f"the {metric} metric needs samples, not a scene's renders")


def sample_weight(metric: str, wi: np.ndarray, wo: np.ndarray, measure: np.ndarray, cosine: bool = True) -> np.ndarray:
    """Per-sample weight of squared differences under `metric` (cosine=False: the
    normalising weight, the measure of the metric's domain)."""
    if metric not in SAMPLE_METRICS:
        raise BRDFLabError(f"unknown sample metric {metric!r} (known: {', '.join(SAMPLE_METRICS)})")
    w = np.asarray(measure, float)
    if metric != "cosL2":
        w = np.where((wi[:, 2] >= NGAN_MAX_COS) & (wo[:, 2] >= NGAN_MAX_COS), w, 0.0)
    return _cosine_weighted(metric, w, wi) if cosine else w


def _cosine_weighted(metric: str, domain: np.ndarray, wi: np.ndarray) -> np.ndarray:
    return domain * wi[:, 2] ** 2 if metric != "L2" else domain


def in_domain(metric: str, wi: np.ndarray, wo: np.ndarray, y: np.ndarray, measure: np.ndarray):
    """A chunk's samples that `metric` weighs (wi, wo, y, their weights) and the measure of the
    metric's domain in the chunk (what the error is normalised by)."""
    domain = sample_weight(metric, wi, wo, measure, cosine=False)
    w = _cosine_weighted(metric, domain, wi)
    inside = w > 0.0  # samples outside the domain cost nothing
    if not inside.all():  # `take` of indices: 4× faster than indexing with the mask
        keep = np.flatnonzero(inside)
        wi, wo, y, w = (np.take(a, keep, axis=0) for a in (wi, wo, y, w))
    return wi, wo, y, w, float(domain.sum())


def metric_errors(materials: list, samples: SampleSet, metric: str) -> list[float]:
    """The named-metric error of each material (None: a zero BRDF) over the samples, in one
    pass: sqrt(Σ w (f − y)² / (Σ w_norm · C)), summed directly from the residuals; the
    image metric's over a scene's renders."""
    check_metric(metric, samples)
    if isinstance(samples, SceneImages):
        return samples.errors(materials)
    num = np.zeros(len(materials))
    den = 0.0
    for chunk in samples.chunks():
        wi, wo, y, w, domain = in_domain(metric, *chunk)
        with shared_half_vectors():
            for k, material in enumerate(materials):
                f = 0.0 if material is None else material.evaluate(wi, wo)
                num[k] += float(np.einsum("n,n->", w, ((f - y) ** 2).sum(axis=1)))
        den += domain
    return [math.sqrt(n / max(den * samples.n_channels, 1e-300)) for n in num]


def metric_error(material, samples: SampleSet, metric: str) -> float:
    """The number a fit with `metric` reports for `material` on `samples`."""
    return metric_errors([material], samples, metric)[0]


def grid_error(reference, candidate, metric: str = "Ngan", n_theta: int = 16, n_phi: int = 64) -> float:
    """The error between two sources on BRDFLab's grid: n_theta θi × n_theta θo × n_phi φo
    cell centres with weights sin θi sin θo, φi = 0 for isotropic references (16 values of
    φi otherwise). θ runs to 80° (Ngan, L2) or 90° (cosL2). An independent check of the
    fitter's reported error: no sample set, no Gram matrices, no bin measures."""
    if metric not in METRICS:
        raise BRDFLabError(f"unknown metric {metric!r} (known: {', '.join(METRICS)})")
    top = 0.5 * math.pi if metric == "cosL2" else MAX_THETA
    theta = (np.arange(n_theta) + 0.5) * top / n_theta
    phi_o = (np.arange(n_phi) + 0.5) * 2.0 * math.pi / n_phi
    n_phi_i = 1 if getattr(reference, "isotropic", False) else 16
    phi_i = np.arange(n_phi_i) * 2.0 * math.pi / n_phi_i
    ti, pi, to, po = (a.ravel() for a in np.meshgrid(theta, phi_i, theta, phi_o, indexing="ij"))
    wi = np.stack([np.sin(ti) * np.cos(pi), np.sin(ti) * np.sin(pi), np.cos(ti)], axis=1)
    wo = np.stack([np.sin(to) * np.cos(po), np.sin(to) * np.sin(po), np.cos(to)], axis=1)
    weight = np.sin(ti) * np.sin(to)
    diff2 = ((np.asarray(candidate.evaluate(wi, wo)) - np.asarray(reference.evaluate(wi, wo))) ** 2).sum(axis=1)
    if metric != "L2":
        diff2 = diff2 * np.cos(ti) ** 2
    return math.sqrt(float(np.einsum("n,n->", weight, diff2)) / (float(weight.sum()) * reference.n_channels))


def lobe_shares(material, samples: SampleSet, metric: str) -> np.ndarray:
    """Each lobe's share of the material's metric-weighted energy on the samples:
    Σ w ‖its contribution‖² / Σ w ‖f‖² (0 for a lobe scaled to 0; the shares need not sum to 1)."""
    check_metric(metric, samples)
    if isinstance(samples, SceneImages):
        return samples.lobe_shares(material, _contribution)
    own = np.zeros(len(material.lobes))
    total = 0.0
    for chunk in samples.chunks():
        wi, wo, _, w, _ = in_domain(metric, *chunk)
        parts = [_contribution(material, lobe, wi, wo) for lobe in material.lobes]
        own += [float(np.einsum("n,n->", w, (p ** 2).sum(axis=1))) for p in parts]
        total += float(np.einsum("n,n->", w, (sum(parts) ** 2).sum(axis=1)))
    return own / max(total, 1e-300)


def _contribution(material, lobe, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """One lobe's part of the material's value, (N, n_channels)."""
    v = lobe.channel_values(wi, wo, material.n_channels)
    if material.combination == "Linear":
        return v * np.asarray(lobe.scale)
    out = np.zeros((wi.shape[0], material.n_channels))
    out[:, lobe.channel] = lobe.scale[0] * v[:, min(lobe.channel, v.shape[-1] - 1)]
    return out
