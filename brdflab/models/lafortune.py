"""Lafortune's generalised cosine lobes, isotropic and anisotropic (normalised as in BRDFLab)."""

import numpy as np

from brdflab.geometry.sampling import cosine_power_around, cosine_power_pdf, stable_axis
from brdflab.geometry.vec import TINY
from brdflab.models.base import LobeModel, Parameter, SplitSum, normalised_phong_factor, phong_roughness
from brdflab.models.registry import register

_C = dict(lower=-5.0, upper=5.0)


class _Lafortune(LobeModel):
    sampling = "cos^n lobe around the lobe axis C∘wo"
    reference = "Lafortune et al. 1997; BRDFLab; Ngan et al. 2005"
    split_sum_rule = ("axis C∘wo (mirror when Cx, Cy < 0, retro when > 0), its own cos^n kernel (phong), "
                      "indexed by α = √(2/(4n+2))")

    def split_sum(self, params):
        axis = tuple(float(c) for c in self._coefficients(params))
        return SplitSum("axis", phong_roughness(params["Exponent"]), kernel="phong", axis=axis)

    def _coefficients(self, p) -> tuple:
        raise NotImplementedError

    def _axis_unnormalised(self, wo, p):
        cx, cy, cz = self._coefficients(p)
        return np.stack(np.broadcast_arrays(cx * wo[..., 0], cy * wo[..., 1], cz * wo[..., 2]), axis=-1)

    def _value(self, wi, wo, p):
        cx, cy, cz = self._coefficients(p)
        n = p["Exponent"]
        s = cx * wi[..., 0] * wo[..., 0] + cy * wi[..., 1] * wo[..., 1] + cz * wi[..., 2] * wo[..., 2]
        cmax = np.maximum(np.maximum(np.abs(cx), np.abs(cy)), np.abs(cz))
        return normalised_phong_factor(n) * (np.maximum(s, 0.0) / np.maximum(cmax, TINY)) ** n

    def _sample(self, wo, u, p):
        return cosine_power_around(stable_axis(self._axis_unnormalised(wo, p)), p["Exponent"], u)

    def _pdf(self, wi, wo, p):
        axis = stable_axis(self._axis_unnormalised(wo, p))
        return cosine_power_pdf(wi, axis, p["Exponent"])


@register
class LafortuneIso(_Lafortune):
    name = "LafortuneIso"
    parameters = (
        Parameter("Cxy", -0.577, doc="weight of the tangential components", **_C),
        Parameter("Cz", 0.577, doc="weight of the normal component", **_C),
        Parameter("Exponent", 20.0, 0.0, 100000.0, "1", "lobe exponent n", log=True),
    )
    scale_invariant = ("Cxy", "Cz")
    starts = tuple(
        {"Cxy": cxy, "Cz": cz, "Exponent": n}
        for cxy, cz in ((-0.58, 0.58), (0.58, 0.58), (-0.7, 0.05))
        for n in (10.0, 100.0, 1000.0, 10000.0)
    )
    summary = "Isotropic Lafortune lobe (n+2)/(2π) max(0, Cxy(ix ox+iy oy)+Cz iz oz)^n / max|C|^n."

    def _coefficients(self, p):
        return p["Cxy"], p["Cxy"], p["Cz"]


@register
class LafortuneAniso(_Lafortune):
    name = "LafortuneAniso"
    isotropic = False
    isotropic_when_equal = ('Cx', 'Cy')
    parameters = (
        Parameter("Cx", -0.577, doc="weight of the tangent component", **_C),
        Parameter("Cy", -0.577, doc="weight of the bitangent component", **_C),
        Parameter("Cz", 0.577, doc="weight of the normal component", **_C),
        Parameter("Exponent", 20.0, 0.0, 100000.0, "1", "lobe exponent n", log=True),
    )
    scale_invariant = ("Cx", "Cy", "Cz")
    starts = tuple(
        {"Cx": cx, "Cy": cy, "Cz": 0.58, "Exponent": n}
        for cx, cy in ((-0.58, -0.58), (-0.8, -0.3), (-0.3, -0.8), (0.58, 0.58))
        for n in (10.0, 100.0, 1000.0)
    )
    summary = "Anisotropic Lafortune lobe with separate Cx, Cy, Cz."

    def _coefficients(self, p):
        return p["Cx"], p["Cy"], p["Cz"]
