"""MIS at 64 samples with the prefiltered image as its control variate (issue 36 goal 2), as the
renderer draws it (`lighting/control_variate.py`, shaders/mis_control.glsl).

    python benchmarks/mis_control_variate.py [--json docs/bench/mis_control_variate.json]

The estimate of a pixel is β P + MIS₆₄[f·cos·L − β g] (g: the irradiance kernel × the diffuse
shares, the fitted lobes' lookups' kernels, × the stack's dimmed map, plus the lights at their
texels; P its integral), β chosen per material and map by `auto_twins.control_weight` (the
least-squares control coefficient on pilot draws of their own). Computed by the renderer's
NumPy twin (`auto_twins.mis_parts`, equal to the shader's image to 1e-4:
tests/test_auto_twins.py), which gives the plain estimate and the control's from the same
samples, so each β is scored on the same draws.

Columns: `MIS 64` plain (the renderer before); `control` at the chosen β (the renderer now);
`β = 1` and `β = ½` held fixed; `best of 0, ¼, ½, ¾, 1` per row (hindsight: what a perfect
choice among those would give, the bound on choosing β better); `… over the view`: plain MIS and
the control at the chosen β by the view's relative RMSE of RGB (Auto judges the larger of the
two measures, and β is chosen for it). Scored as the lab scores
lighting: the reference view at 32², maps at 128 × 64, the RMS of each pixel's relative error
in luminance against the subdivided texel quadrature (`refined_environment_image`), the RMS of
DRAWS independent draws. Every map of `lighting.synthetic_maps` (held out: *); nothing here is
tuned.
"""

from __future__ import annotations

import numpy as np

from json_output import measure_and_write
from lighting_auto_pixels import materials  # the five: Lambertian, GGX m = 0.1 and 0.3, Ward 0.1 × 0.3, a MERL slice

from brdflab.lighting import auto_twins as twins
from brdflab.lighting.control_variate import map_control
from brdflab.lighting.env_sampling import LUMINANCE, environment_distribution
from brdflab.lighting.reference_view import refined_environment_image, sphere_view, weighted_pixel_error
from brdflab.lighting.sampling_sets import pixel_shifts
from brdflab.lighting.synthetic_maps import catalogue
from brdflab.sources.proxy import proxy_lobes

SIZE, SAMPLES, MAP_SIZE, DRAWS = 32, 64, (128, 64), 3
FIXED = (0.0, 0.25, 0.5, 0.75, 1.0)


def measure() -> dict:
    view = sphere_view(SIZE, SIZE)
    frames = (view.normal[view.inside], view.tangent[view.inside], view.bitangent[view.inside])
    pixels = len(frames[0])
    share = np.full(pixels, 1.0 / pixels)
    lum = lambda rgb: rgb[:, :3] @ LUMINANCE
    rows = []
    for spec in catalogue():
        env = spec.build(*MAP_SIZE)
        dist = environment_distribution(env)
        for name, source in materials().items():
            proxy = proxy_lobes(source)
            control = map_control(env, proxy)
            beta = twins.weight_for(source, proxy, env, control, dist)
            rgb = refined_environment_image(source, env, SIZE, SIZE)[view.inside][:, :3]
            truth = lum(rgb)
            parts = [twins.mis_parts(source, proxy, env, dist, frames, SAMPLES,
                                     pixel_shifts(np.arange(pixels), np.full(pixels, draw)), control)
                     for draw in range(DRAWS)]
            error = lambda weight: float(np.sqrt(np.mean([weighted_pixel_error(lum(x + weight * (p - y)), truth, share) ** 2
                                                          for x, y, p in parts])))
            over_view = lambda weight: float(np.sqrt(np.mean([((x + weight * (p - y))[:, :3] - rgb) ** 2 for x, y, p in parts])
                                                     / np.mean(rgb**2)))
            fixed = {w: error(w) for w in FIXED}
            row = {"map": spec.name, "class": spec.kind, "held_out": spec.held_out, "material": name, "beta": beta,
                   "MIS 64": fixed[0.0], "control": error(beta), "β = 1": fixed[1.0], "β = ½": fixed[0.5],
                   "best of 0, ¼, ½, ¾, 1": min(fixed.values()),
                   "MIS 64 over the view": over_view(0.0), "control over the view": over_view(beta)}
            rows.append(row)
            print(f"{spec.name:22s}{'*' if spec.held_out else ' '} {name:22s} β {beta:4.2f} "
                  + "  ".join(f"{key} {100 * row[key]:6.2f}" for key in ("MIS 64", "control", "β = 1", "β = ½",
                                                                         "best of 0, ¼, ½, ¾, 1", "MIS 64 over the view",
                                                                         "control over the view")), flush=True)
    return {"size": SIZE, "samples": SAMPLES, "map_size": MAP_SIZE, "draws": DRAWS, "rows": rows}


if __name__ == "__main__":
    measure_and_write(measure, __doc__)
