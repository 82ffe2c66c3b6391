"""Rusinkiewicz half/difference angles and MERL's sampling grid (Matusik et al. 2003)."""

from __future__ import annotations

import numpy as np

from brdflab.geometry.vec import normalize, spherical_to_cartesian

N_TH, N_TD, N_PD = 90, 90, 180  # θh, θd, φd bins of a MERL table (φd over [0, π))
HALF_PI = 0.5 * np.pi


def _rotate_z(v: np.ndarray, angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1], v[..., 2]], axis=-1)


def _rotate_y(v: np.ndarray, angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * v[..., 0] + s * v[..., 2], v[..., 1], -s * v[..., 0] + c * v[..., 2]], axis=-1)


def to_half_diff(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(θh, φh, θd, φd) of direction pairs; φd in (−π, π]."""
    h = normalize(wi + wo)
    theta_h = np.arccos(np.clip(h[..., 2], -1.0, 1.0))
    phi_h = np.arctan2(h[..., 1], h[..., 0])
    d = _rotate_y(_rotate_z(wi, -phi_h), -theta_h)
    theta_d = np.arccos(np.clip(d[..., 2], -1.0, 1.0))
    phi_d = np.arctan2(d[..., 1], d[..., 0])
    return theta_h, phi_h, theta_d, phi_d


def half_and_difference_angles(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(θh, θd) of direction pairs without φh and φd (what an isotropic slice is indexed by):
    cos θh = h_z and cos θd = wi·h, as `to_half_diff` gives them after its rotations."""
    h = normalize(wi + wo)
    theta_h = np.arccos(np.clip(h[..., 2], -1.0, 1.0))
    theta_d = np.arccos(np.clip(np.einsum("...i,...i->...", wi, h), -1.0, 1.0))
    return theta_h, theta_d


def from_half_diff(theta_h, phi_h, theta_d, phi_d) -> tuple[np.ndarray, np.ndarray]:
    """Direction pairs (wi, wo) from half/difference angles (the inverse of to_half_diff)."""
    d = spherical_to_cartesian(theta_d, phi_d)
    wi = _rotate_z(_rotate_y(d, np.asarray(theta_h, float)), np.asarray(phi_h, float))
    h = spherical_to_cartesian(theta_h, phi_h)
    wo = 2.0 * np.einsum("...i,...i->...", wi, h)[..., None] * h - wi
    return wi, wo


def theta_h_of_bin(x) -> np.ndarray:
    """θh at the centre of MERL bin x, in index space: ((x + ½)/90)² · π/2.

    MERL's lookup takes the floor of √(θh/(π/2))·90, so a bin's value stands for the
    whole bin and its representative is the bin's centre (CONVENTIONS.md "Measured tables")."""
    return ((np.asarray(x, float) + 0.5) / N_TH) ** 2 * HALF_PI


def theta_d_of_bin(y) -> np.ndarray:
    """θd at the centre of bin y: (y + ½)/90 · π/2."""
    return (np.asarray(y, float) + 0.5) / N_TD * HALF_PI


def phi_d_of_bin(z, n_pd: int = N_PD) -> np.ndarray:
    """φd at the centre of bin z of n_pd bins over [0, π): (z + ½)/n_pd · π."""
    return (np.asarray(z, float) + 0.5) / n_pd * np.pi


def theta_h_edge(x) -> np.ndarray:
    """Lower edge of θh bin x (x = 90: the upper edge of the last bin, π/2)."""
    return (np.asarray(x, float) / N_TH) ** 2 * HALF_PI


def theta_d_edge(y) -> np.ndarray:
    """Lower edge of θd bin y (y = 90: π/2)."""
    return np.asarray(y, float) / N_TD * HALF_PI


def continuous_bins(theta_h, theta_d, phi_d) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fractional bin coordinates in which integer k is bin k's centre (so that
    interpolation runs between centres and rounding is MERL's floor lookup); φd folded
    into [0, π) by reciprocity (f(φd) = f(φd + π)), so z may be −½ (wraps to bin 179)."""
    x = N_TH * np.sqrt(np.clip(theta_h, 0.0, HALF_PI) / HALF_PI) - 0.5
    y = np.clip(theta_d, 0.0, HALF_PI) / HALF_PI * N_TD - 0.5
    z = np.mod(phi_d, np.pi) / np.pi * N_PD - 0.5
    return x, y, z
