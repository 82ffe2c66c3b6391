"""The half/difference table a simulated material is rendered and fitted from.

Nodes sit at the centres of an R × R × R grid in MERL's index space (θh = ((x+½)/R)²·π/2,
θd = (y+½)/R·π/2, φd = (z+½)/R·π, φd folded into [0, π) by reciprocity), so R = 90 with
2R φd bins would be MERL's own grid. Lookups are trilinear between node centres
(clamped at the θ ends, periodic in φd), 0 below the horizon.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.geometry.halfdiff import HALF_PI, from_half_diff, to_half_diff


def node_angles(resolution: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """θh, θd, φd of every node, each shaped (R, R, R)."""
    k = (np.arange(resolution) + 0.5) / resolution
    th, td, pd = np.meshgrid(k**2 * HALF_PI, k * HALF_PI, k * np.pi, indexing="ij")
    return th, td, pd


def node_directions(resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """(wi, wo) of every node, flattened to (R³, 3), with φh = 0."""
    th, td, pd = node_angles(resolution)
    wi, wo = from_half_diff(th.ravel(), 0.0, td.ravel(), pd.ravel())
    return wi, wo


@dataclass
class HalfDiffTable:
    """Node values (C, R, R, R) of an isotropic BRDF in 1/sr."""

    values: np.ndarray

    @property
    def resolution(self) -> int:
        return self.values.shape[1]

    @property
    def n_channels(self) -> int:
        return self.values.shape[0]

    def evaluate(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        wi = np.asarray(wi, float)
        wo = np.asarray(wo, float)
        wi, wo = np.broadcast_arrays(wi, wo)
        shape = wi.shape[:-1]
        wi, wo = wi.reshape(-1, 3), wo.reshape(-1, 3)
        r = self.resolution
        th, _, td, pd = to_half_diff(wi, wo)
        x = np.clip(r * np.sqrt(np.clip(th, 0.0, HALF_PI) / HALF_PI) - 0.5, 0.0, r - 1.0)
        y = np.clip(td / HALF_PI * r - 0.5, 0.0, r - 1.0)
        z = np.mod(pd, np.pi) / np.pi * r - 0.5
        x0 = np.minimum(np.floor(x).astype(np.int64), max(r - 2, 0))
        y0 = np.minimum(np.floor(y).astype(np.int64), max(r - 2, 0))
        z0 = np.floor(z).astype(np.int64)
        fx, fy, fz = x - x0, y - y0, z - z0
        out = np.zeros((wi.shape[0], self.n_channels))
        for dx, wx in ((0, 1 - fx), (1, fx)):
            for dy, wy in ((0, 1 - fy), (1, fy)):
                for dz, wz in ((0, 1 - fz), (1, fz)):
                    ix, iy, iz = np.minimum(x0 + dx, r - 1), np.minimum(y0 + dy, r - 1), (z0 + dz) % r
                    out += (wx * wy * wz)[:, None] * self.values[:, ix, iy, iz].T
        above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        return np.where(above[:, None], np.maximum(out, 0.0), 0.0).reshape(shape + (self.n_channels,))
