"""MIS at 64 samples with the prefiltered image as a control variate (issue 36 goal 2), measured
in NumPy before it is built into the shader.

    python benchmarks/mis_control_variate.py [--json docs/bench/mis_control_variate.json]

The estimate of a pixel is P + MIS₆₄[f·cos·L − g], where g is a function of the direction whose
integral is P, exactly:
- for each lookup the prefiltered mode reads (`split_sum.prefiltered_pixels`: the irradiance at n,
  a fitted lobe's lookups on its two rows, the others' taps between two layers), its coefficient
  (albedo, share, weight) × the layer's kernel about the lookup's direction, normalised over the
  sphere, × the dimmed map (the stack's map, its lights taken out) texel by texel; its integral is
  that convolution, which the stack holds at its texel centres (the benchmark's one approximation:
  the stack read bilinearly between them, and by its texel quadrature);
- for each of the stack's lights (a bright texel's excess over the dimmed map), f(c)·cos at its
  texel's centre c × that excess inside the texel: its integral is exactly the prefiltered mode's
  sum over its lights.
The residual is drawn by the renderer's MIS set (`auto_twins`: half from the lobes, half from the
map, each pixel its own shift, the power heuristic) over the whole sphere: below a pixel's horizon
f·cos is 0 but g is not, and only the map's half reaches there (its weight is then 1), so the
estimate stays unbiased for any g. A lookup of a layer that is the map itself (α = 0) has no
kernel and is left out of g and P.

Columns: `MIS 64` as the renderer draws it today; `control` with g from the lobes the prefiltered
mode fits at every view (`view_mixture.fits`) and diffuse shares, plus the lights; `no lights`
the same without the lights' part; `every lobe` with the other lobes' lookups (taps) in g too;
`control × ½` the control at half its weight, ½ P + MIS₆₄[f·cos·L − ½ g] (unbiased for any fixed
weight; made from the same samples as `control`).
Scored as the lab scores lighting: the reference view at 32², maps at 128 × 64, the RMS of each
pixel's relative error in luminance against the subdivided texel quadrature
(`refined_environment_image`), two independent draws (RMS of both), and the mean of the two
draws (what is left of it is the bias and half the variance). Every map of
`lighting.synthetic_maps` (held out: *); nothing here is tuned: the columns are structural
choices, made on the table as a whole.
"""

from __future__ import annotations

import numpy as np

from json_output import measure_and_write
from lighting_auto_pixels import materials  # the five: Lambertian, GGX m = 0.1 and 0.3, Ward 0.1 × 0.3, a MERL slice

from brdflab.lighting import auto_twins as twins
from brdflab.lighting.env_sampling import LUMINANCE, environment_distribution
from brdflab.lighting.envmap import texel_of
from brdflab.lighting.prefilter import ALPHAS, KERNELS, bright_lights, cosine_kernel, prefiltered_stack, reduced, specular_kernel
from brdflab.lighting.reference_view import refined_environment_image, sphere_view, weighted_pixel_error
from brdflab.lighting.sampling_sets import mis_sample_set, pixel_shifts
from brdflab.lighting.split_sum import albedo_at, lookup_direction, material_split, mixture_lookups, sample_latlong
from brdflab.lighting.synthetic_maps import catalogue
from brdflab.material.analytic import AnalyticMaterial
from brdflab.sources.proxy import proxy_lobes

SIZE, SAMPLES, MAP_SIZE, DRAWS = 32, 64, (128, 64), 2
VARIANTS = {"control": (True, True), "no lights": (True, False), "every lobe": (False, True)}  # (fitted lobes only, lights)


def layer_kernel(index: int):
    """(kernel of cos to the lookup direction, what the stack divides its convolution by) of a
    stack layer: 1 for the irradiance (not normalised), the kernel's integral over the sphere for
    the others; (None, None) for a layer that is the map itself."""
    if index == 0:
        return cosine_kernel, 1.0
    kernel, alpha = KERNELS[(index - 1) // len(ALPHAS)], ALPHAS[(index - 1) % len(ALPHAS)]
    if alpha == 0.0:
        return None, None
    k = specular_kernel(kernel, alpha)
    theta = np.linspace(0.0, np.pi, 400_001)
    return k, 2.0 * np.pi * np.trapezoid(k(np.cos(theta)).astype(float) * np.sin(theta), theta)


LAYER_KERNELS = [layer_kernel(i) for i in range(1 + len(KERNELS) * len(ALPHAS))]


def lookups(material: AnalyticMaterial, frames, fitted_only: bool):
    """What `split_sum.prefiltered_pixels` reads, lookup by lookup: layers (pixels, M), world
    directions (pixels, M, 3) and RGB coefficients (pixels, M, 3); with `fitted_only`, the
    diffuse shares and the fitted lobes' lookups alone."""
    n, t, b = frames
    pixels = len(n)
    wo = np.stack([t[:, 2], b[:, 2], n[:, 2]], -1)
    out = [(np.zeros(pixels, int), n, np.zeros((pixels, 3)))]
    for split, rgb in zip(material_split(material), material.rgb_scales()):
        albedo = albedo_at(split.albedo, wo) * rgb
        if split.diffuse_share > 0.0:
            out.append((np.zeros(pixels, int), n, albedo * split.diffuse_share / np.pi))
        if split.mixture is not None:
            layer, d, weight = mixture_lookups(split.mixture, n, t, b, wo)
            out += [(layer[:, m], d[:, m], albedo * weight[:, m, None]) for m in range(layer.shape[1])]
        elif split.diffuse_share < 1.0 and not fitted_only:
            lo, hi, w = split.layers
            for tap in split.taps:
                local = lookup_direction(split, tap, wo)
                d = local[:, :1] * t + local[:, 1:2] * b + local[:, 2:] * n
                c = albedo * (1.0 - split.diffuse_share) * tap[2]
                out += [(np.full(pixels, lo), d, c * (1.0 - w)), (np.full(pixels, hi), d, c * w)]
    layers, dirs, coeff = (np.stack([o[k] for o in out], 1) for k in range(3))
    usable = np.array([k is not None for k, _ in LAYER_KERNELS])[layers]
    return layers, dirs, np.where(usable[..., None], coeff, 0.0)


def estimates(source, env, frames, shifts, fitted_only: bool, with_lights: bool) -> tuple[np.ndarray, np.ndarray]:
    """(the control-variate estimate, plain MIS with the same samples), RGB (pixels, 3)."""
    n, t, b = frames
    pixels = len(n)
    proxy = proxy_lobes(source)
    stack = prefiltered_stack(env)
    small = reduced(env)
    dimmed, lights = bright_lights(small)
    layers, dirs, coeff = lookups(proxy, frames, fitted_only)
    exact = np.zeros((pixels, 3))
    for k in np.unique(layers):
        exact += np.where((layers == k)[..., None], coeff * sample_latlong(stack.layers[k], dirs), 0.0).sum(1)
    # the lights: f·cos at each light's texel centre, per pixel
    wo = np.stack([t[:, 2], b[:, 2], n[:, 2]], -1)
    centres = lights[:, :3].astype(float)
    local = np.stack([centres @ t.T, centres @ b.T, centres @ n.T], -1)  # (lights, pixels, 3)
    f = np.asarray(source.evaluate(local.reshape(-1, 3), np.broadcast_to(wo, local.shape).reshape(-1, 3)))
    f = f.reshape(len(centres), pixels, -1)
    f = f[..., :3] if f.shape[-1] >= 3 else np.repeat(f[..., :1], 3, -1)
    f_cos_lights = np.where(local[..., 2:] > 0.0, f * local[..., 2:], 0.0)
    rows, cols = texel_of(centres, small.height, small.width)
    _, solid = small.texel_directions()
    excess = lights[:, 3:].astype(float) / np.broadcast_to(solid, (small.height, small.width))[rows, cols][:, None]
    light_of = -np.ones((small.height, small.width), int)
    light_of[rows, cols] = np.arange(len(lights))
    if with_lights:
        exact += (f_cos_lights * lights[:, None, 3:]).sum(0)
    # the renderer's MIS set, over the whole sphere
    dist = environment_distribution(env)
    sampling, shares = twins.renderer_sampling(source, proxy)
    data, fractions, env_fraction = mis_sample_set(shares, SAMPLES)
    u = np.mod(data[None, :, :2] + shifts[:, None, :], np.float32(1.0)).astype(float)
    from_map = data[:, 2] < 0
    wi = twins._lobe_directions(sampling, frames, data, u)
    wi[:, from_map] = twins._to_local(frames, dist.sample(u[:, from_map].reshape(-1, 2)).reshape(pixels, -1, 3))
    world = twins._to_world(frames, wi)
    p_map = env_fraction * dist.pdf(world)
    p_lobes = (1.0 - env_fraction) * twins.mixture_pdf(sampling, wi, np.broadcast_to(wo[:, None], wi.shape), fractions)
    own, other = np.where(from_map, p_map, p_lobes), np.where(from_map, p_lobes, p_map)
    ok = own > 0.0
    own = np.where(ok, own, 1.0)
    weight = np.where(ok, 1.0 / (1.0 + (other / own) ** 2), 0.0) / own
    integrand = twins._f_cos(source, frames, wi) * env.data.astype(float)[texel_of(world, env.height, env.width)]
    rows, cols = texel_of(world, small.height, small.width)
    control = np.zeros_like(integrand)
    cosines = np.clip(np.einsum("psc,pmc->psm", world, dirs), -1.0, 1.0)
    for k in np.unique(layers):
        kernel, norm = LAYER_KERNELS[k]
        if kernel is not None:
            control += np.einsum("psm,pmc->psc", kernel(cosines).astype(float) * (layers == k)[:, None] / norm, coeff)
    control *= dimmed.data.astype(float)[rows, cols]
    if with_lights:
        light = light_of[rows, cols]
        hit = light >= 0
        pixel = np.broadcast_to(np.arange(pixels)[:, None], light.shape)
        control[hit] += f_cos_lights[light[hit], pixel[hit]] * excess[light[hit]]
    mean = lambda values: (values * weight[..., None]).sum(1) / len(data)
    return exact + mean(integrand - control), mean(integrand)


def measure() -> dict:
    view = sphere_view(SIZE, SIZE)
    frames = (view.normal[view.inside], view.tangent[view.inside], view.bitangent[view.inside])
    pixels = len(frames[0])
    share = np.full(pixels, 1.0 / pixels)
    lum = lambda rgb: rgb[:, :3] @ LUMINANCE
    rows = []
    for spec in catalogue():
        env = spec.build(*MAP_SIZE)
        for name, source in materials().items():
            truth = lum(refined_environment_image(source, env, SIZE, SIZE)[view.inside])
            errors = {key: [] for key in ("MIS 64", *VARIANTS, "control × ½")}
            means = {key: [] for key in errors}
            for draw in range(DRAWS):
                shifts = pixel_shifts(np.arange(pixels), np.full(pixels, draw))
                for key, (fitted_only, with_lights) in VARIANTS.items():
                    value, plain = estimates(source, env, frames, shifts, fitted_only, with_lights)
                    errors[key].append(weighted_pixel_error(lum(value), truth, share))
                    means[key].append(lum(value))
                    if key == "control":  # ½ P + MIS[f·cos·L − ½ g]: the same samples, half the control
                        half = 0.5 * (value + plain)
                        errors["control × ½"].append(weighted_pixel_error(lum(half), truth, share))
                        means["control × ½"].append(lum(half))
                errors["MIS 64"].append(weighted_pixel_error(lum(plain), truth, share))
                means["MIS 64"].append(lum(plain))
            row = {"map": spec.name, "class": spec.kind, "held_out": spec.held_out, "material": name,
                   **{key: float(np.sqrt(np.mean(np.square(v)))) for key, v in errors.items()},
                   **{f"{key}, mean of {DRAWS}": weighted_pixel_error(np.mean(v, 0), truth, share) for key, v in means.items()}}
            rows.append(row)
            print(f"{spec.name:22s}{'*' if spec.held_out else ' '} {name:22s} "
                  + "  ".join(f"{key} {100 * row[key]:6.2f}" for key in errors), flush=True)
    return {"size": SIZE, "samples": SAMPLES, "map_size": MAP_SIZE, "draws": DRAWS, "rows": rows}


if __name__ == "__main__":
    measure_and_write(measure, __doc__)
