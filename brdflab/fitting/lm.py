"""Levenberg–Marquardt fitting of analytic lobes to any source (BRDFLab §4).

Strategies (BRDFLab): **Linear** — the lobes' own parameters are nonlinear, the
per-channel scaling factors are solved by non-negative least squares inside every
evaluation (variable projection); **Fixed** — every parameter of every per-channel
lobe, magnitude included, is nonlinear.

One pass over the samples (chunked, threaded) evaluates each lobe at the current
parameters and at every finite-difference perturbation, and accumulates per-channel
Gram matrices of these lobe values. Because every residual is linear in the lobe
values, the cost, JᵀJ and Jᵀr of all perturbations follow exactly from those small
matrices: no Jacobian and no per-sample array is ever stored, so memory stays a small
multiple of one chunk, and a MERL table is fitted in place.
"""

from __future__ import annotations

import math
import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.optimize import nnls

from brdflab.errors import BRDFLabError
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.models import get_model
from brdflab.fitting.metrics import sample_weight
from brdflab.fitting.samples import SampleSet

METRICS = {
    "L2": "root-mean-square difference of BRDF values (1/sr)",
    "cosL2": "root-mean-square difference of BRDF values times cos θi",
    "Ngan": "Ngan et al. 2005: solid-angle weighted RMS of (f − f') cos θi, θi and θo below 80°",
}
COMPRESSIONS = ("none", "cbrt", "log")
FD_STEP = 1e-4


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
        v = a + (b - a) / (1.0 + math.exp(-max(-40.0, min(40.0, u))))
        return min(self.hi, max(self.lo, self.lo + math.exp(v) - c if self.log else v))

    def to_u(self, x: float) -> float:
        a, b, c = self._span()
        x = min(self.hi, max(self.lo, x))
        v = math.log(x - self.lo + c) if self.log else x
        t = min(1.0 - 1e-12, max(1e-12, (v - a) / (b - a)))
        return math.log(t / (1.0 - t))


@dataclass(frozen=True)
class Positive:
    """A magnitude ≥ 0 (Fixed strategy): x = exp(u)."""

    def to_x(self, u: float) -> float:
        return math.exp(max(-60.0, min(60.0, u)))

    def to_u(self, x: float) -> float:
        return math.log(max(x, 1e-14))


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
    transform: Bounded | Positive | None = None
    norm: float = 1.0

    @property
    def size(self) -> int:
        return len(self.names) - 1 if self.kind == "direction" else 1

    def to_u(self, lobe: Lobe) -> list[float]:
        if self.kind == "magnitude":
            return [self.transform.to_u(lobe.scale[0])]
        if self.kind == "scalar":
            return [self.transform.to_u(lobe.params[self.names[0]])]
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


def free_blocks(material: AnalyticMaterial) -> list[FreeBlock]:
    """Every search variable of a material's fit, in lobe order."""
    blocks = []
    for l, lobe in enumerate(material.lobes):
        group = lobe.model.scale_invariant
        if group:
            c = np.array([lobe.params[n] for n in group])
            bound = min(min(abs(lobe.model.parameter(n).lower), lobe.model.parameter(n).upper) for n in group)
            norm = float(np.linalg.norm(c)) or 1.0
            blocks.append(FreeBlock(l, tuple(group), "direction", norm=min(norm, bound)))
        for p in lobe.model.parameters:
            if p.name not in group:
                blocks.append(FreeBlock(l, (p.name,), "scalar", Bounded(p.lower, p.upper, p.log)))
        if material.combination == "Fixed":
            blocks.append(FreeBlock(l, (), "magnitude", Positive()))
    return blocks


# --- options, progress, result -----------------------------------------------------------

@dataclass
class FitOptions:
    metric: str = "L2"
    compression: str = "none"
    max_iterations: int = 200
    time_limit: float = math.inf  # seconds
    restarts: bool = False
    coarse_size: int = 60_000  # fit a stratified subset this large first (0: never)
    ftol: float = 1e-6  # stop after two accepted steps that gain less than this fraction
    workers: int = 1  # threads for the sample passes (0: one per core; NumPy holds the GIL too often for more to pay)

    def validate(self) -> None:
        if self.metric not in METRICS:
            raise BRDFLabError(f"unknown metric {self.metric!r} (known: {', '.join(METRICS)})")
        if self.compression not in COMPRESSIONS:
            raise BRDFLabError(f"unknown compression {self.compression!r} (known: {', '.join(COMPRESSIONS)})")
        if self.max_iterations < 1:
            raise BRDFLabError("max_iterations must be at least 1")


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
    status: str  # converged | max-iterations | time-limit | cancelled | stalled
    message: str = ""
    history: list[float] = field(default_factory=list)

    def statistics(self) -> dict:
        return {"metric": self.metric, "seconds": round(self.seconds, 4), "iterations": self.iterations,
                "evaluations": self.evaluations, "status": self.status}

    def as_dict(self) -> dict:
        return {"error": self.error, **self.statistics(), "message": self.message,
                "parameters": self.material.describe()["lobes"]}


class FitCancelled(Exception):
    pass


# --- the problem ---------------------------------------------------------------------------

class _Problem:
    """Lobes, free parameters and a sample set; computes cost and normal equations."""

    def __init__(self, material: AnalyticMaterial, samples: SampleSet, options: FitOptions) -> None:
        if samples.n_channels != material.n_channels:
            raise BRDFLabError(
                f"the source has {samples.n_channels} channels, the material {material.n_channels}")
        if not material.lobes:
            raise BRDFLabError("a fit needs at least one lobe")
        self.material = material
        self.samples = samples
        self.options = options
        self.linear = material.combination == "Linear"
        self.blocks = free_blocks(material)
        # for each search variable: its block and whether it changes the lobe's shape
        self.owner = [b for b in self.blocks for _ in range(b.size)]
        self.shape_vars = [k for k, b in enumerate(self.owner) if b.kind != "magnitude"]
        self.passes = 0
        workers = options.workers or os.cpu_count() or 1
        self._pool = ThreadPoolExecutor(max_workers=workers) if workers > 1 else None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False)

    # vector <-> material
    def initial_u(self) -> np.ndarray:
        return np.array([v for b in self.blocks for v in b.to_u(self.material.lobes[b.lobe])], float)

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
    def _rows(self, u: np.ndarray, with_jacobian: bool) -> tuple[list[tuple[int, dict]], list[np.ndarray]]:
        """Lobe evaluations needed: every lobe at u, and (Jacobian) every lobe whose model
        parameter k is perturbed. Returns (lobe, params) per row and the search vectors."""
        base_params, _ = self.params_of(u)
        rows = [(l, base_params[l]) for l in range(len(self.material.lobes))]
        perturbed = []
        if with_jacobian:
            for k, block in enumerate(self.owner):
                up = u.copy()
                up[k] += FD_STEP
                perturbed.append(up)
                if block.kind != "magnitude":
                    p, _ = self.params_of(up)
                    rows.append((block.lobe, p[block.lobe]))
        return rows, perturbed

    def _chunk_grams(self, rows, chunk):
        wi, wo, y, w = chunk
        cos_i = wi[:, 2]
        weight = self._metric_weight(wi, wo, w)
        E = np.empty((len(rows), wi.shape[0]))
        for r, (l, p) in enumerate(rows):
            E[r] = self.material.lobes[l].model.evaluate(wi, wo, p)
        C = y.shape[1]
        R = len(rows)
        G = np.empty((C, R, R))
        b = np.empty((C, R))
        yy = np.empty(C)
        plain = np.empty((C, len(self.material.lobes), len(self.material.lobes))) if self.options.compression != "none" else None
        plain_b = np.empty((C, len(self.material.lobes))) if plain is not None else None
        plain_yy = np.empty(C) if plain is not None else None
        for c in range(C):
            wc = weight * self._compression_weight(y[:, c])
            Ew = E * wc
            G[c] = Ew @ E.T
            b[c] = Ew @ y[:, c]
            yy[c] = wc @ (y[:, c] ** 2)
            if plain is not None:
                L = plain.shape[1]
                Eb = E[:L] * weight
                plain[c] = Eb @ E[:L].T
                plain_b[c] = Eb @ y[:, c]
                plain_yy[c] = weight @ (y[:, c] ** 2)
        norm = float(self._metric_weight(wi, wo, w, cosine=False).sum())
        return G, b, yy, plain, plain_b, plain_yy, norm

    def _metric_weight(self, wi, wo, w, cosine: bool = True) -> np.ndarray:
        return sample_weight(self.options.metric, wi, wo, w, cosine)

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

    def accumulate(self, rows):
        """Sum the per-chunk Gram matrices over the whole sample set."""
        self.passes += 1
        work = lambda ch: self._chunk_grams(rows, ch)
        parts = self._pool.map(work, self.samples.chunks()) if self._pool else map(work, self.samples.chunks())
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
        """A[c, k, r]: channel c's coefficient of row r for perturbation k (0 = base)."""
        C, R = b.shape
        L = len(self.material.lobes)
        K = 1 + len(perturbed)
        A = np.zeros((C, K, R))
        extra_row = {k: L + j for j, k in enumerate(self.shape_vars)} if perturbed else {}
        for k in range(K):
            rows = list(range(L))
            block = None if k == 0 else self.owner[k - 1]
            if block is not None and block.kind != "magnitude":
                rows[block.lobe] = extra_row[k - 1]
            if self.linear:
                for c in range(C):
                    A[c, k, rows] = _nnls(G[c][np.ix_(rows, rows)], b[c][rows])
            else:
                _, mags = self.params_of(u if k == 0 else perturbed[k - 1])
                for l, lobe in enumerate(self.material.lobes):
                    A[lobe.channel, k, rows[l]] = mags[l]
        return A

    def evaluate(self, u: np.ndarray, with_jacobian: bool = True):
        """Cost (sum of weighted squared residuals), JᵀJ, Jᵀr, named-metric error, scales."""
        rows, perturbed = self._rows(u, with_jacobian)
        G, b, yy, plain, plain_b, plain_yy, norm = self.accumulate(rows)
        A = self._coefficients(G, b, u, perturbed)
        # inner products of the residual vectors of all perturbations, summed over channels
        M = np.einsum("ckr,crs,cls->kl", A, G, A)
        Ab = np.einsum("ckr,cr->ck", A, b)
        inner = M - Ab.sum(0)[:, None] - Ab.sum(0)[None, :] + yy.sum()
        cost = float(inner[0, 0])
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
        d = inner[1:, 1:] - inner[1:, :1] - inner[:1, 1:] + cost
        jtr = (inner[1:, 0] - cost) / FD_STEP
        return cost, _psd(d / (FD_STEP * FD_STEP)), jtr, error, scales


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
    s, _ = nnls(R, z, maxiter=50 * n)
    return s


# --- Levenberg–Marquardt ----------------------------------------------------------------------

ProgressCallback = Callable[[FitProgress], None]


def _lm(problem: _Problem, u: np.ndarray, options: FitOptions, max_iterations: int, ftol: float,
        stage: str, deadline: float, cancel: threading.Event | None,
        progress: ProgressCallback | None, history: list[float], lam: float = 1e-3):
    """Minimise problem's cost from u.

    Returns (u_best, state_best, iterations, status, final damping λ)."""
    if u.size == 0:  # nothing nonlinear: the scaling factors alone are solved
        state = problem.evaluate(u, with_jacobian=False)
        return u, state, 0, "converged", lam
    state = problem.evaluate(u)
    cost, jtj, jtr, error, scales = state
    if not math.isfinite(cost):
        raise BRDFLabError("the initial parameters give a non-finite error")
    best = (cost, u.copy(), state)
    diag_floor = 1e-9 * max(float(np.max(np.diag(jtj))), 1e-300)
    small = 0
    cautious = False  # after a rejection, try steps on the cost alone (a cheaper pass)
    status = "max-iterations"
    it = 0
    for it in range(1, max_iterations + 1):
        if cancel is not None and cancel.is_set():
            status = "cancelled"
            break
        if time.perf_counter() > deadline:
            status = "time-limit"
            break
        D = np.maximum(np.diag(jtj), diag_floor)
        # converged when even the undamped (Gauss–Newton) model promises almost nothing
        gn = _solve(jtj + 1e-12 * np.diag(D), -jtr)
        if gn is not None and -float(jtr @ gn) < ftol * cost:
            status = "converged"
            break
        step = _solve(jtj + lam * np.diag(D), -jtr)
        if step is None:
            lam *= 4.0
            continue
        trial_u = u + step
        trial = problem.evaluate(trial_u, with_jacobian=not cautious)
        predicted = -float(step @ jtr) - 0.5 * float(step @ (jtj @ step))
        if math.isfinite(trial[0]) and trial[0] < cost:
            rho = (cost - trial[0]) / max(predicted, 1e-300)
            small = small + 1 if cost - trial[0] < ftol * cost else 0
            if cautious:
                trial = problem.evaluate(trial_u)
                cautious = False
            u, state = trial_u, trial
            cost, jtj, jtr, error, scales = state
            best = (cost, u.copy(), state)
            lam = lam / 5.0 if rho > 0.75 else (lam * 2.0 if rho < 0.25 else lam)
            lam = max(lam, 1e-12)
            history.append(error)
            if progress is not None:
                progress(FitProgress(stage, it, error, problem.material_of(u, scales)))
            if small >= 2:
                status = "converged"
                break
        else:
            if predicted < ftol * cost or small:
                # the local model promises less than the tolerance, or the last accepted
                # step already gained less and this one fails: nothing left to gain
                status = "converged"
                break
            lam *= 4.0
            cautious = True
            if lam > 1e12:
                status = "converged"  # no direction decreases the error any more
                break
    return best[1], best[2], it, status, lam


def fit(material: AnalyticMaterial, samples: SampleSet, options: FitOptions | None = None,
        progress: ProgressCallback | None = None, cancel: threading.Event | None = None) -> FitResult:
    """Fit `material`'s lobes to `samples`, starting from the material's parameters.

    Never returns NaN: on cancellation, a time limit or an iteration cap it stops and
    returns the best parameters seen, with `status` saying why.
    """
    options = options or FitOptions()
    options.validate()
    material.validate()
    t0 = time.perf_counter()
    deadline = t0 + options.time_limit
    history: list[float] = []
    iterations = 0
    passes = 0

    coarse = None
    if options.coarse_size and samples.size > 2 * options.coarse_size:
        coarse = samples.subset(options.coarse_size)

    start_materials = [material]
    if options.restarts:
        start_materials += restart_guesses(material)

    # stage 1: every start on the coarse set (or the full set when it is small)
    stage_samples = coarse or samples
    candidates = []
    for start in start_materials:
        problem = _Problem(start, stage_samples, options)
        try:
            u, state, its, status, lam = _lm(problem, problem.initial_u(), options,
                                             options.max_iterations if start is material else 40,
                                             max(1e-5, options.ftol) if coarse is not None else options.ftol,
                                             "coarse" if coarse is not None else "fit", deadline, cancel,
                                             progress, history)
        finally:
            problem.close()
        iterations += its
        passes += problem.passes
        candidates.append((state[0], problem.material_of(u, state[4]), status, lam))
        if status in ("cancelled", "time-limit"):
            break
    cost, best_material, status, lam = min(candidates, key=lambda c: c[0])

    # stage 2: polish the best on every sample
    problem = _Problem(best_material, samples, options)
    try:
        if coarse is not None and status not in ("cancelled", "time-limit"):
            u, state, its, status, _ = _lm(problem, problem.initial_u(), options, options.max_iterations,
                                           options.ftol, "fit", deadline, cancel, progress, history, lam)
            iterations += its
        else:
            u = problem.initial_u()
            state = problem.evaluate(u, with_jacobian=False)
        result_material = problem.material_of(u, state[4])
        error = state[3]
    finally:
        problem.close()
    passes += problem.passes
    if not math.isfinite(error):
        raise BRDFLabError("the fit produced a non-finite error")
    messages = {
        "converged": "converged",
        "max-iterations": f"stopped after {options.max_iterations} iterations",
        "time-limit": f"stopped at the time limit of {options.time_limit:g} s",
        "cancelled": "cancelled; the best parameters so far are kept",
    }
    return FitResult(result_material, error, options.metric, time.perf_counter() - t0, iterations,
                     passes, status, messages.get(status, status), history)


def restart_guesses(material: AnalyticMaterial) -> list[AnalyticMaterial]:
    """Model-aware starting points: the i-th guess gives every lobe its model's i-th start."""
    count = max(len(l.model.starts) for l in material.lobes)
    out = []
    for i in range(count):
        m = material.copy()
        for lobe in m.lobes:
            start = lobe.model.starts[i % len(lobe.model.starts)]
            lobe.params.update(start)
        out.append(m)
    return out


def material_from_lobes(names: list[str], combination: str, n_channels: int) -> AnalyticMaterial:
    """A starting material for `brdflab fit --lobes A,B,...`: model defaults, unit scales;
    in Fixed combinations each named lobe is repeated for every channel."""
    if combination not in ("Linear", "Fixed"):
        raise BRDFLabError(f"combination must be linear or fixed, not {combination!r}")
    lobes: list[Lobe] = []
    for name in names:
        model = get_model(name)
        if combination == "Linear":
            lobes.append(Lobe(model, model.defaults(), [0.1] * n_channels))
        else:
            lobes.extend(Lobe(model, model.defaults(), [0.1], c) for c in range(n_channels))
    return AnalyticMaterial("fit", combination, n_channels, lobes)
