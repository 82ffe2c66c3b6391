"""A second export of the same source reads its principled fit from the cache (issue 35, goal 4:
a second export in any format costs ≤ 3× `brdflab info` of the same file).

    python benchmarks/export_cache.py [--slice gold-metallic-paint3] [--samples 3000] [--json docs/bench/export_cache.json]

The source is a raw sample file of `--samples` samples drawn from a shared MERL slice (a measured
file whose principled fit takes a minute, not the full slice's half hour). Each command runs
as a user runs it, a subprocess from another folder with an empty cache: `info`, then the
Mitsuba export (which fits), then MaterialX and glTF (which read the fit back). Times are
wall-clock, measured in one run; the ratios are what the goal is about.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("BRDFLAB_SHARED", ROOT.parent / "shared")) / "data"


def raw_samples(slice_name: str, n: int, path: Path) -> None:
    from brdflab.sources.measured import read_slice

    table = read_slice(DATA / "merl_slices" / f"{slice_name}.slice")
    rng = np.random.default_rng(7)
    ti, to = np.arccos(rng.uniform(0.05, 1.0, (2, n)))
    pi, po = rng.uniform(0.0, 2 * np.pi, (2, n))
    wi = np.stack([np.sin(ti) * np.cos(pi), np.sin(ti) * np.sin(pi), np.cos(ti)], 1)
    wo = np.stack([np.sin(to) * np.cos(po), np.sin(to) * np.sin(po), np.cos(to)], 1)
    np.savetxt(path, np.column_stack([ti, pi, to, po, table.evaluate(wi, wo)]))


def timed(args: list[str], cwd: Path, env: dict) -> float:
    t0 = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "brdflab", *args], cwd=cwd, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    if run.returncode != 0:
        raise SystemExit(f"brdflab {' '.join(args)} failed: {run.stderr.strip()}")
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--slice", default="gold-metallic-paint3")
    parser.add_argument("--samples", type=int, default=3000)
    parser.add_argument("--json", default=str(ROOT / "docs" / "bench" / "export_cache.json"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as work:
        work = Path(work)
        source = work / f"{args.slice}.txt"
        raw_samples(args.slice, args.samples, source)
        env = {**os.environ, "PYTHONPATH": str(ROOT), "BRDFLAB_CACHE": str(work / "cache")}
        times = {"info": timed(["info", str(source)], work, env)}
        for fmt, name in (("mitsuba", "m.xml"), ("mtlx", "m.mtlx"), ("gltf", "m.gltf")):
            times[f"export {fmt}"] = timed(["export", str(source), "--format", fmt, "--out", str(work / name)], work, env)
    result = {"source": f"{args.samples} samples of {args.slice}", "seconds": {k: round(v, 3) for k, v in times.items()},
              "first_export_over_info": round(times["export mitsuba"] / times["info"], 2),
              "second_export_over_info": round(times["export mtlx"] / times["info"], 2),
              "third_export_over_info": round(times["export gltf"] / times["info"], 2)}
    Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
