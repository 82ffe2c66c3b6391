"""The lobe viewer draws what the material says, for analytic and measured sources."""

import numpy as np
import pytest

from brdflab.geometry.geodesic import geodesic_hemisphere
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.sources.measured import tabulate
from brdflab.render.lobe_view import LobeViewer


@pytest.fixture(scope="module")
def viewer():
    from brdflab.render.context import create_context

    return LobeViewer(create_context())


def glossy(n):
    return AnalyticMaterial("g", "Linear", 3, [Lobe.create("Lambertian", [0.05] * 3), Lobe.create("Phong", [0.5] * 3, Exponent=n)])


def coloured(img, color, tol=60):
    return (np.abs(img.astype(int) - np.array(color) * 255 * 0.6).max(axis=2) < tol).sum()


def test_geodesic_hemisphere():
    for level in range(6):
        v, f = geodesic_hemisphere(level)
        assert np.all(v[:, 2] >= 0) and np.allclose(np.linalg.norm(v, axis=1), 1, atol=1e-6)
        assert f.max() < len(v)
    assert len(geodesic_hemisphere(7)[1]) > 160_000  # BRDFLab drew 328,192 triangles over a sphere
    with pytest.raises(ValueError):
        geodesic_hemisphere(9)


def test_the_rim_is_one_circle_just_above_the_horizon():
    """Every vertex on the hemisphere's open edge sits at z = RIM_Z: the icosahedron's edges do
    not follow the horizon, and a rim left where they end zigzagged (level 5: from z = 0.001
    to 0.021), a saw-toothed edge on every lobe."""
    from brdflab.geometry.geodesic import RIM_Z

    for level in range(8):
        v, f = geodesic_hemisphere(level)
        edges, count = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1),
                                 axis=0, return_counts=True)
        rim = np.unique(edges[count == 1])
        assert len(rim) == (count == 1).sum() == 6 * 2**level  # one closed loop
        assert np.allclose(v[rim, 2], RIM_Z, atol=1e-7) and (v[np.setdiff1d(np.arange(len(v)), rim), 2] > RIM_Z).all()
        corners = v[f].astype(float)
        outward = np.einsum("ij,ij->i", np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]),
                            corners.mean(axis=1))
        assert (outward > 0).all()  # no triangle folded over by moving its rim vertices


def test_parameter_change_changes_the_lobe(viewer):
    viewer.set_fitted(None)
    viewer.set_original(glossy(10.0))
    broad = viewer.render(160, 160)
    viewer.update_material(0, glossy(200.0))
    sharp = viewer.render(160, 160)
    assert (broad != sharp).any()
    background = np.array([0.12, 0.12, 0.14]) * 255
    lobe_pixels = lambda img: (np.abs(img - background).max(axis=2) > 10).sum()
    assert lobe_pixels(broad) > 500 and lobe_pixels(sharp) > 100


def test_incident_direction_moves_the_lobe(viewer):
    viewer.set_original(glossy(50.0))
    viewer.settings.theta_i = 10.0
    a = viewer.render(160, 160)
    viewer.settings.theta_i = 60.0
    b = viewer.render(160, 160)
    assert np.abs(a.astype(int) - b).sum() > 1000


def test_original_and_fitted_overlay(viewer):
    material = glossy(30.0)
    viewer.set_original(tabulate(material))  # measured path: (θo, φo) texture
    viewer.set_fitted(material)
    viewer.settings.translucent_fit = False
    img = viewer.render(200, 200)
    viewer.set_fitted(None)
    only = viewer.render(200, 200)
    assert (img != only).any()
    viewer.settings.translucent_fit = True


def test_transfer_functions_and_channels(viewer):
    viewer.set_original(glossy(30.0))
    images = []
    for transfer in ("linear", "cbrt", "log"):
        viewer.settings.transfer = transfer
        images.append(viewer.render(120, 120))
    assert (images[0] != images[1]).any() and (images[1] != images[2]).any()
    viewer.settings.channel = "red"
    viewer.settings.cosine = True
    assert viewer.render(120, 120).any()
    viewer.settings.channel, viewer.settings.cosine, viewer.settings.transfer = "luminance", False, "cbrt"


def test_sharing_a_context_with_the_object_view(viewer):
    """The object view's depth pre-pass must not leave state that hides the lobes."""
    from brdflab.lighting.envmap import constant
    from brdflab.io.mesh import uv_sphere
    from brdflab.render.object_view import ObjectRenderer, RenderSettings

    objects = ObjectRenderer(viewer.ctx)
    objects.set_material(glossy(20.0))
    objects.set_environment(constant(1.0, 16, 8))
    objects.set_mesh(uv_sphere(8, 16))
    objects.render(RenderSettings("fis", 32, 32, samples=8, reference_view=False))
    viewer.set_original(glossy(20.0))
    img = viewer.render(120, 120)
    background = np.array([0.12, 0.12, 0.14]) * 255
    assert (np.abs(img - background).max(axis=2) > 10).sum() > 200


def test_a_surface_refined_near_a_narrow_peak_finds_it_and_stays_closed():
    """Ward ax = 0.001 peaks between level 5's vertices (the uniform surface reaches a third of
    its peak); the refined surface has the peak as a vertex, every edge in at most two faces."""
    from brdflab.geometry import lobe_surface as surface
    from brdflab.geometry.vec import spherical_to_cartesian

    ward = AnalyticMaterial("w", "Linear", 3, [Lobe.create("Ward", [0.5] * 3, ax=0.001, ay=0.1)])
    wi = spherical_to_cartesian(np.radians(30.0), 0.0)
    shape = surface.LobeShape(tuple(float(x) for x in wi))
    peak = surface.lobe_radii(ward, shape, np.array([[-wi[0], -wi[1], wi[2]]]))[0]
    uniform = surface.lobe_radii(ward, shape, geodesic_hemisphere(5)[0].astype(float)).max()
    dirs, faces, found = surface.refined_surface([ward], shape, 5)
    assert uniform < 0.5 * peak and found == pytest.approx(peak, rel=1e-6)
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    assert np.unique(edges, axis=0, return_counts=True)[1].max() == 2  # conforming: no cracks
    assert np.all(dirs[:, 2] > 0) and np.allclose(np.linalg.norm(dirs, axis=1), 1, atol=1e-6)
    assert surface.surface_error(ward, shape, 7)[0] > 0.3  # even level 7 misses it: refinement is needed
