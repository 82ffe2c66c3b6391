"""Auto lighting (lighting/auto.py): deterministic choices from the pilot alone, that honour
the tolerance against the quadrature on small cases, avoid SH under a sun for sharp lobes,
and predict errors within a factor of the measured ones; and `brdflab render --mode auto`."""

import json

import numpy as np
import pytest

from brdflab.cli import main
from brdflab.lighting.auto import choose_lighting, predict_all
from brdflab.lighting.auto_pilot import make_pilot
from brdflab.lighting.envmap import load_environment
from brdflab.lighting.reference_view import environment_image, pixel_relative_rmse, relative_rmse, sphere_view
from brdflab.lighting.synthetic_maps import spec
from brdflab.io import xmlio
from brdflab.io.resources import data_dir
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.render.object_view import ObjectRenderer, RenderSettings
from conftest import DATA, needs_shared

SIZE = 48
TOLERANCE = 0.02
VENICE = data_dir("resources") / "envmaps" / "venice_sunset_1k.hdr"
QUARRY = DATA / "envmaps" / "quarry_01_1k.hdr"


def lobe(model: str, **params) -> AnalyticMaterial:
    return AnalyticMaterial(model, "Linear", 3, [Lobe.create(model, [0.5] * 3, **params)])


def small(path) -> object:
    return load_environment(path).downsampled(128, 64)


@pytest.fixture(scope="module")
def renderer():
    from brdflab.render.context import create_context

    return ObjectRenderer(create_context())


def measured_error(renderer, material, env, mode: str, setting) -> float:
    """The setting rendered (reference view, 48²) against the texel quadrature."""
    renderer.set_source(material)
    renderer.set_environment(env)
    if mode == "sh":
        renderer.set_sh_order(setting)
    image = renderer.render(RenderSettings(mode, SIZE, SIZE, samples=setting if mode in ("fis", "mis") else 1))
    return relative_rmse(image, environment_image(material, env, SIZE, SIZE), sphere_view(SIZE, SIZE).inside)


def test_choice_is_deterministic_and_explained():
    env = small(VENICE)
    first = choose_lighting(lobe("BlinnPhong", Exponent=100.0), env, TOLERANCE).as_dict()
    second = choose_lighting(lobe("BlinnPhong", Exponent=100.0), env, TOLERANCE).as_dict()
    assert first == second
    assert first["reasons"][-1].startswith("chose ")
    costs = [c["cost_ms"] for c in first["candidates"]]
    assert costs == sorted(costs)
    cheaper = [c for c in first["candidates"] if c["cost_ms"] < next(
        c["cost_ms"] for c in first["candidates"] if (c["mode"], c["setting"]) == (first["mode"], first["setting"]))]
    assert all(c["predicted_error"] > TOLERANCE for c in cheaper)  # nothing cheaper was predicted within


@pytest.mark.parametrize("model, params", [("Lambertian", {}), ("BlinnPhong", {"Exponent": 1000.0})])
def test_the_choice_weighs_cheapest_first_and_predicts_nothing_dearer_than_its_pick(model, params):
    """The choice stops weighing at the first candidate predicted within: what it weighed is
    every candidate up to its pick, cheapest first, with the same predictions as weighing them
    all, and its pick is the cheapest of all within (the dearest, FIS and MIS at 1,024 samples,
    were most of the time spent choosing a 5 ms prefiltered frame)."""
    env, material = small(VENICE), lobe(model, **params)
    choice = choose_lighting(material, env, TOLERANCE)
    every = predict_all(material, material, env, make_pilot(material, env))
    weighed = [(c.label, c.predicted_error) for c in choice.candidates]
    assert weighed == [(c.label, c.predicted_error) for c in every[:len(weighed)]]
    within = [c for c in every if c.predicted_error <= TOLERANCE]
    assert choice.within and (choice.mode, choice.setting) == (within[0].mode, within[0].setting)
    assert choice.candidates[-1].label == within[0].label and len(weighed) < len(every)


def test_a_map_with_bright_areas_makes_prefiltered_dearer_by_its_lights():
    """Its stack lights the bright areas exactly (studio-strip: 120 lights, ~0.11 ms a light per
    256² frame): the frame-cost model weighs prefiltered after what its lights make cheaper."""
    from brdflab.lighting.auto import LIGHTS, frame_cost, predict_all
    from brdflab.lighting.prefilter import bright_lights, reduced

    material = lobe("Lambertian")
    costs = {}
    for name in ("overcast", "studio-strip"):
        env = spec(name).build(128, 64)
        lights = len(bright_lights(reduced(env))[1])
        (pref,) = [c for c in predict_all(material, material, env, make_pilot(material, env)) if c.mode == "prefiltered"]
        assert pref.cost_ms == pytest.approx(frame_cost("prefiltered", None, lights))
        costs[name] = (lights, pref.cost_ms)
    assert costs["overcast"] == (LIGHTS, pytest.approx(5.0))
    assert costs["studio-strip"][0] > LIGHTS and costs["studio-strip"][1] > 2 * costs["overcast"][1]


def test_a_rough_lobe_drawn_by_fitted_lookups_makes_prefiltered_dearer():
    """A rough lobe's fitted lookups (lighting/view_mixture.py) cost about half a 32-light frame more."""
    from brdflab.lighting.auto import LIGHTS, frame_cost, predict_all

    material, env = lobe("CookTorranceGGX", m=0.3, F0=1.0), spec("overcast").build(128, 64)
    (pref,) = [c for c in predict_all(material, material, env, make_pilot(material, env)) if c.mode == "prefiltered"]
    assert pref.cost_ms == pytest.approx(frame_cost("prefiltered", None, LIGHTS, 1)) == pytest.approx(7.5, rel=0.01)


def test_a_map_met_for_the_first_time_is_judged_without_building_its_stack():
    """Render Auto meeting a map for the first time predicts the prefiltered image from the
    few layers the material reads (the whole stack, 37 layers, took 1.3–2 s: most of a first
    choice): the stack is not built, and the prediction equals the one made with the whole
    stack in memory, bit for bit (each layer is the same quadrature built alone)."""
    from brdflab.lighting import prefilter

    env = spec("sunrise-tiny").build(128, 64)
    material = AnalyticMaterial("plastic", "Linear", 3, [Lobe.create("Lambertian", [0.3] * 3),
                                                        Lobe.create("CookTorranceGGX", [0.5] * 3, m=0.3, F0=0.5)])
    prefilter._CACHE.clear()
    builds = prefilter.stack_builds()
    first = choose_lighting(material, env, TOLERANCE)
    assert prefilter.stack_builds() == builds and not prefilter.is_cached(env)
    prefilter.prefiltered_stack(env)  # as after a prefiltered frame
    again = choose_lighting(material, env, TOLERANCE)
    assert prefilter.stack_builds() == builds + 1
    assert "prefiltered" in [c.mode for c in first.candidates]
    assert first.as_dict() == again.as_dict()


def test_the_prefiltered_prediction_and_the_control_share_one_build_of_their_layers(monkeypatch):
    """On a map met for the first time, Auto builds the layers that the prefiltered prediction and
    MIS's control read once, together (two builds were 0.1 s of a car paint's 1.1 s choice)."""
    from brdflab.lighting import prefilter
    from brdflab.lighting.control_variate import control_layers

    env = spec("room-lamps").build(128, 64)
    material = AnalyticMaterial("plastic", "Linear", 3, [Lobe.create("Lambertian", [0.3] * 3),
                                                        Lobe.create("CookTorranceGGX", [0.5] * 3, m=0.3, F0=0.5)])
    prefilter._CACHE.clear()
    builds, build_layers = [], prefilter.build_layers
    monkeypatch.setattr(prefilter, "build_layers", lambda split, indices: builds.append(set(indices)) or
                        build_layers(split, indices))
    every = predict_all(material, material, env, make_pilot(material, env))
    assert {"prefiltered", "mis"} <= {c.mode for c in every}
    assert len(builds) == 1 and control_layers(material) <= builds[0]


@pytest.mark.parametrize("name", ["room-one-window", "studio-two-boxes"])  # the second's lights are blocks
def test_some_layers_of_a_stack_are_its_layers_bit_for_bit(name):
    from brdflab.lighting import prefilter

    env = spec(name).build(128, 64)
    prefilter._CACHE.clear()
    wanted = {prefilter.layer_of("ggx", 7), prefilter.layer_of("phong", 0), prefilter.layer_of("beckmann", 12)}
    some = prefilter.stack_layers(env, wanted)
    whole = prefilter.build_stack(env)
    assert sorted(some.layers) == sorted({0, prefilter.EXCESS_IRRADIANCE, *wanted})
    for index, layer in some.layers.items():
        assert np.array_equal(layer, whole.layers[index]), index
    assert np.array_equal(some.light_directions, whole.light_directions)
    assert np.array_equal(some.light_power, whole.light_power)
    assert np.array_equal(some.excess, whole.excess)
    assert some.blocks == whole.blocks == (name == "studio-two-boxes")
    assert whole.excess_irradiance().any() == whole.blocks


def test_lambertian_under_a_smooth_map_is_cheap_and_within_tolerance(renderer):
    env, material = small(VENICE), lobe("Lambertian")
    choice = choose_lighting(material, env, TOLERANCE)
    assert choice.mode == "prefiltered" or (choice.mode == "sh" and choice.setting <= 4)
    assert choice.within
    assert measured_error(renderer, material, env, choice.mode, choice.setting) <= TOLERANCE


def test_the_per_pixel_error_counts_every_pixel_alike_down_to_a_floor():
    """The error a user sees: a sphere 5 % off everywhere is 5 % off; one off by 5 % over its
    dim half only is 3.5 % off pixel by pixel where the view's RMS error, dominated by the
    bright half, says 0.5 %; a pixel darker than 1 % of the mean counts against that 1 %."""
    inside = sphere_view(SIZE, SIZE).inside
    reference = np.zeros((SIZE, SIZE, 3))
    reference[inside] = 1.0
    assert pixel_relative_rmse(1.05 * reference, reference, inside) == pytest.approx(0.05)
    dim = reference.copy()
    dim[:SIZE // 2] *= 0.1
    off = dim.copy()
    off[:SIZE // 2] *= 1.05
    half = inside[:SIZE // 2].sum() / inside.sum()
    assert pixel_relative_rmse(off, dim, inside) == pytest.approx(0.05 * np.sqrt(half))
    assert relative_rmse(off, dim, inside) == pytest.approx(0.005 * np.sqrt(half / (0.01 * half + 1 - half)))
    black = reference.copy()
    black[inside & (np.arange(SIZE)[None, :] < 2)] = 0.0  # a few black pixels, then lit by 1e-3
    mean = (black[inside] @ [0.2126, 0.7152, 0.0722]).mean()
    lit = np.where(black == 0.0, 1e-3, black) * inside[..., None]
    share = (inside & (np.arange(SIZE)[None, :] < 2)).sum() / inside.sum()
    assert pixel_relative_rmse(lit, black, inside) == pytest.approx(np.sqrt(share) * 1e-3 / (0.01 * mean))


@pytest.mark.parametrize("map_name", ["overcast", "sunrise-tiny"])  # a sky it may tune on; a held-out sun
def test_the_pick_is_within_the_tolerance_pixel_by_pixel(renderer, map_name):
    """Issue 36 goal 3: judged by the view's RMS error alone, Auto picked FIS 64 for GGX
    m = 0.3 under the overcast sky (1.9 % over the view, 4.8 % pixel by pixel: the dim rim off,
    the bright centre not) and the prefiltered mode under small suns (0.7 % over the view,
    13 % pixel by pixel: the sun's highlight right, the sky's light on the rest of the sphere
    not). The pick rendered is within the tolerance pixel by pixel against the texel
    quadrature (1.5×: the prediction is an estimate at a few hundred pixels)."""
    size = 32
    env = spec(map_name).build(128, 64)
    material = lobe("CookTorranceGGX", m=0.3, F0=1.0)
    choice = choose_lighting(material, env, TOLERANCE)
    assert choice.within, choice.reasons
    renderer.set_source(material)
    renderer.set_environment(env)
    samples = choice.setting if choice.mode in ("fis", "mis") else 1
    image = renderer.render(RenderSettings(choice.mode, size, size, samples=samples))
    reference = environment_image(material, env, size, size)
    assert pixel_relative_rmse(image, reference, sphere_view(size, size).inside) <= 1.5 * TOLERANCE, choice.reasons


@needs_shared("envmaps", "quarry_01_1k.hdr")
def test_sharp_lobe_under_the_sun_does_not_pick_sh(renderer):
    env, material = small(QUARRY), lobe("BlinnPhong", Exponent=1000.0)
    choice = choose_lighting(material, env, TOLERANCE)
    assert choice.mode != "sh"
    sh = [c for c in choice.candidates if c.mode == "sh"]
    assert min(c.predicted_error for c in sh) > 5 * TOLERANCE  # SH cannot hold a sun's highlight
    # and SH really fails there; the choice's own error is not judged against E: the 128 × 64
    # quadrature cannot resolve this lobe under the sun (its reference floor is ~29 %)
    sh_error = measured_error(renderer, material, env, "sh", 4)
    assert sh_error > 10 * TOLERANCE
    assert measured_error(renderer, material, env, choice.mode, choice.setting) < sh_error / 3


@pytest.mark.parametrize("model, params, mode, setting", [
    ("Lambertian", {}, "fis", 16),
    ("BlinnPhong", {"Exponent": 100.0}, "mis", 64),
    ("BlinnPhong", {"Exponent": 100.0}, "sh", 4),
    ("BlinnPhong", {"Exponent": 100.0}, "prefiltered", None),
])
def test_predicted_error_is_within_a_factor_of_the_measured(renderer, model, params, mode, setting):
    env, material = small(VENICE), lobe(model, **params)
    predicted = next(c.predicted_error for c in predict_all(material, material, env, make_pilot(material, env))
                     if (c.mode, c.setting) == (mode, setting))
    measured = measured_error(renderer, material, env, mode, setting)
    assert measured / 3 <= predicted <= 3 * measured, (predicted, measured)


def test_cli_render_auto_reports_its_pick(tmp_path, monkeypatch, capsys):
    material = tmp_path / "lambert.xml"
    xmlio.save(xmlio.BRDFDocument(lobe("Lambertian")), material)
    monkeypatch.chdir(tmp_path)
    assert main(["render", str(material), "--mode", "auto", "--tolerance", "0.02", "--view", "reference",
                 "--size", "32,32", "--env", str(VENICE), "--out", "auto.exr", "--json"]) == 0
    payload = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    auto = payload["auto"]
    assert payload["settings"]["mode"] == auto["mode"] != "auto"
    assert auto["predicted_error"] <= auto["tolerance"] == 0.02
    assert auto["reasons"] and np.isfinite(auto["predicted_error"])


def test_cli_rejects_a_bad_tolerance(tmp_path, capsys):
    material = tmp_path / "lambert.xml"
    xmlio.save(xmlio.BRDFDocument(lobe("Lambertian")), material)
    assert main(["render", str(material), "--mode", "auto", "--tolerance", "1.5", "--view", "reference",
                 "--size", "8,8", "--env", str(VENICE), "--out", str(tmp_path / "x.exr")]) == 2
    err = capsys.readouterr().err
    assert "tolerance" in err and "Traceback" not in err


def test_cli_prefiltered_says_where_the_split_sum_cannot_be_trusted(tmp_path, capsys):
    """Issue 36 goal 1: where the split sum is far off (an anisotropic lobe, Ward 0.1 × 0.3, under
    a held-out sunrise with a tiny sun: about 17 % per pixel; GGX m = 0.1 was 10 % before rough
    lobes were fitted at every view, 1.4 % since) the mode says so, on stderr and in the JSON; a
    Lambertian under the same map, exact, is trusted."""
    from brdflab.lighting.envmap import write_exr

    env = tmp_path / "sunrise.exr"
    write_exr(env, spec("sunrise-tiny").build(128, 64).data)
    said = {}
    for name, material in (("ward", lobe("Ward", ax=0.1, ay=0.3)), ("lambert", lobe("Lambertian"))):
        path = tmp_path / f"{name}.xml"
        xmlio.save(xmlio.BRDFDocument(material), path)
        assert main(["render", str(path), "--mode", "prefiltered", "--view", "reference", "--size", "16,16",
                     "--env", str(env), "--out", str(tmp_path / f"{name}.exr"), "--json"]) == 0
        captured = capsys.readouterr()
        said[name] = (json.loads(captured.out.strip().splitlines()[-1])["prefiltered"], captured.err)
    ward, warned = said["ward"]
    assert ward["predicted_error"] > 0.07 and not ward["trusted"] and "split sum cannot hold" in warned
    lambert, quiet = said["lambert"]
    assert lambert["predicted_error"] < 0.01 and lambert["trusted"] and "warning" not in quiet
