"""Measured MERL slices → Disney's principled BRDF, next to the lab's own few-lobe fits.

    python benchmarks/principled_fits.py [--quick] [--json docs/bench/principled_fits.json]

For every shared MERL slice, fitted with the defaults (Ngan metric, restarts, all samples):
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


def fit_family(table, samples, candidates: list[list[str]]) -> dict:
    best = None
    for lobes in candidates:
        r = fit(material_from_lobes(lobes, "Linear", 3), samples, FitOptions())
        if best is None or r.error < best[0].error:
            best = (r, lobes)
    r, lobes = best
    return {"lobes": "+".join(lobes), "error": r.error, "grid_error": grid_error(table, r.material),
            "seconds": r.seconds, "status": r.status, "material": r.material}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="every fifth slice")
    ap.add_argument("--json", default="docs/bench/principled_fits.json")
    args = ap.parse_args()
    out_dir = Path(args.json).with_suffix("")
    out_dir.mkdir(parents=True, exist_ok=True)
    names = sorted(p.stem for p in SLICES.glob("*.slice"))[:: 5 if args.quick else 1]
    rows = []
    for name in names:
        table = read_slice(SLICES / f"{name}.slice")
        samples = samples_of(table)
        row = {"material": name}
        for family, candidates in FAMILIES.items():
            result = fit_family(table, samples, candidates)
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
