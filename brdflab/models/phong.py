"""Normalised (modified, reciprocal) Phong: (n+2)/(2π) cos^n α, α between wo and wi's mirror."""

import numpy as np

from brdflab.geometry.sampling import cosine_power_around, cosine_power_pdf
from brdflab.geometry.vec import dot, reflect_about_normal
from brdflab.models.base import LobeModel, Parameter, SplitSum, normalised_phong_factor, phong_roughness
from brdflab.models.registry import register


@register
class Phong(LobeModel):
    name = "Phong"
    parameters = (Parameter("Exponent", 20.0, 0.0, 100000.0, "1", "specular exponent n", log=True),)
    summary = "Energy-normalised Phong lobe around the mirror direction (Lewis 1994)."
    reference = "Phong 1975; Lafortune & Willems 1994; Schwenk 2011 §3.3.2"
    starts = tuple({"Exponent": e} for e in (10.0, 100.0, 1000.0, 10000.0))
    sampling = "cos^n lobe around the mirror direction of wo"
    split_sum_rule = "mirror, its own cos^n kernel (phong), indexed by α = √(2/(4n+2))"

    def split_sum(self, params):
        return SplitSum("mirror", phong_roughness(params["Exponent"]), kernel="phong")

    def _value(self, wi, wo, p):
        c = np.maximum(dot(reflect_about_normal(wi), wo), 0.0)
        return normalised_phong_factor(p["Exponent"]) * c ** p["Exponent"]

    def _sample(self, wo, u, p):
        return cosine_power_around(reflect_about_normal(wo), p["Exponent"], u)

    def _pdf(self, wi, wo, p):
        return cosine_power_pdf(wi, reflect_about_normal(wo), p["Exponent"])
