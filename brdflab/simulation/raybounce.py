"""Ray-bounce simulation of a BRDF from a microgeometry (vectorised NumPy).

Rays arrive from the light direction wi at uniformly random points of a periodic
tile, march to the surface (`surfaces.py` gives safe steps), and bounce on facets
that are mirrors with dielectric Fresnel or Lambertian, until they escape above the
surface or exceed `max_bounces`. Shadowing, masking and interreflection therefore
come out of the geometry itself. The BRDF of an outgoing bin is its escaped weight
over (rays × the bin's projected solid angle ∫cos θo dω).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.geometry.vec import frame_around, normalize
from brdflab.geometry.sampling import cosine_hemisphere

HIT_EPS = 1e-4     # a ray closer than this to the surface has hit it (grid units)
LEAVE_OFFSET = 1e-3  # a bounced ray starts this far along the normal
MAX_MARCH = 600    # steps per ray over all its bounces; rays still inside are counted as lost


@dataclass(frozen=True)
class Facet:
    """The BRDF of the microfacets: 'mirror' (Fresnel of a dielectric of index `ior`) or
    'lambertian' (albedo per channel)."""

    kind: str
    ior: float = 1.5
    albedo: tuple[float, ...] = (0.8, 0.8, 0.8)

    @property
    def n_channels(self) -> int:
        return len(self.albedo)


def fresnel_dielectric(cos_i: np.ndarray, ior: float) -> np.ndarray:
    """Unpolarised Fresnel reflectance from air onto a dielectric of index `ior`."""
    c = np.clip(cos_i, 0.0, 1.0)
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - (1.0 - c * c) / (ior * ior)))
    rs = (c - ior * cos_t) / (c + ior * cos_t)
    rp = (ior * c - cos_t) / (ior * c + cos_t)
    return 0.5 * (rs * rs + rp * rp)


@dataclass
class Escapes:
    """Rays that left the surface: directions (M, 3), weights (M, C), bounce counts (M,) and
    the index of each among the `n_rays` sent; `lost` is the weight of rays absorbed by the
    bounce limit or unfinished."""

    directions: np.ndarray
    weights: np.ndarray
    bounces: np.ndarray
    rays: np.ndarray
    n_rays: int
    lost: float


def _bounce(facet: Facet, d: np.ndarray, n: np.ndarray, w: np.ndarray, rng: np.random.Generator):
    """New directions and weights after one facet interaction."""
    cos = -np.einsum("ij,ij->i", d, n)
    if facet.kind == "mirror":
        new_d = d + 2.0 * cos[:, None] * n
        return normalize(new_d), w * fresnel_dielectric(cos, facet.ior)[:, None]
    local = cosine_hemisphere(rng.random((d.shape[0], 2)))
    t, b = frame_around(n)
    new_d = local[:, :1] * t + local[:, 1:2] * b + local[:, 2:] * n
    return new_d, w * np.asarray(facet.albedo)[None, :]


def trace(surface, facet: Facet, wi: np.ndarray, n_rays: int, rng: np.random.Generator,
          max_bounces: int = 8) -> Escapes:
    """Send `n_rays` rays from direction wi (unit, (N, 3) per ray or (3,)) onto `surface`."""
    wi = np.broadcast_to(np.asarray(wi, float), (n_rays, 3))
    size = getattr(surface, "size", 1.0)
    p = np.column_stack([rng.random(n_rays) * size, rng.random(n_rays) * size, np.full(n_rays, surface.top + 1e-3)])
    d = -wi.copy()
    w = np.ones((n_rays, facet.n_channels))
    bounces = np.zeros(n_rays, np.int64)
    ray = np.arange(n_rays)
    out_d, out_w, out_b, out_r = [], [], [], []
    lost = 0.0
    for _ in range(MAX_MARCH):
        if p.shape[0] == 0:
            break
        t = surface.step(p, d)
        gone = ~np.isfinite(t) | ((p[:, 2] >= surface.top) & (d[:, 2] > 0))
        if gone.any():
            out_d.append(d[gone]); out_w.append(w[gone]); out_b.append(bounces[gone]); out_r.append(ray[gone])
            keep = ~gone
            p, d, w, bounces, ray, t = p[keep], d[keep], w[keep], bounces[keep], ray[keep], t[keep]
        p = p + np.minimum(t, 1e3)[:, None] * d
        hit = surface.gap(p) < HIT_EPS
        if hit.any():
            n = surface.normal(p[hit])
            new_d, new_w = _bounce(facet, d[hit], n, w[hit], rng)
            d[hit], w[hit] = new_d, new_w
            p[hit] = p[hit] + LEAVE_OFFSET * n
            bounces[hit] += 1
            dead = bounces > max_bounces
            if dead.any():
                lost += float(w[dead].mean(axis=1).sum())
                keep = ~dead
                p, d, w, bounces, ray = p[keep], d[keep], w[keep], bounces[keep], ray[keep]
    lost += float(w.mean(axis=1).sum()) if w.size else 0.0
    cat = (lambda xs, shape: np.concatenate(xs) if xs else np.zeros(shape))
    return Escapes(cat(out_d, (0, 3)), cat(out_w, (0, facet.n_channels)), cat(out_b, (0,)).astype(np.int64),
                   cat(out_r, (0,)).astype(np.int64), n_rays, lost)


@dataclass
class Histogram:
    """An isotropic BRDF slice f(θo, Δφ) for one θi: bins uniform in θo over [0, π/2] and in
    |φo − φi − π| folded over [0, π] (Δφ = 0 is the forward, specular side)."""

    values: np.ndarray  # (C, n_theta, n_phi)
    counts: np.ndarray  # (n_theta, n_phi) rays per bin


def histogram(esc: Escapes, n_theta: int, n_phi: int, phi_in: np.ndarray | float = 0.0,
              max_bounces: int | None = None) -> Histogram:
    """BRDF per bin from escaped rays (optionally only those with ≤ max_bounces bounces)."""
    d, w = esc.directions, esc.weights
    phi_in = np.broadcast_to(np.asarray(phi_in, float), (esc.n_rays,))[esc.rays]
    if max_bounces is not None:
        keep = esc.bounces <= max_bounces
        d, w, phi_in = d[keep], w[keep], phi_in[keep]
    theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
    it = np.clip((theta / (0.5 * np.pi) * n_theta).astype(np.int64), 0, n_theta - 1)
    phi = np.arctan2(d[:, 1], d[:, 0])
    rel = np.abs(np.angle(np.exp(1j * (phi - phi_in - np.pi))))
    ip = np.clip((rel / np.pi * n_phi).astype(np.int64), 0, n_phi - 1)
    flat = it * n_phi + ip
    sums = np.stack([np.bincount(flat, weights=w[:, c], minlength=n_theta * n_phi) for c in range(w.shape[1])])
    counts = np.bincount(flat, minlength=n_theta * n_phi).reshape(n_theta, n_phi)
    edges = np.linspace(0.0, 0.5 * np.pi, n_theta + 1)
    proj = 0.5 * (np.sin(edges[1:]) ** 2 - np.sin(edges[:-1]) ** 2) * (2.0 * np.pi / n_phi)  # both Δφ signs
    values = sums.reshape(-1, n_theta, n_phi) / (esc.n_rays * proj[None, :, None])
    return Histogram(values, counts)
