"""The synthetic maps (lighting/synthetic_maps.py): the classes and the held-out third, exact
power of small suns and lamps, the published sky formulas, determinism.

Sums over texels use each lat-long row's solid angle in closed form, written out here."""

from __future__ import annotations

import math

import numpy as np
import pytest

from brdflab.lighting.synthetic_maps import (CATALOGUE, CLASSES, add_disc, catalogue, overcast, preetham_zenith,
                                             spec, sun_direction)

LUMA = np.array([0.2126, 0.7152, 0.0722])


def row_solid_angles(width: int, height: int) -> np.ndarray:
    return np.array([2 * math.pi / width * (math.cos(math.pi * r / height) - math.cos(math.pi * (r + 1) / height))
                     for r in range(height)])[:, None]


def test_every_class_has_tuning_and_held_out_maps_and_a_third_is_held_out():
    assert {m.kind for m in CATALOGUE} == set(CLASSES)
    for kind in CLASSES:
        held = [m.held_out for m in CATALOGUE if m.kind == kind]
        assert any(held) and not all(held), kind
    assert len(catalogue(held_out=True)) == len(CATALOGUE) // 3
    assert len({m.name for m in CATALOGUE}) == len(CATALOGUE)


@pytest.mark.parametrize("radius", [0.05, 0.27, 3.0])
def test_a_disc_keeps_its_power_whatever_its_size(radius):
    image = np.zeros((64, 128, 3))
    add_disc(image, sun_direction(37.0, 15.0), radius, (2.0, 1.0, 0.5))
    solid = row_solid_angles(128, 64)
    expected = 2 * math.pi * (1 - math.cos(math.radians(radius)))
    for c, radiance in enumerate((2.0, 1.0, 0.5)):
        assert float((image[..., c] * solid).sum()) == pytest.approx(radiance * expected, rel=1e-9)
    rows, cols = np.nonzero(image[..., 0])  # where: around 37° elevation, 15° azimuth
    v = (rows.mean() + 0.5) / 64
    assert 90 - 180 * v == pytest.approx(37.0, abs=1.5)


def test_cie_overcast_is_three_times_brighter_at_the_zenith_than_at_the_horizon():
    image = overcast(256, 128)
    lum = image @ LUMA
    top, horizon = math.cos(math.pi * 0.5 / 128), math.cos(math.pi * 63.5 / 128)  # rows 0 and 63's centres
    assert lum[0].mean() / lum[63].mean() == pytest.approx((1 + 2 * top) / (1 + 2 * horizon), rel=1e-6)
    assert (1 + 2 * top) / (1 + 2 * horizon) == pytest.approx(3.0, rel=0.03)


def test_preetham_zenith_matches_the_published_formula():
    """Preetham et al. 1999, A.2, written out again for T = 3, θs = 40°."""
    t, s = 3.0, math.radians(40.0)
    chi = (4 / 9 - t / 120) * (math.pi - 2 * s)
    lum = (4.0453 * t - 4.9710) * math.tan(chi) - 0.2155 * t + 2.4192
    x = (t * t * (0.00166 * s**3 - 0.00375 * s**2 + 0.00209 * s) + t * (-0.02903 * s**3 + 0.06377 * s**2
         - 0.03202 * s + 0.00394) + 0.11693 * s**3 - 0.21196 * s**2 + 0.06052 * s + 0.25886)
    y = (t * t * (0.00275 * s**3 - 0.00610 * s**2 + 0.00317 * s) + t * (-0.04214 * s**3 + 0.08970 * s**2
         - 0.04153 * s + 0.00516) + 0.15346 * s**3 - 0.26756 * s**2 + 0.06670 * s + 0.26688)
    assert preetham_zenith(t, s) == pytest.approx((lum, x, y), rel=1e-12)
    assert x < 0.3 and y < 0.32  # a clear sky's zenith is blue (white is 0.313, 0.329)


def test_a_clear_sky_is_brightest_round_its_sun_and_blue_overhead():
    env = spec("clear-noon-sky").build()
    lum = env.data @ LUMA
    row, col = np.unravel_index(np.argmax(lum), lum.shape)
    elevation = 90 - 180 * (row + 0.5) / env.height
    assert elevation == pytest.approx(65.0, abs=6.0)
    zenith = env.data[0].mean(axis=0)
    assert zenith[2] > zenith[0]


def test_classes_have_their_character():
    for m in CATALOGUE:
        env = m.build()
        assert env.data.dtype == np.float32 and env.data.shape == (128, 256, 3) and np.isfinite(env.data).all()
        lum = env.data.astype(float) @ LUMA
        power = lum * row_solid_angles(256, 128)
        order = np.argsort(lum, axis=None)[::-1]
        cover = np.cumsum(np.broadcast_to(row_solid_angles(256, 128), lum.shape).ravel()[order])
        n = int(np.searchsorted(cover, 1e-3 * 4 * math.pi)) + 1
        small = power.ravel()[order[:n]].sum() / power.sum()
        dynamic = lum.max() / lum[lum > 0].min()
        if m.kind == "sky":
            assert small < 0.02 and dynamic < 100, m.name
        if m.kind == "sun":
            assert small > 0.5 and dynamic > 1e4, m.name
        if m.kind == "night":
            assert 1e5 < dynamic <= 1e7 and small > 0.5, m.name
        if m.kind == "interior":
            assert dynamic > 100, m.name


def test_maps_are_deterministic():
    for name in ("sunrise-tiny", "room-window-and-lamp", "city-night"):
        assert spec(name).build().data.tobytes() == spec(name).build().data.tobytes()
