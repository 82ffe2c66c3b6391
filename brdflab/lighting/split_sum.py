"""A material in prefiltered lighting: per lobe, the second factor of the split sum and
where the first is looked up.

∫ L(ω) f_k(ω, wo) cos θ dω ≈ A_k(cos θo) · L̄_k, where A_k is the lobe's directional albedo
(tabulated over cos θo, and φo for anisotropic lobes, by importance sampling, `material/albedo.lobe_albedo`: right for every
model at every view, not only GGX's) and L̄_k the prefiltered radiance: the irradiance / π for
diffuse lobes, else the stack at the lobe's direction (axis ∘ wo) and equivalent roughness
(`LobeModel.split_sum`). What is approximated: the lobe's shape is the one it has at normal
view around that direction (n = v = r; the direction is pulled toward n for rough lobes, as
Frostbite does, Lagarde & de Rousiers 2014 — the cosine and the horizon pull the real lobe's
light there), so the stretching and off-specular shift of real
lobes at grazing views, and the horizon's clipping of the lobe, are lost; the lobe's shape
is a Beckmann or GGX kernel of matched width; an anisotropic lobe is TAPS lookups with the
kernel of its shorter width around normals spread along its longer axis (`models/base.anisotropic_split`),
and its albedo is tabulated over the view's azimuth too. Energy is right at every view (the
albedo factor); where it goes is not. The map's brightest texels are not in the stack: they are
lights at which the material itself is evaluated (`prefilter.bright_lights`), as the quadrature does.

`prefiltered_image` is the NumPy twin of the renderer's shader (shaders/prefiltered.glsl) in
the reference view, so the GPU image can be checked against an independent computation.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from brdflab.lighting.envmap import EnvironmentMap, direction_to_uv
from brdflab.lighting.prefilter import PrefilteredStack, layer_blend, prefiltered_stack
from brdflab.lighting.view_mixture import COSINES, ROW_ANGLES, mixture_directions, view_mixture
from brdflab.material.analytic import AnalyticMaterial, Lobe

ALBEDO_SIZE = 32  # cos θo = 0, 1/31, …, 1
ALBEDO_PHIS = 12  # view azimuths φo = 2π j / 12 of the table (an anisotropic lobe's albedo depends on φo)
TAPS = 8  # lookups of an anisotropic lobe, around normals at the quantiles of its spread
MIN_COS = 0.01  # the albedo at cos θo = 0 is taken at this cosine
# and at cos θo = 1 at this one (0.08° off the normal): some models are 0/0 exactly there (BRDF
# Explorer's Oren–Nayar normalises V − N (V·N)), and one texel would darken the whole centre
MAX_COS = 1.0 - 1e-6


@dataclass(frozen=True)
class LobeSplit:
    """One lobe's prefiltered lighting: its albedo table, the two stack layers blended for
    its roughness, its lookup axis and the share of its albedo lit by the irradiance."""

    albedo: np.ndarray  # (ALBEDO_PHIS, ALBEDO_SIZE, 3) over φo = 2π j / ALBEDO_PHIS and cos θo = i / (ALBEDO_SIZE − 1), per colour
    layers: tuple[int, int, float]
    axis: tuple[float, float, float]
    diffuse_share: float
    toward_axis: float = 1.0  # the lookup direction: normalize(mix(n, axis ∘ wo, toward_axis))
    taps: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 1.0),)  # (slope along t, along b, weight) of each lookup's normal
    mixture: np.ndarray | None = None  # (COSINES, LOOKUPS, 3) of a fitted rough lobe (`view_mixture`): then no taps

    def stack_layers(self) -> set[int]:
        """The stack's layers its glossy lookups read (none for a diffuse lobe)."""
        if self.diffuse_share >= 1.0:
            return set()
        if self.mixture is not None:
            return {int(k) for k in self.mixture[..., 1][self.mixture[..., 2] > 0.0]}
        return set(self.layers[:2])


def dominant_weight(alpha: float) -> float:
    """How far the lookup goes from n toward the lobe's axis: (1 − α)(√(1 − α) + α), the
    'specular dominant direction' of Lagarde & de Rousiers 2014 (Frostbite), fitted for GGX."""
    a = float(np.clip(alpha, 0.0, 1.0))
    return (1.0 - a) * (np.sqrt(1.0 - a) + a)


def albedo_cosines(size: int = ALBEDO_SIZE) -> np.ndarray:
    return np.linspace(0.0, 1.0, size)


def lobe_albedo_table(lobe: Lobe, size: int = ALBEDO_SIZE) -> np.ndarray:
    """A_k(φo, cos θo) of the unscaled lobe in red, green and blue, (ALBEDO_PHIS, size, 3):
    computed at every view azimuth if the lobe is anisotropic (averaging them lost a factor
    of up to 10: Lafortune's Cx ≠ Cy lobe was 90–104 % off), else once."""
    from brdflab.material.albedo import lobe_albedo_channels

    cos_o = np.clip(albedo_cosines(size), MIN_COS, MAX_COS)
    sin_o = np.sqrt(1.0 - cos_o**2)
    isotropic = lobe.model.is_isotropic(lobe.params)
    phis = [0.0] if isotropic else np.arange(ALBEDO_PHIS) * (2.0 * np.pi / ALBEDO_PHIS)
    wo = np.concatenate([np.stack([sin_o * np.cos(p), sin_o * np.sin(p), cos_o], -1) for p in phis])
    a = np.broadcast_to(lobe_albedo_channels(lobe, wo, 3), (len(wo), 3)).reshape(len(phis), size, 3)
    return np.ascontiguousarray(np.broadcast_to(a, (ALBEDO_PHIS, size, 3)))


def albedo_at(table: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """A table's albedo (pixels, 3) at local views wo (pixels, 3): linear in cos θo and,
    periodically, in φo (the shader's lookup)."""
    size = table.shape[1]
    x = np.clip(wo[:, 2], 0.0, 1.0) * (size - 1)
    i0 = np.minimum(x.astype(int), size - 2)
    fx = (x - i0)[:, None]
    y = (np.arctan2(wo[:, 1], wo[:, 0]) / (2.0 * np.pi) % 1.0) * ALBEDO_PHIS
    j0 = np.minimum(y.astype(int), ALBEDO_PHIS - 1)
    fy = (y - j0)[:, None]
    j1 = (j0 + 1) % ALBEDO_PHIS
    at_cos = table[:, i0] * (1 - fx) + table[:, i0 + 1] * fx  # (ALBEDO_PHIS, pixels, 3)
    pixels = np.arange(len(wo))
    return at_cos[j0, pixels] * (1 - fy) + at_cos[j1, pixels] * fy


def tilt_taps(tilt: tuple[float, float], count: int = TAPS) -> tuple[tuple[float, float, float], ...]:
    """Normals spread as a Gaussian of RMS slopes `tilt` (one of them 0): `count` of them at
    its quantiles (k + ½)/count, equally weighted; the normal itself if there is no spread."""
    if max(tilt) <= 0.0:
        return ((0.0, 0.0, 1.0),)
    from statistics import NormalDist

    quantiles = [NormalDist().inv_cdf((k + 0.5) / count) for k in range(count)]
    return tuple((tilt[0] * q, tilt[1] * q, 1.0 / count) for q in quantiles)


def lobe_split(lobe: Lobe) -> LobeSplit:
    rule = lobe.model.split_sum(lobe.params)
    if rule.kind == "diffuse":
        return LobeSplit(lobe_albedo_table(lobe), (0, 0, 0.0), (0.0, 0.0, 1.0), 1.0)
    return LobeSplit(lobe_albedo_table(lobe), layer_blend(rule.kernel, rule.roughness), rule.axis,
                     float(rule.diffuse_share), dominant_weight(rule.roughness), tilt_taps(rule.tilt),
                     view_mixture(lobe, rule))


def lookup_direction(split: LobeSplit, tap: tuple[float, float, float], wo: np.ndarray) -> np.ndarray:
    """Local direction (pixels, 3) a lobe's lookup `tap` reads at views wo (pixels, 3): the
    lobe's axis ∘ wo (a tilted tap: wo mirrored about its normal), pulled toward that normal."""
    normal = unit(np.array([-tap[0], -tap[1], 1.0]))
    if tap[:2] == (0.0, 0.0):
        axis = unit(np.asarray(split.axis) * wo)
    else:
        axis = unit(2.0 * (wo @ normal)[:, None] * normal - wo)
    return unit(split.toward_axis * axis + (1.0 - split.toward_axis) * normal)


@lru_cache(maxsize=256)
def _cached_split(model: str, params: tuple) -> LobeSplit:
    return lobe_split(Lobe.create(model, [1.0], **dict(params)))


def material_split(material: AnalyticMaterial) -> list[LobeSplit]:
    """Every lobe's split (cached per model and parameters: a GUI slider redraws cheaply)."""
    return [_cached_split(l.model.name, tuple(sorted((k, float(v)) for k, v in l.params.items())))
            for l in material.lobes]


def unit(v: np.ndarray) -> np.ndarray:
    """v normalised; +Z where it is (nearly) zero, as the shader's stable_axis."""
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(length > 1e-9, v / np.maximum(length, 1e-300), np.array([0.0, 0.0, 1.0]))


def sample_latlong(layer: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Bilinear lookup of a lat-long layer at world directions d (..., 3), as GL's LINEAR
    filter with u repeating and v clamped (texel centres at (i + ½)/size)."""
    h, w = layer.shape[:2]
    u, v = direction_to_uv(d)
    x = u * w - 0.5
    y = np.clip(v * h - 0.5, 0.0, h - 1.0)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    x0, x1 = x0 % w, (x0 + 1) % w
    y1 = np.minimum(y0 + 1, h - 1)
    top = layer[y0, x0] * (1 - fx) + layer[y0, x1] * fx
    bottom = layer[y1, x0] * (1 - fx) + layer[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def mixture_lookups(mixture: np.ndarray, n: np.ndarray, t: np.ndarray, b: np.ndarray,
                    wo: np.ndarray, nearest: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A fitted lobe's lookups at each pixel: stack layers (pixels, 2·LOOKUPS), world directions
    (pixels, 2·LOOKUPS, 3) and weights: the lookups of the two view cosines around each pixel's,
    each weighted by its row's share of the linear blend and turned by the pixel's view angle
    less the row's (the lobe moves with the view between rows; the shader's loop). `nearest`:
    the nearer row's LOOKUPS alone, at full weight (MIS's control: half the kernels a sample)."""
    x = np.clip(wo[:, 2], 0.0, 1.0) * (COSINES - 1)
    theta = np.arccos(np.clip(wo[:, 2], 0.0, 1.0))
    i0 = np.minimum(x.astype(int), COSINES - 2)
    tangent = np.hypot(wo[:, 0], wo[:, 1])[:, None]  # the view's projection on the surface (t at normal view), world
    toward = np.where(tangent > 1e-7, wo[:, :2] / np.maximum(tangent, 1e-300), np.array([1.0, 0.0]))
    toward_view = toward[:, :1] * t + toward[:, 1:2] * b
    layers, directions, weights = [], [], []
    rows = [(i0 + (x - i0 >= 0.5), np.ones_like(x))] if nearest else [(i0, 1.0 - (x - i0)), (i0 + 1, x - i0)]
    for row, share in rows:
        psi, layer, weight = np.moveaxis(mixture[row], -1, 0)  # each (pixels, LOOKUPS)
        psi = psi + (theta - ROW_ANGLES[row])[:, None]
        directions.append(mixture_directions(psi, n[:, None], toward_view[:, None]))
        layers.append(layer.astype(int))
        weights.append(share[:, None] * weight)
    return np.concatenate(layers, 1), np.concatenate(directions, 1), np.concatenate(weights, 1)


def mixture_light(mixture: np.ndarray, stack, n: np.ndarray, t: np.ndarray, b: np.ndarray,
                  wo: np.ndarray) -> np.ndarray:
    """A fitted lobe's prefiltered radiance (pixels, 3): its lookups (`mixture_lookups`) read
    from the stack."""
    layer, d, weight = mixture_lookups(mixture, n, t, b, wo)
    light = np.zeros((len(wo), 3))
    for k in np.unique(layer[weight > 0.0]):
        at = weight * (layer == k)
        pixels, lookups = np.nonzero(at)
        np.add.at(light, pixels, at[pixels, lookups][:, None]  # a pixel may read a layer more than once
                  * sample_latlong(stack.layers[k], d[pixels, lookups]))
    return light


def diffuse_coefficient(splits: list, material: AnalyticMaterial, wo: np.ndarray) -> np.ndarray:
    """(pixels, 3): what the material's diffuse shares make of the irradiance, Σ scale × albedo(wo)
    × diffuse share / π over its lobes."""
    return sum((rgb * albedo_at(split.albedo, wo) * split.diffuse_share / np.pi
                for split, rgb in zip(splits, material.rgb_scales())), np.zeros((len(wo), 3)))


def lights_term(lit, stack, frames, diffuse: np.ndarray) -> np.ndarray:
    """(pixels, 3): the stack's lights, the material `lit` evaluated at each. Where they are blocks
    of texels (`prefilter.lit_in_blocks`) the diffuse shares (`diffuse`) are lit by the excess's own
    irradiance instead, exact as the irradiance layer is, and the lights by the material less them."""
    from brdflab.lighting.reference_view import by_texel_centres

    n, t, b = frames
    wo = np.stack([t[:, 2], b[:, 2], n[:, 2]], -1)
    directions, power = stack.light_directions.astype(float), stack.light_power.astype(float)
    colour = by_texel_centres(lit, directions, power, (t, b, n), wo)
    if stack.blocks:
        colour += diffuse * (sample_latlong(stack.excess_irradiance(), n) - np.maximum(n @ directions.T, 0.0) @ power)
    return colour


def prefiltered_image(material: AnalyticMaterial, env: EnvironmentMap, width: int, height: int,
                      stack: PrefilteredStack | None = None) -> np.ndarray:
    """The prefiltered mode's image in the reference view, computed in NumPy."""
    from brdflab.lighting.reference_view import sphere_view

    view = sphere_view(width, height)
    frames = (view.normal[view.inside], view.tangent[view.inside], view.bitangent[view.inside])
    out = np.zeros((height, width, 3))
    out[view.inside] = prefiltered_pixels(material, prefiltered_stack(env) if stack is None else stack, frames)
    return out


def prefiltered_pixels(material: AnalyticMaterial, stack: PrefilteredStack, frames, lit=None) -> np.ndarray:
    """The prefiltered mode's RGB (pixels, 3) at reference-view pixels whose frames are
    (normal, tangent, bitangent), each (pixels, 3): the split sum of the stack's dimmed map
    plus the stack's lights, evaluated with `lit` (the material itself unless given: a
    measured source, whose table the renderer evaluates at the lights)."""
    n, t, b = frames
    wo = np.stack([t[:, 2], b[:, 2], n[:, 2]], -1)  # wo = +Z (world) in each pixel's frame
    irradiance = sample_latlong(stack.irradiance(), n)
    splits = material_split(material)
    colour = lights_term(material if lit is None else lit, stack, frames, diffuse_coefficient(splits, material, wo))
    for split, rgb in zip(splits, material.rgb_scales()):
        albedo = albedo_at(split.albedo, wo)
        light = split.diffuse_share * irradiance / np.pi
        if split.mixture is not None:
            light = light + mixture_light(split.mixture, stack, n, t, b, wo)
        elif split.diffuse_share < 1.0:
            lo, hi, w = split.layers
            for tap in split.taps:
                local = lookup_direction(split, tap, wo)
                d = local[:, :1] * t + local[:, 1:2] * b + local[:, 2:] * n
                glossy = (1 - w) * sample_latlong(stack.layers[lo], d) + w * sample_latlong(stack.layers[hi], d)
                light = light + (1.0 - split.diffuse_share) * tap[2] * glossy
        colour += rgb * albedo * light
    return colour
