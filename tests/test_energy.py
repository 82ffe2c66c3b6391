"""Directional albedo by quadrature and the energy check."""

import math

import numpy as np
import pytest

from brdflab.material.albedo import conserve_energy, directional_albedo, energy_check, lobe_albedo
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.geometry.vec import spherical_to_cartesian


def lambert(rho, channels=3):
    return AnalyticMaterial("l", "Linear", channels, [Lobe.create("Lambertian", [rho / math.pi] * channels)])


def test_lambertian_albedo_is_rho():
    views = spherical_to_cartesian(np.radians([0, 30, 60, 85]), 0.0)
    np.testing.assert_allclose(directional_albedo(lambert(0.7), views), 0.7, rtol=1e-3)


def test_phong_albedo_matches_its_closed_form_at_normal_incidence():
    # normalised Phong at wo = n: ∫ (n+2)/(2π) cos^n α cos θ dω with the lobe around n = 1 exactly
    a = lobe_albedo(Lobe.create("Phong", [1.0], Exponent=30.0), np.array([[0.0, 0.0, 1.0]]))
    assert float(a[0]) == pytest.approx(1.0, rel=2e-3)


def test_non_samplable_lobe_uses_product_quadrature():
    # Strauss with s = 0, m = 0, t = 0: diffuse part C/π (albedo C) plus rj·cos^3 α/cosθi
    lobe = Lobe.create("Strauss", [1.0], smoothness=0.0, metalness=0.0, transparency=1.0, color=0.5)
    # t = 1 leaves rd = 0 and rn = 0: only rj = min(1, 0.1 j) specular, bounded albedo
    a = lobe_albedo(lobe, np.array([[0.0, 0.0, 1.0]]))
    assert 0.0 <= float(a[0]) < 0.2


def test_material_that_conserves_energy_passes():
    report = energy_check(lambert(0.9))
    assert report.conserves
    np.testing.assert_allclose(report.max_albedo, 0.9, rtol=1e-3)


def test_material_that_creates_energy_fails_and_can_be_scaled_down():
    bright = AnalyticMaterial("b", "Linear", 3, [
        Lobe.create("Lambertian", [0.6 / math.pi, 0.2 / math.pi, 0.2 / math.pi]),
        Lobe.create("BlinnPhong", [0.5, 0.05, 0.05], Exponent=100.0),
    ])
    report = energy_check(bright)
    assert not report.conserves
    assert report.max_albedo[0] > 1.0 and report.max_albedo[1] < 1.0
    fixed = conserve_energy(bright)
    after = energy_check(fixed)
    assert after.conserves
    assert after.max_albedo[0] == pytest.approx(1.0, rel=1e-6)
    # the channel that conserved energy is left alone
    assert fixed.lobes[1].scale[1] == bright.lobes[1].scale[1]


def test_fixed_material_energy_is_per_channel():
    m = AnalyticMaterial("f", "Fixed", 2, [
        Lobe.create("Lambertian", [1.5 / math.pi], channel=0),
        Lobe.create("Lambertian", [0.5 / math.pi], channel=1),
    ])
    report = energy_check(m)
    np.testing.assert_allclose(report.max_albedo, [1.5, 0.5], rtol=1e-3)
    assert not report.conserves
    assert energy_check(conserve_energy(m)).conserves


def test_anisotropic_check_visits_azimuths():
    m = AnalyticMaterial("w", "Linear", 1, [Lobe.create("Ward", [1.0], ax=0.05, ay=0.5)])
    report = energy_check(m)
    assert report.max_albedo.shape == (1,)
    assert np.isfinite(report.max_albedo).all()
