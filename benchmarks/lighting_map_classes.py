"""Each lighting mode's error pixel by pixel against its cost, per class of map (issue 36 goal 5):
the study part `lighting-classes` at its full sizes, with a choice of materials and settings.

    python benchmarks/lighting_map_classes.py [--json docs/bench/lighting_map_classes.json]
                                              [--chart docs/images/lighting_map_classes.png]
                                              [--materials "GGX m=0.3" ...] [--settings "fis 64" ...]

`brdflab study --part lighting-classes` measures and charts the same (see the part's
docstring): three materials under the fifteen synthetic maps at 128 × 64, every mode's
settings, the reference view at 32² against the subdivided texel quadrature, frames timed at 64².
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
from pathlib import Path

from brdflab.study.framework import StudyContext, stderr_progress
from brdflab.study.lighting_classes import MATERIALS, SETTINGS, draw, label, maps, measure_maps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json")
    ap.add_argument("--chart")
    ap.add_argument("--materials", nargs="+", choices=list(MATERIALS), help="only these materials")
    ap.add_argument("--settings", nargs="+", help='only these settings ("prefiltered", "sh 4", "fis 64", …)')
    args = ap.parse_args()
    chosen = {name: make for name, make in MATERIALS.items() if not args.materials or name in args.materials}
    settings = [s for s in SETTINGS if not args.settings or label(*s) in args.settings]
    result = measure_maps(chosen, maps(quick=False), settings, 32, 64, (128, 64), StudyContext(progress=stderr_progress))
    for name, entry in result["materials"].items():
        for row in entry["rows"]:
            best = min((e, k) for k, e in row["errors"].items())
            print(f"{name:<11} {row['map']:<22}{'*' if row['held_out'] else ' '} "
                  + "  ".join(f"{k} {100 * e:.1f}" for k, e in row["errors"].items()) + f"   best {best[1]}")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    if args.chart:
        with tempfile.TemporaryDirectory() as tmp:
            shutil.copy(Path(tmp) / draw(result, Path(tmp))[0], args.chart)


if __name__ == "__main__":
    main()
