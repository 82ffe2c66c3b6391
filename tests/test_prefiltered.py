"""Prefiltered environment lighting (the split sum): its stack against direct quadrature, its
images against `environment_image` on real maps, where it fails (grazing views), and the
mode's surfaces (renderer, CLI, `brdflab models`)."""

import json

import numpy as np
import pytest

from brdflab.cli import main
from brdflab.lighting import prefilter
from brdflab.lighting.envmap import EnvironmentMap, constant, load_environment, read_exr
from brdflab.lighting.reference_view import environment_image, relative_rmse, sphere_view
from brdflab.lighting.split_sum import material_split, prefiltered_image
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.models import all_models
from brdflab.models.base import SPLIT_SUM_KINDS
from brdflab.render.object_view import ObjectRenderer, RenderSettings
from conftest import DATA, needs_shared

SIZE = 48
MAPS = ("venice_sunset_1k.hdr", "forest.exr")


def material(*lobes) -> AnalyticMaterial:
    return AnalyticMaterial("m", "Linear", 3, list(lobes))


def view_angles(size: int = SIZE) -> np.ndarray:
    """Angle between n and wo (= +Z) of every reference-view pixel, in degrees."""
    return np.degrees(np.arccos(np.clip(sphere_view(size, size).normal[..., 2], 0.0, 1.0)))


@pytest.fixture(scope="module")
def renderer():
    from brdflab.render.context import create_context

    return ObjectRenderer(create_context())


@pytest.fixture(scope="module")
def maps():
    return {name: load_environment(DATA / "envmaps" / name).downsampled(128, 64) for name in MAPS}


def render(renderer, env, mat, size=SIZE):
    renderer.set_environment(env)
    renderer.set_material(mat)
    return renderer.render(RenderSettings(mode="prefiltered", width=size, height=size))


def test_a_bright_area_of_more_texels_than_lights_is_lit_in_blocks():
    """studio-two-boxes' soft boxes have 1,450 texels above the contrast: each is dimmed to the
    contrast's level, and its excess goes to the light of its block (3 × 3 texels here), at most
    MAX_LIGHTS of them. Dimmed map plus excess is the map texel by texel; a light's power is its
    texels' excess × solid angle; its direction lies within its block."""
    from brdflab.lighting.synthetic_maps import spec

    env = spec("studio-two-boxes").build(128, 64)
    dimmed, lights, excess = prefilter.bright_lights(env)
    d, solid = env.texel_directions()
    lum = env.data.astype(float) @ prefilter.LUMINANCE
    level = prefilter.LIGHT_CONTRAST * prefilter.mean_luminance(lum, solid)
    bright = lum > level
    assert bright.sum() > prefilter.MAX_LIGHTS >= len(lights) > prefilter.MAX_LIGHTS // 2
    np.testing.assert_array_equal(excess[..., 3] >= 0, bright)
    np.testing.assert_allclose(dimmed.data + excess[..., :3], env.data, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(dimmed.data[bright] @ prefilter.LUMINANCE, level, rtol=1e-5)
    index = excess[..., 3].astype(int)[bright]
    power = excess[..., :3][bright] * np.broadcast_to(solid, lum.shape)[bright][:, None]
    np.testing.assert_allclose(np.stack([power[index == k].sum(0) for k in range(len(lights))]), lights[:, 3:],
                               rtol=1e-4)
    for k in range(len(lights)):
        cosines = d[bright][index == k] @ lights[k, :3]
        assert cosines.max() > 0.999 and cosines.min() > np.cos(np.radians(9))
    # a map of fewer bright texels keeps one light per texel, at its centre
    _, lights, excess = prefilter.bright_lights(spec("studio-strip").build(128, 64))
    rows, cols = np.nonzero(excess[..., 3] >= 0)
    assert len(rows) == len(lights)
    np.testing.assert_allclose(d[rows, cols], lights[excess[rows, cols, 3].astype(int), :3], atol=1e-6)


def test_stack_layers_are_the_texel_quadrature():
    """The FFT convolution equals the direct sum over texels of L Ω K(d·t) (normalised), L the
    map without its brightest texels (they are the stack's lights)."""
    rng = np.random.default_rng(3)
    env = EnvironmentMap(rng.gamma(0.5, 1.0, (16, 32, 3)).astype(np.float32))
    stack = prefilter.build_stack(env)
    dimmed, lights, _ = prefilter.bright_lights(env)
    np.testing.assert_array_equal(stack.lights, lights)
    d, solid = env.texel_directions()
    dirs, omega = d.reshape(-1, 3), np.broadcast_to(solid, (16, 32)).ravel()
    radiance = dimmed.data.reshape(-1, 3) * omega[:, None]
    for row, col in ((0, 5), (7, 31), (12, 17)):
        c = np.clip(dirs @ d[row, col], -1.0, 1.0)
        np.testing.assert_allclose(stack.irradiance()[row, col], np.maximum(c, 0) @ radiance, rtol=1e-4)
        for kernel, index in (("beckmann", 6), ("ggx", 11)):
            k = prefilter.specular_kernel(kernel, prefilter.ALPHAS[index])(c)
            np.testing.assert_allclose(stack.layer(kernel, index)[row, col], k @ radiance / (k @ omega), rtol=1e-4)
        np.testing.assert_array_equal(stack.layer("ggx", 0), dimmed.data)  # α = 0: the map itself


def test_the_stack_is_built_once_per_map(renderer):
    env = EnvironmentMap(np.random.default_rng(1).random((32, 64, 3)).astype(np.float32))
    before = prefilter.stack_builds()
    first = prefilter.prefiltered_stack(env)
    assert prefilter.prefiltered_stack(EnvironmentMap(env.data.copy())) is first  # keyed by the pixels
    mat = material(Lobe.create("BlinnPhong", [0.5] * 3, Exponent=50.0))
    render(renderer, env, mat, 16)
    render(renderer, env, mat, 16)
    assert prefilter.stack_builds() == before + 1
    prefilter.prefiltered_stack(EnvironmentMap(env.data[:, ::-1].copy()))
    assert prefilter.stack_builds() == before + 2


def test_layer_blend_brackets_the_roughness():
    for alpha in (0.0, 0.01, 0.02, 0.1, 0.33, 0.9, 1.0, 3.0):
        lo, hi, t = prefilter.layer_blend("ggx", alpha)
        a_lo, a_hi = (prefilter.ALPHAS[i - prefilter.layer_of("ggx", 0)] for i in (lo, hi))
        assert a_lo <= min(alpha, 1.0) <= a_hi and 0.0 <= t <= 1.0


@pytest.mark.parametrize("window", [False, True])
def test_the_gpu_draws_what_its_numpy_twin_computes(renderer, window):
    """shaders/prefiltered.glsl against lighting/split_sum.prefiltered_image, every kind of lobe
    (anisotropic ones' taps and albedo over φo included, and a rough GGX lobe's fitted lookups,
    lighting/view_mixture.py) under a map with a sun (the lights), and with a window of more
    bright texels than lights (lit in blocks, the diffuse share by the excess's irradiance),
    turned by 45° on the GPU against the map's columns turned in NumPy."""
    data = np.random.default_rng(2).gamma(0.7, 1.0, (32, 64, 3)).astype(np.float32)
    data[10, 20] = 5000.0
    if window:
        data[4:19, 30:48] = 300.0
    assert prefilter.bright_lights(EnvironmentMap(data)).blocks == window
    mat = material(Lobe.create("Lambertian", [0.1, 0.2, 0.3]), Lobe.create("Phong", [0.3] * 3, Exponent=40.0),
                   Lobe.create("LafortuneIso", [0.2] * 3, Cxy=0.6, Cz=0.5, Exponent=8.0),
                   Lobe.create("Strauss", [0.5] * 3, smoothness=0.7), Lobe.create("Ward", [0.3] * 3, ax=0.05, ay=0.3),
                   Lobe.create("Principled", [1.0] * 3, roughness=0.4, anisotropic=0.8),
                   Lobe.create("CookTorranceGGX", [0.4] * 3, m=0.3, F0=0.6))
    assert material_split(mat)[-1].mixture is not None
    inside = sphere_view(32, 32).inside
    img = render(renderer, EnvironmentMap(data), mat, 32)
    assert relative_rmse(img, prefiltered_image(mat, EnvironmentMap(data), 32, 32), inside) < 1e-4
    turned = renderer.render(RenderSettings(mode="prefiltered", width=32, height=32, env_rotation=45.0))
    assert relative_rmse(turned, prefiltered_image(mat, EnvironmentMap(np.roll(data, 8, axis=1)), 32, 32), inside) < 1e-4


@needs_shared("envmaps", "forest.exr")
@pytest.mark.parametrize("name", MAPS)
def test_a_lambertian_matches_quadrature(renderer, maps, name):
    mat = material(Lobe.create("Lambertian", [0.25, 0.2, 0.15]))
    ref = environment_image(mat, maps[name], SIZE, SIZE)
    assert relative_rmse(render(renderer, maps[name], mat), ref, sphere_view(SIZE, SIZE).inside) < 0.01


GLOSSY = {
    "Blinn-Phong n=100": material(Lobe.create("BlinnPhong", [0.5] * 3, Exponent=100.0)),
    "GGX m=0.2": material(Lobe.create("CookTorranceGGX", [1.0] * 3, m=0.2, F0=0.9)),
}


@needs_shared("envmaps", "forest.exr")
@pytest.mark.parametrize("name", MAPS)
@pytest.mark.parametrize("lobe", sorted(GLOSSY))
def test_glossy_is_close_at_normal_and_at_grazing_views(renderer, maps, name, lobe):
    """Within 4 % where θo < 30° and within 3 % at 65–85°. The grazing band was the split sum's
    known failure (7–9 % here, over 1.5× the normal band: the lobe's narrowing, shift and
    horizon at grazing views lost with its n = v = r shape); rough lobes are now drawn by
    lookups fitted to their shape at every view (lighting/view_mixture.py): 0.3–1.0 %."""
    mat, env = GLOSSY[lobe], maps[name]
    img, ref = render(renderer, env, mat), environment_image(mat, env, SIZE, SIZE)
    inside, angle = sphere_view(SIZE, SIZE).inside, view_angles()
    assert relative_rmse(img, ref, inside & (angle < 30.0)) < 0.04
    assert relative_rmse(img, ref, inside & (angle >= 65.0) & (angle < 85.0)) < 0.03


def test_energy_is_right_for_every_model_in_a_white_furnace(renderer):
    """Under a constant map the split sum is the albedo factor alone: against the texel
    quadrature of the same integral, for every registry model, away from the rim."""
    env = constant(1.0, 128, 64)
    inside, angle = sphere_view(12, 12).inside, view_angles(12)
    for model in all_models():
        mat = material(Lobe.create(model.name, [0.5] * 3))
        img = render(renderer, env, mat, 12)
        ref = environment_image(mat, env, 12, 12)
        assert relative_rmse(img, ref, inside & (angle < 70.0)) < 0.02, model.name


def test_every_registry_model_renders_finite_non_negative_images(renderer):
    rng = np.random.default_rng(5)
    env = EnvironmentMap(rng.gamma(0.3, 2.0, (32, 64, 3)).astype(np.float32))
    for model in all_models():
        for params in ({}, *model.starts[:2]):
            mat = material(Lobe.create("Lambertian", [0.05] * 3), Lobe.create(model.name, [0.5] * 3, **params))
            img = render(renderer, env, mat, 24)
            assert np.isfinite(img).all() and img.min() >= 0.0 and img.max() > 0.0, (model.name, params)


@needs_shared("merl_slices", "gold-metallic-paint3.slice")
def test_a_measured_source_is_drawn_through_its_proxy_lobes(renderer):
    from brdflab.sources.measured import read_slice

    renderer.set_environment(constant(1.0, 64, 32))
    renderer.set_source(read_slice(DATA / "merl_slices" / "gold-metallic-paint3.slice").to_full())
    img = renderer.render(RenderSettings(mode="prefiltered", width=24, height=24))
    assert np.isfinite(img).all() and img.min() >= 0.0 and img[sphere_view(24, 24).inside].min() > 0.0


def test_models_say_how_they_map_to_the_split_sum(capsys):
    assert main(["models", "--json"]) == 0
    models = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["models"]
    for m in models:
        rule = m["prefiltered"]
        assert rule["kind"] in SPLIT_SUM_KINDS and 0.0 < rule["roughness"] <= 1.0 and rule["rule"], m["id"]
    kinds = {m["id"]: m["prefiltered"]["kind"] for m in models}
    assert kinds["Lambertian"] == "diffuse" and kinds["BlinnPhong"] == "mirror" and kinds["LafortuneIso"] == "axis"
    assert main(["models"]) == 0
    assert "prefiltered: mirror, Beckmann α = √(2/(n+2))" in capsys.readouterr().out


@needs_shared("envmaps", "studio.exr")
def test_cli_renders_the_prefiltered_mode(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "sphere.exr"
    assert main(["render", "example:fig2", "--mode", "prefiltered", "--env", str(DATA / "envmaps" / "studio.exr"),
                 "--view", "reference", "--size", "48,48", "--out", str(out), "--json"]) == 0
    payload = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert payload["settings"]["mode"] == "prefiltered" and payload["frame_ms"] > 0
    img = read_exr(out)
    inside = sphere_view(48, 48).inside
    assert np.isfinite(img).all() and (img[inside] > 0).all() and (img[~inside] == 0).all()


@needs_shared("envmaps", "venice_sunset_1k.hdr")
def test_study_part_maps_the_error_over_glossiness_and_view_angle(quick_study):
    from brdflab.study.prefiltered import BANDS, QUICK_EXPONENTS

    out, payload, study = quick_study  # the session's `brdflab study --quick`
    assert payload["charts"]["prefiltered"] == ["prefiltered_stability.png"]
    assert (out / "prefiltered_stability.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    part = study["parts"]["prefiltered"]
    assert part["frame_ms"] > 0
    (entry,) = part["maps"].values()
    errors = np.array(entry["errors"], float)
    assert errors.shape == (len(QUICK_EXPONENTS), len(BANDS)) and np.isfinite(errors).all()
    # a sharp lobe (not fitted: α < MIN_ROUGHNESS) is worse at grazing views than at normal ones, the
    # split sum's n = v = r failure; lobes fitted at every view (view_mixture.py) are not (n = 5 and 30:
    # 0.4–0.5 % at 80–85° under venice)
    from brdflab.lighting.view_mixture import MIN_ROUGHNESS
    from brdflab.models.base import blinn_roughness

    fitted = np.array([blinn_roughness(n) >= MIN_ROUGHNESS for n in QUICK_EXPONENTS])
    assert fitted.any() and not fitted.all()
    assert (errors[~fitted, -1] > errors[~fitted, 0]).all() and (errors[fitted, -1] < 0.1).all()



def test_a_bright_area_is_lit_exactly_not_blurred_across_the_horizon(renderer):
    """A strip light larger than the 32 lights of old was blurred by the lobe's kernel into
    directions below the surface's horizon (GGX m = 0.3, reference view: up to 41× too bright
    at grazing views, 624 % per pixel); every texel 4× the map's mean is now a light, evaluated
    with the clamped cosine (docs/prefiltered.md)."""
    from brdflab.lighting.env_sampling import LUMINANCE
    from brdflab.lighting.reference_view import pixel_relative_rmse, refined_environment_image
    from brdflab.lighting.synthetic_maps import spec

    env = spec("studio-strip").build(128, 64)
    lum = env.data.astype(float) @ LUMINANCE
    _, solid = env.texel_directions()
    mean = float((lum * solid).sum() / np.broadcast_to(solid, lum.shape).sum())
    _, lights, _ = prefilter.bright_lights(env)
    assert len(lights) == np.count_nonzero(lum > prefilter.LIGHT_CONTRAST * mean) > prefilter.LIGHTS
    mat = material(Lobe.create("CookTorranceGGX", [0.5] * 3, m=0.3, F0=1.0))
    size = 32
    with renderer.ctx:  # the CLI's test before this one left its own context current
        image = render(renderer, env, mat, size)
    error = pixel_relative_rmse(image, refined_environment_image(mat, env, size, size), sphere_view(size, size).inside)
    assert error < 0.03
    # a map without bright areas keeps the 32 brightest texels as before
    sky = spec("overcast").build(128, 64)
    assert len(prefilter.bright_lights(sky)[1]) == prefilter.LIGHTS
