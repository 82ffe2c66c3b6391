"""The survey's own model (Schwenk 2011 §4): specular term driven by smoothness and metalness.

Its diffuse term C(1 − s k) is a Lambertian lobe; this lobe is the specular term
Js = s²/(wo·h) · F(wo·h, F0) · cos θh^e with e = 2/(1 + 1/255 − s) and
F0 = 1 − m + m·tint, where tint is the material colour over its luminance.
"""

import numpy as np

from brdflab.geometry.sampling import cosine_power_around, cosine_power_pdf, half_vector_pdf, reflect
from brdflab.geometry.vec import dot, half_vector, schlick
from brdflab.models.base import LobeModel, Parameter, SplitSum, blinn_roughness
from brdflab.models.registry import register

_Z = np.array([0.0, 0.0, 1.0])


def schwenk_exponent(smoothness):
    return 2.0 / (1.0 + 1.0 / 255.0 - smoothness)


@register
class Schwenk(LobeModel):
    name = "Schwenk"
    parameters = (
        Parameter("smoothness", 0.5, 0.0, 1.0, "1", "s: size and intensity of the highlight"),
        Parameter("metalness", 0.0, 0.0, 1.0, "1", "m: white (0) to tinted (1) highlight"),
        Parameter("tint", 1.0, 0.0, 10.0, "1", "C/lum(C) for this lobe's channel"),
    )
    starts = tuple({"smoothness": s, "metalness": m} for s in (0.2, 0.5, 0.8, 0.95) for m in (0.0, 0.7))
    summary = "s²/(wo·h) F(wo·h, 1−m+m·tint) cos θh^(2/(1.00392−s)) (Schwenk 2011 eqs. 50–52)."
    reference = "Schwenk 2011 §4.2"
    sampling = "half vector from (e+1)/(2π) cos^e θh, reflected"
    split_sum_rule = "mirror, Beckmann α = √(2/(e+2)), e = 2/(1.00392 − s)"

    def split_sum(self, params):
        return SplitSum("mirror", blinn_roughness(schwenk_exponent(params["smoothness"])))

    def _value(self, wi, wo, p):
        s = p["smoothness"]
        h = half_vector(wi, wo)
        woh = dot(wo, h)
        f0 = 1.0 - p["metalness"] + p["metalness"] * p["tint"]
        return s * s / woh * schlick(f0, woh) * np.maximum(h[..., 2], 0.0) ** schwenk_exponent(s)

    def _sample(self, wo, u, p):
        h = cosine_power_around(np.broadcast_to(_Z, wo.shape), schwenk_exponent(p["smoothness"]), u)
        return reflect(wo, h)

    def _pdf(self, wi, wo, p):
        e = schwenk_exponent(p["smoothness"])
        return half_vector_pdf(wi, wo, lambda h: cosine_power_pdf(h, _Z, e))
