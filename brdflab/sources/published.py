"""Published fits of MERL materials, evaluated as their authors' reference code evaluates them
(Dupuy's dj_brdf, `dj::sgd` and `dj::abc`): the state of the art the lab's fits are compared with.

- **SGD**, Bagher et al. 2012, the shifted gamma distribution, per channel:
  f = (ρd + ρs F D G / (cos θi cos θo)) / π, D = κ e^(−a) / (π a^p cos⁴θh) with
  a = α + tan²θh / α, F = F0 − cos θd · F1 + (1 − cos θd)⁵ (1 − F0),
  G = g1(ωi) g1(ωo), g1(ω) = clamp(1 + Λ (1 − e^(c · max(0, θ − θ0)^k)), 0, 1).
- **ABC**, Löw et al. 2012, the smooth-surface model: f = kd/π + F D G / (π cos θi cos θo),
  D = A / (1 + B (1 − cos θh))^C, F the unpolarised Fresnel of a dielectric of index η,
  G = min(1, 2 cos θh cos θi / (ωi·h), 2 cos θh cos θo / (ωo·h)).

The parameters are the tables dj_brdf publishes (one row per material; `read_published`).
They are sources, like measured data: they can be evaluated, rendered and scored, not edited.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdflab.errors import BRDFLabError

SGD_FIELDS = ("rhoD", "rhoS", "alpha", "p", "f0", "f1", "kap", "lambda", "c", "k", "theta0")
ABC_FIELDS = ("kD", "A")  # per channel; B, C and ior are one number each


def _half_vectors(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """h, cos θd = ωi·h (clamped to [0, 1], dj_brdf's `sat`) and the mask of pairs above the surface."""
    h = wi + wo
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
    return h, np.clip((wi * h).sum(-1), 0.0, 1.0), (wi[:, 2] > 0.0) & (wo[:, 2] > 0.0)


@dataclass
class SGDFit:
    """Bagher et al. 2012's fit of one material (each field: red, green, blue)."""

    name: str
    params: dict[str, np.ndarray]
    n_channels = 3
    isotropic = True
    kind = "Published fit (SGD, Bagher et al. 2012)"

    def _g1(self, cos_theta: np.ndarray) -> np.ndarray:
        p = self.params
        excess = np.maximum(0.0, np.arccos(np.clip(cos_theta, -1.0, 1.0))[:, None] - p["theta0"])
        with np.errstate(over="ignore", invalid="ignore"):
            g = 1.0 + p["lambda"] * (1.0 - np.exp(p["c"] * excess ** p["k"]))
        return np.clip(np.nan_to_num(g, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)

    def evaluate(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        p = self.params
        h, cos_d, up = _half_vectors(wi, wo)
        c2 = np.maximum(h[:, 2:3] ** 2, 1e-300)
        a = p["alpha"] + ((1.0 - c2) / c2) / p["alpha"]
        with np.errstate(over="ignore", under="ignore"):
            D = p["kap"] * np.exp(-a) / (math.pi * a ** p["p"] * c2 * c2)
        F = p["f0"] - cos_d[:, None] * p["f1"] + (1.0 - cos_d[:, None]) ** 5 * (1.0 - p["f0"])
        G = self._g1(wi[:, 2]) * self._g1(wo[:, 2])
        cos_io = np.maximum(wi[:, 2:3] * wo[:, 2:3], 1e-300)
        f = (p["rhoD"] + p["rhoS"] * F * D * G / cos_io) / math.pi
        return np.where(up[:, None], f, 0.0)


@dataclass
class ABCFit:
    """Löw et al. 2012's fit of one material."""

    name: str
    kd: np.ndarray  # (3,)
    A: np.ndarray  # (3,)
    B: float
    C: float
    ior: float
    n_channels = 3
    isotropic = True
    kind = "Published fit (ABC, Löw et al. 2012)"

    def evaluate(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        h, cos_d, up = _half_vectors(wi, wo)
        D = self.A / (1.0 + self.B * (1.0 - h[:, 2:3])) ** self.C
        F = unpolarized_fresnel(cos_d, self.ior)[:, None]
        hi, ho = np.maximum((wi * h).sum(-1), 1e-300), np.maximum((wo * h).sum(-1), 1e-300)
        G = np.minimum(1.0, np.minimum(2.0 * h[:, 2] * wi[:, 2] / hi, 2.0 * h[:, 2] * wo[:, 2] / ho))[:, None]
        cos_io = np.maximum(wi[:, 2:3] * wo[:, 2:3], 1e-300)
        f = self.kd / math.pi + F * D * G / (math.pi * cos_io)
        return np.where(up[:, None], f, 0.0)


def unpolarized_fresnel(cos_d: np.ndarray, ior: float) -> np.ndarray:
    """The Fresnel reflectance of unpolarised light on a dielectric of index `ior` (dj_brdf's form)."""
    c = cos_d
    g = np.sqrt(ior * ior + c * c - 1.0)
    a = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return 0.5 * ((g - c) / (g + c)) ** 2 * (1.0 + a * a)


def read_published(path: Path) -> dict[str, SGDFit | ABCFit]:
    """Every material's fit in a dj_brdf table (bagher2012_sgd_fits.csv or low2012_abc_fits.csv),
    by MERL name; the kind is told by the columns."""
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        raise BRDFLabError(f"cannot read: {e.strerror or e}", path) from None
    out: dict[str, SGDFit | ABCFit] = {}
    try:
        for row in rows:
            rgb = lambda key: np.array([float(row[f"{key}_{c}"]) for c in "rgb"])
            if "rhoD_r" in row:
                out[row["material"]] = SGDFit(row["material"], {k: rgb(k) for k in SGD_FIELDS})
            elif "kD_r" in row:
                out[row["material"]] = ABCFit(row["material"], rgb("kD"), rgb("A"), float(row["B"]), float(row["C"]),
                                              float(row["ior"]))
            else:
                raise BRDFLabError("neither SGD (rhoD_r, …) nor ABC (kD_r, …) columns", path)
    except (KeyError, ValueError) as e:
        raise BRDFLabError(f"a row that is not a published fit ({e})", path) from None
    return out
