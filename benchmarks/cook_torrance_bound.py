"""The lowest Ngan error any Lambertian + Cook–Torrance (Beckmann) lobe can reach on a slice,
by a route independent of the fitter: a bound, not a fit.

With Schlick's Fresnel, ks F = ks F0 + ks (1 − F0)(1 − c)^5 = α + β (1 − c)^5 (c = ωo·h),
and α, β ≥ 0 exactly when ks ≥ 0 and F0 ∈ [0, 1] (ks = α + β, F0 = α / (α + β)). So for one
roughness m the lobe ks D_m G F / (4 cos θi cos θo) is a non-negative combination of two
functions of the samples, D_m G / (4 cos θi cos θo) and the same times (1 − c)^5; with the
Lambertian's 1/π that is three non-negative linear coefficients per channel, and the best
error at that m a 3-variable non-negative least squares problem (Gram matrices, every active
set tried). Each channel then takes its own best m on a dense log grid over the lab's range,
refined by a bounded scalar search. This relaxes what the lab's Cook–Torrance shares between
channels (m, F0) and every start and stopping rule of LM: no Cook–Torrance fit, Linear or
Fixed, can end below it.

D, G and F are written here from Cook & Torrance 1982 (Schwenk 2011, eqs. 35 and 38), not
taken from brdflab.models. The measure and the metric's weights are the lab's definition of
the Ngan error (CONVENTIONS.md), read through `samples_of` and `sample_weight`.

    python benchmarks/cook_torrance_bound.py --out docs/bench/cook_torrance_bound.json [MATERIAL ...]
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

from brdflab.fitting.metrics import sample_weight
from brdflab.fitting.samples import samples_of
from brdflab.io.resources import shared_data_dir
from brdflab.sources.measured import read_slice

METALS = ("alum-bronze", "brass", "chrome-steel", "nickel", "ss440", "black-oxidized-steel", "hematite",
          "tungsten-carbide", "grease-covered-steel")
M_GRID = np.geomspace(1e-3, 1.0, 400)  # the lab's bounds of m


def geometry(slice_path: Path) -> dict:
    """Per sample inside the metric's domain: the weight, the data, and the m-independent
    factors of the lobe: G / (4 cos θi cos θo), the same times (1 − c)^5, tan² θh, cos⁴ θh."""
    parts = []
    samples = samples_of(read_slice(slice_path))
    norm = 0.0
    for wi, wo, y, measure in samples.chunks():
        w = sample_weight("Ngan", wi, wo, measure)
        norm += float(sample_weight("Ngan", wi, wo, measure, cosine=False).sum())
        keep = w > 0
        wi, wo, y, w = wi[keep], wo[keep], y[keep], w[keep]
        h = wi + wo
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        ci, co, ch = wi[:, 2], wo[:, 2], h[:, 2]
        c = np.clip(np.einsum("ij,ij->i", wo, h), 0.0, 1.0)
        g = np.minimum(1.0, np.minimum(2 * ch * co / c, 2 * ch * ci / c))
        base = g / (4 * ci * co)
        grazing = (1 - c) ** 5
        parts.append((w, y, base, base * grazing, (1 - ch ** 2) / ch ** 2, ch ** 4))
    w, y, flat, grazing, tan2, cos4 = (np.concatenate(x) for x in zip(*parts))
    return {"w": w, "y": y, "flat": flat, "grazing": grazing, "tan2": tan2, "cos4": cos4, "norm": norm,
            "channels": samples.n_channels}


def nnls_gram(gram: np.ndarray, rhs: np.ndarray, yy: float) -> float:
    """min over x ≥ 0 of x'Gx − 2 r'x + yy, by trying every active set (3 variables)."""
    best = yy
    n = len(rhs)
    for k in range(1, n + 1):
        for free in itertools.combinations(range(n), k):
            idx = list(free)
            try:
                x = np.linalg.solve(gram[np.ix_(idx, idx)], rhs[idx])
            except np.linalg.LinAlgError:
                continue
            if np.all(x >= 0):
                best = min(best, float(yy - rhs[idx] @ x))
    return max(best, 0.0)


def channel_sse(geo: dict, m: float, channel: int) -> float:
    """The least weighted squared error of Lambertian + Cook–Torrance(m) on one channel."""
    d = np.exp(-geo["tan2"] / (m * m)) / (math.pi * m * m * geo["cos4"])
    basis = np.stack([np.full_like(d, 1 / math.pi), d * geo["flat"], d * geo["grazing"]])
    wb = basis * geo["w"]
    gram = wb @ basis.T
    y = geo["y"][:, channel]
    return nnls_gram(gram, wb @ y, float(geo["w"] @ (y * y)))


def bound(geo: dict) -> dict:
    out = {"channels": []}
    total = 0.0
    for ch in range(geo["channels"]):
        grid = np.array([channel_sse(geo, m, ch) for m in M_GRID])
        k = int(np.argmin(grid))
        lo, hi = math.log(M_GRID[max(k - 1, 0)]), math.log(M_GRID[min(k + 1, len(M_GRID) - 1)])
        refined = minimize_scalar(lambda t: channel_sse(geo, math.exp(t), ch), bounds=(lo, hi), method="bounded",
                                  options={"xatol": 1e-4})
        sse, m = (refined.fun, math.exp(refined.x)) if refined.fun < grid[k] else (grid[k], M_GRID[k])
        out["channels"].append({"m": m, "sse": sse})
        total += sse
    out["error_bound"] = math.sqrt(total / (geo["norm"] * geo["channels"]))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("materials", nargs="*", default=list(METALS))
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    folder = shared_data_dir() / "merl_slices"
    rows = []
    for name in args.materials:
        t0 = time.perf_counter()
        result = bound(geometry(folder / f"{name}.slice"))
        rows.append({"material": name, **result, "seconds": time.perf_counter() - t0})
        print(f"{name:<22} lowest Ngan error of L + CookTorrance: {result['error_bound']:.5f}  "
              "(m per channel " + ", ".join(f"{c['m']:.4g}" for c in result["channels"]) + ")", flush=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps({"what": __doc__.splitlines()[0], "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
