"""Direct (θo, φo) textures of a simulated material for one incident direction, as
BRDFLab's lobe viewer shows simulations: computed straight from the simulation (no
table), coarse for quick feedback, then fine.

SCATMECH kinds are evaluated at the texel centres; ray-bounce kinds trace rays from wi
(each with the sample turned by a random azimuth, as in their isotropic tables) and
histogram them over the texels (rays ∝ texels, so the noise per texel stays put).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from brdflab.geometry.vec import spherical_to_cartesian
from brdflab.simulation import microgeometry, scatmech
from brdflab.simulation.material import SimulationSpec
from brdflab.simulation.raybounce import trace
from brdflab.simulation.registry import get_kind

RAYS_PER_TEXEL = 200


@dataclass
class LobeTexture:
    """f(wi, wo) over θo ∈ [0, π/2] (rows) × φo ∈ [0, 2π) (columns), texel centres; (C, n, 2n)
    for ray-bounce kinds, (C, n, n) for SCATMECH. A source for that one wi: `evaluate` looks
    wo up bilinearly (periodic in φo) and ignores wi."""

    values: np.ndarray
    theta_i: float
    phi_i: float
    seconds: float

    n_channels = 3
    isotropic = True

    @property
    def size(self) -> tuple[int, int]:
        return self.values.shape[1], self.values.shape[2]

    def evaluate(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        wo = np.asarray(wo, float).reshape(-1, 3)
        n_t, n_p = self.size
        t = np.arccos(np.clip(wo[:, 2], -1, 1)) / (0.5 * np.pi) * n_t - 0.5
        p = np.mod(np.arctan2(wo[:, 1], wo[:, 0]), 2 * np.pi) / (2 * np.pi) * n_p - 0.5
        t = np.clip(t, 0, n_t - 1)
        t0 = np.minimum(np.floor(t).astype(np.int64), max(n_t - 2, 0))
        p0 = np.floor(p).astype(np.int64)
        ft, fp = t - t0, p - p0
        out = np.zeros((wo.shape[0], self.values.shape[0]))
        for dt, wt in ((0, 1 - ft), (1, ft)):
            for dp, wp in ((0, 1 - fp), (1, fp)):
                out += (wt * wp)[:, None] * self.values[:, np.minimum(t0 + dt, n_t - 1), (p0 + dp) % n_p].T
        return np.where((wo[:, 2] > 0)[:, None], out, 0.0)

    def describe(self) -> dict:
        return {"type": "LobeTexture", "size": list(self.size), "seconds": self.seconds}


def lobe_texture(spec: SimulationSpec, theta_i: float, phi_i: float, n: int) -> LobeTexture:
    """The texture of `spec` for wi = (θi, φi) (radians) at n θo rows."""
    t0 = time.perf_counter()
    if get_kind(spec.kind).uses_rays:
        rays = max(1000, RAYS_PER_TEXEL * n * 2 * n)
        rng = np.random.default_rng([spec.seed, 10_000 + n])
        surface = microgeometry.make_surface(spec.kind, spec.params, spec.seed)
        turn = rng.uniform(0.0, 2 * np.pi, rays)  # the sample turned under the beam, as in the tables
        wi = spherical_to_cartesian(np.full(rays, theta_i), phi_i + turn)
        esc = trace(surface, microgeometry.make_facet(spec.params), wi, rays, rng, spec.params["max_bounces"])
        theta = np.arccos(np.clip(esc.directions[:, 2], -1, 1))
        phi = np.mod(np.arctan2(esc.directions[:, 1], esc.directions[:, 0]) - turn[esc.rays], 2 * np.pi)
        it = np.clip((theta / (0.5 * np.pi) * n).astype(np.int64), 0, n - 1)
        ip = np.clip((phi / (2 * np.pi) * 2 * n).astype(np.int64), 0, 2 * n - 1)
        flat = it * 2 * n + ip
        sums = np.stack([np.bincount(flat, weights=esc.weights[:, c], minlength=2 * n * n) for c in range(3)])
        edges = np.linspace(0, 0.5 * np.pi, n + 1)
        proj = 0.5 * np.diff(np.sin(edges) ** 2) * (np.pi / n)
        values = sums.reshape(3, n, 2 * n) / (rays * proj[None, :, None])
    else:
        theta = (np.arange(n) + 0.5) / n * 0.5 * np.pi
        phi = (np.arange(n) + 0.5) / n * 2 * np.pi
        wo = spherical_to_cartesian(theta[:, None], phi[None, :]).reshape(-1, 3)
        wi = spherical_to_cartesian(theta_i, phi_i)
        values = scatmech.evaluate_chunk(spec.kind, spec.params, np.broadcast_to(wi, wo.shape), wo).T.reshape(3, n, n)
    return LobeTexture(values, theta_i, phi_i, time.perf_counter() - t0)
