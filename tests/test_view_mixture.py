"""Rough lobes drawn by lookups fitted to their shape at every view (lighting/view_mixture.py):
the fit's table, and issue 36 goal 1 on synthetic maps of every class — tuning and held-out —
against the subdivided texel quadrature (an independent route: it never reads the stack)."""

import numpy as np
import pytest

from brdflab.lighting import prefilter, view_mixture
from brdflab.lighting.reference_view import pixel_relative_rmse, refined_environment_image, sphere_view
from brdflab.lighting.split_sum import material_split, prefiltered_image
from brdflab.lighting.synthetic_maps import spec
from brdflab.material.analytic import AnalyticMaterial, Lobe

SIZE = 24
BELOW_60 = 0.5  # n·v of the reference view's pixels counted (θo < 60°)


def lobe_material(model: str, **params) -> AnalyticMaterial:
    return AnalyticMaterial("m", "Linear", 3, [Lobe.create(model, [1.0] * 3, **params)])


def test_a_rough_lobe_is_fitted_and_its_weights_keep_the_albedos_energy():
    """Each view's weights sum to 1 (the energy is the albedo table's); every lookup reads a
    layer of the lobe's own kernel family; at normal view every lookup is along n (the plane of
    incidence is any there)."""
    table = material_split(lobe_material("CookTorranceGGX", m=0.3, F0=1.0))[0].mixture
    assert table.shape == (view_mixture.COSINES, view_mixture.LOOKUPS, 3)
    used = table[..., 2] > 0.0
    np.testing.assert_allclose(table[..., 2].sum(axis=1), 1.0, atol=1e-9)
    first = prefilter.layer_of("ggx", 1)
    assert ((table[..., 1][used] >= first) & (table[..., 1][used] < first + len(prefilter.ALPHAS) - 1)).all()
    assert (table[-1, :, 0][used[-1]] == 0.0).all()
    # the fitted lookups move toward the normal and beyond the mirror direction as the view tilts
    assert np.ptp(table[1, :, 0][used[1]]) > 0.0


@pytest.mark.parametrize("model, params, fitted", [
    ("CookTorranceGGX", {"m": 0.3, "F0": 1.0}, True), ("CookTorrance", {"m": 0.3, "F0": 1.0}, True),
    ("Ward", {"ax": 0.3, "ay": 0.3}, True), ("CookTorranceGGX", {"m": 0.02, "F0": 1.0}, False),
    ("Ward", {"ax": 0.1, "ay": 0.3}, False), ("Phong", {"Exponent": 10.0}, False), ("Lambertian", {}, False)])
def test_which_lobes_are_fitted(model, params, fitted):
    """Isotropic glossy lobes of a half-vector kernel and α ≥ MIN_ROUGHNESS; anisotropic lobes keep
    their taps, Phong-kernel lobes (a wi-space lobe keeps its shape) and diffuse ones their split."""
    assert (material_split(lobe_material(model, **params))[0].mixture is not None) == fitted


# one tuning and one held-out map of each class, and studio-two-boxes, whose soft boxes have more
# texels than the stack has lights (6.8–9.6 % below 60° before they were lit in blocks; docs/prefiltered.md)
MAPS = ("overcast", "hazy-afternoon-sky", "sun-low-small", "sunrise-tiny", "room-one-window",
        "room-window-and-lamp", "city-night", "moonlit-night", "studio-strip", "studio-rim-light",
        "studio-two-boxes")


@pytest.mark.parametrize("model, params", [("CookTorranceGGX", {"m": 0.3, "F0": 1.0}),
                                           ("CookTorrance", {"m": 0.3, "F0": 1.0})])
def test_rough_lobes_are_within_five_percent_per_pixel_below_60_degrees(model, params):
    """Issue 36 goal 1 on the maps above (128 × 64, per pixel in luminance): 0.1–3.2 % at 32²
    (benchmarks/prefiltered_maps.py);
    before the fit, GGX was 5.1–7.6 % and Beckmann 7.4–39.5 % on the skies, suns, the held-out
    night and the held-out studio."""
    view = sphere_view(SIZE, SIZE)
    below = view.inside & (view.normal[..., 2] > BELOW_60)
    mat = lobe_material(model, **params)
    errors = {}
    for name in MAPS:
        env = spec(name).build(128, 64)
        errors[name] = pixel_relative_rmse(prefiltered_image(mat, env, SIZE, SIZE),
                                           refined_environment_image(mat, env, SIZE, SIZE), below)
    assert max(errors.values()) < 0.05, errors
