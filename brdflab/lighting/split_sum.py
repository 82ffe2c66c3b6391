"""A material in prefiltered lighting: per lobe, the second factor of the split sum and
where the first is looked up.

∫ L(ω) f_k(ω, wo) cos θ dω ≈ A_k(cos θo) · L̄_k, where A_k is the lobe's directional albedo
(tabulated over cos θo by importance sampling, `material/albedo.lobe_albedo`: right for every
model at every view, not only GGX's) and L̄_k the prefiltered radiance: the irradiance / π for
diffuse lobes, else the stack at the lobe's direction (axis ∘ wo) and equivalent roughness
(`LobeModel.split_sum`). What is approximated: the lobe's shape is the one it has at normal
view around that direction (n = v = r; the direction is pulled toward n for rough lobes, as
Frostbite does, Lagarde & de Rousiers 2014 — the cosine and the horizon pull the real lobe's
light there), so the stretching and off-specular shift of real
lobes at grazing views, and the horizon's clipping of the lobe, are lost; the lobe's shape
is a Beckmann or GGX kernel of matched width; anisotropic lobes become isotropic ones of the
same solid angle. Energy is right at every view (the albedo factor); where it goes is not.

`prefiltered_image` is the NumPy twin of the renderer's shader (shaders/prefiltered.glsl) in
the reference view, so the GPU image can be checked against an independent computation.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from brdflab.lighting.envmap import EnvironmentMap, direction_to_uv
from brdflab.lighting.prefilter import PrefilteredStack, layer_blend, prefiltered_stack
from brdflab.material.analytic import AnalyticMaterial, Lobe

ALBEDO_SIZE = 32  # cos θo = 0, 1/31, …, 1
ANISOTROPIC_PHIS = 4  # view azimuths averaged for anisotropic lobes
MIN_COS = 0.01  # the albedo at cos θo = 0 is taken at this cosine
# and at cos θo = 1 at this one (0.08° off the normal): some models are 0/0 exactly there (BRDF
# Explorer's Oren–Nayar normalises V − N (V·N)), and one texel would darken the whole centre
MAX_COS = 1.0 - 1e-6


@dataclass(frozen=True)
class LobeSplit:
    """One lobe's prefiltered lighting: its albedo table, the two stack layers blended for
    its roughness, its lookup axis and the share of its albedo lit by the irradiance."""

    albedo: np.ndarray  # (ALBEDO_SIZE, 3) over cos θo = i / (ALBEDO_SIZE − 1), per colour (a colour lobe's differ)
    layers: tuple[int, int, float]
    axis: tuple[float, float, float]
    diffuse_share: float
    toward_axis: float = 1.0  # the lookup direction: normalize(mix(n, axis ∘ wo, toward_axis))


def dominant_weight(alpha: float) -> float:
    """How far the lookup goes from n toward the lobe's axis: (1 − α)(√(1 − α) + α), the
    'specular dominant direction' of Lagarde & de Rousiers 2014 (Frostbite), fitted for GGX."""
    a = float(np.clip(alpha, 0.0, 1.0))
    return (1.0 - a) * (np.sqrt(1.0 - a) + a)


def albedo_cosines(size: int = ALBEDO_SIZE) -> np.ndarray:
    return np.linspace(0.0, 1.0, size)


def lobe_albedo_table(lobe: Lobe, size: int = ALBEDO_SIZE) -> np.ndarray:
    """A_k(cos θo) of the unscaled lobe in red, green and blue, (size, 3), averaged over view
    azimuths if it is anisotropic."""
    from brdflab.material.albedo import lobe_albedo_channels

    cos_o = np.clip(albedo_cosines(size), MIN_COS, MAX_COS)
    sin_o = np.sqrt(1.0 - cos_o**2)
    phis = [0.0] if lobe.model.is_isotropic(lobe.params) else np.arange(ANISOTROPIC_PHIS) * (np.pi / ANISOTROPIC_PHIS)
    wo = np.concatenate([np.stack([sin_o * np.cos(p), sin_o * np.sin(p), cos_o], -1) for p in phis])
    a = lobe_albedo_channels(lobe, wo, 3)
    return np.broadcast_to(a, (len(wo), 3)).reshape(len(phis), size, 3).mean(axis=0)


def lobe_split(lobe: Lobe) -> LobeSplit:
    rule = lobe.model.split_sum(lobe.params)
    if rule.kind == "diffuse":
        return LobeSplit(lobe_albedo_table(lobe), (0, 0, 0.0), (0.0, 0.0, 1.0), 1.0)
    return LobeSplit(lobe_albedo_table(lobe), layer_blend(rule.kernel, rule.roughness), rule.axis,
                     float(rule.diffuse_share), dominant_weight(rule.roughness))


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


def prefiltered_image(material: AnalyticMaterial, env: EnvironmentMap, width: int, height: int,
                      stack: PrefilteredStack | None = None) -> np.ndarray:
    """The prefiltered mode's image in the reference view, computed in NumPy."""
    from brdflab.lighting.reference_view import sphere_view

    view = sphere_view(width, height)
    frames = (view.normal[view.inside], view.tangent[view.inside], view.bitangent[view.inside])
    out = np.zeros((height, width, 3))
    out[view.inside] = prefiltered_pixels(material, prefiltered_stack(env) if stack is None else stack, frames)
    return out


def prefiltered_pixels(material: AnalyticMaterial, stack: PrefilteredStack, frames) -> np.ndarray:
    """The prefiltered mode's RGB (pixels, 3) at reference-view pixels whose frames are
    (normal, tangent, bitangent), each (pixels, 3)."""
    n, t, b = frames
    wo = np.stack([t[:, 2], b[:, 2], n[:, 2]], -1)  # wo = +Z (world) in each pixel's frame
    irradiance = sample_latlong(stack.irradiance(), n)
    colour = np.zeros((len(n), 3))
    cosines = albedo_cosines()
    for split, rgb in zip(material_split(material), material.rgb_scales()):
        x = np.clip(wo[:, 2], 0.0, 1.0)
        albedo = np.stack([np.interp(x, cosines, split.albedo[:, c]) for c in range(3)], -1)
        light = split.diffuse_share * irradiance / np.pi
        if split.diffuse_share < 1.0:
            local = unit(split.toward_axis * unit(np.asarray(split.axis) * wo)
                         + (1.0 - split.toward_axis) * np.array([0.0, 0.0, 1.0]))
            d = local[:, :1] * t + local[:, 1:2] * b + local[:, 2:] * n
            lo, hi, w = split.layers
            glossy = (1 - w) * sample_latlong(stack.layers[lo], d) + w * sample_latlong(stack.layers[hi], d)
            light = light + (1.0 - split.diffuse_share) * glossy
        colour += rgb * albedo * light
    return colour
