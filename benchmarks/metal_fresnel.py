"""Why a principled metal stays above Lambertian + GGX in the picture (issue 34 goal 3).

    python benchmarks/metal_fresnel.py [--json docs/bench/metal_fresnel.json] [nickel chrome-steel brass]

Per shared metal: Lambertian + GGX fitted by the image metric (default maps); then the same
fit with its GGX lobe given Schlick's Fresnel rising from F0 to 1 at grazing, for several F0,
its scale divided by F0 so that it reflects the same at normal incidence (what a principled
metal must do: F0 is its base colour, and its Fresnel rises to white); then Principled fitted by
the image metric twice, from its own starts and from a metal made from the Lambertian + GGX
fit (metallic 0.99, base colour = the GGX scale × F0, roughness = √m), to tell a poor start
from the model's limit. Image errors by the image metric's quadrature.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import numpy as np

from brdflab.fitting.image_metric import SceneImages
from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.sources.files import load_source

DATA = Path(os.environ.get("BRDFLAB_SHARED", Path(__file__).resolve().parents[2] / "shared")) / "data"
FRESNEL_F0 = (0.9, 0.5, 0.3, 0.17)


def with_fresnel(material: AnalyticMaterial, f0: float) -> AnalyticMaterial:
    """The fit with its GGX lobe's F0 set to `f0` and its scale divided by the change: equal at
    normal incidence, brighter towards grazing by Schlick's rise."""
    out = material.copy()
    ggx = out.lobes[1]
    ggx.scale = [s * ggx.params["F0"] / f0 for s in ggx.scale]
    ggx.params["F0"] = f0
    return out


def metal_start(material: AnalyticMaterial) -> AnalyticMaterial:
    ggx = material.lobes[1]
    colour = np.clip(np.asarray(ggx.scale) * ggx.params["F0"], 0.0, 1.0)
    return AnalyticMaterial("start", "Linear", 3, [Lobe.create(
        "Principled", [1.0, 1.0, 1.0], base_color_r=float(colour[0]), base_color_g=float(colour[1]),
        base_color_b=float(colour[2]), metallic=0.99, roughness=float(min(0.99, math.sqrt(ggx.params["m"]))))])


def one(name: str) -> dict:
    scene = SceneImages.of_source(load_source(DATA / "merl_slices" / f"{name}.slice"))
    image = lambda m: float(scene.errors([m])[0])
    brightness = lambda m: float(scene.render(m.evaluate).mean() / scene.target.mean())
    ggx = fit(material_from_lobes(["Lambertian", "CookTorranceGGX"], "Linear", 3), scene, FitOptions(metric="image"))
    row = {"slice": name, "lggx_image_error": image(ggx.material), "lggx_F0": ggx.material.lobes[1].params["F0"],
           "lggx_m": ggx.material.lobes[1].params["m"], "lggx_scale": list(ggx.material.lobes[1].scale),
           "with_schlick_rise": {str(f0): image(with_fresnel(ggx.material, f0)) for f0 in FRESNEL_F0}}
    for label, start, restarts in (("principled_own_starts", material_from_lobes(["Principled"], "Linear", 3), True),
                                   ("principled_from_lggx", metal_start(ggx.material), False)):
        t0 = time.perf_counter()
        r = fit(start, scene, FitOptions(metric="image", restarts=restarts))
        p = r.material.lobes[0].params
        row[label] = {"image_error": image(r.material), "brightness": brightness(r.material),
                      "seconds": time.perf_counter() - t0,
                      "base_color": [p["base_color_r"], p["base_color_g"], p["base_color_b"]],
                      "metallic": p["metallic"], "roughness": p["roughness"]}
    print(name, json.dumps(row), flush=True)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("slices", nargs="*", default=["nickel", "chrome-steel", "brass"])
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    rows = [one(name) for name in args.slices]
    if args.json:
        args.json.write_text(json.dumps({"rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
