"""The image metric (issue 34, goal 1): renders of the reference view under maps, as a linear
operator on the BRDF, compared after a cube-root tone curve, and fitted by LM."""

import json
import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from brdflab.fitting.image_metric import SceneImages, map_quadrature, tone
from brdflab.fitting.lm import FitOptions, _Problem, fit, material_from_lobes
from brdflab.fitting.metrics import metric_errors
from brdflab.lighting.envmap import constant
from brdflab.lighting.reference_view import refined_environment_image, relative_rmse
from brdflab.lighting.synthetic_maps import spec
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.models import get_model
from conftest import DATA, ROOT, needs_shared

SMALL = {"view": 12, "dim_width": 16, "fine_width": 64}  # a scene fast enough for a test


def lobes(*specs, combination="Linear") -> AnalyticMaterial:
    """A material of (model, params, scale) lobes."""
    return AnalyticMaterial("m", combination, 3, [Lobe(get_model(m), dict(p), list(s)) for m, p, s in specs])


SOURCE = lobes(("Lambertian", {}, (0.30, 0.20, 0.10)), ("Ward", {"ax": 0.25, "ay": 0.25}, (0.20, 0.20, 0.25)))
GLOSSY = lobes(("Lambertian", {}, (0.1, 0.1, 0.1)), ("CookTorranceGGX", {"m": 0.1, "F0": 0.9}, (0.5, 0.4, 0.3)))


def small_maps(*names, size=(128, 64)):
    return [spec(n).build(*size) for n in names]


def test_the_quadratures_dot_products_are_numpys_sums_bit_for_bit():
    """`_rowdot` stands for (a * b).sum(axis=1) in the quadrature of every image-metric fit: it
    must give the same bits, signed zeros, infinities and NaN included, or fits would move."""
    from brdflab.fitting.image_metric import _rowdot

    rng = np.random.default_rng(7)
    a = rng.normal(size=(200_000, 3)) * 10.0 ** rng.integers(-8, 8, size=(200_000, 3))
    b = rng.normal(size=(200_000, 3))
    for value, share in ((-0.0, 0.05), (0.0, 0.02), (np.inf, 0.001), (np.nan, 0.001)):
        a[rng.random(a.shape) < share] = value
    b[:1000] = -0.0
    with np.errstate(invalid="ignore", over="ignore"):  # inf × 0 and inf − inf: NaN, as intended
        np.testing.assert_array_equal(_rowdot(a, b).view(np.int64), (a * b).sum(axis=1).view(np.int64))


def test_a_render_is_linear_in_the_brdf():
    q = map_quadrature(spec("sun-low-small").build(128, 64), 12, 16, 64)
    a = lobes(("Lambertian", {}, (0.3, 0.2, 0.1)))
    b = lobes(("CookTorranceGGX", {"m": 0.2, "F0": 0.5}, (0.4, 0.5, 0.6)))
    both = lobes(("Lambertian", {}, (0.3, 0.2, 0.1)), ("CookTorranceGGX", {"m": 0.2, "F0": 0.5}, (0.4, 0.5, 0.6)))
    ra, rb, rab = (q.render(m.evaluate, 3) for m in (a, b, both))
    np.testing.assert_allclose(rab, ra + rb, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(q.render(lambda wi, wo: 2.5 * b.evaluate(wi, wo), 3), 2.5 * rb, rtol=1e-12)


def test_a_lambertian_under_a_uniform_sky_renders_its_albedo():
    """∫ f L cos θ dω = π f L on every pixel (the Lambertian lobe is 1/sr times its scale):
    the quadrature's texels cover each pixel's hemisphere with their exact solid angles."""
    q = map_quadrature(constant(2.0, 128, 64), 12, 16, 64)
    image = q.render(lobes(("Lambertian", {}, (0.5, 0.25, 0.1))).evaluate, 3)
    expected = 2.0 * math.pi * np.array([0.5, 0.25, 0.1])[:, None] * np.ones_like(image)
    np.testing.assert_allclose(image, expected, rtol=0.015)
    assert abs(image.mean() / expected.mean() - 1.0) < 0.005


@pytest.mark.parametrize("name", ["sun-low-small", "room-lamps", "studio-rim-light"])
def test_the_quadrature_equals_the_labs_reference_render(name):
    """The operator's render against reference_view's independent texel quadrature (every
    texel near the mirror direction and every bright one split 4 × 4 for every pixel)."""
    env = spec(name).build(256, 128)
    q = map_quadrature(env, 12, 32, 256)
    for material in (SOURCE, GLOSSY):
        ours = q.image(q.render(material.evaluate, 3))
        reference = refined_environment_image(material, env, 12, 12, subdivision=4)
        assert relative_rmse(ours, reference, q.inside) < 0.02, (name, relative_rmse(ours, reference, q.inside))


def test_the_error_is_relative_to_the_toned_source_and_a_zero_brdf_scores_one():
    scene = SceneImages.of_source(SOURCE, small_maps("overcast", "room-one-window"), **SMALL)
    zero, itself = scene.errors([None, SOURCE])
    assert zero == pytest.approx(1.0, rel=1e-12) and itself == pytest.approx(0.0, abs=1e-12)
    # by hand, map by map: RMS of ∛a − ∛y over the RMS of ∛y, the maps' squares averaged
    brighter = lobes(*[(l.model.name, l.params, [1.2 * s for s in l.scale]) for l in SOURCE.lobes])
    by_hand = []
    for q, s, e in zip(scene.quadratures, scene.bounds[:-1], scene.bounds[1:]):
        y = scene.target[:, s:e]
        a = q.render(brighter.evaluate, 3)
        by_hand.append(((np.cbrt(a) - np.cbrt(y)) ** 2).sum() / (np.cbrt(y) ** 2).sum())
    assert scene.errors([brighter])[0] == pytest.approx(math.sqrt(np.mean(by_hand)), rel=1e-10)
    assert scene.errors([brighter])[0] == pytest.approx(1.2 ** (1 / 3) - 1, rel=1e-9)  # 20 % brighter everywhere


def test_the_metric_converges_in_its_resolution():
    """Doubling the view and the map's levels changes a candidate's error by < 1 %."""
    candidate = lobes(("Lambertian", {}, (0.28, 0.2, 0.12)), ("CookTorranceGGX", {"m": 0.3, "F0": 0.8}, (0.3, 0.3, 0.3)))
    maps = small_maps("sun-high-small", "room-one-window", "studio-two-boxes", size=(256, 128))
    base = SceneImages.of_source(SOURCE, maps, view=32, dim_width=32, fine_width=128).errors([candidate])[0]
    for view, dim, fine in ((64, 32, 128), (32, 64, 128), (32, 32, 256)):
        finer = SceneImages.of_source(SOURCE, maps, view=view, dim_width=dim, fine_width=fine).errors([candidate])[0]
        assert abs(finer / base - 1.0) < 0.01, (view, dim, fine, finer, base)


def test_the_fitters_gradient_is_the_metrics_through_the_tone_curve():
    """JᵀR of the fitter's image pass against central differences of the metric computed
    by the other route (each material rendered whole, `SceneImages.errors`)."""
    scene = SceneImages.of_source(SOURCE, small_maps("sun-mid-large", "room-lamps"), **SMALL)
    start = lobes(("Lambertian", {}, (0.2,)), ("Lambertian", {}, (0.2,)), ("Lambertian", {}, (0.2,)),
                  ("CookTorranceGGX", {"m": 0.2, "F0": 0.6}, (0.3,)), ("CookTorranceGGX", {"m": 0.2, "F0": 0.6}, (0.3,)),
                  ("CookTorranceGGX", {"m": 0.2, "F0": 0.6}, (0.3,)), combination="Fixed")
    for k, lobe in enumerate(start.lobes):
        lobe.channel = k % 3
    problem = _Problem(start, scene, FitOptions(metric="image"))
    problem.central = True
    u = problem.initial_u() + 0.1
    cost, _, jtr, error, _ = problem.evaluate(u)
    assert error ** 2 == pytest.approx(cost) and error == pytest.approx(scene.errors([problem.material_of(u, None)])[0])
    h = 1e-5
    for k in range(len(u)):
        up, down = u.copy(), u.copy()
        up[k] += h
        down[k] -= h
        e_up, e_down = (scene.errors([problem.material_of(x, None)])[0] for x in (up, down))
        assert jtr[k] == pytest.approx(0.5 * (e_up ** 2 - e_down ** 2) / (2 * h), rel=1e-3, abs=1e-9)


def test_an_image_fit_finds_a_known_material_and_reports_its_metric():
    scene = SceneImages.of_source(SOURCE, small_maps("sun-high-small", "room-one-window"), **SMALL)
    start = material_from_lobes(["Lambertian", "Ward"], "Linear", 3)
    result = fit(start, scene, FitOptions(metric="image", restarts=False))
    assert result.metric == "image" and result.scored_on == "renders under 2 maps (sun-high-small, room-one-window)"
    assert result.error < 2e-3 and result.error == pytest.approx(metric_errors([result.material], scene, "image")[0])
    assert result.material.lobes[1].params["ax"] == pytest.approx(0.25, rel=0.05)


@needs_shared("merl_slices", "nickel.slice")
def test_on_a_metal_the_image_fit_is_better_in_the_image_by_an_independent_render():
    """Nickel, Lambertian + GGX: the fit by the image metric beats the fit by Ngan's in the
    picture, scored by reference_view's own renders under a map neither fit saw."""
    from brdflab.fitting.samples import samples_of
    from brdflab.sources.files import load_source

    nickel = load_source(DATA / "merl_slices" / "nickel.slice")
    start = material_from_lobes(["Lambertian", "CookTorranceGGX"], "Linear", 3)
    by_image = fit(start, SceneImages.of_source(nickel), FitOptions(metric="image")).material
    by_samples = fit(start, samples_of(nickel), FitOptions()).material
    env = spec("room-window-and-lamp").build(128, 64)  # held out: never used to fit or tune
    reference = refined_environment_image(nickel, env, 16, 16, subdivision=4)
    mask = reference.sum(-1) > 0

    def image_error(material):
        image = refined_environment_image(material, env, 16, 16, subdivision=4)
        return math.sqrt(((tone(image[mask]) - tone(reference[mask])) ** 2).sum() / (tone(reference[mask]) ** 2).sum())

    ours, theirs = image_error(by_image), image_error(by_samples)
    assert ours < 0.8 * theirs, (ours, theirs)


def _cli(*args, cwd):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "brdflab", *args], capture_output=True, text=True, cwd=cwd,
                          env=env, timeout=300)


def test_cli_fits_by_the_image_metric_and_every_fit_reports_both_numbers(tmp_path):
    image = _cli("fit", "example:ward", "--lobes", "Lambertian,CookTorranceGGX", "--metric", "image", "--json",
                 cwd=tmp_path)
    assert image.returncode == 0, image.stderr
    out = json.loads(image.stdout.splitlines()[-1])
    assert out["metric"] == "image" and out["scoredOn"].startswith("renders under 3 maps (") and 0 < out["error"] < 1
    assert out["sampleMetric"] == "Ngan" and out["sampleError"] > 0
    plain = _cli("fit", "example:ward", "--lobes", "Lambertian,CookTorranceGGX", cwd=tmp_path)
    assert plain.returncode == 0, plain.stderr
    said = re.search(r"Ngan error ([0-9.e-]+) on all samples fitted .*; image error ([0-9.e-]+) under "
                     r"sun-high-small, room-one-window, studio-two-boxes", plain.stdout)
    assert said, plain.stdout
    # the image fit is the better one in the image, the sample fit by Ngan's error
    assert out["error"] <= float(said.group(2)) * 1.001
    assert float(said.group(1)) <= out["sampleError"] * 1.001


@pytest.mark.parametrize("args, says", [
    (["--metric", "image", "--env", "missing.exr"], "missing.exr"),
    (["--metric", "image", "--samples", "subset"], "--samples subset"),
    (["--env", "missing.exr"], "--env applies to --metric image"),
    (["--metric", "image", "--compression", "cbrt"], "tone curve"),
])
def test_cli_bad_image_metric_options_exit_2_with_one_line(tmp_path, args, says):
    run = _cli("fit", "example:ward", "--lobes", "Lambertian", *args, cwd=tmp_path)
    assert run.returncode == 2 and says in run.stderr and len(run.stderr.strip().splitlines()) == 1, run.stderr


def test_a_one_channel_source_is_rendered_in_luminance_and_fitted():
    grey = AnalyticMaterial("g", "Linear", 1, [Lobe(get_model("Lambertian"), {}, [0.3]),
                                              Lobe(get_model("Ward"), {"ax": 0.3, "ay": 0.3}, [0.2])])
    env = spec("sun-mid-large").build(128, 64)
    scene = SceneImages.of_source(grey, [env], **SMALL)
    assert scene.target.shape == (1, scene.size)
    # a grey BRDF under a coloured map: the luminance of the RGB render
    rgb = lobes(("Lambertian", {}, (0.3,) * 3), ("Ward", {"ax": 0.3, "ay": 0.3}, (0.2,) * 3))
    q = scene.quadratures[0]
    from brdflab.lighting.env_sampling import LUMINANCE
    np.testing.assert_allclose(scene.target[0], LUMINANCE @ q.render(rgb.evaluate, 3), rtol=1e-10)
    result = fit(material_from_lobes(["Lambertian", "Ward"], "Linear", 1), scene,
                 FitOptions(metric="image", restarts=False))
    assert result.error < 2e-3


def test_the_metric_equals_the_one_computed_from_the_labs_own_renders():
    """The operator's renders against the lab's OpenGL renderer (reference view, MIS 4,096
    samples per pixel, llvmpipe), and the image error computed from those renders instead."""
    from brdflab.render.context import create_context
    from brdflab.render.object_view import ObjectRenderer, RenderSettings

    maps = small_maps("room-one-window", "sun-mid-large", size=(256, 128))
    scene = SceneImages.of_source(SOURCE, maps)
    renderer = ObjectRenderer(create_context())
    squares = []
    for env, q in zip(maps, scene.quadratures):
        renderer.set_environment(env)
        images = []
        for material in (SOURCE, GLOSSY):
            renderer.set_source(material)
            gl = renderer.render(RenderSettings(mode="mis", width=q.inside.shape[1], height=q.inside.shape[0], samples=4096,
                                                reference_view=True))[..., :3]
            ours = q.image(q.render(material.evaluate, 3))
            assert relative_rmse(gl, ours, q.inside) < 0.01
            images.append(gl[q.inside])
        y, a = images
        squares.append(((np.cbrt(a) - np.cbrt(y)) ** 2).sum() / (np.cbrt(y) ** 2).sum())
    assert scene.errors([GLOSSY])[0] == pytest.approx(math.sqrt(np.mean(squares)), rel=0.02)


def test_on_a_mesh_the_metric_renders_what_the_labs_renderer_draws():
    """A mesh's frames (render/gbuffer.py: the object view's own rasterisation, camera and two-
    sided normals) give the operator the lab's own orbit-view render of the mesh: the same
    pixels, and within 1 % against MIS at 4,096 samples — an anisotropic Ward included, whose
    image depends on the mesh's tangents."""
    from brdflab.io.mesh import load_mesh
    from brdflab.render.camera import OrbitCamera
    from brdflab.render.context import create_context
    from brdflab.render.gbuffer import frames_covering
    from brdflab.render.object_view import ObjectRenderer, RenderSettings

    mesh = load_mesh(ROOT / "resources" / "meshes" / "spot.obj")
    env = small_maps("room-one-window", size=(256, 128))[0]
    renderer = ObjectRenderer(create_context())
    renderer.set_mesh(mesh)
    renderer.set_environment(env)
    frames = frames_covering(renderer.ctx, mesh, OrbitCamera(), pixels=812)
    assert 0.85 * 812 <= frames.inside.sum() <= 1.3 * 812
    q = map_quadrature(env, frames)
    height, width = frames.inside.shape
    ward = AnalyticMaterial("aniso", "Linear", 3, [Lobe.create("Ward", [0.6, 0.5, 0.4], ax=0.1, ay=0.3)])
    for material in (GLOSSY, ward):
        renderer.set_source(material)
        gl = renderer.render(RenderSettings(mode="mis", width=width, height=height, samples=4096,
                                            reference_view=False))[..., :3]
        assert np.array_equal(gl.sum(axis=-1) > 0, frames.inside)
        assert relative_rmse(gl, q.image(q.render(material.evaluate, 3)), frames.inside) < 0.01


def test_a_fit_stopped_by_its_time_limit_ends_without_the_second_number(tmp_path):
    run = _cli("fit", "example:ward", "--lobes", "Lambertian,CookTorranceGGX,CookTorranceGGX", "--time-limit", "0.01",
               "--json", cwd=tmp_path)
    out = json.loads(run.stdout.splitlines()[-1])
    assert run.returncode == 0 and out["status"] == "time-limit"
    assert "imageError" not in out  # the limit is the user's: no render after it
