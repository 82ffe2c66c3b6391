"""What a model from a file costs: Disney's principled BRDF from BRDF Explorer's disney.brdf
(GLSL, evaluated through the headless OpenGL context) against built-in lobes (NumPy).

    python benchmarks/file_models.py [--slices red-specular-plastic,nickel] [--out docs/file-models.json]

Per slice, a 5,000-sample Levenberg–Marquardt fit (the lab's defaults, Ngan metric; its time excludes scoring the result
on every sample and the energy check afterwards) of:
one disney.brdf lobe; one built-in CookTorranceGGX lobe; Lambertian + CookTorranceGGX;
Lambertian + Kurt (the built-in with most parameters). Time per LM evaluation is the fit's
CPU-independent wall seconds over its evaluations (each evaluation computes the lobes at the
search point and at every finite-difference step). Also the raw throughput of one lobe
evaluation on 5,000 pairs. The fit's error is scored on every sample of the slice, and
again on BRDFLab's 16 × 16 × 64 grid (`fitting.metrics.grid_error`, an independent route).
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from brdflab.fitting.lm import FitOptions, fit
from brdflab.fitting.metrics import grid_error
from brdflab.fitting.samples import samples_of
from brdflab.fitting.stored import material_from_lobes
from brdflab.io.resources import shared_data_dir
from brdflab.models import get_model
from brdflab.models.files.library import load_model_file, probe_pairs
from brdflab.sources.files import load_source

FAMILIES = {
    "disney.brdf": ["disney"],
    "CookTorranceGGX": ["CookTorranceGGX"],
    "Lambertian + CookTorranceGGX": ["Lambertian", "CookTorranceGGX"],
    "Lambertian + Kurt": ["Lambertian", "Kurt"],
}


def throughput(name: str, n: int = 5000, repeat: int = 20) -> float:
    """Seconds of one evaluation of the lobe at n pairs (best of `repeat`)."""
    model = get_model(name)
    wi, wo = probe_pairs(n, seed=3)
    model.evaluate(wi, wo)
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        model.evaluate(wi, wo)
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slices", default="red-specular-plastic,nickel")
    ap.add_argument("--out", help="write the numbers here (JSON)")
    args = ap.parse_args()
    shared = shared_data_dir()
    load_model_file(shared / "models" / "brdf_explorer" / "disney.brdf")
    rows = []
    for slice_name in args.slices.split(","):
        source = load_source(shared / "merl_slices" / f"{slice_name}.slice")
        samples = samples_of(source, "subset", size=5000)
        everything = samples_of(source)
        for family, lobes in FAMILIES.items():
            start = material_from_lobes(lobes, "Linear", source.n_channels)
            t0 = time.perf_counter()
            result = fit(start, samples, FitOptions(diagnose=False))
            wall = time.perf_counter() - t0
            from brdflab.fitting.metrics import metric_error

            result.error = metric_error(result.material, everything, "Ngan")
            rows.append({"slice": slice_name, "family": family, "error": result.error,
                         "grid_error": grid_error(source, result.material, "Ngan"), "seconds": result.seconds,
                         "wall": wall, "evaluations": result.evaluations,
                         "ms_per_evaluation": 1e3 * result.seconds / max(result.evaluations, 1),
                         "parameters": sum(len(get_model(m).parameters) for m in lobes)})
            # an evaluation computes every lobe once and once more per finite-difference step
            rows[-1]["lobe_evaluations"] = len(lobes) + rows[-1]["parameters"]
            rows[-1]["ms_per_lobe_evaluation"] = rows[-1]["ms_per_evaluation"] / rows[-1]["lobe_evaluations"]
            r = rows[-1]
            print(f"{slice_name:<22}{family:<30} error {r['error']:.5f} (grid {r['grid_error']:.5f})  "
                  f"{r['seconds']:6.2f} s  {r['evaluations']:4d} evaluations  {r['ms_per_evaluation']:7.2f} ms each, "
                  f"{r['ms_per_lobe_evaluation']:6.2f} ms per lobe evaluation")
    lobe = {name: throughput(name) for name in ("disney", "CookTorranceGGX", "Kurt")}
    for name, s in lobe.items():
        print(f"one {name} evaluation at 5,000 pairs: {1e3 * s:.3f} ms")
    if args.out:
        Path(args.out).write_text(json.dumps({"machine": platform.platform(), "fits": rows,
                                              "lobe_ms_5000_pairs": {k: 1e3 * v for k, v in lobe.items()}}, indent=2))


if __name__ == "__main__":
    main()
