"""Scene-Auto against Auto: what each picks, what it costs, and how the picks look under maps
neither saw (issue 34 goal 4; issue 35 goal 3's ratio to one Lambertian + 2 GGX fit).

    python benchmarks/scene_auto.py [--json docs/bench/scene_auto.json] [--materials a,b,...]

Per shared MERL slice, in one process, one after the other: Auto (`auto_fit`, its defaults:
held-back Ngan error, 5 % relative gain), scene-Auto (`scene_auto` under the image metric's
default maps, 2 % image error), and one Lambertian + 2 Cook–Torrance GGX fit by Ngan's metric
(the unit of issue 35 goal 3). Each pick's image error under the default maps (the fitter's
operator) and under four held-out maps rendered by `reference_view.refined_environment_image`
(as benchmarks/image_metric.py), its parameters and wall time.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from image_metric import SHARED, VIEW, held_out_maps, toned_error  # noqa: E402  (the same held-out scoring)

from brdflab.fitting.auto import auto_fit  # noqa: E402
from brdflab.fitting.image_metric import SceneImages  # noqa: E402
from brdflab.fitting.lm import FitOptions, fit, material_from_lobes  # noqa: E402
from brdflab.fitting.samples import samples_of  # noqa: E402
from brdflab.fitting.scene_auto import scene_auto  # noqa: E402
from brdflab.lighting.reference_view import refined_environment_image  # noqa: E402
from brdflab.sources.files import load_source  # noqa: E402

MATERIALS = ("pink-felt", "blue-fabric", "red-specular-plastic", "nickel", "brass")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path)
    parser.add_argument("--materials", default=",".join(MATERIALS))
    args = parser.parse_args()
    maps = held_out_maps()
    rows = []
    for name in args.materials.split(","):
        source = load_source(SHARED / "merl_slices" / f"{name}.slice")
        samples = samples_of(source)
        references = [refined_environment_image(source, env, VIEW, VIEW, subdivision=4) for env in maps]
        t0 = time.perf_counter()
        fit(material_from_lobes(["Lambertian", "CookTorranceGGX", "CookTorranceGGX"], "Linear", 3), samples,
            FitOptions())
        unit = time.perf_counter() - t0
        t0 = time.perf_counter()
        auto = auto_fit(samples)
        auto_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        scene = SceneImages.of_source(source)
        ladder = scene_auto(scene)
        scene_s = time.perf_counter() - t0
        row = {"material": name, "l_2ggx_seconds": unit}
        for label, run, seconds in (("auto", auto, auto_s), ("scene_auto", ladder, scene_s)):
            material = run.chosen.result.material
            held = [toned_error(refined_environment_image(material, env, VIEW, VIEW, subdivision=4), ref)
                    for env, ref in zip(maps, references)]
            row[label] = {"lobes": ["Lambertian", *run.chosen.lobes], "parameters": run.chosen.parameters,
                          "seconds": seconds, "ratio_to_l_2ggx": seconds / unit, "candidates_fitted":
                          sum(c.fitted for c in run.candidates), "image_default_maps": scene.errors([material])[0],
                          "held_out": dict(zip([m.name for m in maps], held)),
                          "held_out_rms": math.sqrt(float(np.mean(np.square(held)))), "reason": run.reason}
        rows.append(row)
        a, s = row["auto"], row["scene_auto"]
        print(f"{name:22s} Auto {'+'.join(a['lobes'])} ({a['parameters']} p) {a['seconds']:.0f} s = "
              f"{a['ratio_to_l_2ggx']:.1f}×, image {a['image_default_maps']:.4f}, held out {a['held_out_rms']:.4f} | "
              f"scene-Auto {'+'.join(s['lobes'])} ({s['parameters']} p) {s['seconds']:.0f} s = "
              f"{s['ratio_to_l_2ggx']:.1f}×, image {s['image_default_maps']:.4f}, held out {s['held_out_rms']:.4f}",
              flush=True)
        if args.json:
            args.json.write_text(json.dumps({"view": VIEW, "held_out_maps": [m.name for m in maps], "rows": rows},
                                            indent=1))


if __name__ == "__main__":
    main()
