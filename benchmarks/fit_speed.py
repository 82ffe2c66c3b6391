"""A two-lobe fit of a full MERL table against what issue 35 goal 1 measures it by.

    python benchmarks/fit_speed.py [--slices a,b,...] [--json docs/bench/fit_speed.json]

Per slice (a real 90 × 90 × 180 `.binary` written from the shared slice) and per pair of
lobes (Lambertian + GGX, Lambertian + Beckmann Cook–Torrance), in one run:

- the lab's fit with the defaults, reading the file included (best of two);
- one plain NumPy evaluation of a Cook–Torrance lobe over as many direction pairs as the fit
  has samples (written here from its formula, not the lab's code; best of three);
- scipy's `least_squares` (trust-region reflective, bounds, its default tolerances) from the
  same start on the same samples (`tests/scipy_minimum.py`: every parameter and scaling
  factor at once, exact columns for the scales, central differences for the shape).

Both fits' errors are summed directly over every sample by `scipy_minimum.Residuals`. Goal:
the lab ≤ 1 s, ≤ 6 × the evaluation, ≥ 10 × faster than scipy at equal or lower error.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from scipy_minimum import Residuals

from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
from brdflab.fitting.samples import samples_of
from brdflab.sources.measured import read_merl_binary, read_slice, write_merl_binary

DATA = Path(os.environ.get("BRDFLAB_SHARED", ROOT.parent / "shared")) / "data"
PAIRS = (["Lambertian", "CookTorranceGGX"], ["Lambertian", "CookTorrance"])


def plain_cook_torrance(wi: np.ndarray, wo: np.ndarray, m: float, f0: float) -> np.ndarray:
    """Beckmann D · V-cavity G · Schlick F / (4 cos θi cos θo), straight from the formula."""
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    ci, co, ch = wi[:, 2], wo[:, 2], h[:, 2]
    oh = np.einsum("ij,ij->i", wo, h)
    tan2 = (1.0 - ch * ch) / (ch * ch)
    d = np.exp(-tan2 / (m * m)) / (np.pi * m * m * ch ** 4)
    g = np.minimum(1.0, np.minimum(2.0 * ch * co / oh, 2.0 * ch * ci / oh))
    f = f0 + (1.0 - f0) * (1.0 - oh) ** 5
    return d * g * f / (4.0 * ci * co)


def best_of(n: int, run) -> tuple[float, object]:
    times, out = [], None
    for _ in range(n):
        t0 = time.perf_counter()
        out = run()
        times.append(time.perf_counter() - t0)
    return min(times), out


def one(name: str, lobes: list[str], path: Path) -> dict:
    def lab():
        samples = samples_of(read_merl_binary(path))
        return samples, fit(material_from_lobes(lobes, "Linear", 3), samples, FitOptions())

    lab_s, (samples, result) = best_of(2, lab)
    wi, wo, y, measure = (np.concatenate(x) for x in zip(*samples.chunks()))
    evaluation_s, _ = best_of(3, lambda: plain_cook_torrance(wi, wo, 0.2, 0.05))
    residuals = Residuals(lobes, wi, wo, y, measure)
    start = material_from_lobes(lobes, "Linear", 3)
    t0 = time.perf_counter()
    found = least_squares(residuals, residuals.vector(start), jac=residuals.jacobian, bounds=residuals.bounds(),
                          x_scale="jac")
    scipy_s = time.perf_counter() - t0
    lab_error = residuals.error(residuals.vector(result.material))
    row = {"slice": name, "lobes": "+".join(lobes), "samples": samples.size, "lab_s": lab_s,
           "lab_iterations": result.iterations, "lab_error": lab_error, "lab_reported_error": result.error,
           "evaluation_s": evaluation_s, "scipy_s": scipy_s, "scipy_evaluations": int(found.nfev),
           "scipy_error": residuals.error(found.x), "lab_per_evaluation": lab_s / evaluation_s,
           "scipy_per_lab": scipy_s / lab_s}
    print(f"{name:<14} {row['lobes']:<26} lab {lab_s:5.2f} s ({row['lab_per_evaluation']:4.1f} × an evaluation of "
          f"{evaluation_s:.3f} s), error {lab_error:.6g}; scipy {scipy_s:6.1f} s = {row['scipy_per_lab']:5.1f} × the "
          f"lab, error {row['scipy_error']:.6g}", flush=True)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slices", default="nickel,white-paint,blue-fabric")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.slices.split(","):
            path = Path(tmp) / f"{name}.binary"
            write_merl_binary(read_slice(DATA / "merl_slices" / f"{name}.slice").to_full(), path)
            rows += [one(name, lobes, path) for lobes in PAIRS]
    if args.json:
        args.json.write_text(json.dumps({"command": " ".join(sys.argv), "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
