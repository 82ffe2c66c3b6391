"""An independent minimum of a Linear fit: scipy.optimize.least_squares (trust-region
reflective, bounds) over every parameter and scaling factor at once, multi-start, on the
same samples and metric as the lab, without the lab's Gram matrices, variable projection
or search transforms. The Ngan weight is written here again from its definition
(cos²θi times the sample's measure, θi and θo ≤ 80°). Used by tests/test_fit_minimum.py
and benchmarks/fit_minimum.py to check that a fit does not stop short."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.models import get_model

NGAN_COS = math.cos(math.radians(80.0))


class Residuals:
    """√w (f − y) of a Linear material with lobes `names` on samples (wi, wo, y, measure)."""

    def __init__(self, names: list[str], wi: np.ndarray, wo: np.ndarray, y: np.ndarray, measure: np.ndarray) -> None:
        inside = (wi[:, 2] >= NGAN_COS) & (wo[:, 2] >= NGAN_COS)
        self.norm = float(measure[inside].sum()) * y.shape[1]
        self.wi, self.wo, self.y = wi[inside], wo[inside], y[inside]
        self.sw = np.sqrt(measure[inside] * self.wi[:, 2] ** 2)
        self.models = [get_model(n) for n in names]
        self.shape = [self._variables(m) for m in self.models]
        self.n_shape = sum(len(v) for v in self.shape)

    @staticmethod
    def _variables(model) -> list[tuple[str, float, float]]:
        """(name, low, high) of a model's shape variables here: a scale-invariant pair is one
        angle; a log parameter is searched as its logarithm."""
        out = [("angle", -math.pi, math.pi)] if model.scale_invariant else []
        for p in model.parameters:
            if p.name in model.scale_invariant or not p.fitted or p.upper <= p.lower:
                continue
            out.append((p.name, math.log(max(p.lower, 1e-6)), math.log(p.upper)) if p.log else (p.name, p.lower, p.upper))
        return out

    def params(self, x: np.ndarray) -> list[dict]:
        out, k = [], 0
        for model, variables in zip(self.models, self.shape):
            values = model.defaults()
            for name, _, _ in variables:
                if name == "angle":
                    a, b = model.scale_invariant
                    values[a], values[b] = math.cos(x[k]), math.sin(x[k])
                else:
                    values[name] = math.exp(x[k]) if model.parameter(name).log else float(x[k])
                k += 1
            out.append(values)
        return out

    def lobes(self, x: np.ndarray) -> np.ndarray:
        """(N, lobes) values of each lobe (one value per lobe: no colour lobes here)."""
        return np.stack([m.evaluate(self.wi, self.wo, p) for m, p in zip(self.models, self.params(x))], axis=1)

    def scales(self, x: np.ndarray) -> np.ndarray:
        return x[self.n_shape:].reshape(len(self.models), self.y.shape[1])

    def __call__(self, x: np.ndarray) -> np.ndarray:
        f = self.lobes(x) @ self.scales(x)
        return (self.sw[:, None] * (f - self.y)).ravel()

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """Central differences for the shape variables, exact columns for the scales."""
        E = self.lobes(x)
        C = self.y.shape[1]
        J = np.zeros((self.y.size, x.size))
        for k in range(self.n_shape):
            h = 1e-6 * max(1.0, abs(x[k]))
            up, down = x.copy(), x.copy()
            up[k] += h
            down[k] -= h
            J[:, k] = (self(up) - self(down)) / (2.0 * h)
        for l in range(len(self.models)):
            for c in range(C):
                J[c::C, self.n_shape + l * C + c] = self.sw * E[:, l]
        return J

    def error(self, x: np.ndarray) -> float:
        return math.sqrt(float((self(x) ** 2).sum()) / self.norm)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = [v[1] for vs in self.shape for v in vs] + [0.0] * (len(self.models) * self.y.shape[1])
        hi = [v[2] for vs in self.shape for v in vs] + [np.inf] * (len(self.models) * self.y.shape[1])
        return np.array(lo), np.array(hi)

    def vector(self, material: AnalyticMaterial) -> np.ndarray:
        """The variables of a Linear material with these lobes."""
        x = []
        for model, variables, lobe in zip(self.models, self.shape, material.lobes):
            for name, _, _ in variables:
                if name == "angle":
                    a, b = model.scale_invariant
                    x.append(math.atan2(lobe.params[b], lobe.params[a]))
                else:
                    v = lobe.params[name]
                    x.append(math.log(max(v, 1e-6)) if model.parameter(name).log else v)
        return np.clip(np.r_[x, [s for lobe in material.lobes for s in lobe.scale]], *self.bounds())

    def material(self, x: np.ndarray) -> AnalyticMaterial:
        scales = self.scales(x)
        return AnalyticMaterial("scipy", "Linear", self.y.shape[1], [
            Lobe.create(m.name, list(s), **p) for m, s, p in zip(self.models, scales, self.params(x))])


def scipy_minimum(names: list[str], samples, starts: list[AnalyticMaterial],
                  max_nfev: int = 200) -> tuple[float, AnalyticMaterial]:
    """The lowest Ngan error least_squares reaches from `starts` (materials with lobes
    `names`), and its material."""
    wi, wo, y, measure = (np.concatenate(x) for x in zip(*samples.chunks()))
    r = Residuals(names, wi, wo, y, measure)
    best = (math.inf, None)
    for start in starts:
        found = least_squares(r, r.vector(start), jac=r.jacobian, bounds=r.bounds(), x_scale="jac",
                              ftol=1e-12, xtol=1e-12, gtol=1e-12, max_nfev=max_nfev)
        error = r.error(found.x)
        if error < best[0]:
            best = (error, r.material(found.x))
    return best
