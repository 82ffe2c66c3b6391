"""The lab's fits against the published state of the art, in the picture (issue 34 goal 5).

    python benchmarks/published_fits.py [--json docs/bench/published_fits.json] [--materials a,b,...]

Per shared MERL slice: Bagher 2012 (SGD) and Löw 2012 (ABC) as published with dj_brdf
(`sources/published.py`), and the lab's Lambertian + GGX and Lambertian + 2 GGX fitted by the
image metric (default maps); each scored by its image error under the default maps (the
fitter's operator) and, by an independent route, under four maps no fit and no tuning saw
(`reference_view.refined_environment_image`, as benchmarks/image_metric.py), beside its Ngan
error over every sample and its fitting time. A case is one material × held-out map.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from image_metric import SHARED, VIEW, held_out_maps, toned_error  # noqa: E402

from brdflab.fitting.image_metric import SceneImages  # noqa: E402
from brdflab.fitting.lm import FitOptions, fit, material_from_lobes  # noqa: E402
from brdflab.fitting.metrics import metric_errors  # noqa: E402
from brdflab.fitting.samples import samples_of  # noqa: E402
from brdflab.lighting.reference_view import refined_environment_image  # noqa: E402
from brdflab.sources.files import load_source  # noqa: E402
from brdflab.sources.published import read_published  # noqa: E402

MATERIALS = ("alum-bronze", "black-oxidized-steel", "brass", "chrome-steel", "grease-covered-steel", "hematite",
             "nickel", "ss440", "tungsten-carbide", "pink-felt", "blue-fabric", "white-fabric", "red-specular-plastic",
             "specular-black-phenolic", "pvc", "white-paint")
OURS = {"L+GGX": ["Lambertian", "CookTorranceGGX"], "L+2GGX": ["Lambertian", "CookTorranceGGX", "CookTorranceGGX"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path)
    parser.add_argument("--materials", default=",".join(MATERIALS))
    args = parser.parse_args()
    maps = held_out_maps()
    sgd = read_published(SHARED / "tables" / "bagher2012_sgd_fits.csv")
    abc = read_published(SHARED / "tables" / "low2012_abc_fits.csv")
    rows = []
    for name in args.materials.split(","):
        source = load_source(SHARED / "merl_slices" / f"{name}.slice")
        samples = samples_of(source)
        scene = SceneImages.of_source(source)
        references = [refined_environment_image(source, env, VIEW, VIEW, subdivision=4) for env in maps]
        candidates = {"SGD": (sgd[name], 0.0), "ABC": (abc[name], 0.0)}
        for label, lobes in OURS.items():
            t0 = time.perf_counter()
            result = fit(material_from_lobes(lobes, "Linear", 3), scene, FitOptions(metric="image"))
            candidates[label] = (result.material, time.perf_counter() - t0)
        row = {"material": name}
        ngan = metric_errors([m for m, _ in candidates.values()], samples, "Ngan")
        for (label, (material, seconds)), sample_error in zip(candidates.items(), ngan):
            held = [toned_error(refined_environment_image(material, env, VIEW, VIEW, subdivision=4), ref)
                    for env, ref in zip(maps, references)]
            row[label] = {"image_default_maps": scene.errors([material])[0], "ngan": sample_error,
                          "held_out": dict(zip([m.name for m in maps], held)), "seconds": seconds}
        rows.append(row)
        print(f"{name:24s} " + " | ".join(
            f"{k} {row[k]['image_default_maps']:.3f} / " + " ".join(f"{v:.3f}" for v in row[k]["held_out"].values())
            for k in ("SGD", "ABC", *OURS)), flush=True)
        cases = [(r, m) for r in rows for m in r["SGD"]["held_out"]]
        below = {k: sum(r[k]["held_out"][m] < min(r["SGD"]["held_out"][m], r["ABC"]["held_out"][m]) for r, m in cases)
                 for k in OURS}
        if args.json:
            args.json.write_text(json.dumps({"view": VIEW, "held_out_maps": [m.name for m in maps], "rows": rows,
                                             "cases": len(cases), "below_min_published": below}, indent=1))
    print(f"below min(SGD, ABC) under held-out maps: {below} of {len(cases)} cases")


if __name__ == "__main__":
    main()
