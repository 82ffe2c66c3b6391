"""The reference view's texel quadrature, the independent route renders and twins are checked
against: it evaluates only the (texel, pixel) pairs above the pixel's horizon, and must equal
the quadrature written out over every pair."""

import numpy as np
import pytest

from brdflab.io.resources import data_dir
from brdflab.io.xmlio import load
from brdflab.lighting.envmap import EnvironmentMap
from brdflab.lighting.reference_view import environment_image, sphere_view

SIZE = 8


@pytest.mark.parametrize("name", ["fig2_lambertian_lafortune", "ward"])
def test_the_texel_quadrature_is_the_sum_over_every_texel_and_pixel(name):
    material = load(data_dir("materials") / f"{name}.xml").material
    env = EnvironmentMap(np.random.default_rng(3).random((8, 16, 3)).astype(np.float32) ** 4 * 5)
    view = sphere_view(SIZE, SIZE)
    d, solid = env.texel_directions()
    d, radiance = d.reshape(-1, 3), (env.data * solid[:, :, None]).reshape(-1, 3)
    wo_all = view.to_local(np.array([0.0, 0.0, 1.0]))
    expected = np.zeros((SIZE, SIZE, 3))
    for row, col in np.argwhere(view.inside):
        frame = np.stack([view.tangent[row, col], view.bitangent[row, col], view.normal[row, col]])
        wi = d @ frame.T  # every texel, those below the horizon too
        f = material.evaluate(wi, np.broadcast_to(wo_all[row, col], wi.shape))[:, :3]
        expected[row, col] = (f * np.maximum(wi[:, 2], 0.0)[:, None] * radiance).sum(axis=0)
    image = environment_image(material, env, SIZE, SIZE)
    np.testing.assert_allclose(image, expected, rtol=1e-12, atol=1e-15 * np.abs(expected).max())
    assert (image[view.inside] > 0).all() and (image[~view.inside] == 0).all()
