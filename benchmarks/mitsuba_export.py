"""Mitsuba 3 renders of `brdflab export --format mitsuba` against the lab's renders.

    python benchmarks/mitsuba_export.py [--size 64] [--spp 4096] [--json docs/bench/mitsuba_export.json]

Three analytic Principled materials and three MERL slices fitted to Principled (a plastic, a
metal, a fabric; the fits of benchmarks/principled_fits.py), in the reference view under the
shipped map (256 × 128): Mitsuba (scalar_rgb, direct lighting, two seeds) against the lab's
NumPy quadrature and its MIS renderer (study/mitsuba_check.py says how noise is taken out).
Writes the numbers and, per material, a picture lab | Mitsuba (docs/images/mitsuba_NAME.png).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from test_export_principled import ANALYTIC, FITS, MERL_FITS

from brdflab.io import xmlio
from brdflab.io.resources import default_environment_path
from brdflab.lighting.envmap import load_environment
from brdflab.lighting.tonemap import tonemap
from brdflab.sources.measured import read_slice
from brdflab.study.mitsuba_check import compare, lab_mis

SLICES = ROOT.parent / "shared" / "data" / "merl_slices"


def labelled_row(path: Path, panels: list[tuple[str, np.ndarray]]) -> None:
    """Tone-mapped images side by side, each with its label."""
    from PIL import Image, ImageDraw

    tiles = []
    for label, image in panels:
        tile = Image.fromarray(tonemap(image, exposure=0.0))
        ImageDraw.Draw(tile).text((4, 2), label, fill=(255, 255, 255))
        tiles.append(np.asarray(tile))
        tiles.append(np.full((image.shape[0], 3, 3), 255, np.uint8))
    Image.fromarray(np.concatenate(tiles[:-1], axis=1)).save(path)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--spp", type=int, default=4096)
    ap.add_argument("--lab-samples", type=int, default=1024, help="the lab's MIS at this and 4× as many")
    ap.add_argument("--json", default="docs/bench/mitsuba_export.json")
    args = ap.parse_args()
    env = load_environment(default_environment_path()).downsampled(256, 128)
    rows = []
    for name in [*ANALYTIC, *MERL_FITS]:
        material = ANALYTIC[name]() if name in ANALYTIC else xmlio.load(FITS / f"{name}.xml").material
        c = compare(name, material, env, args.size, args.spp, args.lab_samples)
        rows.append({**c.as_dict(), "size": args.size, "spp": args.spp, "lab_mis_samples": [args.lab_samples, 4 * args.lab_samples]})
        print(json.dumps(rows[-1]), flush=True)
        panels = [("lab (MIS)", c.lab), ("Mitsuba 3", c.mitsuba)]
        if name in MERL_FITS:  # the round trip: the measurement, its principled fit in the lab, in Mitsuba
            measured = lab_mis(read_slice(SLICES / f"{name}.slice"), env, args.size, 4 * args.lab_samples)
            panels = [("measured (lab)", measured), ("principled fit: lab", c.lab), ("fit: Mitsuba 3", c.mitsuba)]
        labelled_row(ROOT / "docs" / "images" / f"mitsuba_{name.replace(' ', '_')}.png", panels)
    Path(args.json).write_text(json.dumps({"map": "venice_sunset_1k.hdr at 256 × 128", "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
