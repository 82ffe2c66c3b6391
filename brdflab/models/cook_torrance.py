"""Cook–Torrance microfacet lobes: Beckmann with V-cavity masking, and GGX with Smith masking.

A fitting pass evaluates a lobe once per perturbed parameter at the same directions: the terms
that do not change (the masking and Fresnel's (1 − o·h)⁵ always, D·G when only F0 moves) are
`shared_term`s, computed once per pass by the same arithmetic, so every value is what a lone
evaluation gives, bit for bit."""

import numpy as np

from brdflab.geometry.sampling import beckmann_d, beckmann_half_vector, ggx_d, ggx_visible_half_vector, half_vector_pdf, reflect
from brdflab.geometry.vec import TINY, dot, half_vector, schlick_of_weight, schlick_weight, shared_term
from brdflab.models.base import LobeModel, Parameter, SplitSum
from brdflab.models.registry import register

_STARTS = tuple({"m": m, "F0": f} for m in (0.02, 0.08, 0.25, 0.5) for f in (0.05, 0.8))
_PARAMS = (
    Parameter("m", 0.2, 0.001, 1.0, "1", "RMS microfacet slope (Beckmann m, GGX α)", log=True),
    Parameter("F0", 0.05, 0.0, 1.0, "1", "Fresnel reflectance at normal incidence"),
)


def _specular(wi, wo, h, dg, f0):
    """D·G · F(wo·h) / (4 cos θi cos θo), the Fresnel factor's (1 − wo·h)⁵ and the
    denominator shared by every evaluation at these directions."""
    fresnel = schlick_of_weight(f0, shared_term(wi, wo, ("(1 − o·h)⁵",), lambda: schlick_weight(dot(wo, h))))
    return dg * fresnel / shared_term(wi, wo, ("4 cos θi cos θo",), lambda: 4.0 * wi[..., 2] * wo[..., 2])


@register
class CookTorrance(LobeModel):
    name = "CookTorrance"
    parameters = _PARAMS
    summary = "D·G·F(wo·h)/(4 cosθi cosθo), Beckmann D, Cook–Torrance G."
    reference = "Cook & Torrance 1982; BRDFLab; Schwenk 2011 §3.5"
    starts = _STARTS
    sampling = "half vector from D(h) cos θh (Beckmann)"
    split_sum_rule = "mirror, Beckmann α = m"

    def split_sum(self, params):
        return SplitSum("mirror", float(min(1.0, params["m"])))

    def _value(self, wi, wo, p):
        h = half_vector(wi, wo)
        m = p["m"]

        def masking():
            woh, hz = dot(wo, h), h[..., 2]
            return np.minimum(1.0, np.minimum(2.0 * hz * wo[..., 2] / woh, 2.0 * hz * wi[..., 2] / woh))

        dg = shared_term(wi, wo, ("Beckmann D·G", m),
                         lambda: beckmann_d(h, m, m) * shared_term(wi, wo, ("V-cavity G",), masking))
        return _specular(wi, wo, h, dg, p["F0"])

    def _sample(self, wo, u, p):
        return reflect(wo, beckmann_half_vector(p["m"], p["m"], u))

    def _pdf(self, wi, wo, p):
        return half_vector_pdf(wi, wo, lambda h: beckmann_d(h, p["m"], p["m"]) * h[..., 2])


def tan2_of(cos_theta):
    """tan² θ from cos θ (cos² floored at 1e-12)."""
    c2 = np.maximum(cos_theta * cos_theta, 1e-12)
    return (1.0 - c2) / c2


def smith_ggx_g1(cos_theta, alpha):
    """Smith's masking of GGX for one direction."""
    return smith_ggx_g1_of_tan2(tan2_of(cos_theta), alpha)


def smith_ggx_g1_of_tan2(tan2, alpha):
    """Smith's masking of GGX from the direction's tan² θ (`tan2_of`), where a caller has it."""
    return 2.0 / (1.0 + np.sqrt(1.0 + alpha * alpha * tan2))


@register
class CookTorranceGGX(LobeModel):
    name = "CookTorranceGGX"
    parameters = _PARAMS
    summary = "D·G·F(wo·h)/(4 cosθi cosθo) with the GGX D and separable Smith G."
    reference = "Walter et al. 2007 (microfacet models for refraction)"
    starts = _STARTS
    sampling = "visible normals of GGX (Heitz 2018)"
    split_sum_rule = "mirror, GGX α = m (Karis 2013 exactly)"

    def split_sum(self, params):
        return SplitSum("mirror", float(min(1.0, params["m"])), kernel="ggx")

    def _value(self, wi, wo, p):
        h = half_vector(wi, wo)
        a = p["m"]

        def dg():
            ti = shared_term(wi, wo, ("tan² θi",), lambda: tan2_of(wi[..., 2]))
            to = shared_term(wi, wo, ("tan² θo",), lambda: tan2_of(wo[..., 2]))
            return ggx_d(h, a) * (smith_ggx_g1_of_tan2(ti, a) * smith_ggx_g1_of_tan2(to, a))

        return _specular(wi, wo, h, shared_term(wi, wo, ("GGX D·G", a), dg), p["F0"])

    def _sample(self, wo, u, p):
        return reflect(wo, ggx_visible_half_vector(wo, p["m"], u))

    def _pdf(self, wi, wo, p):
        cos_o = np.maximum(wo[..., 2], TINY)
        g1 = smith_ggx_g1(cos_o, p["m"])
        return half_vector_pdf(wi, wo, lambda h: ggx_d(h, p["m"]) * g1 * np.maximum(dot(wo, h), 0.0) / cos_o)
