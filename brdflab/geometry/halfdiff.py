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


def from_half_diff(theta_h, phi_h, theta_d, phi_d) -> tuple[np.ndarray, np.ndarray]:
    """Direction pairs (wi, wo) from half/difference angles (the inverse of to_half_diff)."""
    d = spherical_to_cartesian(theta_d, phi_d)
    wi = _rotate_z(_rotate_y(d, np.asarray(theta_h, float)), np.asarray(phi_h, float))
    h = spherical_to_cartesian(theta_h, phi_h)
    wo = 2.0 * np.einsum("...i,...i->...", wi, h)[..., None] * h - wi
    return wi, wo


def theta_h_of_bin(x) -> np.ndarray:
    """θh of MERL bin x: (x/90)² · π/2 (bins are denser near the specular peak)."""
    return (np.asarray(x, float) / N_TH) ** 2 * HALF_PI


def theta_d_of_bin(y) -> np.ndarray:
    return np.asarray(y, float) / N_TD * HALF_PI


def phi_d_of_bin(z) -> np.ndarray:
    return np.asarray(z, float) / N_PD * np.pi


def continuous_bins(theta_h, theta_d, phi_d) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fractional bin coordinates; φd folded into [0, π) by reciprocity (f(φd) = f(φd + π))."""
    x = N_TH * np.sqrt(np.clip(theta_h, 0.0, HALF_PI) / HALF_PI)
    y = np.clip(theta_d, 0.0, HALF_PI) / HALF_PI * N_TD
    z = np.mod(phi_d, np.pi) / np.pi * N_PD
    return x, y, z
