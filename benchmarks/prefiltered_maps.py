"""Issue 36 goal 1: prefiltered lighting per pixel below 60° on the fifteen synthetic maps.

    python benchmarks/prefiltered_maps.py [--json docs/bench/prefiltered_maps.json]

For rough lobes (GGX, Beckmann and Ward at m = 0.3, GGX at 0.5; F0 = 1) under every map of
`lighting.synthetic_maps` (128 × 64, held-out maps marked): the NumPy twin of the renderer's
prefiltered image (`split_sum.prefiltered_image`, equal to the GPU's to 1e-6; tests/test_prefiltered.py)
in the reference view at 32², against the subdivided texel quadrature
(`reference_view.refined_environment_image`, which never reads the stack), as the RMS of each
pixel's relative error in luminance over the pixels with θo < 60° and over the whole sphere; and
the time to make each material's split (its albedo tables and fitted lookups). Run it against
another tree (`PYTHONPATH=…`) in the same session to compare before and after.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

from brdflab.io.atomic import atomic_write
from brdflab.lighting.reference_view import pixel_relative_rmse, refined_environment_image, sphere_view
from brdflab.lighting.split_sum import material_split, prefiltered_image
from brdflab.lighting.synthetic_maps import catalogue
from brdflab.material.analytic import AnalyticMaterial, Lobe

SIZE = 32
MATERIALS = {
    "GGX m=0.3": ("CookTorranceGGX", {"m": 0.3, "F0": 1.0}),
    "Beckmann m=0.3": ("CookTorrance", {"m": 0.3, "F0": 1.0}),
    "Ward 0.3": ("Ward", {"ax": 0.3, "ay": 0.3}),
    "GGX m=0.5": ("CookTorranceGGX", {"m": 0.5, "F0": 1.0}),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default="docs/bench/prefiltered_maps.json")
    args = parser.parse_args()
    view = sphere_view(SIZE, SIZE)
    below = view.inside & (view.normal[..., 2] > 0.5)
    rows = []
    for name, (model, params) in MATERIALS.items():
        material = AnalyticMaterial(name, "Linear", 3, [Lobe.create(model, [1.0] * 3, **params)])
        t0 = time.perf_counter()
        material_split(material)
        split_s = time.perf_counter() - t0
        for spec in catalogue():
            env = spec.build(128, 64)
            image = prefiltered_image(material, env, SIZE, SIZE)
            reference = refined_environment_image(material, env, SIZE, SIZE)
            rows.append({"material": name, "map": spec.name, "class": spec.kind, "held_out": spec.held_out,
                         "below_60": pixel_relative_rmse(image, reference, below),
                         "sphere": pixel_relative_rmse(image, reference, view.inside), "split_s": split_s})
            print(f"{name:15s} {spec.name:22s}{'*' if spec.held_out else ' '} below 60°: "
                  f"{100 * rows[-1]['below_60']:5.1f} %   sphere: {100 * rows[-1]['sphere']:5.1f} %", flush=True)
    payload = {"machine": platform.platform(), "size": SIZE, "rows": rows}
    atomic_write(Path(args.json), json.dumps(payload, indent=1).encode())


if __name__ == "__main__":
    main()
