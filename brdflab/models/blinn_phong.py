"""Normalised Blinn–Phong: (n+2)/(2π) cos^n θh."""

from brdflab.geometry.sampling import cosine_power_around, cosine_power_pdf, half_vector_pdf, reflect
from brdflab.geometry.vec import half_vector
from brdflab.models.base import LobeModel, Parameter, SplitSum, blinn_roughness, normalised_phong_factor
from brdflab.models.registry import register
import numpy as np

_Z = np.array([0.0, 0.0, 1.0])


@register
class BlinnPhong(LobeModel):
    name = "BlinnPhong"
    parameters = (Parameter("Exponent", 20.0, 0.0, 100000.0, "1", "specular exponent n", log=True),)
    summary = "Blinn–Phong half-vector cosine lobe, (n+2)/(2π) cos^n θh."
    reference = "Blinn 1977; BRDFLab; Schwenk 2011 §3.3.1"
    starts = tuple({"Exponent": e} for e in (10.0, 100.0, 1000.0, 10000.0))
    sampling = "half vector from (n+1)/(2π) cos^n θh, reflected"
    split_sum_rule = "mirror, Beckmann α = √(2/(n+2))"

    def split_sum(self, params):
        return SplitSum("mirror", blinn_roughness(params["Exponent"]))

    def _value(self, wi, wo, p):
        h = half_vector(wi, wo)
        return normalised_phong_factor(p["Exponent"]) * np.maximum(h[..., 2], 0.0) ** p["Exponent"]

    def _sample(self, wo, u, p):
        h = cosine_power_around(np.broadcast_to(_Z, wo.shape), p["Exponent"], u)
        return reflect(wo, h)

    def _pdf(self, wi, wo, p):
        return half_vector_pdf(wi, wo, lambda h: cosine_power_pdf(h, _Z, p["Exponent"]))
