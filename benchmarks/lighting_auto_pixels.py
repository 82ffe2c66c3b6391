"""Render Auto's pick judged pixel by pixel, on maps of every class (issue 36 goal 3).

    python benchmarks/lighting_auto_pixels.py [--json docs/bench/lighting_auto_pixels.json]

Per (material, synthetic map): `choose_lighting` picks a setting at the default tolerance (2 %);
the pick is rendered by the renderer (reference view, 32², the map at 128 × 64) and scored
against a quadrature of the same map with the texels near each mirror direction subdivided
(`study.lighting.quadrature_reference`), by two measures computed here, not by the lab's
functions: the view's RMS error over its RMS (what Auto judged until now) and the RMS of each
pixel's relative error in luminance, a pixel darker than 1 % of the view's mean counted
against that 1 % (what a user sees). Materials: the issue's five (Lambertian, GGX m = 0.1 and
0.3, Ward 0.1 × 0.3, a measured MERL slice when the shared data is there); maps: the fifteen of
`lighting.synthetic_maps`, the held-out ones marked. The time to choose is taken as
`brdflab render --mode auto` and the window call `choose_lighting`: after the renderer has taken
the source, with the renderer's proxy lobes (a measured source's proxy is fitted once, when the
renderer or the window opens it; that fit is timed apart as `proxy_s`, a new source object per
map). Run it against another tree (`PYTHONPATH=…`) in the same session to compare before and after.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from brdflab.lighting import prefilter
from brdflab.lighting.auto import choose_lighting
from brdflab.lighting.reference_view import sphere_view
from brdflab.lighting.synthetic_maps import catalogue
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.render.context import create_context
from brdflab.render.object_view import ObjectRenderer, RenderSettings
from brdflab.sources.proxy import proxy_lobes
from brdflab.study.framework import measured_slice
from brdflab.study.lighting import build_sh_table, quadrature_reference

SIZE = 32
MAP_SIZE = (128, 64)
TOLERANCE = 0.02
WEIGHTS = np.array([0.2126, 0.7152, 0.0722])


def lobe(model: str, **params: float) -> AnalyticMaterial:
    return AnalyticMaterial(model, "Linear", 3, [Lobe.create(model, [0.5] * 3, **params)])


def materials() -> dict:
    out = {"Lambertian": lobe("Lambertian"), "GGX m=0.1": lobe("CookTorranceGGX", m=0.1, F0=1.0),
           "GGX m=0.3": lobe("CookTorranceGGX", m=0.3, F0=1.0), "Ward 0.1x0.3": lobe("Ward", ax=0.1, ay=0.3)}
    path, _ = measured_slice()
    if path is not None:
        from brdflab.sources.measured import read_slice

        out[path.stem] = read_slice(path)
    return out


def errors(image: np.ndarray, reference: np.ndarray, inside: np.ndarray) -> tuple[float, float]:
    """(RMS over RMS of RGB, RMS of per-pixel relative luminance error with a 1 %-of-mean floor)."""
    a, b = image[inside][:, :3], reference[inside][:, :3]
    rms = np.sqrt(((a - b) ** 2).mean()) / np.sqrt((b**2).mean())
    la, lb = a @ WEIGHTS, b @ WEIGHTS
    per_pixel = np.sqrt((((la - lb) / np.maximum(lb, 0.01 * lb.mean())) ** 2).mean())
    return float(rms), float(per_pixel)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json")
    args = ap.parse_args()
    renderer = ObjectRenderer(create_context())
    inside = sphere_view(SIZE, SIZE).inside
    rows = []
    for spec in catalogue():
        env = spec.build(*MAP_SIZE)
        renderer.set_environment(env)
        for name, material in materials().items():
            prefilter._CACHE.clear()
            t0 = time.perf_counter()
            proxy_lobes(material)  # what the renderer's set_source fits, once per source object
            proxy_s = time.perf_counter() - t0
            renderer.set_source(material)
            t0 = time.perf_counter()
            choice = choose_lighting(material, env, TOLERANCE, proxy=renderer.material)
            seconds = time.perf_counter() - t0
            if choice.mode == "sh":
                build_sh_table(material, choice.setting)
                renderer.set_sh_order(choice.setting)
            samples = choice.setting if choice.mode in ("fis", "mis") else 1
            image = renderer.render(RenderSettings(choice.mode, SIZE, SIZE, samples=samples))
            reference, floor, _ = quadrature_reference(material, env, SIZE)
            rms, per_pixel = errors(image, reference, inside)
            rows.append({"map": spec.name, "class": spec.kind, "held_out": spec.held_out, "material": name,
                         "choice": f"{choice.mode} {choice.setting or ''}".strip(),
                         "predicted": choice.predicted_error, "rms": rms, "per_pixel": per_pixel,
                         "reference_floor": floor, "choose_s": seconds, "proxy_s": proxy_s, "weighed": len(choice.candidates)})
            print(f"{spec.name:<22}{'*' if spec.held_out else ' '} {name:<24} {rows[-1]['choice']:<12} "
                  f"predicted {100 * choice.predicted_error:5.2f} %  rms {100 * rms:5.2f} %  "
                  f"per pixel {100 * per_pixel:6.2f} %  choose {seconds:4.2f} s", flush=True)
    within = [r for r in rows if r["per_pixel"] <= TOLERANCE]
    print(f"within {100 * TOLERANCE:g} % per pixel: {len(within)} of {len(rows)}; "
          f"held out: {sum(r['held_out'] for r in within)} of {sum(r['held_out'] for r in rows)}")
    if args.json:
        Path(args.json).write_text(json.dumps({"tree": str(Path(prefilter.__file__).parents[2]), "size": SIZE,
                                               "map_size": MAP_SIZE, "tolerance": TOLERANCE, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
