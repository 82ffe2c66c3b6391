"""Fitting speed and accuracy on real measured data.

    python benchmarks/fitting.py [--quick] [--json OUT]

1. Wall time (load included) of Linear fits on full MERL-size tables (90×90×180,
   written as real .binary files from the measured slices).
2. Lambertian + LafortuneIso fitted with the defaults (Ngan metric, restarts) on every
   slice that has a published fit (Ngan et al. 2005), against the published parameters on
   the same data, by the reported error and by BRDFLab's 16 × 16 × 64 grid.
3. For each model, the error our fit reaches against the best of a long multi-start search.
4. Peak memory while fitting a MERL table, relative to the table's float32 size.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

from brdflab.fitting.lm import FitOptions, fit, material_from_lobes, restart_guesses
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.sources.measured import read_merl_binary, read_slice, write_merl_binary
from brdflab.fitting.metrics import grid_error, metric_error
from brdflab.models import get_model
from brdflab.fitting.samples import samples_of

DATA = Path(os.environ.get("BRDFLAB_SHARED", Path(__file__).resolve().parents[2] / "shared")) / "data"
SLICES = DATA / "merl_slices"


def speed(materials: list[str], metric: str) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in materials:
            path = Path(tmp) / f"{name}.binary"
            write_merl_binary(read_slice(SLICES / f"{name}.slice").to_full(), path)
            for lobes in (["Lambertian", "LafortuneIso"], ["Lambertian", "CookTorrance"],
                          ["Lambertian", "CookTorrance", "CookTorrance"]):
                t0 = time.perf_counter()
                table = read_merl_binary(path)
                samples = samples_of(table)
                start = material_from_lobes(lobes, "Linear", 3)
                if lobes.count("CookTorrance") == 2:  # two distinct specular scales
                    start.lobes[1].params["m"], start.lobes[2].params["m"] = 0.05, 0.3
                r = fit(start, samples, FitOptions(metric=metric))
                wall = time.perf_counter() - t0
                rows.append({"material": name, "lobes": "+".join(lobes), "metric": metric, "samples": samples.size,
                             "wall_s": wall, "fit_s": r.seconds, "iterations": r.iterations, "error": r.error,
                             "status": r.status})
                print(f"  {name:<22} {'+'.join(lobes):<38} {samples.size:>8} samples  {wall:6.2f} s  "
                      f"{r.iterations:3d} it  {metric} {r.error:.5g}", flush=True)
    return rows


def published(quick: bool) -> list[dict]:
    """Default fits (only --lobes) against the published parameters, by the reported error
    and by BRDFLab's 16 × 16 × 64 grid (grid_error, an independent route)."""
    table_rows = list(csv.DictReader(open(DATA / "tables" / "ngan2005_lafortune_fits.csv")))
    if quick:
        table_rows = table_rows[::5]
    out = []
    for row in table_rows:
        table = read_slice(SLICES / f"{row['material']}.slice")
        samples = samples_of(table)
        kd = np.array([float(row[k]) for k in ("kd_r", "kd_g", "kd_b")])
        pub = AnalyticMaterial("published", "Linear", 3, [
            Lobe.create("Lambertian", list(kd / np.pi)),
            Lobe.create("LafortuneIso", [float(row[k]) for k in ("ks_r", "ks_g", "ks_b")],
                        Cxy=float(row["Cxy"]), Cz=float(row["Cz"]), Exponent=float(row["n"]))])
        e_pub = metric_error(pub, samples, "Ngan")
        r = fit(material_from_lobes(["Lambertian", "LafortuneIso"], "Linear", 3), samples, FitOptions())
        g_pub, g_fit = grid_error(table, pub), grid_error(table, r.material)
        out.append({"material": row["material"], "published": e_pub, "fitted": r.error, "seconds": r.seconds,
                    "better": r.error < e_pub, "grid_published": g_pub, "grid_fitted": g_fit,
                    "status": r.status, "warnings": r.warnings})
        print(f"  {row['material']:<26} published {e_pub:.5f}   fitted {r.error:.5f}   "
              f"{'better' if r.error < e_pub else 'WORSE'}  ({r.seconds:.1f} s)  "
              f"grid published {g_pub:.5f} fitted {g_fit:.5f}", flush=True)
    return out


def multistart(materials: list[str], models: list[str], starts: int) -> list[dict]:
    """Our fit (with its model-aware restarts) against the best of many random starts."""
    rng = np.random.default_rng(11)
    out = []
    for name in materials:
        samples = samples_of(read_slice(SLICES / f"{name}.slice"))
        for model_name in models:
            model = get_model(model_name)
            base = material_from_lobes(["Lambertian", model_name], "Linear", 3)
            ours = fit(base, samples, FitOptions(metric="Ngan", restarts=True)).error
            best = np.inf
            for _ in range(starts):
                start = base.copy()
                for p in model.parameters:
                    lo, hi = p.lower, p.upper
                    v = np.exp(rng.uniform(np.log(max(lo, 1e-3)), np.log(hi))) if p.log else rng.uniform(lo, hi)
                    start.lobes[1].params[p.name] = float(v)
                r = fit(start, samples, FitOptions(metric="Ngan", coarse_size=0))
                best = min(best, r.error)
            gap = ours / best - 1.0
            out.append({"material": name, "model": model_name, "ours": ours, "multistart_best": best, "gap": gap})
            print(f"  {name:<22} {model_name:<24} ours {ours:.5g}  best of {starts} starts {best:.5g}  "
                  f"gap {100 * gap:+.2f} %", flush=True)
    return out


def memory(name: str) -> dict:
    table = read_slice(SLICES / f"{name}.slice").to_full()
    samples = samples_of(table)
    tracemalloc.start()
    fit(material_from_lobes(["Lambertian", "LafortuneIso"], "Linear", 3), samples, FitOptions(metric="Ngan"))
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    ratio = peak / (table.values.size * 4)
    print(f"  peak {peak / 2**20:.1f} MiB while fitting = {ratio:.2f} × the table's float32 size")
    return {"material": name, "peak_bytes": peak, "ratio_to_table": ratio}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json")
    ap.add_argument("--only-published", action="store_true", help="section 2 alone")
    ap.add_argument("--only-speed", action="store_true", help="section 1 alone, replacing it in an existing --json")
    args = ap.parse_args()
    if args.only_speed:
        mats = ["nickel", "white-paint", "blue-fabric"] if not args.quick else ["nickel"]
        print("1. MERL-size tables, load + fit wall time")
        speeds = speed(mats, "Ngan") + speed(mats, "L2")
        if args.json:
            path = Path(args.json)
            result = json.loads(path.read_text()) if path.is_file() else {}
            path.write_text(json.dumps({**result, "speed": speeds}, indent=2))
        return
    if args.only_published:
        print("2. default fits against published Lafortune fits (Ngan et al. 2005)")
        result = {"published": published(args.quick)}
        if args.json:
            Path(args.json).write_text(json.dumps(result, indent=2))
        return
    mats = ["nickel", "white-paint", "blue-fabric"] if not args.quick else ["nickel"]
    print("1. MERL-size tables, load + fit wall time")
    result = {"speed": speed(mats, "Ngan") + speed(mats, "L2")}
    print("2. Ngan metric against published Lafortune fits (Ngan et al. 2005)")
    result["published"] = published(args.quick)
    print("3. our fit against the best of a multi-start search")
    models = ["BlinnPhong", "Phong", "LafortuneIso", "Ward", "WardDuer", "AshikhminShirley", "CookTorrance",
              "CookTorranceGGX", "Kurt", "Schwenk", "OrenNayar"]
    result["multistart"] = multistart(["nickel", "white-paint"][: 1 if args.quick else 2],
                                      models[:3] if args.quick else models, 8 if args.quick else 30)
    print("4. memory")
    result["memory"] = memory("nickel")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
