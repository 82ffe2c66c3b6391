"""Principled fits of metals by Ngan's sample metric and by the image metric (issue 34 goal 3).

    python benchmarks/principled_image_metric.py [--json docs/bench/principled_image_metric.json]
        [--picture docs/images/principled_metals_image_metric.png] [nickel brass chrome-steel]

Per slice: Lambertian + GGX and Principled, each fitted by Ngan's metric over every sample and
by the image metric (default maps); for each its image error under the default maps, its mean
brightness in those renders over the measurement's, its Ngan error, its time and parameters.
The picture: one row per slice, measurement | Principled by Ngan | Principled by the image
metric, the reference view at 96² under the held-out room-window-and-lamp map (the image
metric's own quadrature; exposure set by the measurement's 90th percentile).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from brdflab.fitting.image_metric import SceneImages, map_quadrature
from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
from brdflab.fitting.samples import samples_of
from brdflab.lighting.synthetic_maps import spec
from brdflab.lighting.tonemap import write_png
from brdflab.sources.files import load_source

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("materials", nargs="*", default=["nickel", "brass", "chrome-steel"])
    parser.add_argument("--json", type=Path)
    parser.add_argument("--picture", type=Path)
    args = parser.parse_args()
    q = map_quadrature(spec("room-window-and-lamp").build(256, 128), 96)
    out, rows = {}, []
    for name in args.materials:
        source = load_source(SHARED / "merl_slices" / f"{name}.slice")
        scene, samples = SceneImages.of_source(source), samples_of(source)
        row, pictures = {}, [q.image(q.render(source.evaluate, 3))]
        for metric, target in (("Ngan", samples), ("image", scene)):
            for lobes in (["Lambertian", "CookTorranceGGX"], ["Principled"]):
                t0 = time.perf_counter()
                result = fit(material_from_lobes(lobes, "Linear", 3), target, FitOptions(metric=metric))
                material = result.material
                key = f"{metric}:{'+'.join(lobes)}"
                row[key] = {"image_error": scene.errors([material])[0],
                            "brightness": float(scene.render(material.evaluate).mean() / scene.target.mean()),
                            "ngan": result.error if metric == "Ngan" else None,
                            "seconds": time.perf_counter() - t0,
                            "params": material.describe()["lobes"][-1]["parameters"]}
                print(name, key, {k: v for k, v in row[key].items() if k != "params"}, flush=True)
                if lobes == ["Principled"]:
                    pictures.append(q.image(q.render(material.evaluate, 3)))
        out[name] = row
        p90 = float(np.percentile(pictures[0][q.inside].mean(-1), 90))
        rows.append(np.concatenate(pictures, axis=1) * (0.7 / p90))
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))
    if args.picture:
        write_png(args.picture, np.concatenate(rows, axis=0))


if __name__ == "__main__":
    main()
