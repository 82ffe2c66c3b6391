"""Fits by the image metric against fits by Ngan's sample metric, judged in the picture by an
independent renderer under maps neither fit saw (issue 34, goals 1 and 2).

    python benchmarks/image_metric.py [--json docs/bench/image_metric.json] [--lobes Lambertian,CookTorranceGGX]

Per shared MERL slice: the lobes fitted by `--metric image` (the default three maps) and by
Ngan's metric over every sample; for each fit its Ngan error over every sample, its image error
under the default maps (the fitter's own operator), its time, and its image error under held-out
maps computed by another route: `reference_view.refined_environment_image` (texel quadrature,
near and bright texels split 4 × 4) renders the measurement and the fit at VIEW², and the cube-
root toned RMS is taken here. Held-out maps: three synthetic ones kept out of all tuning and
the shared forest map (a real probe), each at 256 × 128.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from brdflab.fitting.image_metric import SceneImages, tone
from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
from brdflab.fitting.metrics import metric_error
from brdflab.fitting.samples import samples_of
from brdflab.lighting.envmap import load_environment
from brdflab.lighting.reference_view import refined_environment_image
from brdflab.lighting.synthetic_maps import spec
from brdflab.sources.files import load_source

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
MATERIALS = ("nickel", "chrome-steel", "brass", "ss440", "tungsten-carbide", "alum-bronze", "pink-felt", "white-paint",
             "red-specular-plastic", "blue-fabric")
HELD_OUT = ("room-window-and-lamp", "sunrise-tiny", "studio-rim-light")
VIEW = 16


def held_out_maps() -> list:
    maps = [spec(name).build(256, 128) for name in HELD_OUT]
    forest = load_environment(SHARED / "envmaps" / "forest.exr").downsampled_within(256, 128)
    forest.name = "forest"
    return maps + [forest]


def toned_error(image: np.ndarray, reference: np.ndarray) -> float:
    mask = reference.sum(-1) > 0
    return math.sqrt(((tone(image[mask]) - tone(reference[mask])) ** 2).sum() / (tone(reference[mask]) ** 2).sum())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path)
    parser.add_argument("--lobes", default="Lambertian,CookTorranceGGX")
    parser.add_argument("--materials", default=",".join(MATERIALS))
    args = parser.parse_args()
    lobes = args.lobes.split(",")
    maps = held_out_maps()
    rows = []
    for name in args.materials.split(","):
        source = load_source(SHARED / "merl_slices" / f"{name}.slice")
        samples = samples_of(source)
        t0 = time.perf_counter()
        scene = SceneImages.of_source(source)
        scene_seconds = time.perf_counter() - t0
        references = [refined_environment_image(source, env, VIEW, VIEW, subdivision=4) for env in maps]
        row = {"material": name, "lobes": lobes, "scene_seconds": scene_seconds}
        for metric, target in (("image", scene), ("Ngan", samples)):
            t0 = time.perf_counter()
            result = fit(material_from_lobes(lobes, "Linear", 3), target, FitOptions(metric=metric))
            seconds = time.perf_counter() - t0
            material = result.material
            held = [toned_error(refined_environment_image(material, env, VIEW, VIEW, subdivision=4), ref)
                    for env, ref in zip(maps, references)]
            row[metric] = {"seconds": seconds, "ngan": metric_error(material, samples, "Ngan"),
                           "image_default_maps": scene.errors([material])[0],
                           "held_out": dict(zip([m.name for m in maps], held)),
                           "held_out_rms": math.sqrt(float(np.mean(np.square(held)))),
                           "brightness": float(scene.render(material.evaluate).mean() / scene.target.mean()),
                           "parameters": material.describe()["lobes"]}
        rows.append(row)
        i, n = row["image"], row["Ngan"]
        print(f"{name:22s} image fit: {i['image_default_maps']:.4f} default, {i['held_out_rms']:.4f} held out, "
              f"Ngan {i['ngan']:.4f}, {i['seconds']:.1f} s | Ngan fit: {n['image_default_maps']:.4f} default, "
              f"{n['held_out_rms']:.4f} held out, Ngan {n['ngan']:.4f}, {n['seconds']:.1f} s", flush=True)
    wins = sum(r["image"]["held_out"][m] < r["Ngan"]["held_out"][m] for r in rows for m in r["image"]["held_out"])
    cases = sum(len(r["image"]["held_out"]) for r in rows)
    print(f"image fit better under a held-out map in {wins} of {cases} material × map cases")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"view": VIEW, "held_out_maps": [m.name for m in maps], "rows": rows,
                                         "image_fit_wins": wins, "cases": cases}, indent=1))


if __name__ == "__main__":
    main()
