"""Principled against Lambertian + GGX: the time of a default fit of each on the same samples
(issue 35 goal 2: Principled ≤ 5× Lambertian + GGX).

    python benchmarks/principled_speed.py [--quick] [--json docs/bench/principled_speed.json]

Sources: full MERL-size tables (90 × 90 × 180, written as real .binary files from measured
slices: a metal, a paint, a fabric, a plastic) and the analytic Ward material the window's
export fits on the way out (`materials/ward.xml`, the lab's grid of it). Each fit runs with the
defaults (Ngan metric, restarts, one worker so that the two fits of a row share the machine
alike); the row reports process CPU seconds, passes over the samples by size, the error, and
the ratio Principled / Lambertian + GGX. Run it against another tree (`PYTHONPATH=…`) in the
same session to compare before and after.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import tempfile
import time
from pathlib import Path

from brdflab.fitting import lm
from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
from brdflab.fitting.samples import samples_of
from brdflab.io import xmlio
from brdflab.sources.measured import read_merl_binary, read_slice, write_merl_binary

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("BRDFLAB_SHARED", ROOT.parent / "shared")) / "data"
MATERIALS = ("nickel", "white-paint", "blue-fabric", "red-specular-plastic")
FAMILIES = {"lambertian_ggx": ["Lambertian", "CookTorranceGGX"], "principled": ["Principled"]}


def timed_fit(lobes: list[str], samples) -> dict:
    """One default fit: CPU seconds, passes per sample-set size, error."""
    passes: collections.Counter = collections.Counter()
    accumulate = lm._Problem.accumulate

    def counted(problem, rows):
        passes[problem.samples.size] += 1
        return accumulate(problem, rows)

    lm._Problem.accumulate = counted
    try:
        cpu, wall = time.process_time(), time.perf_counter()
        result = fit(material_from_lobes(lobes, "Linear", samples.n_channels), samples, FitOptions(workers=1))
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    finally:
        lm._Problem.accumulate = accumulate
    return {"cpu_s": cpu, "wall_s": wall, "error": result.error, "passes": {str(k): v for k, v in sorted(passes.items())}}


def sources(quick: bool, tmp: Path):
    """(name, samples) of every source: the Ward grid first, then the MERL tables."""
    yield "ward.xml (analytic grid)", samples_of(xmlio.load(ROOT / "materials" / "ward.xml").material)
    for name in MATERIALS[:1] if quick else MATERIALS:
        path = tmp / f"{name}.binary"
        write_merl_binary(read_slice(DATA / "merl_slices" / f"{name}.slice").to_full(), path)
        yield f"{name} (full MERL table)", samples_of(read_merl_binary(path))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="Ward and one table")
    ap.add_argument("--json")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, samples in sources(args.quick, Path(tmp)):
            row = {"source": name, "samples": samples.size}
            for family, lobes in FAMILIES.items():
                row[family] = timed_fit(lobes, samples)
            row["ratio"] = row["principled"]["cpu_s"] / row["lambertian_ggx"]["cpu_s"]
            rows.append(row)
            print(f"{name:<36} {samples.size:>8} samples  L+GGX {row['lambertian_ggx']['cpu_s']:6.2f} s "
                  f"(error {row['lambertian_ggx']['error']:.5g})  Principled {row['principled']['cpu_s']:6.2f} s "
                  f"(error {row['principled']['error']:.5g})  ratio {row['ratio']:.1f}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({"tree": str(Path(lm.__file__).parents[2]), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
