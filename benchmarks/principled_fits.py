"""Measured MERL slices → Disney's principled BRDF, next to the lab's own few-lobe fits.

    python benchmarks/principled_fits.py [--quick] [--json docs/bench/principled_fits.json]

For every shared MERL slice, fitted with the defaults (Ngan metric, restarts) on a stratified
subset of 100,000 of its ~1.1 million samples and scored on all of them (`--subset 0`: all):
Principled alone; Lambertian + GGX (CookTorranceGGX); and the lab's best few-lobe fit, the
best of Lambertian + 2 GGX and Lambertian + 2 Beckmann Cook–Torrance. Each error is the
fitter's own and, independently, BRDFLab's 16 θi × 16 θo × 64 φo grid (`grid_error`: no
sample set, no Gram matrices). The fitted principled materials are written beside the JSON
(`principled_fits/NAME.xml`) for renders and exports.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
from brdflab.fitting.metrics import grid_error
from brdflab.fitting.samples import samples_of
from brdflab.io import xmlio
from brdflab.sources.measured import read_slice

DATA = Path(os.environ.get("BRDFLAB_SHARED", Path(__file__).resolve().parents[2] / "shared")) / "data"
SLICES = DATA / "merl_slices"
FAMILIES = {
    "principled": [["Principled"]],
    "lambertian_ggx": [["Lambertian", "CookTorranceGGX"]],
    "best_few_lobes": [["Lambertian", "CookTorranceGGX", "CookTorranceGGX"],
                       ["Lambertian", "CookTorrance", "CookTorrance"]],
}


def fit_family(table, samples, candidates: list[list[str]], subset: int) -> dict:
    fitted = samples.subset(subset) if subset and samples.size > subset else samples
    best = None
    for lobes in candidates:
        r = fit(material_from_lobes(lobes, "Linear", 3), fitted, FitOptions(), score_on=samples)
        if best is None or r.error < best[0].error:
            best = (r, lobes)
    r, lobes = best
    return {"lobes": "+".join(lobes), "fitted_samples": fitted.size, "error": r.error, "grid_error": grid_error(table, r.material),
            "seconds": r.seconds, "status": r.status, "material": r.material}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="every fifth slice")
    ap.add_argument("--only", help="these slices (comma-separated names), e.g. to share them among processes")
    ap.add_argument("--json", default="docs/bench/principled_fits.json")
    ap.add_argument("--subset", type=int, default=100_000,
                    help="fit a stratified subset this large (0: every sample); errors are over all samples")
    ap.add_argument("--families", default=",".join(FAMILIES),
                    help="refit only these; the others' rows are kept from --json")
    args = ap.parse_args()
    families = args.families.split(",")
    kept = {r["material"]: r for r in json.loads(Path(args.json).read_text())["rows"]} if Path(args.json).is_file() else {}
    out_dir = Path(args.json).with_suffix("")
    out_dir.mkdir(parents=True, exist_ok=True)
    names = sorted(p.stem for p in SLICES.glob("*.slice"))[:: 5 if args.quick else 1]
    if args.only:
        names = [n for n in names if n in args.only.split(",")]
    rows = []
    for name in names:
        table = read_slice(SLICES / f"{name}.slice")
        samples = samples_of(table)
        row = {"material": name, **{f: v for f, v in kept.get(name, {}).items() if f in FAMILIES and f not in families}}
        for family in families:
            candidates = FAMILIES[family]
            result = fit_family(table, samples, candidates, args.subset)
            material = result.pop("material")
            if family == "principled":
                material.name = f"{name} (principled fit)"
                xmlio.save(xmlio.BRDFDocument(material), out_dir / f"{name}.xml")
                result["parameters"] = dict(material.lobes[0].params)
            row[family] = result
        rows.append(row)
        print(f"{name:<28}" + "  ".join(f"{f} {row[f]['error']:.4f} ({row[f]['grid_error']:.4f})" for f in FAMILIES),
              flush=True)
        Path(args.json).write_text(json.dumps({"rows": rows}, indent=1))


if __name__ == "__main__":
    main()
