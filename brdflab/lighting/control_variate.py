"""The prefiltered image as a control variate for MIS (issue 36 goal 2): the NumPy twin of
shaders/mis_control.glsl.

A pixel is estimated as β P + MIS_N[f·cos·L − β g], where g is a function of the incoming
direction whose integral over the sphere is P, exactly:
- the irradiance kernel max(0, n·ω) × the diffuse shares' coefficient (albedo × share / π), and
  for each lookup of a rough lobe's fitted mixture at the view cosine nearest the pixel's
  (`split_sum.mixture_lookups`, such lobes among the first FITTED_LOBES; the prefiltered mode blends
  two, twice the kernels a sample for a few hundredths of a point of error) its coefficient × its layer's
  kernel about the lookup's direction, normalised over the sphere (`layer_kernels`) — all × the
  stack's dimmed map texel by texel; their integrals are the stack's convolutions, read at the
  lookups' directions;
- for each of the stack's lights (the excess of a bright texel, or of a block of them, over the
  dimmed map), f·cos at the light's direction × the excess inside its texels: its integral is
  the prefiltered mode's sum over its lights. Where the lights are blocks, f less the diffuse
  shares' coefficient at the light, and the diffuse kernel × the excess texel by texel, whose
  integral is the stack's irradiance of the excess (a Lambertian's g is then f·cos·L itself).
So P is close to the prefiltered mode's image, less its glossy and anisotropic lobes' taps
(which, not close to their lobes sample by sample, added variance: docs/mis.md). The estimate is unbiased
for any g with a known integral and any weight β fixed before the samples are drawn: below a
pixel's horizon f·cos is 0 and g is not, and the map's half of the set reaches there with
weight 1 (the lobes' density is taken as 0 below the horizon, in the shader as here). The one
approximation is how the stack holds a convolution (by its texel quadrature at texel centres,
read bilinearly between them), bounded in tests/test_mis_control.py.

β is chosen per material and map by `auto_twins.control_weight` (the least-squares control
coefficient over pilot pixels): 1 where the split sum is close to the lobe (a Lambertian, a
rough fitted lobe), less where it is not (a glossy lobe, a measured table against its proxy),
and 0 (plain MIS) where what it takes from the variance does not pay for its cost (`frame_cost`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from brdflab.lighting.envmap import texel_of
from brdflab.lighting.prefilter import ALPHAS, KERNELS, PrefilteredStack, StackLayers
from brdflab.lighting.split_sum import albedo_at, material_split, mixture_lookups, sample_latlong
from brdflab.lighting.view_mixture import kernel_values as mixture_kernel_values
from brdflab.material.analytic import AnalyticMaterial

FITTED_LOBES = 4  # the lobes whose fitted lookups may be in the control (the shader holds 8 a lobe per pixel)
DIMMED_LAYER = 1  # the stack's first Beckmann layer, α = 0: the dimmed map itself
FAMILIES = ("cosine", *KERNELS)  # a layer's kernel, by its index in the shader's u_cv_layer


def frame_cost(fitted: int) -> float:
    """A MIS frame's cost with the control over plain MIS's (llvmpipe, 128², 64 samples, three
    maps): 1.37–1.41 without a fitted lobe in g (the irradiance kernel and the lights), 1.51–1.69
    with one (its eight lookups' kernels at every sample)."""
    return 1.4 + 0.2 * min(fitted, FITTED_LOBES)


def fitted_in_control(material: AnalyticMaterial) -> int:
    """How many of `material`'s lobes have their fitted lookups in g."""
    return sum(split.mixture is not None for split in material_split(material)[:FITTED_LOBES])


def layer_families() -> list[tuple[int, float]]:
    """Per stack layer: (family index in FAMILIES, its α; −1 for a layer that is the map itself);
    the first and the last are irradiances (the dimmed map's, the lights' excess's)."""
    out = [(0, 0.0)]
    for kernel in KERNELS:
        out += [(FAMILIES.index(kernel), alpha) if alpha > 0.0 else (-1, 0.0) for alpha in ALPHAS]
    return out + [(0, 0.0)]


def kernel_values(family: int, alpha, c: np.ndarray) -> np.ndarray:
    """A stack layer's kernel at cosines c to its centre, unnormalised (the stack's own:
    `prefilter.cosine_kernel`, and `view_mixture.kernel_values`' of the others; α may be an
    array, one per cosine)."""
    c = np.asarray(c, float)
    name = FAMILIES[family]
    return np.maximum(c, 0.0) if name == "cosine" else mixture_kernel_values(name, alpha, c)


@lru_cache(maxsize=1)
def layer_kernels() -> np.ndarray:
    """(layers, 3): each layer's (family, α, 1 / what its convolution is divided by): 1 for the irradiance (unnormalised), 1 / ∫K over the sphere for the others, 0
    for a layer that is the map itself (no kernel). The integral by the trapezoid rule in θ on a
    grid dense at θ = 0, where the narrowest kernel (α = 0.02) lives."""
    theta = np.pi * np.linspace(0.0, 1.0, 20_001) ** 3  # 2e-8 from 2,000,001 points
    rows = []
    for family, alpha in layer_families():
        if family < 0:
            rows.append((0.0, 0.0, 0.0))
            continue
        if FAMILIES[family] == "cosine":
            rows.append((0.0, 0.0, 1.0))
            continue
        k = kernel_values(family, alpha, np.cos(theta))
        integral = 2.0 * np.pi * np.trapezoid(k * np.sin(theta), theta)
        rows.append((float(family), alpha, 1.0 / integral))
    return np.array(rows)


def excess_radiance(stack: PrefilteredStack | StackLayers) -> np.ndarray:
    """(H, W, 4) at the stack's texels: the excess radiance each texel gave its light and that
    light's index among the stack's lights; 0 and −1 elsewhere (`prefilter.MapLights`)."""
    return stack.excess.astype(float)


@dataclass(frozen=True)
class PixelControl:
    """The control at some pixels: what it integrates to (`exact`, (pixels, 3)) and what g is
    made of there — the irradiance kernel's coefficient (pixels, 3) and the fitted lookups'
    layers (pixels, M), world directions (pixels, M, 3) and coefficients (pixels, M, 3)."""

    exact: np.ndarray
    diffuse: np.ndarray
    layers: np.ndarray
    directions: np.ndarray
    coefficients: np.ndarray
    lights: np.ndarray  # (pixels, lights, 3): f·cos at each of the stack's lights (0 below the horizon)

    def take(self, rows: np.ndarray) -> "PixelControl":
        """The control at some of its pixels (`rows`, indices into them)."""
        return PixelControl(*(np.take(part, rows, axis=0) for part in (self.exact, self.diffuse, self.layers,
                                                                       self.directions, self.coefficients, self.lights)))


def fitted_lookups(material: AnalyticMaterial, frames) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(irradiance coefficient (pixels, 3), layers, directions, coefficients) of g at pixels whose
    frames are (normal, tangent, bitangent) with the view world +Z (the reference view)."""
    n, t, b = frames
    pixels = len(n)
    wo = np.stack([t[:, 2], b[:, 2], n[:, 2]], -1)
    diffuse = np.zeros((pixels, 3))
    layers, directions, coefficients = [np.zeros((pixels, 0), int)], [np.zeros((pixels, 0, 3))], [np.zeros((pixels, 0, 3))]
    for k, (split, rgb) in enumerate(zip(material_split(material), material.rgb_scales())):
        scale = albedo_at(split.albedo, wo) * rgb
        diffuse += scale * split.diffuse_share / np.pi
        if split.mixture is not None and k < FITTED_LOBES:
            layer, d, weight = mixture_lookups(split.mixture, n, t, b, wo, nearest=True)
            layers.append(layer)
            directions.append(d)
            coefficients.append(scale[:, None] * weight[..., None])
    return diffuse, np.concatenate(layers, 1), np.concatenate(directions, 1), np.concatenate(coefficients, 1)


def pixel_control(material: AnalyticMaterial, stack: PrefilteredStack | StackLayers, frames, lit=None) -> PixelControl:
    """The control at the pixels (`fitted_lookups`), with its integral: the irradiance and each
    lookup's layer read from the stack as the prefiltered mode reads them, and the stack's
    lights evaluated with `lit` (the material itself unless given: a measured source), once per
    pixel and light (a sample in a light's texel reads its pixel's value: under a city's lamps
    most of the map's half of the samples are)."""
    from brdflab.lighting.reference_view import texel_f_cos

    n, t, b = frames
    wo = np.stack([t[:, 2], b[:, 2], n[:, 2]], -1)
    diffuse, layers, directions, coefficients = fitted_lookups(material, frames)
    centres = stack.light_directions.astype(float)
    light, pixel, f, cosine = texel_f_cos(material if lit is None else lit, centres, (t, b, n), wo)
    lights = np.zeros((len(n), len(centres), 3))
    blocks = stack.blocks  # the diffuse shares then lit by the excess's irradiance, the lights by the rest (`lights_term`)
    lights[pixel, light] = (f - diffuse[pixel] if blocks else f) * cosine[:, None]
    exact = diffuse * sample_latlong(stack.irradiance(), n) + np.einsum("plc,lc->pc", lights, stack.light_power.astype(float))
    if blocks:
        exact += diffuse * sample_latlong(stack.excess_irradiance(), n)
    for k in np.unique(layers):
        at = np.where((layers == k)[..., None], coefficients, 0.0)
        exact += (at * sample_latlong(stack.layers[k], directions)).sum(1)
    return PixelControl(exact, diffuse, layers, directions, coefficients, lights)


def control_values(control: PixelControl, stack: PrefilteredStack | StackLayers, excess: np.ndarray, frames,
                   world: np.ndarray) -> np.ndarray:
    """g (pixels, samples, 3) at world directions `world` (pixels, samples, 3): the kernels
    × the dimmed map texel by texel, plus, in a light's texel, f·cos at the light × the texel's excess."""
    n, t, b = frames
    rows, cols = texel_of(world, *excess.shape[:2])
    diffuse = control.diffuse[:, None] * np.maximum(np.einsum("psc,pc->ps", world, n), 0.0)[..., None]
    weight = diffuse
    if control.layers.shape[1]:
        family, alpha, inverse = np.moveaxis(layer_kernels()[control.layers], -1, 0)  # each (pixels, M)
        inverse = np.where((control.coefficients != 0.0).any(-1), inverse, 0.0)  # a row's empty lookups: none
        cosines = np.matmul(world, np.swapaxes(control.directions, 1, 2))  # (pixels, samples, M); einsum took 2×
        values = np.zeros_like(cosines)
        for kind in np.unique(family[inverse > 0.0]):  # one pass per kernel family, every α at once
            with np.errstate(divide="ignore", invalid="ignore"):  # another family's α (masked below) may be 0
                kernel = kernel_values(int(kind), alpha[:, None], cosines) * inverse[:, None]
            values += np.where(((family == kind) & (inverse > 0.0))[:, None], kernel, 0.0)
        weight = diffuse + np.matmul(values, control.coefficients)
    g = weight * stack.layers[DIMMED_LAYER][rows, cols].astype(float)
    light = excess[rows, cols, 3].astype(int)
    hit = light >= 0
    if hit.any():
        pixel = np.broadcast_to(np.arange(len(n))[:, None], light.shape)[hit]
        at_light = control.lights[pixel, light[hit]]
        if stack.blocks:  # the diffuse shares × the excess texel by texel too (`pixel_control`)
            at_light = at_light + diffuse[hit]
        g[hit] += at_light * excess[rows[hit], cols[hit], :3]
    return g


def control_layers(material: AnalyticMaterial) -> set[int]:
    """The stack layers the control of `material` reads: the irradiance, the dimmed map and its
    fitted lobes' layers."""
    wanted = {0, DIMMED_LAYER}
    return wanted.union(*(split.stack_layers() for split in material_split(material)[:FITTED_LOBES]
                          if split.mixture is not None))


@dataclass(frozen=True)
class MapControl:
    """A map's part of the control: its stack (or the layers a material's control reads) and
    its lights' excess texel by texel (`excess_radiance`)."""

    stack: PrefilteredStack | StackLayers
    excess: np.ndarray


def map_control(env, material: AnalyticMaterial, stack: PrefilteredStack | StackLayers | None = None) -> MapControl:
    """The control on `stack` (default: the map's stack where it is built, else the layers
    `material`'s control reads; one that holds them)."""
    from brdflab.lighting.prefilter import stack_layers

    stack = stack_layers(env, control_layers(material)) if stack is None else stack
    return MapControl(stack, excess_radiance(stack))
