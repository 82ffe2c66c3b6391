"""Mitsuba 3 renders of `brdflab export --format mitsuba` against the lab's renders.

    python benchmarks/mitsuba_export.py [--size 64] [--spp 4096] [--json docs/bench/mitsuba_export.json]

Three analytic Principled materials and three MERL slices fitted to Principled (a plastic, a
metal, a fabric; the fits of benchmarks/principled_fits.py), in the reference view under the
shipped map (256 × 128): Mitsuba (scalar_rgb, direct lighting, two seeds) against the lab's
NumPy quadrature and its MIS renderer (study/mitsuba_check.py says how noise is taken out).
Writes the numbers; `--picture 192` draws the README's round trip instead.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
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
from brdflab.study.mitsuba_check import compare, lab_mis, mitsuba_renders

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


def roundtrip_picture(name: str, size: int) -> None:
    """The README's picture: the slice rendered by the lab, its principled fit rendered by the
    lab, and the fit's Mitsuba export rendered by Mitsuba 3 (512 × 256 map)."""
    env = load_environment(default_environment_path()).downsampled(512, 256)
    fit = xmlio.load(FITS / f"{name}.xml").material
    with tempfile.TemporaryDirectory() as tmp:
        first, second = mitsuba_renders(fit, env, size, 512, Path(tmp))
    panels = [("measured (lab)", lab_mis(read_slice(SLICES / f"{name}.slice"), env, size, 1024)),
              ("principled fit (lab)", lab_mis(fit, env, size, 1024)), ("the export in Mitsuba 3", 0.5 * (first + second))]
    labelled_row(ROOT / "docs" / "images" / f"roundtrip_{name}.png", panels)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--spp", type=int, default=4096)
    ap.add_argument("--lab-samples", type=int, default=1024, help="the lab's MIS at this and 4× as many")
    ap.add_argument("--json", default="docs/bench/mitsuba_export.json")
    ap.add_argument("--picture", type=int, default=0, metavar="SIZE",
                    help="instead: docs/images/roundtrip_red-specular-plastic.png at SIZE² (measured | fit in the lab | in Mitsuba)")
    args = ap.parse_args()
    if args.picture:
        return roundtrip_picture("red-specular-plastic", args.picture)
    env = load_environment(default_environment_path()).downsampled(256, 128)
    rows = []
    for name in [*ANALYTIC, *MERL_FITS]:
        material = ANALYTIC[name]() if name in ANALYTIC else xmlio.load(FITS / f"{name}.xml").material
        c = compare(name, material, env, args.size, args.spp, args.lab_samples)
        rows.append({**c.as_dict(), "size": args.size, "spp": args.spp, "lab_mis_samples": [args.lab_samples, 4 * args.lab_samples]})
        print(json.dumps(rows[-1]), flush=True)
    Path(args.json).write_text(json.dumps({"map": "venice_sunset_1k.hdr at 256 × 128", "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
