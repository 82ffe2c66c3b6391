"""MIS with the prefiltered image as a control variate (lighting/control_variate.py,
shaders/mis_control.glsl): what the control adds back is its integral, by an independent
quadrature; the estimate is unbiased for any weight; on the held-out maps of every class
(`synthetic_maps`, checked last, never tuned on) a Lambertian is within issue 36's 2 % per pixel
at 64 samples and a rough lobe far closer than plain MIS. The shader equals its NumPy twin
in tests/test_auto_twins.py."""

import numpy as np
import pytest

from brdflab.lighting.control_variate import control_values, map_control, pixel_control
from brdflab.lighting.envmap import EnvironmentMap
from brdflab.lighting.reference_view import pixel_relative_rmse, refined_environment_image, sphere_view
from brdflab.lighting.synthetic_maps import catalogue
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.render.object_view import ObjectRenderer, RenderSettings, independent_image

MAPS = {spec.name: spec for spec in catalogue()}
HELD_OUT = [spec.name for spec in catalogue() if spec.held_out]  # one per class: sky, sun, interior, night, studio


def lobe(name: str, **params) -> AnalyticMaterial:
    return AnalyticMaterial(name, "Linear", 3, [Lobe.create(name, [0.8, 0.7, 0.6], **params)])


def diffuse_and_rough() -> AnalyticMaterial:
    return AnalyticMaterial("two", "Linear", 3, [Lobe.create("Lambertian", [0.3, 0.2, 0.1]),
                                                Lobe.create("CookTorranceGGX", [0.6] * 3, m=0.3, F0=0.9)])


@pytest.fixture(scope="module")
def renderer():
    from brdflab.render.context import create_context

    return ObjectRenderer(create_context())


@pytest.mark.parametrize("map_name", ["city-night", "studio-strip", "studio-two-boxes"])
def test_what_the_control_adds_back_is_its_integral(map_name):
    """P (the stack's irradiance and layers read at the lookups, plus the lights) against g
    integrated over the sphere by a texel quadrature four times finer than the stack's, point by
    point: the only difference is how the stack holds a convolution (its texel quadrature at
    texel centres, read bilinearly), measured ≤ 0.001 % of the view's brightest pixel under the
    city's lamps and the strip light (one light a texel), 0.19 % under the soft boxes (GGX
    m = 0.1; a light a block of texels, the boxes' rest in the layers)."""
    env = MAPS[map_name].build(128, 64)
    view = sphere_view(6, 6)
    frames = (view.normal[view.inside], view.tangent[view.inside], view.bitangent[view.inside])
    for material in (diffuse_and_rough(), lobe("CookTorranceGGX", m=0.1, F0=1.0)):
        control = map_control(env, material)
        terms = pixel_control(material, control.stack, frames)
        assert terms.layers.shape[1] > 0  # the rough lobe's lookups are in g
        h, w = control.excess.shape[:2]
        fine = EnvironmentMap(np.zeros((4 * h, 4 * w, 3), np.float32), "fine")
        d, solid = fine.texel_directions()
        d, solid = d.reshape(-1, 3), np.broadcast_to(solid, (4 * h, 4 * w)).reshape(-1)
        total = np.zeros_like(terms.exact)
        for i in range(0, len(d), 8192):
            world = np.broadcast_to(d[i:i + 8192], (len(frames[0]), *d[i:i + 8192].shape))
            total += (control_values(terms, control.stack, control.excess, frames, world)
                      * solid[i:i + 8192, None]).sum(1)
        assert np.abs(total - terms.exact).max() <= 0.006 * np.abs(terms.exact).max(), map_name


def test_any_weight_is_unbiased(renderer):
    """At 4,096 samples the control's estimate meets the subdivided texel quadrature whatever
    its weight (β = 1, the chosen one, and 0.3 held fixed), under a map of lamps where plain
    MIS at that count is still noisy: a biased control would leave its bias at any count."""
    env = MAPS["room-lamps"].build(128, 64)
    material = diffuse_and_rough()
    size = 12
    inside = sphere_view(size, size).inside
    reference = refined_environment_image(material, env, size, size)
    renderer.set_source(material)
    renderer.set_environment(env)
    chosen = renderer.control_weight()
    assert 0.5 < chosen <= 1.0
    key = renderer.prefiltered.material_key(material)
    for weight in (1.0, chosen, 0.3):
        renderer.remember_control_weight(key, material, env, weight)
        image = renderer.render(RenderSettings("mis", size, size, samples=4096))
        assert pixel_relative_rmse(image, reference, inside) < 0.006, weight


@pytest.mark.parametrize("map_name", HELD_OUT)
def test_held_out_maps_at_64_samples(renderer, map_name):
    """Issue 36 goal 2 on the maps kept out of every choice: the window's MIS at 64 samples, the
    RMS over three independent images of each pixel's relative error in luminance against the
    subdivided texel quadrature. Measured: a Lambertian 0.03–0.78 % (plain MIS 2.9–9.3 %); GGX
    m = 0.3 1.36–2.73 % (plain 2.7–8.3 %), within 2 % on three of the five (the lamp-lit room
    2.10 %, the moonlit night 2.73 %): the control at most half plain MIS's error."""
    env = MAPS[map_name].build(128, 64)
    size = 24
    inside = sphere_view(size, size).inside
    for material, bound in ((lobe("Lambertian"), 0.02), (lobe("CookTorranceGGX", m=0.3, F0=1.0), None)):
        reference = refined_environment_image(material, env, size, size)
        renderer.set_source(material)
        renderer.set_environment(env)
        errors = {}
        for control in (False, True):
            settings = RenderSettings("mis", size, size, samples=64, mis_control=control)
            errors[control] = float(np.sqrt(np.mean([pixel_relative_rmse(independent_image(renderer, settings, seed),
                                                                         reference, inside) ** 2 for seed in range(3)])))
        if bound is not None:
            assert errors[True] <= bound, (map_name, material.name, errors)
        assert errors[True] <= 0.7 * errors[False], (map_name, material.name, errors)


def test_render_says_the_control_and_its_weight(tmp_path, capsys):
    """`render --mode mis` draws with the control and says its weight (JSON and one line);
    `--mis-control off` is plain MIS, another image of the same scene."""
    import json

    from brdflab.cli import main
    from brdflab.lighting.envmap import read_exr

    images = {}
    for state in ("on", "off"):
        out = tmp_path / f"{state}.exr"
        assert main(["render", "example:fig2", "--mode", "mis", "--view", "reference", "--size", "16,16",
                     "--samples", "16", "--mis-control", state, "--out", str(out), "--json"]) == 0
        said = json.loads(capsys.readouterr().out)["settings"]["mis_control"]
        assert said["on"] == (state == "on") and (0.0 < said["weight"] <= 1.0) == (state == "on")
        images[state] = read_exr(out)
    assert not np.array_equal(images["on"], images["off"])
    assert main(["render", "example:fig2", "--mode", "mis", "--view", "reference", "--size", "8,8", "--samples", "4",
                 "--out", str(tmp_path / "x.png")]) == 0
    assert capsys.readouterr().out.startswith("MIS control: weight ")


def test_mis_without_a_map_says_so(renderer):
    """MIS asks for its control's weight before it draws: without a map that is the renderer's
    one clear error, not a failure inside the weight's pilot."""
    from brdflab.errors import BRDFLabError

    fresh = ObjectRenderer(renderer.ctx)
    fresh.set_source(lobe("Lambertian"))
    with pytest.raises(BRDFLabError, match="no environment map"):
        fresh.render(RenderSettings("mis", 8, 8, samples=4))


@pytest.mark.parametrize("model, params", [("CookTorrance", {"m": 0.2}), ("BlinnPhong", {"Exponent": 100.0})])
def test_the_weight_does_not_trade_the_view_for_its_pixels(renderer, model, params):
    """β is chosen for the error Auto judges, the larger of the view's relative RMSE and the
    per-pixel one: under the shipped sunset (the lighting study's map, reduced as it reduces it)
    the control at 64 samples is no worse than plain MIS by either measure, over four
    independent images. Chosen for the per-pixel error alone, β = 0.66 took Cook–Torrance m = 0.2
    from 3.0 to 2.4 % per pixel and from 3.7 to 8.2 % over the view."""
    from brdflab.io.resources import data_dir
    from brdflab.lighting.envmap import load_environment
    from brdflab.lighting.reference_view import relative_rmse
    from brdflab.study.lighting import reduced

    env = reduced(load_environment(data_dir("resources") / "envmaps" / "venice_sunset_1k.hdr"))
    material = lobe(model, **params)
    size = 48
    inside = sphere_view(size, size).inside
    reference = refined_environment_image(material, env, size, size)
    renderer.set_source(material)
    renderer.set_environment(env)
    errors = {}
    for control in (False, True):
        images = [independent_image(renderer, RenderSettings("mis", size, size, samples=64, mis_control=control), seed)
                  for seed in range(4)]
        errors[control] = [float(np.sqrt(np.mean([measure(image, reference, inside) ** 2 for image in images])))
                           for measure in (relative_rmse, pixel_relative_rmse)]
    assert max(errors[True]) <= 1.05 * max(errors[False]), errors
    assert errors[True][0] <= 1.1 * errors[False][0], errors  # the view's error is not traded for the pixels'
