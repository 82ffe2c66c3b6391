"""SCATMECH models (NIST's polarized light scattering library) through pySCATMECH.

pySCATMECH is optional: without it the lab works and asking for a SCATMECH material
raises one clear BRDFLabError. Values are the unpolarised BRDF, the Mueller matrix's
m00, in 1/sr, one channel per wavelength (`wavelength_r/g/b`, default 650, 550 and
450 nm). pySCATMECH evaluates one geometry per call, so node values are computed in
chunks spread over worker processes.
"""

from __future__ import annotations

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.simulation.params import SimParameter

LIBRARY = "SCATMECH"

WAVELENGTHS = (
    SimParameter("wavelength_r", 0.65, 0.2, 2.0, "µm", "wavelength of the red channel"),
    SimParameter("wavelength_g", 0.55, 0.2, 2.0, "µm", "wavelength of the green channel"),
    SimParameter("wavelength_b", 0.45, 0.2, 2.0, "µm", "wavelength of the blue channel"),
)


def _substrate(n: float, k: float, what: str = "substrate") -> tuple[SimParameter, SimParameter]:
    return (SimParameter(f"{what}_n", n, 1.0, 10.0, "", f"refractive index of the {what}"),
            SimParameter(f"{what}_k", k, 0.0, 10.0, "", f"extinction coefficient of the {what}"))


# kind → (SCATMECH class, parameters, doc)
MODELS = {
    "SubsurfaceParticle": ("Subsurface_Particle_BRDF_Model", (
        SimParameter("radius", 0.1, 0.005, 2.0, "µm", "radius of the (Mie) sphere"),
        *_substrate(1.59, 0.0, "particle"),
        SimParameter("depth", 0.3, 0.0, 10.0, "µm", "depth of the sphere's centre below the surface"),
        SimParameter("density", 1.0, 1e-4, 100.0, "µm⁻²", "particles per unit area"),
        *_substrate(1.5, 0.0),
    ), "a sphere under a smooth dielectric surface (BRDFLab's Figs. 9–10)"),
    "Microroughness": ("Microroughness_BRDF_Model", (
        SimParameter("sigma", 0.01, 0.0005, 0.1, "µm", "RMS height of the Gaussian roughness spectrum"),
        SimParameter("length", 1.0, 0.05, 50.0, "µm", "correlation length of the Gaussian roughness spectrum"),
        *_substrate(4.05, 0.05),
    ), "first-order vector perturbation (Rayleigh–Rice) scattering of a slightly rough surface"),
    "Facet": ("Facet_BRDF_Model", (
        SimParameter("rms_slope", 0.3, 0.01, 1.5, "", "RMS slope of the Gaussian facet slope distribution"),
        *_substrate(1.5, 0.0),
    ), "specular facets with a Gaussian slope distribution (no shadowing)"),
    "DiffuseSubsurface": ("Diffuse_Subsurface_BRDF_Model", (
        SimParameter("reflectance", 0.5, 0.0, 1.0, "", "reflectance of the diffuse layer under the surface"),
        *_substrate(1.5, 0.0),
    ), "Lambertian scattering beneath a smooth dielectric surface (Fresnel in and out)"),
}


def available() -> bool:
    try:
        import pySCATMECH  # noqa: F401
    except ImportError:
        return False
    return True


def require(kind: str) -> None:
    if not available():
        raise BRDFLabError(f"the SCATMECH material {kind} needs pySCATMECH, which is not installed "
                           "(pip install pySCATMECH, or bash scripts/setup.sh --scatmech)")


def _settings(kind: str, params: dict, wavelength: float) -> dict:
    """pySCATMECH parameter strings for one wavelength."""
    out = {"lambda": wavelength, "substrate": f"({params['substrate_n']},{params['substrate_k']})"}
    if kind == "SubsurfaceParticle":
        out.update({"scatterer": "MieScatterer", "scatterer.radius": params["radius"],
                    "scatterer.sphere": f"({params['particle_n']},{params['particle_k']})",
                    "scatterer.lambda": wavelength, "scatterer.medium": out["substrate"],
                    "depth": params["depth"], "density": params["density"]})
    elif kind == "Microroughness":
        out.update({"psd": "Gaussian_PSD_Function", "psd.sigma": params["sigma"], "psd.length": params["length"]})
    elif kind == "Facet":
        out.update({"sdf": "Gaussian_Slope_Distribution_Function", "sdf.s": params["rms_slope"]})
    elif kind == "DiffuseSubsurface":
        out.update({"reflectance": "Table_Reflectance", "reflectance.table": params["reflectance"]})
    return out


def evaluate_chunk(kind: str, params: dict, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """m00 BRDF (N, 3) at direction pairs above the surface (0 elsewhere)."""
    require(kind)
    from pySCATMECH.brdf import BRDF_Model

    theta_i = np.arccos(np.clip(wi[:, 2], -1, 1))
    theta_s = np.arccos(np.clip(wo[:, 2], -1, 1))
    phi_s = np.arctan2(wo[:, 1], wo[:, 0]) - np.arctan2(wi[:, 1], wi[:, 0]) - np.pi  # SCATMECH: 0 = specular
    above = (wi[:, 2] > 1e-6) & (wo[:, 2] > 1e-6)
    out = np.zeros((wi.shape[0], 3))
    for c, wl in enumerate((params["wavelength_r"], params["wavelength_g"], params["wavelength_b"])):
        model = BRDF_Model(MODELS[kind][0], **{k: str(v) for k, v in _settings(kind, params, wl).items()})
        for j in np.nonzero(above)[0]:  # pySCATMECH has no array interface
            out[j, c] = model.MuellerBRDF(theta_i[j], theta_s[j], phi_s[j])[0][0]
    return out
