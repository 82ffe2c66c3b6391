"""Strauss 1990's phenomenological model (Schwenk 2011 §3.9, eq. 46)."""

import numpy as np

from brdflab.geometry.vec import TINY, dot, reflect_about_normal
from brdflab.models.base import LobeModel, Parameter, SplitSum, phong_roughness
from brdflab.models.registry import register

KF, KG, KJ = 1.12, 1.01, 0.1


def strauss_fresnel(theta):
    """(1/(x−kf)² − 1/kf²) / (1/(1−kf)² − 1/kf²), x = θ/(π/2), written without the
    cancellation of the differences of large reciprocals (1/A² − 1/B² = (B−A)(B+A)/(AB)²)."""
    x = theta / (0.5 * np.pi)
    num = x * (2.0 * KF - x) / (KF * (x - KF)) ** 2
    den = (2.0 * KF - 1.0) / (KF * (1.0 - KF)) ** 2
    return num / den


def strauss_shadow(theta):
    """(1/(1−kg)² − 1/(x−kg)²) / (1/(1−kg)² − 1/kg²), in the same stable form."""
    x = theta / (0.5 * np.pi)
    num = (1.0 - x) * (1.0 + x - 2.0 * KG) / ((1.0 - KG) * (x - KG)) ** 2
    den = (1.0 - 2.0 * KG) / (KG * (1.0 - KG)) ** 2
    return num / den


@register
class Strauss(LobeModel):
    name = "Strauss"
    reciprocal = False
    parameters = (
        Parameter("smoothness", 0.5, 0.0, 0.99, "1", "s: 0 rough, 1 mirror-like"),
        Parameter("metalness", 0.0, 0.0, 1.0, "1", "m: 0 dielectric, 1 metal"),
        Parameter("transparency", 0.0, 0.0, 1.0, "1", "t"),
        Parameter("color", 1.0, 0.0, 1.0, "1", "material colour C of this lobe's channel"),
    )
    starts = tuple({"smoothness": s, "metalness": m} for s in (0.2, 0.5, 0.8, 0.95) for m in (0.0, 0.7))
    summary = ("rd d C/π + rs Cs / cosθi with rd = (1−s³)(1−t), d = 1−ms, rs = rj cos^(3/(1−s)) α "
               "and Strauss's Fresnel/shadow approximations.")
    reference = "Strauss 1990; Schwenk 2011 §3.9 (diffuse part divided by π so C is an albedo)"
    split_sum_rule = ("mirror, the cos^e kernel (phong) indexed by α = √(2/(4e+2)), e = 3/(1−s); its diffuse term's share of the "
                      "normal-view albedo, rd·d·C against rj·Cs·2π/(e+1), is lit by the irradiance")

    def split_sum(self, params):
        s, m, t, c = params["smoothness"], params["metalness"], params["transparency"], params["color"]
        e = 3.0 / (1.0 - s)
        rd = (1.0 - s**3) * (1.0 - t)
        diffuse = rd * (1.0 - m * s) * c
        specular = min(1.0, (1.0 - t) - rd) * (1.0 + m * (c - 1.0)) * 2.0 * np.pi / (e + 1.0)
        share = diffuse / (diffuse + specular) if diffuse + specular > 0.0 else 0.0
        return SplitSum("mirror", phong_roughness(e), kernel="phong", diffuse_share=float(share))

    def _value(self, wi, wo, p):
        s, m, t, c = p["smoothness"], p["metalness"], p["transparency"], p["color"]
        theta_i = np.arccos(np.clip(wi[..., 2], -1.0, 1.0))
        theta_o = np.arccos(np.clip(wo[..., 2], -1.0, 1.0))
        rd = (1.0 - s**3) * (1.0 - t)
        d = 1.0 - m * s
        rn = (1.0 - t) - rd
        fi = strauss_fresnel(theta_i)
        j = fi * strauss_shadow(theta_i) * strauss_shadow(theta_o)
        rj = np.minimum(1.0, rn + (rn + KJ) * j)
        e = 3.0 / (1.0 - s)
        rs = rj * np.maximum(dot(reflect_about_normal(wi), wo), 0.0) ** e
        cs = 1.0 + m * (1.0 - fi) * (c - 1.0)
        return rd * d * c / np.pi + rs * cs / np.maximum(wi[..., 2], TINY)
