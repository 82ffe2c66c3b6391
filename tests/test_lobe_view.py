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


def _lobe_pixels(img: np.ndarray) -> np.ndarray:
    """Where the image shows the original's orange (shaded), not the axes' red, green, blue or yellow."""
    rgb = img.astype(float)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return (r > 60) & (g > 0.35 * r) & (g < 0.85 * r) & (b < g)


def test_a_lobe_narrower_than_a_pixel_is_a_solid_line_framed_at_every_level(viewer):
    """Issue 37 §4: Ward ax = ay = 0.001 was a dotted line at subdivision 5 (a needle thinner
    than a pixel, rasterised); with auto (level 7), the uniform surface drawn while its refined
    one was computed, framed by level 5's vertices, ran off the top, then flipped back."""
    from brdflab.geometry.lobe_surface import lobe_tips, refined_surface

    viewer = LobeViewer(viewer.ctx)  # the default camera and settings, whatever earlier tests set
    needle = AnalyticMaterial("n", "Linear", 3, [Lobe.create("Lambertian", [0.3] * 3),
                                                 Lobe.create("Ward", [0.5] * 3, ax=0.001, ay=0.001)])
    viewer.set_original(needle)
    viewer.settings.level = 5
    shape, sources = viewer.settings.shape, viewer.analytic_sources()
    dirs, faces, peak = refined_surface(sources, shape, 5)
    viewer.set_refined(viewer.surface_key(), dirs, faces, peak, lobe_tips(sources, shape, dirs))
    size = 400
    img = viewer.render(size, size)
    lobe = _lobe_pixels(img)
    # the needle's axis on screen: every point along it is the lobe's colour (within a pixel)
    tip = lobe_tips(sources, shape, dirs)[0] * viewer.gain()
    clip = viewer.view_projection(size, size) @ np.array([[0, 0, 0, 1], [*tip, 1]], float).T
    ends = (clip[:2] / clip[3]).T
    cols = (ends[:, 0] + 1) / 2 * size
    rows = (1 - ends[:, 1]) / 2 * size
    t = np.linspace(0.2, 0.9, 200)
    c, r = np.round(cols[0] + t * (cols[1] - cols[0])).astype(int), np.round(rows[0] + t * (rows[1] - rows[0])).astype(int)
    assert abs(c[-1] - c[0]) < abs(r[-1] - r[0])  # steep on screen: a pixel per row when solid
    near = lobe | np.roll(lobe, 1, axis=1) | np.roll(lobe, -1, axis=1)  # within a pixel sideways
    solid = near[r, c].mean()
    assert solid > 0.97, f"{solid:.0%} of the needle drawn"  # before: a dotted line
    gain = viewer.gain()
    viewer.settings.level = 7  # auto's level: drawn uniform until its own refined surface comes
    assert viewer.gain() == pytest.approx(gain)  # before: 54× larger (1.49 against 0.028)
    img = viewer.render(size, size)
    border = np.concatenate([_lobe_pixels(img)[0], _lobe_pixels(img)[:, 0], _lobe_pixels(img)[:, -1]])
    assert not border.any()  # before: a stub running off the top
