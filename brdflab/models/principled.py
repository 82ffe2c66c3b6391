"""Disney's principled BRDF (reflection only), as Mitsuba 3's `principled` plugin evaluates it.

| parameter | default | range | meaning |
|---|---|---|---|
| base_color_r/g/b | 0.5 | 0–1 | base colour (diffuse albedo; a metal's F0) |
| metallic | 0 | 0–1 | blend of dielectric and metal |
| subsurface | 0 | 0–1 | Hanrahan–Krueger "flatness" blend of the diffuse (Mitsuba's `flatness`) |
| specular | 0.5 | 0–1 (fits: from 1e-4) | dielectric F0 = 0.08 · specular, i.e. η = 2 / (1 − √(0.08 specular)) − 1 |
| specular_tint | 0 | 0–1 | share of the dielectric reflection tinted towards the base colour's hue |
| roughness | 0.5 | 0–1 | GGX α = max(0.001, roughness²) |
| anisotropic | 0 | 0–1 | αx = α / √(1 − 0.9 a), αy = α √(1 − 0.9 a) |
| sheen, sheen_tint | 0 | 0–1 | grazing sheen and its tint |
| clearcoat, clearcoat_gloss | 0 | 0–1 | a second, GTR1 specular lobe with F0 = 0.04 and α from 0.1 to 0.001 |

Burley 2012 (Physically Based Shading at Disney, §5.3 and its BRDF Explorer file) as
Mitsuba 3 implements it with the 2015 course notes' changes; where they differ from the
2012 file, this model follows Mitsuba (so that an exported material renders the same there):

- the untinted dielectric part of the main lobe uses the exact dielectric Fresnel at
  η(specular), not Schlick; the metallic and tinted parts use Schlick;
- the diffuse is written as Lambert × (1 − F/2)(1 − F/2) plus a retro-reflection term,
  which is algebraically the 2012 Fd (the test checks it);
- the clearcoat lobe is 0.25 · clearcoat · F · D · G without the 1/(4 cos θi cos θo) that
  the 2012 file's `smithG_GGX` carries (at normal view, 4× weaker than Burley's).

The lobe is a colour lobe: `evaluate_rgb` gives red, green and blue; its scaling factors are
held at 1 by a fit (the base colour carries the colour).
"""

from __future__ import annotations

import numpy as np

from brdflab.geometry.sampling import (
    INV_PI,
    cosine_hemisphere,
    cosine_hemisphere_pdf,
    half_vector_pdf,
    reflect,
)
from brdflab.geometry.vec import TINY, dot, half_vector, schlick_weight, shared_term
from brdflab.models.base import LUMINANCE, LobeModel, Parameter, anisotropic_split
from brdflab.models.registry import register

# Mitsuba's luminance of linear sRGB (mitsuba/core/spectrum.h), used for the tints
TINT_LUMINANCE = np.array([0.212671, 0.715160, 0.072169])
CHANNELS = ("r", "g", "b")
SHAPE = ("roughness", "anisotropic", "specular", "clearcoat_gloss", "subsurface")  # what `_terms` depend on
# Mitsuba's `specular` = 0 is η = 1, for which it drops its whole main lobe (the metal and the
# tint too) while the lab's value runs on continuously: fits end at this at least, and the
# exports write at least this (tests/test_principled.py measures both against Mitsuba)
MIN_SPECULAR = 1e-4


def _unit(name: str, default: float, doc: str, fit_lower: float | None = None) -> Parameter:
    return Parameter(name, default, 0.0, 1.0, "1", doc, fit_lower=fit_lower)


PARAMETERS = (
    *(Parameter(f"base_color_{c}", 0.5, 0.0, 1.0, "1", f"base colour, {c}", kind="colour") for c in CHANNELS),
    _unit("metallic", 0.0, "0 dielectric, 1 metal"),
    _unit("subsurface", 0.0, "flattens the diffuse (Mitsuba's flatness)"),
    _unit("specular", 0.5, "dielectric F0 = 0.08 specular", fit_lower=MIN_SPECULAR),
    _unit("specular_tint", 0.0, "tints the dielectric reflection towards the base colour"),
    _unit("roughness", 0.5, "GGX α = roughness²"),
    _unit("anisotropic", 0.0, "0 isotropic; stretches α along x"),
    _unit("sheen", 0.0, "grazing sheen"),
    _unit("sheen_tint", 0.0, "tints the sheen towards the base colour"),
    _unit("clearcoat", 0.0, "weight of the clear-coat lobe"),
    _unit("clearcoat_gloss", 0.0, "0: clear-coat α = 0.1, 1: α = 0.001"),
)


def specular_eta(specular):
    """The relative index of refraction whose normal-incidence reflectance is 0.08 · specular."""
    return 2.0 / (1.0 - np.sqrt(0.08 * np.asarray(specular, float))) - 1.0


def dielectric_fresnel(cos_i, eta):
    """Unpolarised Fresnel reflectance of a dielectric interface (η > 1, light from outside)."""
    cos_i = np.clip(cos_i, 0.0, 1.0)
    sin_t2 = (1.0 - cos_i * cos_i) / (eta * eta)
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin_t2))
    rs = (cos_i - eta * cos_t) / np.maximum(cos_i + eta * cos_t, TINY)
    rp = (eta * cos_i - cos_t) / np.maximum(eta * cos_i + cos_t, TINY)
    return np.where(sin_t2 >= 1.0, 1.0, 0.5 * (rs * rs + rp * rp))


def alphas(roughness, anisotropic):
    """GGX (αx, αy) of the main lobe (Mitsuba's calc_dist_params)."""
    r2 = np.asarray(roughness, float) ** 2
    aspect = np.sqrt(1.0 - 0.9 * np.asarray(anisotropic, float))
    return np.maximum(0.001, r2 / aspect), np.maximum(0.001, r2 * aspect)


def ggx_aniso_d(h, ax, ay):
    """Anisotropic GGX distribution, ∫ D cos θh dω = 1."""
    e = (h[..., 0] / ax) ** 2 + (h[..., 1] / ay) ** 2 + h[..., 2] ** 2
    return np.where(h[..., 2] > 0.0, 1.0 / (np.pi * ax * ay * np.maximum(e * e, TINY)), 0.0)


def ggx_aniso_g1(v, ax, ay):
    """Smith's masking for the anisotropic GGX distribution."""
    z2 = np.maximum(v[..., 2] ** 2, TINY)
    t2 = ((ax * v[..., 0]) ** 2 + (ay * v[..., 1]) ** 2) / z2
    return 2.0 / (1.0 + np.sqrt(1.0 + t2))


def ggx_aniso_half_vector(ax, ay, u):
    """Half vectors with density D(h) cos θh for the anisotropic GGX distribution."""
    phase = 2.0 * np.pi * u[..., 1]
    phi = np.arctan2(np.asarray(ay, float) * np.sin(phase), np.asarray(ax, float) * np.cos(phase))
    c, s = np.cos(phi), np.sin(phi)
    a2 = 1.0 / (c * c / ax**2 + s * s / ay**2)
    tan2 = a2 * u[..., 0] / np.maximum(1.0 - u[..., 0], TINY)
    cos_t = 1.0 / np.sqrt(1.0 + tan2)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    return np.stack([sin_t * c, sin_t * s, cos_t], axis=-1)


def clearcoat_alpha(gloss):
    return 0.1 + (0.001 - 0.1) * np.asarray(gloss, float)


def gtr1_d(h, alpha):
    """Burley's GTR1 (Berry) distribution of the clear coat, ∫ D cos θh dω = 1."""
    a2 = alpha * alpha
    hz2 = h[..., 2] ** 2
    return np.where(h[..., 2] > 0.0, (a2 - 1.0) / (np.pi * np.log(a2) * (1.0 + (a2 - 1.0) * hz2)), 0.0)


def gtr1_half_vector(alpha, u):
    """Half vectors with density GTR1(h) cos θh."""
    a2 = np.asarray(alpha, float) ** 2
    cos2 = (1.0 - a2 ** (1.0 - u[..., 0])) / (1.0 - a2)
    cos_t = np.sqrt(np.clip(cos2, 0.0, 1.0))
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = 2.0 * np.pi * u[..., 1]
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)


def _zeroed(value: np.ndarray, above: np.ndarray) -> np.ndarray:
    """`value` where both directions are above the horizon and it is finite, else 0."""
    return np.where(above & np.isfinite(value), value, 0.0)


def base_color(p) -> np.ndarray:
    """The base colour, shape (..., 3)."""
    return np.stack(np.broadcast_arrays(*(np.asarray(p[f"base_color_{c}"], float) for c in CHANNELS)), axis=-1)


def tint(colour: np.ndarray) -> np.ndarray:
    """The base colour's hue at luminance 1 (white where it is black)."""
    lum = colour @ TINT_LUMINANCE
    return np.where(lum[..., None] > 0.0, colour / np.where(lum > 0.0, lum, 1.0)[..., None], 1.0)


def lobe_probabilities(p) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How often `sample` draws the diffuse, clear-coat and main lobes (Mitsuba's rates:
    1 − metallic, clearcoat / 4 and 1)."""
    diffuse = 1.0 - np.asarray(p["metallic"], float)
    coat = 0.25 * np.asarray(p["clearcoat"], float)
    total = diffuse + coat + 1.0
    return diffuse / total, coat / total, 1.0 / total


@register
class Principled(LobeModel):
    name = "Principled"
    parameters = PARAMETERS
    isotropic = False
    colour = True
    scaled = False
    weights_on_bounds = True
    summary = ("Disney's principled BRDF (reflection): GGX specular with a dielectric/metal Fresnel, "
               "Burley diffuse with retro-reflection and flatness, sheen, GTR1 clear coat.")
    reference = "Burley 2012 (Physically Based Shading at Disney); Mitsuba 3 `principled` (Burley 2015 changes)"
    sampling = "mixture: cosine (diffuse), GGX half vector D(h) cos θh (main), GTR1 (clear coat)"
    split_sum_rule = ("mirror, GGX α = min(αx, αy) around normals spread along the longer axis; the diffuse share of the normal-view albedo, (1 − metallic) "
                      "× base luminance against the specular F0 + clear coat, is lit by the irradiance")
    starts = (
        {},
        {"metallic": 0.0, "roughness": 0.2, "specular": 0.5},
        {"metallic": 1.0, "roughness": 0.3},
        {"metallic": 0.0, "roughness": 0.8, "sheen": 1.0},
        {"metallic": 0.0, "roughness": 0.1, "clearcoat": 1.0, "clearcoat_gloss": 0.8},
    )

    def is_isotropic(self, params) -> bool:
        return float(params["anisotropic"]) == 0.0

    def split_sum(self, params):
        ax, ay = alphas(params["roughness"], params["anisotropic"])
        colour = base_color(params)
        lum = float(colour @ TINT_LUMINANCE)
        metallic = float(params["metallic"])
        diffuse = (1.0 - metallic) * lum
        f0 = (1.0 - metallic) * 0.08 * float(params["specular"]) + metallic * lum
        specular = f0 + 0.04 * 0.25 * float(params["clearcoat"])
        share = diffuse / (diffuse + specular) if diffuse + specular > 0.0 else 0.0
        return anisotropic_split(ax, ay, kernel="ggx", diffuse_share=float(share))

    def _value(self, wi, wo, p):
        return self._rgb(wi, wo, p) @ LUMINANCE

    def evaluate_rgb(self, wi, wo, params=None):
        wi = np.asarray(wi, float)
        wo = np.asarray(wo, float)
        p = self._with_defaults(params)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            return self._rgb(wi, wo, p)

    def _rgb(self, wi, wo, p):
        """f(wi, wo) in linear RGB, shape (..., 3): Mitsuba's principled `eval` / cos θo,
        written as six terms of the directions and the shape parameters (`_terms`) weighed
        per channel by the colour parameters (`_weights`)."""
        weights = self._weights(p)
        if weights.ndim == 2:
            stacked = lambda: np.stack(self._terms(wi, wo, p), axis=-1)
            return shared_term(wi, wo, ("principled terms", *(p[n] for n in SHAPE)), stacked) @ weights
        return sum(t[..., None] * weights[..., k, :] for k, t in enumerate(self._terms(wi, wo, p)))

    @staticmethod
    def _terms(wi, wo, p) -> list[np.ndarray]:
        """The six terms f is a per-channel weighted sum of: the main lobe D G / (4 cos θi cos θo)
        times the dielectric Fresnel, times 1 and times the Schlick weight (1 − cos θd)⁵; the
        clear coat; the diffuse / π; the Schlick weight alone (the sheen). Each depends on at
        most three parameters and is shared by the evaluations of one fitting pass that keep
        them (`vec.shared_term`): a pass perturbs twelve parameters, eight of them weights."""
        ci, co = wi[..., 2], wo[..., 2]
        h = half_vector(wi, wo)
        cos_d = shared_term(wi, wo, ("principled cos θd",), lambda: dot(wi, h))
        w_d = shared_term(wi, wo, ("principled schlick",), lambda: schlick_weight(cos_d))
        above = shared_term(wi, wo, ("principled above",), lambda: (ci > 0.0) & (co > 0.0))

        def term(name, names, compute):  # 0 below the horizon and where it is not finite
            return shared_term(wi, wo, (name, *(p[n] for n in names)), lambda: _zeroed(compute(), above))

        def main():
            ax, ay = alphas(p["roughness"], p["anisotropic"])
            return ggx_aniso_d(h, ax, ay) * ggx_aniso_g1(wi, ax, ay) * ggx_aniso_g1(wo, ax, ay) / (4.0 * ci * co)

        shape = ("roughness", "anisotropic")
        spec = term("principled main", shape, main)
        dielectric = term("principled dielectric", ("specular", *shape),
                          lambda: dielectric_fresnel(cos_d, specular_eta(p["specular"])) * spec)
        tinted = term("principled schlick main", shape, lambda: w_d * spec)

        def coat():
            g_cc = shared_term(wi, wo, ("principled coat G",),
                               lambda: ggx_aniso_g1(wi, 0.25, 0.25) * ggx_aniso_g1(wo, 0.25, 0.25))
            return (0.04 + 0.96 * w_d) * gtr1_d(h, clearcoat_alpha(p["clearcoat_gloss"])) * g_cc

        def diffuse():  # with retro-reflection, flattened by `subsurface`
            fo = shared_term(wi, wo, ("principled schlick o",), lambda: schlick_weight(co))
            fi = shared_term(wi, wo, ("principled schlick i",), lambda: schlick_weight(ci))
            rr = 2.0 * np.asarray(p["roughness"], float) * cos_d * cos_d
            lambert = (1.0 - 0.5 * fi) * (1.0 - 0.5 * fo)
            retro = rr * (fo + fi + fo * fi * (rr - 1.0))
            fss90 = 0.5 * rr
            fss = (1.0 + (fss90 - 1.0) * fo) * (1.0 + (fss90 - 1.0) * fi)
            flat = 1.25 * (fss * (1.0 / (ci + co) - 0.5) + 0.5)
            s = np.asarray(p["subsurface"], float)
            return INV_PI * ((1.0 - s) * (lambert + retro) + s * flat)

        return [dielectric, spec, tinted, term("principled coat", ("clearcoat_gloss",), coat),
                term("principled diffuse", ("roughness", "subsurface"), diffuse), term("principled sheen", (), lambda: w_d)]

    @staticmethod
    def _weights(p) -> np.ndarray:
        """Each term's weight per channel, shape (..., 6, 3) in `_terms`' order: the Fresnel
        (1 − m)(1 − t) F_dielectric + m F_metal + (1 − m) t F_tint with F_x = F0_x + (1 − F0_x) w
        split into what multiplies F_dielectric, 1 and w; the clear coat's 0.25 · clearcoat;
        the diffuse's (1 − m) · base; the sheen's sheen (1 − m) · its colour."""
        colour = base_color(p)
        col = lambda name: np.asarray(p[name], float)[..., None]
        metallic, st = col("metallic"), col("specular_tint")
        eta = specular_eta(p["specular"])
        r0 = np.asarray(((eta - 1.0) / (eta + 1.0)) ** 2, float)[..., None]
        tinted = tint(colour) * r0
        sheen_colour = 1.0 + col("sheen_tint") * (tint(colour) - 1.0)
        ones = np.ones_like(colour)
        weights = [(1.0 - metallic) * (1.0 - st) * ones,
                   metallic * colour + (1.0 - metallic) * st * tinted,
                   metallic * (1.0 - colour) + (1.0 - metallic) * st * (1.0 - tinted),
                   0.25 * col("clearcoat") * ones,
                   (1.0 - metallic) * colour,
                   col("sheen") * (1.0 - metallic) * sheen_colour]
        return np.stack(np.broadcast_arrays(*weights), axis=-2)

    def _sample(self, wo, u, p):
        pd, pc, ps = lobe_probabilities(p)
        u0 = u[..., 0]
        diffuse = u0 < pd
        coat = ~diffuse & (u0 < pd + pc)
        lo = np.where(diffuse, 0.0, np.where(coat, pd, pd + pc))
        width = np.where(diffuse, pd, np.where(coat, pc, ps))
        v = np.stack([np.clip((u0 - lo) / np.maximum(width, TINY), 0.0, 1.0 - 1e-12), u[..., 1]], axis=-1)
        ax, ay = alphas(p["roughness"], p["anisotropic"])
        main = reflect(wo, ggx_aniso_half_vector(ax, ay, v))
        cc = reflect(wo, gtr1_half_vector(clearcoat_alpha(p["clearcoat_gloss"]), v))
        return np.where(diffuse[..., None], cosine_hemisphere(v), np.where(coat[..., None], cc, main))

    def _pdf(self, wi, wo, p):
        pd, pc, ps = lobe_probabilities(p)
        ax, ay = alphas(p["roughness"], p["anisotropic"])
        a_cc = clearcoat_alpha(p["clearcoat_gloss"])
        main = half_vector_pdf(wi, wo, lambda h: ggx_aniso_d(h, ax, ay) * h[..., 2])
        cc = half_vector_pdf(wi, wo, lambda h: gtr1_d(h, a_cc) * h[..., 2])
        return pd * cosine_hemisphere_pdf(wi) + pc * cc + ps * main

