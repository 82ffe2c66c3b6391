"""Kurt, Szirmay-Kalos & Křivánek 2010: anisotropic data-fitting lobe (eq. 10) and
its Fresnel-coupled diffuse term (eq. 13). Lambertian + Kurt is eq. 11, KurtDiffuse +
Kurt is eq. 13 and Lambertian + several Kurt lobes is eq. 14."""

from brdflab.geometry.sampling import (
    beckmann_d,
    beckmann_half_vector,
    half_vector_pdf,
    reflect,
)
from brdflab.geometry.vec import dot, half_vector, schlick
from brdflab.models.base import CosineSampled, LobeModel, Parameter, anisotropic_split
from brdflab.models.registry import register


@register
class Kurt(LobeModel):
    name = "Kurt"
    isotropic = False
    isotropic_when_equal = ('mx', 'my')
    reciprocal = False  # reciprocal only when alpha = 1
    parameters = (
        Parameter("mx", 0.2, 0.001, 1.0, "1", "RMS slope along the tangent", log=True),
        Parameter("my", 0.2, 0.001, 1.0, "1", "RMS slope along the bitangent", log=True),
        Parameter("F0", 0.05, 0.0, 1.0, "1", "Fresnel reflectance at normal incidence"),
        Parameter("alpha", 0.5, 0.0, 2.0, "1", "exponent of cosθo in the denominator"),
    )
    summary = "F(wo·h) D(h) / (4 (wo·h) cosθi cosθo^α), D anisotropic Beckmann (eq. 10)."
    reference = "Kurt, Szirmay-Kalos & Křivánek 2010, eqs. 4–5, 10, 16–20"
    starts = tuple({"mx": m, "my": m, "F0": f, "alpha": a} for m in (0.03, 0.1, 0.3) for f, a in ((0.1, 0.2), (0.6, 0.8)))
    sampling = "half vector by eqs. 16–19, pdf eq. 20"
    split_sum_rule = "mirror, Beckmann α = min(mx, my) around normals spread along the longer axis (slopes √((m² − α²)/2))"

    def split_sum(self, params):
        return anisotropic_split(params["mx"], params["my"])

    def _value(self, wi, wo, p):
        h = half_vector(wi, wo)
        woh = dot(wo, h)
        d = beckmann_d(h, p["mx"], p["my"])
        return schlick(p["F0"], woh) * d / (4.0 * woh * wi[..., 2] * wo[..., 2] ** p["alpha"])

    def _sample(self, wo, u, p):
        return reflect(wo, beckmann_half_vector(p["mx"], p["my"], u))

    def _pdf(self, wi, wo, p):
        return half_vector_pdf(wi, wo, lambda h: beckmann_d(h, p["mx"], p["my"]) * h[..., 2])


@register
class KurtDiffuse(CosineSampled):
    name = "KurtDiffuse"
    parameters = (Parameter("F0", 0.05, 0.0, 1.0, "1", "Fresnel reflectance of the coupled specular lobe"),)
    summary = "Fresnel-coupled diffuse term 1 − F(wo·h) of eq. 13; scale it by kd/π."
    reference = "Kurt, Szirmay-Kalos & Křivánek 2010, eq. 13"

    def _value(self, wi, wo, p):
        return 1.0 - schlick(p["F0"], dot(wo, half_vector(wi, wo)))

