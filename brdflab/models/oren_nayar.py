"""Oren–Nayar's qualitative rough-diffuse model (Oren & Nayar 1994; Schwenk 2011 eq. 34)."""

import numpy as np

from brdflab.geometry.vec import TINY
from brdflab.models.base import CosineSampled, Parameter
from brdflab.models.registry import register


@register
class OrenNayar(CosineSampled):
    name = "OrenNayar"
    parameters = (Parameter("sigma", 0.3, 0.0, 1.5, "rad", "standard deviation of facet slope angles"),)
    starts = tuple({"sigma": s} for s in (0.1, 0.4, 0.8, 1.2))
    summary = "A + B max(0, cos(φi−φo)) sin α tan β; scale it by ρ/π (σ = 0 is Lambertian)."
    reference = "Oren & Nayar 1994; Schwenk 2011 §3.4.2"

    def _value(self, wi, wo, p):
        s2 = p["sigma"] ** 2
        a = 1.0 - 0.5 * s2 / (s2 + 0.33)
        b = 0.45 * s2 / (s2 + 0.09)
        ci, co = np.clip(wi[..., 2], -1, 1), np.clip(wo[..., 2], -1, 1)
        si, so = np.sqrt(1.0 - ci * ci), np.sqrt(1.0 - co * co)
        denom = si * so
        cos_dphi = np.where(denom > TINY, (wi[..., 0] * wo[..., 0] + wi[..., 1] * wo[..., 1]) / np.maximum(denom, TINY), 0.0)
        # α = max(θi, θo) has the smaller cosine; sin α tan β = sin α sin β / cos β
        sin_alpha = np.where(ci < co, si, so)
        sin_beta = np.where(ci < co, so, si)
        cos_beta = np.maximum(ci, co)
        return a + b * np.maximum(cos_dphi, 0.0) * sin_alpha * sin_beta / np.maximum(cos_beta, TINY)
