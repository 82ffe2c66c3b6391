"""Auto SH tables against an exhaustive sweep of the same ladder.

    python benchmarks/sh_table_auto.py [--orders 4,8] [--materials a,b,...] [--tolerance T] [--json OUT]
    python benchmarks/sh_table_auto.py --report [--json OUT]   # the docs' table from the JSON
    python benchmarks/sh_table_auto.py --reuse-sweep OLD.json   # new estimates, the same sweep

Per (material, order): a converged reference, c(v) at REFERENCE_VIEWS random views (uniform in
solid angle, θ ≤ 80°, seeded) integrated directly with 2^16 samples each (four independent
scramblings of 2^14, whose spread also gives the reference's own error); then every setting
of the ladder is built as the renderer builds it, timed (CPU seconds, one thread), and its
true error measured by `relative_rms` of its bilinear lookup against the reference. Auto's
pick (`choose_table`, timed) is a hit when its true error is within the tolerance; its build
time is compared with the cheapest setting that truly meets the tolerance. Every setting's
estimate (resolution and sampling parts) is recorded beside its true error. The JSON is
rewritten after every case.
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one thread: CPU times compare
    os.environ.setdefault(_name, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from brdflab.io.atomic import atomic_write  # noqa: E402
from brdflab.lighting.sh_table_auto import (DEFAULT_TOLERANCE, MAX_VIEW_THETA_DEG, ErrorEstimate,  # noqa: E402
                                            build_cost, choose_table, ladder, luminance, table_error)
from brdflab.lighting.sh_tables import STANDARD, sampling_proxy, table_for, view_integrals  # noqa: E402
from brdflab.material.analytic import AnalyticMaterial, Lobe  # noqa: E402
from brdflab.sources.measured import read_slice  # noqa: E402

DATA = Path(os.environ.get("BRDFLAB_SHARED", Path(__file__).resolve().parents[2] / "shared")) / "data"
REFERENCE_VIEWS = 160
REFERENCE_SEEDS = (9001, 9002, 9003, 9004)
REFERENCE_LOG2 = 14  # per scrambling: 2^16 samples per view in all


def materials() -> dict:
    """The benchmark's materials, from broad to sharp, and one measured slice."""
    def one(name, *lobes):
        return AnalyticMaterial(name, "Linear", 3, list(lobes))

    return {
        "lambertian": lambda: one("Lambertian", Lobe.create("Lambertian", [0.25] * 3)),
        "blinn-phong-10": lambda: one("Blinn-Phong n=10", Lobe.create("BlinnPhong", [0.5] * 3, Exponent=10.0)),
        "blinn-phong-100": lambda: one("Blinn-Phong n=100", Lobe.create("BlinnPhong", [0.5] * 3, Exponent=100.0)),
        "cook-torrance-0.2": lambda: one("Cook-Torrance m=0.2", Lobe.create("CookTorrance", [0.8] * 3, m=0.2, F0=0.5)),
        "ward-aniso": lambda: one("Ward ax=0.08 ay=0.3 + Lambertian", Lobe.create("Lambertian", [0.1] * 3),
                                  Lobe.create("Ward", [0.6] * 3, ax=0.08, ay=0.3)),
        "merl-gold-metallic-paint3": lambda: read_slice(DATA / "merl_slices" / "gold-metallic-paint3.slice"),
        "merl-chrome-steel": lambda: read_slice(DATA / "merl_slices" / "chrome-steel.slice"),
    }


def reference_views(n: int = REFERENCE_VIEWS, seed: int = 5) -> np.ndarray:
    """Random views uniform in solid angle over θ ≤ 80° (not the estimator's Fibonacci spots)."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(math.cos(math.radians(MAX_VIEW_THETA_DEG)), 1.0, n)
    phi = rng.uniform(0.0, 2 * math.pi, n)
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def reference(source, order: int, views: np.ndarray) -> tuple[np.ndarray, float]:
    """Converged integrals at views, and their own relative error (spread of the scramblings / 2)."""
    proxy = sampling_proxy(source)
    runs = np.stack([view_integrals(source, proxy, views, order, REFERENCE_LOG2, seed=s) for s in REFERENCE_SEEDS])
    mean = runs.mean(axis=0)
    lum = luminance(runs)
    spread = np.sum((lum - lum.mean(axis=0)) ** 2) / (len(runs) - 1) / len(runs)
    return mean, float(np.sqrt(spread / np.sum(luminance(mean) ** 2)))


def timed_build(source, order: int, setting) -> tuple[np.ndarray, float]:
    """The table and its build's CPU seconds: the least of repeated builds while they total
    under 0.3 s (millisecond builds are otherwise at the mercy of the shared machine)."""
    best, spent = math.inf, 0.0
    while True:
        t0 = time.process_time()
        table = table_for(source, order, setting)
        seconds = time.process_time() - t0
        best, spent = min(best, seconds), spent + seconds
        if spent > 0.3 or seconds > 0.1:
            return table, best


def case(name: str, source, order: int, tolerance: float, swept: dict | None = None) -> dict:
    """One (material, order); `swept`: an earlier run's row of the same case, whose reference,
    build times and true errors are taken as they are (they do not depend on the estimator)."""
    estimate = ErrorEstimate(source, order)
    if swept is None:
        views = reference_views()
        t0 = time.process_time()
        truth, noise = reference(source, order, views)
        row = {"reference_error": noise, "reference_seconds": time.process_time() - t0}
    else:
        row = {k: swept[k] for k in ("reference_error", "reference_seconds")}
        old = {(s["size"], s["samples_log2"]): s for s in swept["settings"]}
    row.update(material=name, order=order, isotropic=bool(source.isotropic), tolerance=tolerance, settings=[],
               sweep_reused=swept is not None)
    for setting in ladder(source):
        if swept is None:
            table, seconds = timed_build(source, order, setting)
            true_error = table_error(table, truth, views)
        else:
            seconds, true_error = (old[(setting.size, setting.samples_log2)][k] for k in ("build_seconds", "true_error"))
        res, mc = estimate.resolution(setting.size), estimate.sampling(setting.samples_log2)
        row["settings"].append({"size": setting.size, "samples_log2": setting.samples_log2,
                                "cost": build_cost(source, setting), "build_seconds": seconds,
                                "true_error": true_error, "estimated_error": math.hypot(res, mc),
                                "resolution_estimate": res, "sampling_estimate": mc})
    t0 = time.process_time()
    choice = choose_table(source, order, tolerance)
    row["auto_seconds"] = time.process_time() - t0
    by_label = {(s["size"], s["samples_log2"]): s for s in row["settings"]}
    pick = by_label[(choice.setting.size, choice.setting.samples_log2)]
    meeting = [s for s in row["settings"] if s["true_error"] <= tolerance]
    cheapest = min(meeting, key=lambda s: s["build_seconds"]) if meeting else None
    cheapest_cost = min(meeting, key=lambda s: s["cost"]) if meeting else None
    standard = STANDARD.of(source)
    brief = lambda s: None if s is None else {k: s[k] for k in ("size", "samples_log2", "build_seconds", "cost", "true_error")}
    row.update(auto=choice.as_dict(), pick_true_error=pick["true_error"], hit=pick["true_error"] <= tolerance,
               pick_build_seconds=pick["build_seconds"],
               cheapest_meeting=brief(cheapest), cheapest_meeting_by_cost=brief(cheapest_cost),
               time_ratio=None if cheapest is None else pick["build_seconds"] / max(cheapest["build_seconds"], 1e-9),
               cost_ratio=None if cheapest_cost is None else pick["cost"] / cheapest_cost["cost"],
               standard={"size": standard.size, "samples_log2": standard.samples_log2,
                         **{k: by_label[(standard.size, standard.samples_log2)][k] for k in ("true_error", "build_seconds")}})
    return row


def report(result: dict) -> str:
    """The Markdown table of docs/benchmarks.md, from the JSON alone."""
    pct = lambda x: f"{100 * x:.2f} %"
    label = lambda s: f"{s['size']}²×2^{s['samples_log2']}"
    lines = ["| material | L | Auto's pick | estimated | true error | hit | cheapest truly within (by time) | its error "
             "| build s: pick / cheapest | cost ratio | Auto's decision s | standard 128² table: error, build s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in result["cases"]:
        a, low = c["auto"], c["cheapest_meeting"]
        lines.append(f"| {c['material']} | {c['order']} | {label(a)} | {pct(a['estimated_error'])} | {pct(c['pick_true_error'])} "
                     f"| {'hit' if c['hit'] else '**miss**'} | {label(low) if low else '—'} | {pct(low['true_error']) if low else '—'} "
                     f"| {c['pick_build_seconds']:.3f} / {low['build_seconds']:.3f} | {c['cost_ratio']:.2f} "
                     f"| {c['auto_seconds']:.2f} | {pct(c['standard']['true_error'])}, {c['standard']['build_seconds']:.2f} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--orders", default="4,8")
    parser.add_argument("--materials", default=",".join(materials()))
    parser.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE)
    parser.add_argument("--json", default=str(Path(__file__).resolve().parents[1] / "docs" / "bench" / "sh_table_auto.json"))
    parser.add_argument("--report", action="store_true", help="print the Markdown table of an existing --json and stop")
    parser.add_argument("--reuse-sweep", metavar="JSON",
                        help="take the references, build times and true errors from an earlier run's JSON "
                             "(same ladder and tables); estimate and choose anew")
    args = parser.parse_args()
    swept = {} if not args.reuse_sweep else {(c["material"], c["order"]): c
                                             for c in json.loads(Path(args.reuse_sweep).read_text())["cases"]}
    if args.report:
        print(report(json.loads(Path(args.json).read_text())))
        return
    known = materials()
    result = {"tolerance": args.tolerance, "reference_views": REFERENCE_VIEWS,
              "reference_samples": len(REFERENCE_SEEDS) << REFERENCE_LOG2, "cases": []}
    for name in args.materials.split(","):
        source = known[name]()
        for order in (int(o) for o in args.orders.split(",")):
            row = case(name, source, order, args.tolerance, swept.get((name, order)))
            result["cases"].append(row)
            hits = [c["hit"] for c in result["cases"]]
            result["summary"] = {"cases": len(hits), "hits": sum(hits),
                                 "time_ratios": [c["time_ratio"] for c in result["cases"]],
                                 "cost_ratios": [c["cost_ratio"] for c in result["cases"]]}
            atomic_write(Path(args.json), json.dumps(result, indent=1).encode())
            print(f"{name} L={order}: auto {row['auto']['size']}x2^{row['auto']['samples_log2']} "
                  f"est {100 * row['auto']['estimated_error']:.2f} % true {100 * row['pick_true_error']:.2f} % "
                  f"{'hit' if row['hit'] else 'MISS'}; cheapest meeting {row['cheapest_meeting']}; "
                  f"ratio {row['time_ratio']}; reference noise {100 * row['reference_error']:.3f} %", flush=True)


if __name__ == "__main__":
    main()
