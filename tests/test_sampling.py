"""Importance sampling: ∫ pdf = 1 over the sphere and samples distributed as the pdf."""

import numpy as np
import pytest

from brdflab.models import all_models
from brdflab.geometry.vec import spherical_to_cartesian

SAMPLABLE = [m for m in all_models() if m.samplable]

# moderate lobes, so that a fixed quadrature grid resolves them
PARAMS = {
    "BlinnPhong": {"Exponent": 30.0},
    "Phong": {"Exponent": 20.0},
    "LafortuneIso": {"Cxy": -0.8, "Cz": 0.6, "Exponent": 15.0},
    "LafortuneAniso": {"Cx": -0.9, "Cy": -0.5, "Cz": 0.7, "Exponent": 12.0},
    "Ward": {"ax": 0.2, "ay": 0.4},
    "WardDuer": {"ax": 0.3, "ay": 0.2},
    "AshikhminShirley": {"nu": 40.0, "nv": 10.0, "F0": 0.1},
    "CookTorrance": {"m": 0.3, "F0": 0.2},
    "CookTorranceGGX": {"m": 0.3, "F0": 0.2},
    "Kurt": {"mx": 0.25, "my": 0.45, "F0": 0.3, "alpha": 0.4},
    "Schwenk": {"smoothness": 0.3, "metalness": 0.5, "tint": 1.0},
}
VIEWS_DEG = [(0.0, 0.0), (35.0, 20.0), (70.0, 130.0)]


def sphere_grid(n_z=600, n_phi=1200):
    """Midpoint rule in (z = cos θ, φ) over the whole sphere: equal-area cells."""
    z = -1.0 + (np.arange(n_z) + 0.5) * (2.0 / n_z)
    phi = (np.arange(n_phi) + 0.5) * (2.0 * np.pi / n_phi)
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    dirs = spherical_to_cartesian(np.arccos(zz), pp)
    return dirs, (2.0 / n_z) * (2.0 * np.pi / n_phi)


def wo_of(theta, phi):
    return spherical_to_cartesian(np.radians(theta), np.radians(phi))


@pytest.mark.parametrize("model", SAMPLABLE, ids=lambda m: m.name)
def test_pdf_integrates_to_one_over_the_sphere(model):
    dirs, area = sphere_grid()
    p = PARAMS.get(model.name, {})
    for view in VIEWS_DEG:
        wo = np.broadcast_to(wo_of(*view), dirs.shape)
        total = model.pdf(dirs, wo, p).sum() * area
        assert total == pytest.approx(1.0, abs=5e-3), view


@pytest.mark.parametrize("model", SAMPLABLE, ids=lambda m: m.name)
def test_samples_follow_the_pdf(model):
    """Histogram of 400k samples in 16 × 32 equal-area bins against ∫ pdf over each bin."""
    rng = np.random.default_rng(7)
    n, nz, nphi, sub = 400_000, 16, 32, 12
    p = PARAMS.get(model.name, {})
    for view in VIEWS_DEG:
        wo = wo_of(*view)
        u = rng.random((n, 2))
        wi = model.sample(np.broadcast_to(wo, (n, 3)), u, p)
        assert np.allclose(np.linalg.norm(wi, axis=1), 1.0, atol=1e-9)
        zi = np.clip(((wi[:, 2] + 1.0) * 0.5 * nz).astype(int), 0, nz - 1)
        pi = (np.mod(np.arctan2(wi[:, 1], wi[:, 0]), 2 * np.pi) / (2 * np.pi) * nphi).astype(int) % nphi
        counts = np.bincount(zi * nphi + pi, minlength=nz * nphi)
        dirs, area = sphere_grid(nz * sub, nphi * sub)
        dens = model.pdf(dirs, np.broadcast_to(wo, dirs.shape), p) * area
        expected = dens.reshape(nz, sub, nphi, sub).sum(axis=(1, 3)).ravel() * n
        # bins near wi = −wo hold the integrable 1/|wo·h| singularity of half-vector
        # samplers, which a midpoint rule cannot resolve: compare everywhere else
        centres = spherical_to_cartesian(
            np.arccos(-1.0 + (np.arange(nz) + 0.5) * 2.0 / nz)[:, None],
            ((np.arange(nphi) + 0.5) * 2.0 * np.pi / nphi)[None, :],
        ).reshape(-1, 3)
        near_singularity = centres @ -wo > np.cos(0.4)
        big = (expected > 200) & ~near_singularity
        assert expected[big].sum() > 0.6 * n  # most of the mass is compared
        # Poisson noise: a few standard deviations, plus 2 % for the quadrature of the expectation
        dev = np.abs(counts[big] - expected[big]) / (np.sqrt(expected[big]) * 5 + 0.02 * expected[big])
        assert dev.max() < 1.0, (view, float(dev.max()))
        assert counts[~big & ~near_singularity].sum() < 0.1 * n


@pytest.mark.parametrize("model", SAMPLABLE, ids=lambda m: m.name)
def test_pdf_is_positive_wherever_the_lobe_is(model, rng):
    """An unbiased estimator needs p > 0 wherever f cos > 0 (checked on the lobe's own samples)."""
    from conftest import random_upper

    p = PARAMS.get(model.name, {})
    wo = random_upper(rng, 2000)
    wi = random_upper(rng, 2000)
    f = model.evaluate(wi, wo, p)
    pdf = model.pdf(wi, wo, p)
    significant = f > 1e-6 * f.max()
    assert np.all(pdf[significant] > 0.0)


@pytest.mark.parametrize("m", [0.05, 0.3, 0.8])
def test_ggx_samples_visible_normals_so_no_weight_exceeds_one(m):
    """GGX draws half vectors from the normals visible from wo (Heitz 2018): with F0 = 1 each
    sample's weight f cos θi / pdf is G₁(wi) ≤ 1, at grazing views too. Half vectors from D cos θh
    gave weights G₁(wi) G₁(wo) (wo·h) / (cos θo cos θh), up to several at grazing views: 64 of
    them over a white map were 3.1 % off per pixel, 0.6 % now (docs/mis.md)."""
    from brdflab.models.cook_torrance import smith_ggx_g1
    from brdflab.models.registry import get_model

    ggx = get_model("CookTorranceGGX")
    params = {"m": m, "F0": 1.0}
    rng = np.random.default_rng(5)
    for theta in (0.0, 45.0, 80.0, 89.0):
        wo = np.broadcast_to(wo_of(theta, 30.0), (20000, 3))
        wi = ggx.sample(wo, rng.random((20000, 2)), params)
        up = wi[:, 2] > 0
        weight = ggx.evaluate(wi[up], wo[up], params) * wi[up, 2] / ggx.pdf(wi[up], wo[up], params)
        assert weight.max() <= 1.0 + 1e-9, (theta, weight.max())
        np.testing.assert_allclose(weight, smith_ggx_g1(wi[up, 2], m), rtol=1e-6)
