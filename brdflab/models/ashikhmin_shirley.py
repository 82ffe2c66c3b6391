"""Ashikhmin–Shirley's anisotropic Phong specular lobe and its coupled diffuse term."""

import numpy as np

from brdflab.geometry.sampling import (
    ashikhmin_shirley_exponent,
    ashikhmin_shirley_half_pdf,
    ashikhmin_shirley_half_vector,
    half_vector_pdf,
    reflect,
)
from brdflab.geometry.vec import dot, half_vector, schlick
from brdflab.models.base import CosineSampled, LobeModel, Parameter, anisotropic_split, blinn_roughness
from brdflab.models.registry import register

_EXP = dict(lower=0.0, upper=100000.0, unit="1", log=True)


@register
class AshikhminShirley(LobeModel):
    name = "AshikhminShirley"
    isotropic = False
    isotropic_when_equal = ('nu', 'nv')
    parameters = (
        Parameter("nu", 100.0, doc="exponent along the tangent", **_EXP),
        Parameter("nv", 100.0, doc="exponent along the bitangent", **_EXP),
        Parameter("F0", 0.05, 0.0, 1.0, "1", "Fresnel reflectance at normal incidence"),
    )
    summary = ("√((nu+1)(nv+1))/(8π) cosθh^(nu cos²φh+nv sin²φh) F(wi·h) / "
               "((wi·h) max(cosθi, cosθo)).")
    reference = "Ashikhmin & Shirley 2000; BRDFLab; Schwenk 2011 §3.6"
    starts = tuple({"nu": e, "nv": e} for e in (10.0, 100.0, 1000.0, 10000.0))
    sampling = "half vector by Ashikhmin & Shirley 2000 (eq. 9)"
    split_sum_rule = ("mirror, Beckmann αu,v = √(2/(nu,v+2)) (Blinn-like exponents): α = min(αu, αv) around "
                      "normals spread along the longer axis")

    def split_sum(self, params):
        return anisotropic_split(blinn_roughness(params["nu"]), blinn_roughness(params["nv"]))

    def complete(self, given):
        out = dict(given)
        if "Exponent" in out:  # BRDFLab's isotropic form
            e = out.pop("Exponent")
            out.setdefault("nu", e)
            out.setdefault("nv", e)
        return out

    def _value(self, wi, wo, p):
        h = half_vector(wi, wo)
        nu, nv = p["nu"], p["nv"]
        e = ashikhmin_shirley_exponent(h, nu, nv)
        wih = dot(wi, h)
        norm = np.sqrt((nu + 1.0) * (nv + 1.0)) / (8.0 * np.pi)
        return (norm * np.maximum(h[..., 2], 0.0) ** e * schlick(p["F0"], wih)
                / (wih * np.maximum(wi[..., 2], wo[..., 2])))

    def _sample(self, wo, u, p):
        return reflect(wo, ashikhmin_shirley_half_vector(p["nu"], p["nv"], u))

    def _pdf(self, wi, wo, p):
        return half_vector_pdf(wi, wo, lambda h: ashikhmin_shirley_half_pdf(h, p["nu"], p["nv"]))


@register
class AshikhminShirleyDiffuse(CosineSampled):
    name = "AshikhminShirleyDiffuse"
    parameters = (Parameter("Rs", 0.05, 0.0, 1.0, "1", "specular reflectance of the coupled lobe"),)
    summary = ("Coupled diffuse term 28/23 (1−Rs)(1−(1−cosθi/2)^5)(1−(1−cosθo/2)^5); "
               "scale it by ρd/π.")
    reference = "Ashikhmin & Shirley 2000; Schwenk 2011 §3.6"

    def _value(self, wi, wo, p):
        a = 1.0 - (1.0 - 0.5 * wi[..., 2]) ** 5
        b = 1.0 - (1.0 - 0.5 * wo[..., 2]) ** 5
        return 28.0 / 23.0 * (1.0 - p["Rs"]) * a * b

