"""Importance-sampling building blocks shared by the lobe models.

Every sampler maps two uniforms u = (u1, u2) in [0, 1)² to directions, and every
density is with respect to solid angle over the whole sphere, so that it
integrates to exactly 1 there (directions that fall below the surface carry
density too; the BRDF is zero there).
"""

from __future__ import annotations

import numpy as np

from brdflab.geometry.vec import TINY, dot, frame_around, normalize

INV_PI = 1.0 / np.pi
INV_2PI = 0.5 / np.pi


def cosine_hemisphere(u: np.ndarray) -> np.ndarray:
    """Cosine-weighted directions on the upper hemisphere (Malley's method)."""
    r = np.sqrt(u[..., 0])
    phi = 2.0 * np.pi * u[..., 1]
    z = np.sqrt(np.maximum(0.0, 1.0 - u[..., 0]))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def cosine_hemisphere_pdf(wi: np.ndarray) -> np.ndarray:
    return np.maximum(wi[..., 2], 0.0) * INV_PI


def cosine_power_around(axis: np.ndarray, exponent, u: np.ndarray) -> np.ndarray:
    """Directions with density (n+1)/(2π) cos^n of the angle to `axis` (unit)."""
    cos_a = u[..., 0] ** (1.0 / (np.asarray(exponent, float) + 1.0))
    sin_a = np.sqrt(np.maximum(0.0, 1.0 - cos_a * cos_a))
    phi = 2.0 * np.pi * u[..., 1]
    t, b = frame_around(axis)
    return (
        (sin_a * np.cos(phi))[..., None] * t
        + (sin_a * np.sin(phi))[..., None] * b
        + cos_a[..., None] * axis
    )


def cosine_power_pdf(w: np.ndarray, axis: np.ndarray, exponent) -> np.ndarray:
    n = np.asarray(exponent, float)
    return (n + 1.0) * INV_2PI * np.maximum(dot(w, axis), 0.0) ** n


def stable_axis(v: np.ndarray) -> np.ndarray:
    """Normalised v, or +z where v vanishes (a lobe whose axis collapses)."""
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    z = np.zeros_like(v)
    z[..., 2] = 1.0
    return np.where(norm > 1e-9, v / np.maximum(norm, TINY), z)


# --- half-vector (microfacet) sampling -------------------------------------------------

def reflect(wo: np.ndarray, h: np.ndarray) -> np.ndarray:
    """wi = 2 (wo·h) h − wo: the direction whose half vector with wo is ±h."""
    return 2.0 * dot(wo, h)[..., None] * h - wo


def upper_half_vector(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The half vector of (wi, wo) flipped into the upper hemisphere, and |wo·h|.

    Reflection about h and about −h give the same wi, so a sampler that draws h
    with h.z > 0 produces wi with density p_h(h⁺) / (4 |wo·h⁺|) over the whole
    sphere; using h⁺ makes that density integrate to 1 even for grazing wo.
    """
    h = normalize(wi + wo)
    h = h * np.where(h[..., 2] < 0.0, -1.0, 1.0)[..., None]
    return h, np.abs(dot(wo, h))


def half_vector_pdf(wi: np.ndarray, wo: np.ndarray, pdf_h) -> np.ndarray:
    """Solid-angle density of wi = reflect(wo, h) when h has density pdf_h(h)."""
    h, wo_h = upper_half_vector(wi, wo)
    return np.where(wo_h > TINY, pdf_h(h) / (4.0 * np.maximum(wo_h, TINY)), 0.0)


def beckmann_half_vector(mx, my, u: np.ndarray) -> np.ndarray:
    """Half vectors with density D(h) cos θh, D the anisotropic Beckmann/Ward
    distribution (Kurt et al. 2010, eqs. 16–18; Walter 2005)."""
    phase = 2.0 * np.pi * u[..., 1]
    phi = np.arctan2(np.asarray(my, float) * np.sin(phase), np.asarray(mx, float) * np.cos(phase))
    c, s = np.cos(phi), np.sin(phi)
    tan2 = -np.log(np.maximum(1.0 - u[..., 0], TINY)) / (c * c / mx**2 + s * s / my**2)
    cos_t = 1.0 / np.sqrt(1.0 + tan2)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    return np.stack([sin_t * c, sin_t * s, cos_t], axis=-1)


def beckmann_d(h: np.ndarray, mx, my) -> np.ndarray:
    """Anisotropic Beckmann distribution, normalised so ∫ D cos θh dω = 1 (eq. 5)."""
    hz = h[..., 2]
    hz2 = np.maximum(hz * hz, TINY)
    e = (h[..., 0] ** 2 / mx**2 + h[..., 1] ** 2 / my**2) / hz2
    return np.where(hz > 0.0, np.exp(-e) / (np.pi * mx * my * hz2 * hz2), 0.0)


def ggx_visible_half_vector(wo: np.ndarray, alpha, u: np.ndarray) -> np.ndarray:
    """Half vectors of the isotropic GGX distribution as seen from wo (Heitz 2018, "Sampling the
    GGX distribution of visible normals"): density G₁(wo) max(0, wo·h) D(h) / cos θo. The
    estimate's weight f cos θi / pdf is then F·G₂/G₁(wo) ≤ 1 where D cos θh gave weights that
    grow at grazing views (on a white map 64 samples: 3.1 → 0.6 % per pixel, docs/mis.md)."""
    a = np.asarray(alpha, float)
    v = np.stack(np.broadcast_arrays(a * wo[..., 0], a * wo[..., 1], wo[..., 2]), axis=-1)
    v = v / np.linalg.norm(v, axis=-1, keepdims=True)
    lensq = v[..., 0] ** 2 + v[..., 1] ** 2
    inv = 1.0 / np.sqrt(np.maximum(lensq, TINY))
    t1 = np.where((lensq > TINY)[..., None], np.stack([-v[..., 1] * inv, v[..., 0] * inv, np.zeros_like(inv)], axis=-1),
                  np.array([1.0, 0.0, 0.0]))
    t2 = np.cross(v, t1)
    r, phi = np.sqrt(u[..., 0]), 2.0 * np.pi * u[..., 1]
    p1, p2 = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + v[..., 2])
    p2 = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + s * p2
    nh = p1[..., None] * t1 + p2[..., None] * t2 + np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))[..., None] * v
    h = np.stack(np.broadcast_arrays(a * nh[..., 0], a * nh[..., 1], np.maximum(nh[..., 2], 1e-6)), axis=-1)
    return h / np.linalg.norm(h, axis=-1, keepdims=True)


def ggx_d(h: np.ndarray, alpha) -> np.ndarray:
    """Isotropic GGX (Trowbridge–Reitz) distribution, ∫ D cos θh dω = 1."""
    hz = h[..., 2]
    a2 = np.asarray(alpha, float) ** 2
    hz2 = hz * hz
    denom = np.pi * (hz2 * (a2 - 1.0) + 1.0) ** 2
    return np.where(hz > 0.0, a2 / np.maximum(denom, TINY), 0.0)


def ashikhmin_shirley_half_vector(nu, nv, u: np.ndarray) -> np.ndarray:
    """Half vectors of the Ashikhmin–Shirley anisotropic Phong distribution (AS 2000, eq. 9)."""
    nu = np.asarray(nu, float)
    nv = np.asarray(nv, float)
    phase = 2.0 * np.pi * u[..., 0]
    phi = np.arctan2(np.sqrt(nu + 1.0) * np.sin(phase), np.sqrt(nv + 1.0) * np.cos(phase))
    c, s = np.cos(phi), np.sin(phi)
    exponent = nu * c * c + nv * s * s
    cos_t = (1.0 - u[..., 1]) ** (1.0 / (exponent + 1.0))
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    return np.stack([sin_t * c, sin_t * s, cos_t], axis=-1)


def ashikhmin_shirley_exponent(h: np.ndarray, nu, nv) -> np.ndarray:
    """nu cos²φh + nv sin²φh, with its limit (nu+nv)/2 at h = n."""
    hx2, hy2 = h[..., 0] ** 2, h[..., 1] ** 2
    s2 = hx2 + hy2
    safe = s2 > 1e-14
    return np.where(safe, (nu * hx2 + nv * hy2) / np.where(safe, s2, 1.0), 0.5 * (nu + nv))


def ashikhmin_shirley_half_pdf(h: np.ndarray, nu, nv) -> np.ndarray:
    hz = np.maximum(h[..., 2], 0.0)
    e = ashikhmin_shirley_exponent(h, nu, nv)
    return np.sqrt((nu + 1.0) * (nv + 1.0)) * INV_2PI * hz**e
