"""Cook–Torrance microfacet lobes: Beckmann with V-cavity masking, and GGX with Smith masking."""

import numpy as np

from brdflab.geometry.sampling import beckmann_d, beckmann_half_vector, ggx_d, ggx_visible_half_vector, half_vector_pdf, reflect
from brdflab.geometry.vec import TINY, dot, half_vector, schlick
from brdflab.models.base import LobeModel, Parameter, SplitSum
from brdflab.models.registry import register

_STARTS = tuple({"m": m, "F0": f} for m in (0.02, 0.08, 0.25, 0.5) for f in (0.05, 0.8))
_PARAMS = (
    Parameter("m", 0.2, 0.001, 1.0, "1", "RMS microfacet slope (Beckmann m, GGX α)", log=True),
    Parameter("F0", 0.05, 0.0, 1.0, "1", "Fresnel reflectance at normal incidence"),
)


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
        woh = dot(wo, h)
        hz = h[..., 2]
        g = np.minimum(1.0, np.minimum(2.0 * hz * wo[..., 2] / woh, 2.0 * hz * wi[..., 2] / woh))
        d = beckmann_d(h, p["m"], p["m"])
        return d * g * schlick(p["F0"], woh) / (4.0 * wi[..., 2] * wo[..., 2])

    def _sample(self, wo, u, p):
        return reflect(wo, beckmann_half_vector(p["m"], p["m"], u))

    def _pdf(self, wi, wo, p):
        return half_vector_pdf(wi, wo, lambda h: beckmann_d(h, p["m"], p["m"]) * h[..., 2])


def smith_ggx_g1(cos_theta, alpha):
    c2 = np.maximum(cos_theta * cos_theta, 1e-12)
    tan2 = (1.0 - c2) / c2
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
        g = smith_ggx_g1(wi[..., 2], a) * smith_ggx_g1(wo[..., 2], a)
        return ggx_d(h, a) * g * schlick(p["F0"], dot(wo, h)) / (4.0 * wi[..., 2] * wo[..., 2])

    def _sample(self, wo, u, p):
        return reflect(wo, ggx_visible_half_vector(wo, p["m"], u))

    def _pdf(self, wi, wo, p):
        cos_o = np.maximum(wo[..., 2], TINY)
        g1 = smith_ggx_g1(cos_o, p["m"])
        return half_vector_pdf(wi, wo, lambda h: ggx_d(h, p["m"]) * g1 * np.maximum(dot(wo, h), 0.0) / cos_o)
