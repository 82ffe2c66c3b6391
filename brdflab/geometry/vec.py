"""Vectorised helpers for unit directions in the local shading frame (z = normal)."""

from __future__ import annotations

import threading
from contextlib import contextmanager
from typing import Callable, Iterator

import numpy as np

TINY = 1e-12
MAX_SHARED_TERMS = 64  # a fitting pass shares a few dozen: more is someone else's loop, not kept


def normalize(v: np.ndarray) -> np.ndarray:
    """Unit vectors along the last axis (zero vectors stay zero)."""
    n = np.sqrt(np.einsum("...i,...i->...", v, v))[..., None]
    return v / np.maximum(n, TINY)


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


_shared = threading.local()


@contextmanager
def shared_half_vectors() -> Iterator[None]:
    """Within this block each `shared_term` (the half vector among them) of the same two
    arrays (by identity) is computed once and returned read-only: the lobes of a material,
    and each perturbed copy of a lobe in a fitting pass, evaluate the same chunk of
    directions one after another."""
    outer = getattr(_shared, "on", False)
    _shared.on, _shared.key, _shared.terms = True, None, {}
    try:
        yield
    finally:
        _shared.on, _shared.key, _shared.terms = outer, None, {}


def shared_term(wi: np.ndarray, wo: np.ndarray, key: tuple, compute: Callable[[], np.ndarray]) -> np.ndarray:
    """`compute()`, a term of a lobe at directions wi, wo that depends only on the parameter
    values in `key`: within `shared_half_vectors` computed once per key for the same two arrays
    (by identity) and returned read-only. A fitting pass evaluates a lobe once per perturbed
    parameter; a perturbation of a colour leaves its distribution and masking as they were.
    A parameter given per sample (an array) is not shared: the term is computed every time."""
    if not getattr(_shared, "on", False) or any(np.ndim(k) for k in key):
        return compute()
    key = tuple(k.item() if isinstance(k, np.ndarray) else k for k in key)  # a 0-d array is its number
    if _shared.key is None or _shared.key[0] is not wi or _shared.key[1] is not wo:
        _shared.key, _shared.terms = (wi, wo), {}
    terms = _shared.terms
    if key not in terms and len(terms) >= MAX_SHARED_TERMS:
        terms.clear()
    if key not in terms:
        value = compute()
        value.flags.writeable = False
        terms[key] = value
    return terms[key]


def half_vector(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    return shared_term(wi, wo, ("half vector",), lambda: normalize(wi + wo))


def schlick_weight(cos_theta):
    """(1 − cos)⁵, cos clamped to [0, 1]: Schlick's Fresnel without its F0."""
    c = np.clip(1.0 - cos_theta, 0.0, 1.0)
    return (c * c) * (c * c) * c


def schlick(f0, cos_theta):
    """Schlick's Fresnel approximation F0 + (1 − F0)(1 − cos)⁵."""
    return schlick_of_weight(f0, schlick_weight(cos_theta))


def schlick_of_weight(f0, weight):
    """Schlick's Fresnel from its weight (1 − cos)⁵ (`schlick_weight`), where a caller has it."""
    return f0 + (1.0 - f0) * weight


def spherical_to_cartesian(theta, phi) -> np.ndarray:
    """Directions from θ (from +z) and φ (from +x towards +y)."""
    theta = np.asarray(theta, dtype=float)
    phi = np.asarray(phi, dtype=float)
    s = np.sin(theta)
    return np.stack(np.broadcast_arrays(s * np.cos(phi), s * np.sin(phi), np.cos(theta)), axis=-1)


def cartesian_to_spherical(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    theta = np.arccos(np.clip(w[..., 2], -1.0, 1.0))
    phi = np.arctan2(w[..., 1], w[..., 0])
    return theta, phi


def rotate_about_z(w: np.ndarray, angle) -> np.ndarray:
    """w turned by `angle` (radians, broadcast over the leading shape) about the normal z."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * w[..., 0] - s * w[..., 1], s * w[..., 0] + c * w[..., 1], w[..., 2]], axis=-1)


def reflect_about_normal(w: np.ndarray) -> np.ndarray:
    """Mirror direction of w about the surface normal z."""
    return w * np.array([-1.0, -1.0, 1.0])


def frame_around(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing `axis` (unit, shape (..., 3)) to an orthonormal frame.

    Branchless construction of Duff et al. 2017 (no singularity except none at all).
    """
    x, y, z = axis[..., 0], axis[..., 1], axis[..., 2]
    sign = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    t = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=-1)
    bt = np.stack([b, sign + y * y * a, -y], axis=-1)
    return t, bt


def upper_hemisphere(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """True where both directions are strictly above the surface."""
    return (wi[..., 2] > 0.0) & (wo[..., 2] > 0.0)
