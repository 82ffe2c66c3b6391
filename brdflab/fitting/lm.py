"""Levenberg–Marquardt fitting of analytic lobes to any source (BRDFLab §4).

Strategies (BRDFLab): **Linear** — the lobes' own parameters are nonlinear, the
per-channel scaling factors are solved by non-negative least squares inside every
evaluation (variable projection); **Fixed** — every parameter of every per-channel
lobe, magnitude included, is nonlinear. Magnitudes are searched unbounded (exp); a fit that
ends with one above MAX_SCALE, which a material may not hold, goes on from there with the
magnitudes capped (`_refit_within_cap`), so every fit returned is a material that loads.

One pass over the samples (chunked, threaded) evaluates each lobe at the current
parameters and at every finite-difference perturbation, and accumulates per-channel
Gram matrices of these lobe values. Because every residual is linear in the lobe
values, the cost, JᵀJ and Jᵀr of all perturbations follow exactly from those small
matrices: no Jacobian and no per-sample array is ever stored, so memory stays a small
multiple of one chunk, and a MERL table is fitted in place.

A large sample set is fitted coarse to fine: every start on a 60,000-sample stratified
subset, the best of them on a subset MEDIUM times that (a long crawl along a flat valley,
Principled's on a fabric, costs a fifth there), then on every sample with central
differences; the last iterations and the error reported are always over every sample.

The error a fit reports is summed directly from the residuals in a last pass (the Gram
expansion loses digits near an exact fit), and a fit never returns anything worse than
its start: when it finds nothing better, it returns the start unchanged.
"""

from __future__ import annotations

import math
import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.material.analytic import MAX_SCALE, AnalyticMaterial, Lobe, lobe_channels
from brdflab.models import get_model
from brdflab.fitting.defaults import DEFAULT_METRIC, DEFAULT_RESTARTS
from brdflab.fitting.diagnosis import suspicions
from brdflab.fitting.nnls import nnls
from brdflab.fitting.image_metric import SPHERE, SceneImages, tone
from brdflab.fitting.metrics import METRICS, check_metric, in_domain, lobe_shares, metric_errors
from brdflab.fitting.samples import SampleSet
from brdflab.geometry.vec import shared_half_vectors

COMPRESSIONS = ("none", "cbrt", "log")
FD_STEP = 1e-5  # in the search variables; 1e-4 was too coarse for sharp lobes (see `_normal_equations`)
COST_ROUNDING = 16 * np.finfo(float).eps  # relative rounding of a cost summed from Gram matrices
MEDIUM = 4  # the middle stage's subset, in coarse subsets
TONE_STEPS = 3  # Gauss–Newton steps of the Linear scales on the image metric's toned residuals
SCENE_COARSE = 16  # the image metric's coarse stage: every fourth pixel's row and column
RESTART_ITERATIONS = 40  # LM steps of each restart (the start the user gave gets max_iterations)
DEAD_SHARE = 1e-3  # a lobe carrying less of a fit's metric-weighted energy is dead (see `_revive`)
# a parameter that starts within this fraction of its (logistic) range from a bound is
# moved inside first: on the bound itself the bounded map has no gradient
START_MARGIN = 0.01
# the search variables of bounded parameters stay within ±U_LIMIT (their logistic tail: 3e-7
# of the range from a bound), and one LM step moves none by more than MAX_STEP: a variable
# whose gradient vanishes (a weight whose lobe is off) once took a step to ±40, where the map
# is flat, and never came back (Principled's clear coat, its gloss, its colour)
U_LIMIT = 15.0
MAX_STEP = 4.0
# a parameter this close to a bound (fraction of its searched range) is reported on it
SATURATED = 1e-6
FIT_NAME = "fit"  # the name of every fit's material: it says nothing of what was fitted
MAX_FIT_LOBES = 16  # lobes of one fit (per channel in Fixed materials): more is no model of a BRDF, and costs minutes



# --- parameter transforms: unbounded search variables u ↔ bounded parameters x ------------

@dataclass(frozen=True)
class Bounded:
    """x in [lo, hi] through a logistic map, on a log scale for parameters spanning decades."""

    lo: float
    hi: float
    log: bool

    def _span(self) -> tuple[float, float, float]:
        if self.log:
            c = max(1e-5 * (self.hi - self.lo), 1e-12)
            return math.log(c), math.log(self.hi - self.lo + c), c
        return self.lo, self.hi, 0.0

    def to_x(self, u: float) -> float:
        a, b, c = self._span()
        v = a + (b - a) / (1.0 + math.exp(-max(-U_LIMIT, min(U_LIMIT, u))))
        return min(self.hi, max(self.lo, self.lo + math.exp(v) - c if self.log else v))

    def on_bound(self, x: float) -> float:
        """x, or the bound it has run onto (within SATURATED of the range): a fit reports
        clearcoat = 0, not 3e-7."""
        t = self.position(x)
        return self.lo if t < SATURATED else (self.hi if t > 1.0 - SATURATED else x)

    def position(self, x: float) -> float:
        """Where x lies in its range, 0 (lower bound) to 1 (upper), on the searched scale."""
        a, b, c = self._span()
        x = min(self.hi, max(self.lo, x))
        v = math.log(x - self.lo + c) if self.log else x
        return (v - a) / (b - a)

    def to_u(self, x: float, margin: float = 1e-12) -> float:
        """The search variable of x, at least `margin` (a fraction of the range) inside."""
        t = min(1.0 - margin, max(margin, self.position(x)))
        return math.log(t / (1.0 - t))


@dataclass(frozen=True)
class Positive:
    """A magnitude ≥ 0 (Fixed strategy): x = exp(u)."""

    def to_x(self, u: float) -> float:
        return math.exp(max(-60.0, min(60.0, u)))

    def to_u(self, x: float, margin: float = 0.0) -> float:
        return math.log(max(x, 1e-14))


@dataclass(frozen=True)
class Capped:
    """A magnitude in [0, cap]: x = cap / (1 + exp(−u)). Far below the cap this is
    cap · exp(u), Positive's map shifted, so the search there moves as Positive's does."""

    cap: float

    def to_x(self, u: float) -> float:
        return self.cap / (1.0 + math.exp(-max(-60.0, min(60.0, u))))

    def to_u(self, x: float, margin: float = 0.0) -> float:
        """The search variable of x, at least `margin` (a fraction of the cap) below the cap."""
        t = min(1.0 - max(margin, 1e-12), max(x, 1e-14) / self.cap)
        return math.log(t / (1.0 - t))


@dataclass(frozen=True)
class FreeBlock:
    """Search variables that set some of one lobe's values.

    kind 'scalar': one bounded parameter; 'magnitude': a Fixed lobe's value; 'direction':
    a scale-invariant group (Lafortune's C) of k parameters searched as k − 1 angles at
    fixed norm, which removes the direction along which the lobe does not change.
    """

    lobe: int
    names: tuple[str, ...]  # () for a magnitude
    kind: str
    transform: Bounded | Positive | Capped | None = None
    norm: float = 1.0

    @property
    def size(self) -> int:
        return len(self.names) - 1 if self.kind == "direction" else 1

    def to_u(self, lobe: Lobe, margin: float = 1e-12) -> list[float]:
        if self.kind == "magnitude":
            return [self.transform.to_u(lobe.scale[0], margin)]
        if self.kind == "scalar":
            return [self.transform.to_u(lobe.params[self.names[0]], margin)]
        c = np.array([lobe.params[n] for n in self.names]) / self.norm
        if len(c) == 2:
            return [math.atan2(c[1], c[0])]
        return [math.acos(max(-1.0, min(1.0, c[2]))), math.atan2(c[1], c[0])]

    def apply(self, u: np.ndarray, params: dict, mags: np.ndarray) -> None:
        if self.kind == "magnitude":
            mags[self.lobe] = self.transform.to_x(float(u[0]))
        elif self.kind == "scalar":
            params[self.names[0]] = self.transform.to_x(float(u[0]))
        elif len(self.names) == 2:
            params[self.names[0]] = self.norm * math.cos(u[0])
            params[self.names[1]] = self.norm * math.sin(u[0])
        else:
            t, p = float(u[0]), float(u[1])
            for n, v in zip(self.names, (math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t))):
                params[n] = self.norm * v


def free_blocks(material: AnalyticMaterial, magnitude_cap: float | None = None) -> list[FreeBlock]:
    """Every search variable of a material's fit, in lobe order; Fixed magnitudes are
    unbounded above unless `magnitude_cap` is given."""
    blocks = []
    for l, lobe in enumerate(material.lobes):
        group = lobe.model.scale_invariant
        if group:
            c = np.array([lobe.params[n] for n in group])
            bound = min(min(abs(lobe.model.parameter(n).lower), lobe.model.parameter(n).upper) for n in group)
            norm = float(np.linalg.norm(c)) or 1.0
            blocks.append(FreeBlock(l, tuple(group), "direction", norm=min(norm, bound)))
        for p in lobe.model.parameters:
            if p.name not in group and p.fitted and p.upper > p.lower:  # a switch keeps its value
                blocks.append(FreeBlock(l, (p.name,), "scalar", Bounded(p.search_lower, p.upper, p.log)))
        if material.combination == "Fixed" and lobe.model.scaled:
            blocks.append(FreeBlock(l, (), "magnitude", Positive() if magnitude_cap is None else Capped(magnitude_cap)))
    return blocks


def on_bounds(material: AnalyticMaterial) -> AnalyticMaterial:
    """The material with every fitted parameter that ran onto a bound set on it."""
    out = material.copy()
    for b in free_blocks(out):
        if b.kind == "scalar":
            params = out.lobes[b.lobe].params
            params[b.names[0]] = b.transform.on_bound(params[b.names[0]])
    return out


def parameter_count(material: AnalyticMaterial) -> int:
    """Every number the fit sets: nonlinear search variables, plus one scaling factor per
    lobe and channel in Linear combinations (solved by NNLS; a lobe that carries its own
    magnitude, Principled, has none)."""
    nonlinear = sum(b.size for b in free_blocks(material))
    scaled = sum(l.model.scaled for l in material.lobes)
    return nonlinear + (material.n_channels * scaled if material.combination == "Linear" else 0)


# --- options, progress, result -----------------------------------------------------------

@dataclass
class FitOptions:
    metric: str = DEFAULT_METRIC
    compression: str = "none"
    max_iterations: int = 200
    time_limit: float = math.inf  # seconds, > 0
    restarts: bool = DEFAULT_RESTARTS
    coarse_size: int = 60_000  # fit a stratified subset this large first (0: never)
    ftol: float = 1e-5  # stop after two accepted steps that gain less than this fraction
    workers: int = 1  # threads for the sample passes (0: one per core; NumPy holds the GIL too often for more to pay)
    diagnose: bool = True  # look for parameters on bounds and energy violations in the result

    def validate(self) -> None:
        if self.metric not in METRICS:
            raise BRDFLabError(f"unknown metric {self.metric!r} (known: {', '.join(METRICS)})")
        if self.compression not in COMPRESSIONS:
            raise BRDFLabError(f"unknown compression {self.compression!r} (known: {', '.join(COMPRESSIONS)})")
        if self.metric == "image" and self.compression != "none":
            raise BRDFLabError("the image metric has its own tone curve: no --compression with it")
        if self.max_iterations < 1:
            raise BRDFLabError("max_iterations must be at least 1")
        if not self.time_limit > 0:  # also refuses NaN
            raise BRDFLabError(f"the time limit must be a positive number of seconds, not {self.time_limit:g}")


@dataclass
class FitProgress:
    stage: str
    iteration: int
    error: float
    material: AnalyticMaterial


@dataclass
class FitResult:
    material: AnalyticMaterial
    error: float
    metric: str
    seconds: float
    iterations: int
    evaluations: int
    status: str  # converged | max-iterations | time-limit | cancelled | no-better-than-zero
    message: str = ""
    history: list[float] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)  # parameters on bounds, energy violations
    zero_error: float = math.nan  # the error of a zero BRDF on the same samples
    scored_on: str = "all samples fitted"  # which samples `error` is measured over
    second: dict = field(default_factory=dict)  # the number it was not fitted by (second_error.py)

    @property
    def suspect(self) -> bool:
        return bool(self.warnings) or self.status == "no-better-than-zero"

    def statistics(self) -> dict:
        stats = {"metric": self.metric, "seconds": round(self.seconds, 4), "iterations": self.iterations,
                 "evaluations": self.evaluations, "status": self.status, "scoredOn": self.scored_on}
        if self.warnings:
            stats["warnings"] = "; ".join(self.warnings)
        return {**stats, **self.second}

    def as_dict(self) -> dict:
        return {"error": self.error, **self.statistics(), "warnings": list(self.warnings),
                "zero_error": self.zero_error, "message": self.message,
                "parameters": self.material.describe()["lobes"]}


class _Stopped(Exception):
    """Raised inside a sample pass when the fit must stop (cancel or time limit)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


# --- the problem ---------------------------------------------------------------------------

KEEP_PREPARED = 100_000  # a sample set up to this size keeps its prepared chunks for the whole descent


@dataclass
class _Prepared:
    """A chunk inside the metric's domain: directions, values, weights (per channel: the
    compression's too), Σ w y² per channel (with and without compression), and the measure."""

    wi: np.ndarray
    wo: np.ndarray
    y: np.ndarray
    weight: np.ndarray
    channel_weight: list  # the weight itself for every channel where nothing is compressed
    yy: np.ndarray
    plain_yy: np.ndarray | None  # without compression: only where there is one
    norm: float


class _Problem:
    """Lobes, free parameters and a sample set; computes cost and normal equations."""

    def __init__(self, material: AnalyticMaterial, samples: SampleSet, options: FitOptions,
                 stop: Callable[[], str | None] = lambda: None, magnitude_cap: float | None = None) -> None:
        if samples.n_channels != material.n_channels:
            raise BRDFLabError(
                f"the source has {samples.n_channels} channels, the material {material.n_channels}")
        if not material.lobes:
            raise BRDFLabError("a fit needs at least one lobe")
        check_metric(options.metric, samples)
        self.material = material
        self.samples = samples
        self.scene = samples if isinstance(samples, SceneImages) else None  # the image metric
        self.options = options
        self.linear = material.combination == "Linear"
        self.held = [l for l, lobe in enumerate(material.lobes) if not lobe.model.scaled]  # lobes that keep their scale
        self.blocks = free_blocks(material, magnitude_cap)
        # for each search variable: its block and whether it changes the lobe's shape
        self.owner = [b for b in self.blocks for _ in range(b.size)]
        self.shape_vars = [k for k, b in enumerate(self.owner) if b.kind != "magnitude"]
        self.passes = 0
        self.cost_floor = 0.0  # what the cost cannot resolve (set by `evaluate`)
        self.central = False  # central differences for the Jacobian (see `_normal_equations`)
        self.stop = stop
        self._prepared: list[_Prepared] | None = None
        workers = options.workers or os.cpu_count() or 1
        self._pool = ThreadPoolExecutor(max_workers=workers) if workers > 1 else None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False)

    # vector <-> material
    def initial_u(self) -> np.ndarray:
        """The start's search vector, every bounded parameter START_MARGIN inside its range."""
        return np.array([v for b in self.blocks for v in b.to_u(self.material.lobes[b.lobe], START_MARGIN)], float)

    def params_of(self, u: np.ndarray) -> tuple[list[dict], np.ndarray]:
        """Per-lobe parameter dicts and Fixed magnitudes for search vector u."""
        params = [dict(l.params) for l in self.material.lobes]
        mags = np.array([l.scale[0] for l in self.material.lobes], float)
        k = 0
        for b in self.blocks:
            b.apply(u[k:k + b.size], params[b.lobe], mags)
            k += b.size
        return params, mags

    def material_of(self, u: np.ndarray, scales: np.ndarray | None) -> AnalyticMaterial:
        params, mags = self.params_of(u)
        out = self.material.copy()
        for l, lobe in enumerate(out.lobes):
            lobe.params = params[l]
            lobe.scale = [float(s) for s in scales[:, l]] if self.linear else [float(mags[l])]
        return out

    # one pass over the samples
    def _perturbations(self, u: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """(variable, search vector) of every finite-difference evaluation: +FD_STEP along
        each variable, and −FD_STEP too when `central`."""
        signs = (1.0, -1.0) if self.central else (1.0,)
        out = []
        for k in range(len(self.owner)):
            for sign in signs:
                up = u.copy()
                up[k] += sign * FD_STEP
                out.append((k, up))
        return out

    def _rows(self, u: np.ndarray, with_jacobian: bool) -> tuple[list[tuple[int, dict]], list[tuple[int, np.ndarray]]]:
        """Lobe evaluations needed: every lobe at u, and (Jacobian) the lobe each perturbation
        of a shape variable changes. Returns (lobe, params) per row and the perturbations."""
        base_params, _ = self.params_of(u)
        rows = [(l, base_params[l]) for l in range(len(self.material.lobes))]
        perturbed = self._perturbations(u) if with_jacobian else []
        for k, up in perturbed:
            block = self.owner[k]
            if block.kind != "magnitude":
                rows.append((block.lobe, self.params_of(up)[0][block.lobe]))
        return rows, perturbed

    def _prepare(self, chunk) -> _Prepared:
        """What a pass needs of a chunk besides the lobes' values: its samples inside the
        metric's domain and their weights per channel."""
        wi, wo, y, weight, norm = in_domain(self.options.metric, *chunk)
        C = y.shape[1]
        compressed = self.options.compression != "none"
        channel_weight = [weight * self._compression_weight(y[:, c]) for c in range(C)] if compressed else [weight] * C
        # not `@`: OpenBLAS threads 1-D dots badly
        yy = np.array([np.einsum("n,n->", wc, y[:, c] ** 2) for c, wc in enumerate(channel_weight)])
        plain_yy = np.array([np.einsum("n,n->", weight, y[:, c] ** 2) for c in range(C)]) if compressed else None
        return _Prepared(wi, wo, y, weight, channel_weight, yy, plain_yy, norm)

    def _prepared_chunks(self):
        """The sample set's chunks, prepared; kept for the fit where the set is small (the
        coarse stage's passes spent a third of their time preparing the same samples again)."""
        if self._prepared is not None:
            return self._prepared
        prepared = map(self._prepare, self.samples.chunks())
        if self.samples.size <= KEEP_PREPARED:
            self._prepared = list(prepared)
            return self._prepared
        return prepared

    def _chunk_grams(self, rows, chunk: _Prepared):
        reason = self.stop()
        if reason is not None:
            raise _Stopped(reason)
        wi, wo, y = chunk.wi, chunk.wo, chunk.y
        C = y.shape[1]
        R = len(rows)
        # E[k, r]: row r's lobe values, one plane for all channels, or one per channel when a
        # colour lobe gives each channel its own
        lobes = self.material.lobes
        K = 3 if C == 3 and any(lobes[l].model.colour for l, _ in rows) else 1
        E = np.empty((K, R, wi.shape[0]))
        with shared_half_vectors():  # every row is one lobe at these directions
            for r, (l, p) in enumerate(rows):
                E[:, r] = lobe_channels(lobes[l].model, wi, wo, p, C).T
        G = np.empty((C, R, R))
        b = np.empty((C, R))
        plain = np.empty((C, len(self.material.lobes), len(self.material.lobes))) if self.options.compression != "none" else None
        plain_b = np.empty((C, len(self.material.lobes))) if plain is not None else None
        for c in range(C):
            Ec = E[min(c, K - 1)]
            G[c], b[c] = _weighted_gram(Ec, chunk.channel_weight[c], y[:, c])
            if plain is not None:
                L = plain.shape[1]
                Eb = Ec[:L] * chunk.weight
                plain[c] = Eb @ Ec[:L].T
                plain_b[c] = Eb @ y[:, c]
        return G, b, chunk.yy, plain, plain_b, chunk.plain_yy, chunk.norm

    def _compression_weight(self, y: np.ndarray) -> np.ndarray:
        """Squared derivative of the compression at the data: residuals g(f) − g(y) are
        linearised as g'(y)(f − y), which keeps them linear in the lobes."""
        c = self.options.compression
        if c == "none":
            return 1.0
        y = np.maximum(y, 0.0)
        if c == "cbrt":
            d = (1.0 / 3.0) * (y + 1e-4) ** (-2.0 / 3.0)
        else:
            d = 1.0 / (1.0 + y)
        return d * d

    def _block_images(self, rows, block) -> np.ndarray:
        """(C, R, P): the rows' images from one block of the scene's pairs."""
        reason = self.stop()
        if reason is not None:
            raise _Stopped(reason)
        _, _, wi, wo, _ = block
        lobes = self.material.lobes
        C = self.scene.n_channels
        K = 3 if C == 3 and any(lobes[l].model.colour for l, _ in rows) else 1
        E = np.empty((K, len(rows), wi.shape[0]))
        with shared_half_vectors():
            for r, (l, p) in enumerate(rows):
                E[:, r] = lobe_channels(lobes[l].model, wi, wo, p, C).T
        return self.scene.block_images(block, E)

    def scene_images(self, rows) -> np.ndarray:
        """(C, R, P): every row's images under the scene's maps."""
        self.passes += 1
        work = lambda block: self._block_images(rows, block)
        parts = self._pool.map(work, self.scene.blocks()) if self._pool else map(work, self.scene.blocks())
        return sum(parts)

    def accumulate(self, rows):
        """Sum the per-chunk Gram matrices over the whole sample set."""
        self.passes += 1
        work = lambda ch: self._chunk_grams(rows, ch)
        chunks = self._prepared_chunks()
        parts = self._pool.map(work, chunks) if self._pool else map(work, chunks)
        total = None
        for part in parts:
            if total is None:
                total = [None if x is None else (x.copy() if isinstance(x, np.ndarray) else x) for x in part]
            else:
                for i, x in enumerate(part):
                    if x is not None:
                        total[i] = total[i] + x
        return total

    # coefficients of each perturbation on the rows, per channel
    def _coefficients(self, G, b, u, perturbed) -> np.ndarray:
        """A[c, k, r]: channel c's coefficient of row r for perturbation k (0 = base). G and b
        are (C, R, R) and (C, R), or (C, K, R, R) and (C, K, R): a Gram matrix per perturbation."""
        C, R = b.shape[0], b.shape[-1]
        L = len(self.material.lobes)
        A = np.zeros((C, 1 + len(perturbed), R))
        extra = L
        for k, (var, up) in enumerate([(None, u), *perturbed]):
            rows = list(range(L))
            block = None if var is None else self.owner[var]
            if block is not None and block.kind != "magnitude":
                rows[block.lobe] = extra
                extra += 1
            if self.linear:
                Gk, bk = (G, b) if b.ndim == 2 else (G[:, k], b[:, k])
                for c in range(C):
                    A[c, k, rows] = self._linear_scales(Gk[c], bk[c], rows, c)
            else:
                _, mags = self.params_of(up)
                for l, lobe in enumerate(self.material.lobes):
                    A[lobe.channel, k, rows[l]] = mags[l]
        return A

    def _linear_scales(self, G: np.ndarray, b: np.ndarray, rows: list[int], channel: int) -> np.ndarray:
        """One channel's scaling factors of the lobes on `rows`: NNLS, but a lobe that carries
        its own magnitude (model.scaled False) keeps its scale and the others fit what it leaves."""
        held = self.held
        if not held:
            r = np.array(rows)
            return _nnls(G[r[:, None], r], b[r])
        out = np.empty(len(rows))
        fixed = [rows[l] for l in held]
        out[held] = [self.material.lobes[l].scale[channel] for l in held]
        free = [l for l in range(len(rows)) if l not in held]
        if free:
            free_rows = [rows[l] for l in free]
            out[free] = _nnls(G[np.ix_(free_rows, free_rows)], b[free_rows] - G[np.ix_(free_rows, fixed)] @ out[held])
        return out

    def evaluate(self, u: np.ndarray, with_jacobian: bool = True):
        """Cost (sum of weighted squared residuals), JᵀJ, Jᵀr, named-metric error, scales."""
        rows, perturbed = self._rows(u, with_jacobian)
        if self.scene is not None:
            return self._evaluate_images(u, rows, perturbed, with_jacobian)
        G, b, yy, plain, plain_b, plain_yy, norm = self.accumulate(rows)
        A = self._coefficients(G, b, u, perturbed)
        # inner products of the residual vectors of all perturbations, summed over channels
        M = np.einsum("ckr,crs,cls->kl", A, G, A)
        Ab = np.einsum("ckr,cr->ck", A, b)
        inner = M - Ab.sum(0)[:, None] - Ab.sum(0)[None, :] + yy.sum()
        cost = float(inner[0, 0])
        # the cost is a difference of sums as large as Σ w y²: gains below its rounding are none
        self.cost_floor = COST_ROUNDING * float(yy.sum())
        L = len(self.material.lobes)
        if plain is None:
            named = cost
        else:
            a0 = A[:, 0, :L]
            named = float(np.einsum("cr,crs,cs->", a0, plain, a0) - 2 * np.einsum("cr,cr->", a0, plain_b) + plain_yy.sum())
        error = math.sqrt(max(named, 0.0) / max(norm * self.material.n_channels, 1e-300))
        scales = A[:, 0, :L]
        if not with_jacobian:
            return cost, None, None, error, scales
        jtj, jtr = _normal_equations(inner, self.central)
        return cost, jtj, jtr, error, scales

    def _evaluate_images(self, u, rows, perturbed, with_jacobian: bool):
        """`evaluate` under the image metric: the rows' images, Linear scales by NNLS on the
        tone curve linearised at the source, then every perturbation's image taken through
        the tone curve itself, so the cost is the metric's and the finite differences of
        the Jacobian see the curve exactly."""
        images = self.scene_images(rows)  # (C, R, P)
        lw, y = self.scene.linear_weight, self.scene.target
        G = np.einsum("crp,cp,csp->crs", images, lw, images)
        b = np.einsum("crp,cp,cp->cr", images, lw, y)
        A = self._coefficients(G, b, u, perturbed)
        for _ in range(TONE_STEPS if self.linear else 0):
            # Gauss–Newton on the scales for the toned residuals, the tone re-linearised at each
            # perturbation's current image (at the source's alone, a Lambertian fitted by the
            # image metric scored worse in it than one fitted by Ngan's)
            a = np.einsum("ckr,crp->ckp", A, images)
            slope = (1.0 / 3.0) * np.maximum(a, self.scene.tone_floor[:, None]) ** (-2.0 / 3.0)
            w = self.scene.pixel_weight[:, None] * slope ** 2
            z = a + (self.scene.toned[:, None] - tone(a)) / slope
            A = self._coefficients(np.einsum("crp,ckp,csp->ckrs", images, w, images),
                                   np.einsum("crp,ckp,ckp->ckr", images, w, z), u, perturbed)
        residuals = self.scene.toned_residuals(np.einsum("ckr,crp->kcp", A, images))  # (K, C·P)
        inner = residuals @ residuals.T
        cost = float(inner[0, 0])
        self.cost_floor = COST_ROUNDING
        scales = A[:, 0, :len(self.material.lobes)]
        if not with_jacobian:
            return cost, None, None, math.sqrt(max(cost, 0.0)), scales
        jtj, jtr = _normal_equations(inner, self.central)
        return cost, jtj, jtr, math.sqrt(max(cost, 0.0)), scales


GRAM_BLOCK = 8192  # samples per block of a Gram matrix: R rows of it stay in the CPU's cache


def _weighted_gram(E: np.ndarray, w: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """E diag(w) Eᵀ and E diag(w) y (E: rows × samples), summed over blocks of GRAM_BLOCK
    samples: the weighted copy of a 65,536-sample chunk of a dozen rows does not fit in the
    cache, and one pass over it cost twice the blocks' time (Principled, 13 rows)."""
    R = E.shape[0]
    G, b = np.zeros((R, R)), np.zeros(R)
    for s in range(0, E.shape[1], GRAM_BLOCK):
        Ew = E[:, s:s + GRAM_BLOCK] * w[s:s + GRAM_BLOCK]
        G += Ew @ E[:, s:s + GRAM_BLOCK].T
        b += Ew @ y[s:s + GRAM_BLOCK]
    return G, b


def _normal_equations(inner: np.ndarray, central: bool) -> tuple[np.ndarray, np.ndarray]:
    """JᵀJ and Jᵀr from the inner products of the residual vectors: base first, then each
    variable's +FD_STEP perturbation (and its −FD_STEP one when `central`). Forward
    differences carry a bias of FD_STEP/2 · r″ that moves the minimum they find off the
    true one on sharp lobes (chrome's Lafortune exponent: 1.7 % in error); central ones
    do not."""
    if not central:
        cost = inner[0, 0]
        d = inner[1:, 1:] - inner[1:, :1] - inner[:1, 1:] + cost
        return _psd(d / (FD_STEP * FD_STEP)), (inner[1:, 0] - cost) / FD_STEP
    plus, minus = np.arange(1, inner.shape[0], 2), np.arange(2, inner.shape[0], 2)
    d = (inner[np.ix_(plus, plus)] - inner[np.ix_(plus, minus)] - inner[np.ix_(minus, plus)]
         + inner[np.ix_(minus, minus)])
    return _psd(d / (4.0 * FD_STEP * FD_STEP)), (inner[plus, 0] - inner[minus, 0]) / (2.0 * FD_STEP)


def _psd(m: np.ndarray) -> np.ndarray:
    """JᵀJ is positive semidefinite; rounding in directions without curvature (a parameter
    at its bound) can leave tiny negative eigenvalues, which would make steps unbounded."""
    w, v = np.linalg.eigh(0.5 * (m + m.T))
    return (v * np.maximum(w, 0.0)) @ v.T


def _solve(A: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    try:
        x = np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return None
    return x if np.all(np.isfinite(x)) else None


def _nnls(G: np.ndarray, b: np.ndarray) -> np.ndarray:
    """min ‖R s − z‖ with s ≥ 0 where RᵀR = G, Rᵀz = b (the normal equations of the
    weighted least-squares problem, solved without forming it)."""
    n = G.shape[0]
    jitter = 1e-13 * max(np.trace(G), 1e-300)
    try:
        R = np.linalg.cholesky(G + jitter * np.eye(n)).T
    except np.linalg.LinAlgError:
        return np.zeros(n)
    z = np.linalg.solve(R.T, b)
    return nnls(R, z, max_iterations=50 * n)


# --- Levenberg–Marquardt ----------------------------------------------------------------------

ProgressCallback = Callable[[FitProgress], None]


def _lm(problem: _Problem, u: np.ndarray, options: FitOptions, max_iterations: int, ftol: float,
        stage: str, progress: ProgressCallback | None, history: list[float], lam: float = 1e-3,
        refine: bool = True):
    """Minimise problem's cost from u: forward differences until converged, then (`refine`)
    central ones from there until converged again (they find a sharp lobe's minimum where
    forward ones stop short; see `_normal_equations`), within `max_iterations` in all.

    Returns (u_best, state_best or None if stopped before the first pass, iterations,
    status, final damping λ)."""
    problem.central = False
    found = _lm_run(problem, u, max_iterations, ftol, stage, progress, history, lam)
    if not refine or found[3] != "converged" or found[2] >= max_iterations or found[0].size == 0:
        return found
    problem.central = True
    refined = _lm_run(problem, found[0], max_iterations - found[2], ftol, stage, progress, history, found[4])
    if refined[1] is None:  # stopped before its first pass
        return found[0], found[1], found[2], refined[3], found[4]
    return refined[0], refined[1], found[2] + refined[2], refined[3], refined[4]


def _lm_run(problem: _Problem, u: np.ndarray, max_iterations: int, ftol: float, stage: str,
            progress: ProgressCallback | None, history: list[float], lam: float):
    """One Levenberg–Marquardt run from u with the problem's differences; returns as `_lm`."""
    try:
        if u.size == 0:  # nothing nonlinear: the scaling factors alone are solved
            return u, problem.evaluate(u, with_jacobian=False), 0, "converged", lam
        state = problem.evaluate(u)
    except _Stopped as e:
        return u, None, 0, e.reason, lam
    cost, jtj, jtr, error, scales = state
    if not math.isfinite(cost):
        raise BRDFLabError("the initial parameters give a non-finite error")
    best = (u.copy(), state)
    diag_floor = 1e-9 * max(float(np.max(np.diag(jtj))), 1e-300)
    small = 0
    cautious = False  # after a rejection, try steps on the cost alone (a cheaper pass)
    status = "max-iterations"
    it = 0
    try:
        for it in range(1, max_iterations + 1):
            reason = problem.stop()
            if reason is not None:
                status = reason
                break
            D = np.maximum(np.diag(jtj), diag_floor)
            # converged when even the undamped (Gauss–Newton) model promises almost nothing
            gn = _solve(jtj + 1e-12 * np.diag(D), -jtr)
            if gn is not None and -float(jtr @ gn) < max(ftol * cost, problem.cost_floor):
                status = "converged"
                break
            step = _solve(jtj + lam * np.diag(D), -jtr)
            if step is None:
                lam *= 4.0
                continue
            clipped = bool(np.any(np.abs(step) > MAX_STEP))  # then λ grows until it is not
            trial_u = np.clip(u + np.clip(step, -MAX_STEP, MAX_STEP), -U_LIMIT, U_LIMIT)
            step = trial_u - u
            trial = problem.evaluate(trial_u, with_jacobian=not cautious)
            predicted = -float(step @ jtr) - 0.5 * float(step @ (jtj @ step))
            if math.isfinite(trial[0]) and trial[0] < cost:
                rho = (cost - trial[0]) / max(predicted, 1e-300)
                small = small + 1 if cost - trial[0] < max(ftol * cost, problem.cost_floor) else 0
                best = (trial_u.copy(), trial)  # the best so far, even if its Jacobian pass is stopped
                if cautious:
                    trial = problem.evaluate(trial_u)
                    cautious = False
                u, state = trial_u, trial
                cost, jtj, jtr, error, scales = state
                best = (u.copy(), state)
                lam = lam / 5.0 if rho > 0.75 else (lam * 2.0 if rho < 0.25 else lam)
                lam = max(lam, 1e-12)
                history.append(error)
                if progress is not None:
                    progress(FitProgress(stage, it, error, problem.material_of(u, scales)))
                if small >= 2:
                    status = "converged"
                    break
            else:
                if not clipped and (predicted < max(ftol * cost, problem.cost_floor) or small):
                    # the local model promises less than the tolerance, or the last accepted
                    # step already gained less and this one fails: nothing left to gain
                    status = "converged"
                    break
                lam *= 4.0
                cautious = True
                if lam > 1e12:
                    status = "converged"  # no direction decreases the error any more
                    break
    except _Stopped as e:
        status = e.reason
    return best[0], best[1], it, status, lam


STOPPED = ("cancelled", "time-limit")


def fit(material: AnalyticMaterial, samples: SampleSet, options: FitOptions | None = None,
        progress: ProgressCallback | None = None, cancel: threading.Event | None = None,
        score_on: SampleSet | None = None) -> FitResult:
    """Fit `material`'s lobes to `samples`, starting from the material's parameters.

    Never returns NaN and never anything worse than the start (by the named metric on
    the scored samples): on cancellation, a time limit or an iteration cap it stops
    within one sample chunk and returns the best parameters seen, with `status` saying
    why. `score_on` (default: `samples`) is the sample set the returned error is
    measured on, e.g. all samples of a source fitted on a subset.
    """
    options = options or FitOptions()
    options.validate()
    material.validate()
    t0 = time.perf_counter()
    deadline = t0 + options.time_limit

    def stop() -> str | None:
        if cancel is not None and cancel.is_set():
            return "cancelled"
        return "time-limit" if time.perf_counter() > deadline else None

    history: list[float] = []
    iterations = 0
    passes = 0

    coarse = None
    if options.coarse_size and samples.size > 2 * options.coarse_size:
        coarse = samples.subset(options.coarse_size)
    elif options.coarse_size and isinstance(samples, SceneImages):
        coarse = samples.subset(samples.size // SCENE_COARSE)  # every other pixel's row and column

    start_materials = [material]
    if options.restarts:
        start_materials += restart_guesses(material)

    # stage 1: every start on the coarse set (or the full set when it is small)
    stage_samples = coarse or samples
    stage = "coarse" if coarse is not None else "fit"
    ftol = max(1e-5, options.ftol) if coarse is not None else options.ftol
    runs = []
    for start in start_materials:
        run = _descend(start, stage_samples, options, stop, options.max_iterations if start is material
                       else RESTART_ITERATIONS, ftol, stage, progress, history)
        iterations, passes = iterations + run.iterations, passes + run.passes
        runs.append(run)
        if run.status in STOPPED:
            break
    status = runs[-1].status
    finished = [r for r in runs if math.isfinite(r.cost)]
    result_material = material
    if finished:
        best = min(finished, key=lambda r: r.cost)
        if status not in STOPPED:
            best, its, evaluations = _revive(best, stage_samples, options, stop, ftol, stage, progress, history)
            iterations, passes, status = iterations + its, passes + evaluations, best.status
        # stage 2: the best polished on every sample (or finished, when a restart's iteration cap
        # cut it short) and refined with central differences, from its own search vector (not
        # moved off a bound again: that would change the lobe the first stage found)
        left = options.max_iterations if coarse is not None else options.max_iterations - best.iterations
        if status not in STOPPED and left > 0 and coarse is not None and samples.size > 2 * MEDIUM * coarse.size:
            # between: a subset MEDIUM times the coarse one, where a long crawl down a flat valley costs
            # a fraction of what it costs on every sample (Principled on blue-fabric: 121 full passes)
            medium = _descend(best.material, samples.subset(MEDIUM * coarse.size), options, stop, left, ftol, "medium",
                              progress, history, best.u, best.lam)
            iterations, passes, status = iterations + medium.iterations, passes + medium.passes, medium.status
            if math.isfinite(medium.cost):
                best = medium
        if status not in STOPPED and left > 0:
            polished = _descend(best.material, samples, options, stop, left, options.ftol, "fit", progress,
                                history, best.u, best.lam, refine=True)
            iterations, passes, status = iterations + polished.iterations, passes + polished.passes, polished.status
            if math.isfinite(polished.cost):
                best = polished
        result_material, u = best.material, best.u
        if _over_cap(result_material):
            if status in STOPPED:
                result_material = _continue_capped(result_material, u, samples, options, stop, None, [], 0)[0]
            else:
                result_material, its, evaluations, status = _refit_within_cap(
                    finished, (result_material, u), coarse is not None, stage_samples, samples, options, stop,
                    progress, history)
                iterations += its
                passes += evaluations

    # the reported error: summed directly over the scored samples, against the start's
    result_material = on_bounds(result_material)
    scored = score_on or samples
    start_error, error, zero_error = metric_errors([material, result_material, None], scored, options.metric)
    passes += 1
    kept_start = not math.isfinite(error) or start_error <= error
    if kept_start:
        result_material, error = material.copy(), start_error
    if not math.isfinite(error):
        raise BRDFLabError("the fit produced a non-finite error")
    messages = {
        "converged": "converged",
        "max-iterations": f"stopped after {options.max_iterations} iterations",
        "time-limit": f"stopped at the time limit of {options.time_limit:g} s; the best parameters so far are kept",
        "cancelled": "cancelled; the best parameters so far are kept",
    }
    message = messages.get(status, status)
    if kept_start and status == "converged":
        message = "converged: nothing better than the start was found, so the start is returned unchanged"
    if error >= zero_error and status not in STOPPED:
        status = "no-better-than-zero"
        message = (f"no better than a zero BRDF ({options.metric} {zero_error:.6g}): "
                   "these lobes cannot represent this source")
    warnings = suspicions(result_material) if options.diagnose else []
    what = "all samples fitted" if score_on is None or score_on is samples else f"{scored.size} samples (all of the source)"
    if isinstance(scored, SceneImages):
        n = len(scored.quadratures)
        what = (f"renders{'' if scored.seen == SPHERE else ' of ' + scored.seen} under {n} map{'s' * (n != 1)} "
                f"({', '.join(q.name for q in scored.quadratures)})")
    return FitResult(result_material, error, options.metric, time.perf_counter() - t0, iterations,
                     passes, status, message, history, warnings, zero_error, what)


@dataclass
class _Run:
    """Where one Levenberg–Marquardt descent ended (cost inf: stopped before its first pass)."""

    material: AnalyticMaterial
    u: np.ndarray
    cost: float
    lam: float
    status: str
    iterations: int
    passes: int


def _descend(start: AnalyticMaterial, samples: SampleSet, options: FitOptions, stop: Callable[[], str | None],
             max_iterations: int, ftol: float, stage: str, progress: ProgressCallback | None,
             history: list[float], u: np.ndarray | None = None, lam: float = 1e-3, refine: bool = False) -> _Run:
    """LM from `start` (from search vector `u`, by default the start's own moved inside its
    bounds); `refine`: finish with central differences (see `_lm`)."""
    problem = _Problem(start, samples, options, stop)
    try:
        found, state, its, status, lam = _lm(problem, problem.initial_u() if u is None else u, options,
                                             max_iterations, ftol, stage, progress, history, lam, refine)
    finally:
        problem.close()
    if state is None:
        return _Run(start, found, math.inf, lam, status, its, problem.passes)
    return _Run(problem.material_of(found, state[4]), found, state[0], lam, status, its, problem.passes)


def dead_lobes(material: AnalyticMaterial, samples: SampleSet, metric: str) -> list[int]:
    """The lobes that carry less than DEAD_SHARE of a fit (scaled to 0, or collapsed onto a
    spike or a shape the data do not have) and that a restart could move: those with a shape."""
    shares = lobe_shares(material, samples, metric)
    return [l for l, lobe in enumerate(material.lobes)
            if shares[l] < DEAD_SHARE and lobe.model.starts and lobe.model.scaled]


def _revive(run: _Run, samples: SampleSet, options: FitOptions, stop: Callable[[], str | None], ftol: float,
            stage: str, progress: ProgressCallback | None, history: list[float]) -> tuple[_Run, int, int]:
    """Restart every dead lobe from each of its model's starts, the other lobes where the fit
    left them: NNLS keeps a lobe at scale 0 once it is there, and a lobe at scale 0 has no
    gradient, so the descent cannot bring it back by itself (green-fabric's second GGX at
    m = 0.001, scale 0). A restart that lowers the cost is kept. Returns the run, iterations
    and passes spent."""
    iterations, passes = 0, 1  # the pass that finds the dead lobes
    for l in dead_lobes(run.material, samples, options.metric):
        for params in run.material.lobes[l].model.starts:
            start = run.material.copy()
            start.lobes[l].params.update(params)
            start.lobes[l].scale = [max(s, 0.1) for s in start.lobes[l].scale]
            trial = _descend(start, samples, options, stop, RESTART_ITERATIONS, ftol, stage, progress, history)
            iterations, passes = iterations + trial.iterations, passes + trial.passes
            if trial.status in STOPPED:
                return (trial if trial.cost < run.cost else replace(run, status=trial.status)), iterations, passes
            if trial.cost < run.cost * (1.0 - ftol):
                run = trial
    return run, iterations, passes


def _over_cap(material: AnalyticMaterial) -> bool:
    return material.combination == "Fixed" and any(l.scale[0] > MAX_SCALE for l in material.lobes)


def _continue_capped(material: AnalyticMaterial, u: np.ndarray, samples: SampleSet, options: FitOptions,
                     stop: Callable[[], str | None], progress: ProgressCallback | None, history: list[float],
                     max_iterations: int) -> tuple[AnalyticMaterial, np.ndarray, float, int, int, str]:
    """LM from a Fixed fit's search vector `u` with every magnitude capped at MAX_SCALE
    (those above start just below it). Returns the material, its search vector, its cost
    (inf when stopped before the first pass), iterations, passes and status."""
    problem = _Problem(material, samples, options, stop, magnitude_cap=MAX_SCALE)
    try:
        start = u.copy()  # the shape parameters where the fit left them, not moved off their bounds
        k = 0
        for block in problem.blocks:
            if block.kind == "magnitude":
                start[k:k + 1] = block.to_u(material.lobes[block.lobe], START_MARGIN)
            k += block.size
        if max_iterations == 0:
            return problem.material_of(start, None), start, math.inf, 0, 0, "converged"
        found, state, its, status, _ = _lm(problem, start, options, max_iterations, options.ftol,
                                           "capped", progress, history)
    finally:
        problem.close()
    cost = state[0] if state is not None else math.inf
    return problem.material_of(found, None), found, cost, its, problem.passes, status


def _refit_within_cap(candidates: list, final: tuple[AnalyticMaterial, np.ndarray], polished: bool,
                      stage_samples: SampleSet, samples: SampleSet, options: FitOptions,
                      stop: Callable[[], str | None], progress: ProgressCallback | None,
                      history: list[float]) -> tuple[AnalyticMaterial, int, int, str]:
    """A Fixed fit whose magnitudes ran past MAX_SCALE (the unbounded search's way of switching
    a lobe off, or of scaling up a lobe that vanishes, e.g. Schwenk's s² at s → 0), fitted
    again within it, so the result is a material that loads: every start's result continues
    with capped magnitudes on the first stage's samples, the best is polished (capped) on
    every sample, and the over-cap result itself continues capped; the lower cost wins.

    Entered only for such fits: every other fit's path is the unbounded one. Returns the
    material, iterations, passes and status."""
    iterations = passes = 0
    best = None  # (cost, material, search vector, status)
    for run in candidates:
        material, u = run.material, run.u
        m, v, cost, its, n, status = _continue_capped(material, u, stage_samples, options, stop, progress, history,
                                                      options.max_iterations)
        iterations, passes = iterations + its, passes + n
        if best is None or cost < best[0]:
            best = (cost, m, v, status)
        if status in STOPPED:
            return best[1], iterations, passes, status
    if not polished:  # the first stage fitted every sample: the best start's result is the fit
        return best[1], iterations, passes, best[3]
    tries = []  # (cost on every sample, material, status)
    for m, v in (best[1:3], final):
        m, _, cost, its, n, status = _continue_capped(m, v, samples, options, stop, progress, history,
                                                      options.max_iterations)
        iterations, passes = iterations + its, passes + n
        tries.append((cost, m, status))
        if status in STOPPED:
            break
    cost, material, status = min(tries, key=lambda t: t[0])
    return material, iterations, passes, status


def _occurrences(names: list[str]) -> list[tuple[int, int]]:
    """For each lobe: which occurrence of its model it is, and how many there are."""
    return [(names[:k].count(n), names.count(n)) for k, n in enumerate(names)]


def restart_guesses(material: AnalyticMaterial) -> list[AnalyticMaterial]:
    """Model-aware starting points: the i-th guess gives every lobe its model's i-th start;
    repeated lobes of one model take starts spread apart (a sharp and a broad lobe, …)."""
    names = material.lobe_models()
    place = dict(zip(range(len(names)), _occurrences(names)))
    count = max(len(l.model.starts) for l in material.lobes)
    out = []
    for i in range(count):
        m = material.copy()
        k = -1
        for lobe in m.lobes:
            k += lobe.channel in (None, 0)
            j, n = place[k]
            starts = lobe.model.starts
            lobe.params.update(starts[(i + j * max(1, len(starts) // n)) % len(starts)])
        out.append(m)
    return out


def check_fit_size(n_lobes: int, where: object | None = None) -> None:
    """Refuse, up front, a fit of more than MAX_FIT_LOBES lobes (1,000 Ward lobes ran for
    minutes, an --init of 10⁵ lobes took 10 GB)."""
    if n_lobes > MAX_FIT_LOBES:
        raise BRDFLabError(f"a fit of {n_lobes:,} lobes: the lab fits at most {MAX_FIT_LOBES} (Auto climbs to 4)", where)


def material_from_lobes(names: list[str], combination: str, n_channels: int) -> AnalyticMaterial:
    """A starting material for `brdflab fit --lobes A,B,...`: model defaults, unit scales;
    a model named more than once starts its lobes apart (its own starts, first to last), so
    that they do not collapse onto one; in Fixed combinations each named lobe is repeated
    for every channel."""
    if combination not in ("Linear", "Fixed"):
        raise BRDFLabError(f"combination must be linear or fixed, not {combination!r}")
    check_fit_size(len(names))
    lobes: list[Lobe] = []
    for name, (j, n) in zip(names, _occurrences(names)):
        model = get_model(name)
        params = model.defaults()
        if n > 1 and len(model.starts) > 1:
            params.update(model.starts[round(j * (len(model.starts) - 1) / (n - 1))])
        if not model.scaled:
            if combination == "Fixed":
                raise BRDFLabError(f"{model.name} carries its own colour and magnitude: it is fitted in a Linear "
                                   "material, with its scaling factors held at 1")
            lobes.append(Lobe(model, params, [1.0] * n_channels))
        elif combination == "Linear":
            lobes.append(Lobe(model, params, [0.1] * n_channels))
        else:
            lobes.extend(Lobe(model, dict(params), [0.1], c) for c in range(n_channels))
    return AnalyticMaterial(FIT_NAME, combination, n_channels, lobes)
