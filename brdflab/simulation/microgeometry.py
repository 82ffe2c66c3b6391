"""The lab's own simulated kinds: ray-bounce BRDFs of random height fields, V-grooves and
spheres on a plane, tabulated over incident angles in parallel and resampled onto the
half/difference nodes.

The simulated surface is made isotropic by giving every ray its own random incident
azimuth (the same as rotating the sample under the beam), so V-grooves stand for a
groove array in random orientation; `trace` itself handles fixed orientations.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from brdflab.geometry.vec import spherical_to_cartesian
from brdflab.simulation.params import SimParameter
from brdflab.simulation.raybounce import Facet, histogram, trace
from brdflab.simulation.surfaces import SpheresOnPlane, VGrooves, gaussian_height_field
from brdflab.simulation.table import HalfDiffTable, node_directions

LIBRARY = "RayBounce"
GRID = 256  # height-field tile, in cells

FACET_PARAMETERS = (
    SimParameter("facet", "mirror", unit="", doc="facet BRDF: mirror (dielectric Fresnel) or lambertian",
                 choices=("mirror", "lambertian")),
    SimParameter("ior", 1.5, 1.0, 4.0, "", "refractive index of mirror facets (Fresnel)"),
    SimParameter("albedo_r", 0.8, 0.0, 1.0, "", "albedo of Lambertian facets, red channel"),
    SimParameter("albedo_g", 0.8, 0.0, 1.0, "", "albedo of Lambertian facets, green channel"),
    SimParameter("albedo_b", 0.8, 0.0, 1.0, "", "albedo of Lambertian facets, blue channel"),
    SimParameter("max_bounces", 8, 1, 32, "", "bounces followed before a ray counts as absorbed", integer=True),
)

GEOMETRY_PARAMETERS = {
    "GaussianHeightField": (
        SimParameter("rms_slope", 0.3, 0.02, 1.5, "", "RMS slope √⟨|∇h|²⟩ (Beckmann m of the slopes)"),
        SimParameter("correlation", 8.0, 4.0, 32.0, "cells", "Gaussian correlation length of the heights"),
    ),
    "VGrooves": (
        SimParameter("groove_angle", 30.0, 1.0, 75.0, "deg", "tilt of each groove facet from the mean plane"),
    ),
    "SpheresOnPlane": (
        SimParameter("coverage", 0.5, 0.05, 0.75, "", "fraction of the plane covered by spheres (seen from above)"),
    ),
}

DOCS = {
    "GaussianHeightField": "ray-bounced periodic Gaussian random height field (256² cells)",
    "VGrooves": "ray-bounced array of symmetric V-grooves, in random orientation",
    "SpheresOnPlane": "ray-bounced layer of equal spheres resting on a plane",
}


def make_surface(model: str, params: dict, seed: int):
    """The microgeometry of `model`, deterministic for `seed`."""
    rng = np.random.default_rng([seed, 0])
    if model == "GaussianHeightField":
        return gaussian_height_field(GRID, params["correlation"], params["rms_slope"], rng)
    if model == "VGrooves":
        return VGrooves(np.radians(params["groove_angle"]))
    return SpheresOnPlane(1.0, params["coverage"], rng)


def make_facet(params: dict) -> Facet:
    return Facet(params["facet"], params["ior"], (params["albedo_r"], params["albedo_g"], params["albedo_b"]))


def incident_angles(resolution: int) -> np.ndarray:
    n = max(4, resolution // 2)
    return (np.arange(n) + 0.5) / n * 0.5 * np.pi


def simulate_incidence(model: str, params: dict, seed: int, samples: int, resolution: int, k: int) -> np.ndarray:
    """BRDF histogram (C, n, n) for the k-th incident angle, every ray at a random azimuth."""
    surface = make_surface(model, params, seed)
    rng = np.random.default_rng([seed, k + 1])
    theta_i = incident_angles(resolution)[k]
    phi_i = rng.uniform(0.0, 2.0 * np.pi, samples)
    wi = spherical_to_cartesian(np.full(samples, theta_i), phi_i)
    escapes = trace(surface, make_facet(params), wi, samples, rng, params["max_bounces"])
    n = max(4, resolution // 2)
    return histogram(escapes, n, n, phi_i).values


def table_from_histograms(slices: np.ndarray, resolution: int) -> HalfDiffTable:
    """Resample per-θi histograms (K, C, n, n) onto the half/difference nodes (trilinear
    between bin centres, clamped at the ends)."""
    k, c, n, _ = slices.shape
    ti = incident_angles(resolution)
    to = (np.arange(n) + 0.5) / n * 0.5 * np.pi
    dp = (np.arange(n) + 0.5) / n * np.pi
    wi, wo = node_directions(resolution)
    theta_i = np.arccos(np.clip(wi[:, 2], -1, 1))
    theta_o = np.arccos(np.clip(wo[:, 2], -1, 1))
    rel = np.abs(np.angle(np.exp(1j * (np.arctan2(wo[:, 1], wo[:, 0]) - np.arctan2(wi[:, 1], wi[:, 0]) - np.pi))))
    points = np.column_stack([np.clip(theta_i, ti[0], ti[-1]), np.clip(theta_o, to[0], to[-1]), np.clip(rel, dp[0], dp[-1])])
    values = np.empty((c, wi.shape[0]))
    for ch in range(c):
        values[ch] = RegularGridInterpolator((ti, to, dp), slices[:, ch])(points)
    above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    values[:, ~above] = 0.0
    return HalfDiffTable(values.reshape(c, resolution, resolution, resolution).astype(np.float32))
