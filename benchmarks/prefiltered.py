"""Prefiltered lighting against the texel quadrature, per material class and map, and its cost.

    python benchmarks/prefiltered.py [--json docs/bench/prefiltered.json]

For each material and real map (area-averaged to 128 × 64 texels, the quadrature's map and
the stack's): the renderer's prefiltered image (reference view, 48²) against
`environment_image`, as relative RMSE over the whole sphere, over θo < 30° (normal-ish views)
and over 65° ≤ θo < 85° (grazing); the same image computed by the NumPy twin
(lighting/split_sum.prefiltered_image) must agree with the GPU's (an independent route to
the same numbers). Also: the time to build a 1024 × 512 map's stack and the frame time at 256².
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from brdflab.io.atomic import atomic_write
from brdflab.io.resources import shared_data_dir
from brdflab.lighting.envmap import load_environment
from brdflab.lighting.prefilter import build_stack, map_key, reduced
from brdflab.lighting.reference_view import environment_image, relative_rmse, sphere_view
from brdflab.lighting.split_sum import prefiltered_image
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.render.context import create_context
from brdflab.render.object_view import ObjectRenderer, RenderSettings
from brdflab.study.framework import timed

MAPS = ("venice_sunset_1k.hdr", "forest.exr", "studio.exr")
SIZE = 48


def materials() -> dict[str, AnalyticMaterial]:
    def one(name, model, **params):
        return name, AnalyticMaterial(name, "Linear", 3, [Lobe.create(model, [0.5] * 3, **params)])

    return dict([
        one("Lambertian", "Lambertian"),
        one("Oren-Nayar σ=0.5", "OrenNayar", sigma=0.5),
        one("Blinn-Phong n=10", "BlinnPhong", Exponent=10.0),
        one("Blinn-Phong n=100", "BlinnPhong", Exponent=100.0),
        one("Blinn-Phong n=1000", "BlinnPhong", Exponent=1000.0),
        one("Cook-Torrance m=0.5", "CookTorrance", m=0.5, F0=0.9),
        one("Cook-Torrance m=0.2", "CookTorrance", m=0.2, F0=0.9),
        one("Cook-Torrance m=0.05", "CookTorrance", m=0.05, F0=0.9),
        one("GGX α=0.2", "CookTorranceGGX", m=0.2, F0=0.9),
        one("Ward 0.05×0.3", "Ward", ax=0.05, ay=0.3),
        one("Lafortune retro n=10", "LafortuneIso", Cxy=0.6, Cz=0.6, Exponent=10.0),
    ])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default="docs/bench/prefiltered.json")
    args = parser.parse_args()
    shared = shared_data_dir()
    if shared is None:
        raise SystemExit("needs the shared data (../shared/data or $BRDFLAB_SHARED)")
    renderer = ObjectRenderer(create_context())
    view = sphere_view(SIZE, SIZE)
    angle = np.degrees(np.arccos(np.clip(view.normal[..., 2], 0.0, 1.0)))
    masks = {"all": view.inside, "normal": view.inside & (angle < 30.0),
             "grazing": view.inside & (angle >= 65.0) & (angle < 85.0)}
    rows, worst_twin = [], 0.0
    for map_name in MAPS:
        env = reduced(load_environment(shared / "envmaps" / map_name), 128)
        renderer.set_environment(env)
        for name, material in materials().items():
            renderer.set_material(material)
            image = renderer.render(RenderSettings(mode="prefiltered", width=SIZE, height=SIZE))
            worst_twin = max(worst_twin, relative_rmse(image, prefiltered_image(material, env, SIZE, SIZE), view.inside))
            reference = environment_image(material, env, SIZE, SIZE)
            rows.append({"map": Path(map_name).stem, "material": name,
                         **{k: relative_rmse(image, reference, m) for k, m in masks.items()}})
            print(f"{rows[-1]['map']:<18} {name:<22} " + "  ".join(f"{k} {100 * rows[-1][k]:5.1f} %" for k in masks),
                  flush=True)
    full = load_environment(shared / "envmaps" / MAPS[0])
    t0 = time.perf_counter()
    build_stack(full, map_key(full))
    build_seconds = time.perf_counter() - t0
    renderer.set_environment(full)
    renderer.set_material(materials()["Blinn-Phong n=100"])
    frame = RenderSettings(mode="prefiltered", width=256, height=256)
    frame_ms = 1e3 * timed(lambda: renderer.render(frame), 5)
    payload = {"machine": {"platform": platform.platform(), "renderer": renderer.ctx.info.get("GL_RENDERER", "")},
               "size": SIZE, "reference_texels": [128, 64], "rows": rows, "gpu_vs_numpy_twin": worst_twin,
               "stack_build_seconds_1024x512": build_seconds, "frame_ms_256": frame_ms}
    atomic_write(Path(args.json), json.dumps(payload, indent=1).encode())
    print(f"GPU against the NumPy twin: worst relative RMSE {worst_twin:.1e}; stack of a 1024×512 map "
          f"{build_seconds:.1f} s; {frame_ms:.1f} ms per 256² frame; wrote {args.json}")


if __name__ == "__main__":
    main()
