"""Study part `lighting`: every lighting mode measured, error against frame time, its
summary, its charts, and a run scoped to one scene (the GUI's Charts dock)."""

import json

import numpy as np
import pytest

from brdflab.errors import BRDFLabError
from brdflab.lighting.envmap import constant
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.models import get_model
from brdflab.render import object_view
from brdflab.study import lighting
from brdflab.study.framework import StudyContext, run_study
from brdflab.study.lighting_charts import draw, fis_caption, sh_caption, summary
from brdflab.study.tradeoff import cheapest_under, pareto_front


def test_every_renderer_mode_has_settings_and_a_new_one_without_is_an_error(monkeypatch):
    for quick in (False, True):
        table = lighting.sweeps(quick)
        assert list(table) == list(object_view.MODES) and all(table.values())
    monkeypatch.setattr(object_view, "MODES", object_view.MODES + ("raytraced",))
    with pytest.raises(BRDFLabError, match="lighting mode raytraced has no settings"):
        lighting.sweeps(quick=True)
    with pytest.raises(BRDFLabError, match="raytraced"):
        lighting.measure(StudyContext(quick=True))  # refused before anything is measured


def test_pareto_front_and_cheapest_method_on_synthetic_numbers():
    rows = [{"mode": "point", "ms": 0.1, "error": None},
            {"mode": "fis", "ms": 1.0, "error": 0.30}, {"mode": "fis", "ms": 4.0, "error": 0.04},
            {"mode": "fis", "ms": 16.0, "error": 0.015},
            {"mode": "sh", "ms": 2.0, "error": 0.50},  # dearer and worse than FIS at 1 ms: dominated
            {"mode": "sh", "ms": 3.0, "error": 0.019}]
    assert [(r["mode"], r["ms"]) for r in pareto_front(rows)] == [("fis", 1.0), ("sh", 3.0), ("fis", 16.0)]
    assert cheapest_under(rows, 0.02)["ms"] == 3.0 and cheapest_under(rows, 0.05)["ms"] == 3.0
    assert cheapest_under(rows, 0.01) is None  # the point light (no error) is never chosen
    table = summary([{**r, "material": "m", "map": "a", "setting": ""} for r in rows], [0.01, 0.02, 0.05])
    assert [(s["target"], s["mode"], s["ms"]) for s in table] == [(0.01, None, None), (0.02, "sh", 3.0),
                                                                  (0.05, "sh", 3.0)]


def synthetic_numbers():
    """A run's numbers, made up: FIS breaks for the Lambertian on the sun map, SH for n=1000."""
    classes = ("Lambertian", "Blinn-Phong n=100", "Blinn-Phong n=1000")
    rows, tables = [], []
    for k, material in enumerate(classes):
        for env in ("sun", "sky"):
            rows.append({"material": material, "map": env, "mode": "point", "setting": "", "value": None,
                         "ms": 0.2, "error": None, "negative_pixels": None})
            for n in (4, 16, 64):
                error = (0.5 if material == "Lambertian" and env == "sun" else 0.1) * (4 / n) ** 0.5
                rows.append({"material": material, "map": env, "mode": "fis", "setting": f"n={n}", "value": n,
                             "ms": 0.5 * n, "error": error, "negative_pixels": None})
            for order in (2, 4):
                rows.append({"material": material, "map": env, "mode": "sh", "setting": f"L={order}",
                             "value": order, "ms": 0.3 * order, "error": 0.005 * 10 ** k / order,
                             "negative_pixels": 7 if k == 2 else 0})
        tables += [{"material": material, "order": o, "seconds": 1.5 * o} for o in (2, 4)]
    numbers = {"renderer": "synthetic (test)", "frame_size": 64, "error_size": 32, "reduced": [128, 64],
               "timing_map": "sun", "thresholds": [0.01, 0.02, 0.05], "modes": ["point", "fis", "sh"],
               "skipped": [{"what": "a measured slice", "why": "not found: nowhere"}],
               "maps": [{"name": "sun", "character": "a sun", "size": [8, 4]},
                        {"name": "sky", "character": "a sky", "size": [8, 4]}],
               "materials": list(classes), "rows": rows, "sh_tables": tables,
               "floors": [{"material": "Blinn-Phong n=1000", "map": "sun", "floor": 0.015}]}
    numbers["summary"] = summary(rows, numbers["thresholds"], numbers["floors"])
    return numbers


def test_charts_and_summary_are_drawn_from_the_numbers(tmp_path):
    numbers = synthetic_numbers()
    files = draw(numbers, tmp_path)
    assert files == ["lighting_pareto_lambertian.png", "lighting_pareto_blinn_phong_n_100.png",
                     "lighting_pareto_blinn_phong_n_1000.png", "lighting_fis_heatmap.png",
                     "lighting_sh_heatmap.png", "lighting_summary.md"]
    for name in files[:-1]:
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "Breaks (above 5 % at n=64): Lambertian on sun 12 %." in fis_caption(numbers)  # 0.5·√(4/64)
    assert ("Breaks (above 5 % at L=4): Blinn-Phong n=1000 on sun 12 %; Blinn-Phong n=1000 on sky 12 %."
            in sh_caption(numbers))
    assert "most 7" in sh_caption(numbers)
    text = (tmp_path / "lighting_summary.md").read_text()
    assert "| Lambertian | sun | SH L=2: 0.6 ms (0.25 %) | SH L=2: 0.6 ms (0.25 %) | SH L=2: 0.6 ms (0.25 %) |" in text
    assert ("| Blinn-Phong n=100 | sky | none (best SH L=4 1.2 %) | SH L=4: 1.2 ms (1.2 %) | "
            "SH L=2: 0.6 ms (2.5 %) |") in text
    assert ("| Blinn-Phong n=1000 | sun | not judged (reference ±1.5 %) | none (best FIS n=64 2.5 %) | "
            "FIS n=16: 8 ms (5 %) |") in text  # the reference resolves 2 % there, not 1 %
    assert "| Lambertian | 3.0 s | 6.0 s |" in text and "Skipped a measured slice: not found: nowhere." in text


def test_a_scoped_run_measures_every_mode_on_the_current_scene(tmp_path):
    """The GUI's Charts dock: one material, one map. Under a constant sky of radiance 1 a
    Lambertian lobe of value f has radiance π f everywhere: the errors are checked against
    that, not against the study's own quadrature."""
    material = AnalyticMaterial("white", "Linear", 3, [Lobe.create("Lambertian", [0.5] * 3)])
    result = run_study(tmp_path, StudyContext(quick=True, material=material, environment=constant(1.0, 64, 32)),
                       ["lighting"])
    numbers = json.loads((tmp_path / "study.json").read_text())["parts"]["lighting"]
    assert result.charts["lighting"] == ["lighting_pareto_current_material.png", "lighting_summary.md"]
    assert (tmp_path / "lighting_pareto_current_material.png").stat().st_size > 10_000
    rows = numbers["rows"]
    assert {r["mode"] for r in rows} == set(object_view.MODES)
    assert all(r["ms"] > 0 for r in rows) and numbers["reduced"] == [64, 32]
    assert numbers["floors"][0]["floor"] < 1e-3  # a constant sky: texel centres integrate it exactly
    errors = {(r["mode"], r["value"]): r["error"] for r in rows if r["error"] is not None}
    for mode in {m for m, _ in errors}:  # a constant sky is easy: every method gets within 3 %
        assert min(e for (m, _), e in errors.items() if m == mode) < 0.03, mode
    from brdflab.lighting.reference_view import relative_rmse, sphere_view
    from brdflab.render.context import create_context

    renderer = object_view.ObjectRenderer(create_context())
    renderer.set_source(material)
    renderer.set_environment(constant(1.0, 64, 32))
    view = sphere_view(32, 32)
    image = renderer.render(object_view.RenderSettings("fis", 32, 32, samples=16))
    f = material.evaluate(np.array([[0.0, 0.0, 1.0]]), np.array([[0.6, 0.0, 0.8]]))[0, 0]
    exact = np.where(view.inside[..., None], np.pi * f, 0.0)
    assert errors[("fis", 16)] == pytest.approx(relative_rmse(image, exact, view.inside), abs=2e-3)
    assert "| current material | constant |" in (tmp_path / "lighting_summary.md").read_text()


def test_a_cancelled_run_returns_what_it_has_and_still_draws(tmp_path):
    material = AnalyticMaterial("white", "Linear", 3, [Lobe.create("Lambertian", [0.5] * 3)])
    context = StudyContext(quick=True, material=material, environment=constant(1.0, 64, 32), cancelled=lambda: True)
    result = run_study(tmp_path, context, ["lighting"])
    assert result.numbers["lighting"]["rows"] == [] and result.charts["lighting"] == ["lighting_summary.md"]


def test_maps_without_the_shared_data_fall_back_to_the_shipped_one_and_say_why(tmp_path, monkeypatch):
    monkeypatch.setenv("BRDFLAB_SHARED", str(tmp_path))
    skipped = []
    maps = lighting.study_maps(quick=True, skipped=skipped)
    assert [name for name, _, _ in maps] == ["venice_sunset_1k"]
    assert skipped[0]["what"] == "quarry_01_1k.hdr" and "no shared data" in skipped[0]["why"]
    classes = lighting.material_classes(quick=False, skipped=skipped)
    assert lighting.MEASURED_CLASS not in classes and skipped[-1]["what"] == lighting.MEASURED_CLASS


def test_the_reference_resolves_broad_lobes_and_says_when_a_lobe_falls_between_texels():
    """On the shipped sunset map (128 × 64 texels of 2.8°): a Lambertian integrates the same
    when texels are split, a Blinn-Phong n=10000 lobe (about 1° wide) does not."""
    from brdflab.io.resources import data_dir
    from brdflab.lighting.envmap import load_environment

    small = lighting.reduced(load_environment(data_dir("resources") / "envmaps" / "venice_sunset_1k.hdr"))
    assert lighting.reference_floor(lighting.MATERIAL_CLASSES["Lambertian"](), small) < 0.005
    assert lighting.reference_floor(lighting.MATERIAL_CLASSES["Blinn-Phong n=10000"](), small) > 0.05


def test_subdivided_reference_equals_splitting_every_texel_where_a_sharp_lobe_is():
    """refined_environment_image against an independent route: the plain quadrature over a
    map whose every texel is split 8 × 8 (the same radiance). A Blinn-Phong n=2000 lobe
    (zero beyond the subdivided cone) must agree closely; texel centres alone must not."""
    from brdflab.lighting.envmap import EnvironmentMap
    from brdflab.lighting.reference_view import environment_image, refined_environment_image, relative_rmse, sphere_view

    rng = np.random.default_rng(4)
    data = rng.uniform(0.2, 1.0, (16, 32, 3)).astype(np.float32)
    data[5, 9] = 400.0  # a sun, one texel
    small = EnvironmentMap(data, "test")
    material = AnalyticMaterial("sharp", "Linear", 3, [Lobe(get_model("BlinnPhong"), {"Exponent": 2000.0}, [1.0, 1.0, 1.0])])
    inside = sphere_view(8, 8).inside
    split = EnvironmentMap(np.repeat(np.repeat(data, 8, axis=0), 8, axis=1), "split")
    truth = environment_image(material, split, 8, 8)
    refined = refined_environment_image(material, small, 8, 8, subdivision=8)
    assert relative_rmse(refined, truth, inside) < 1e-3
    assert relative_rmse(environment_image(material, small, 8, 8), truth, inside) > 0.05
    assert lighting.refined_floor(material, small) < lighting.reference_floor(material, small) / 5


def test_subdivided_reference_splits_a_sun_for_every_pixel():
    """Pixel by pixel, under a one-texel sun: a texel's centre alone cannot see a lobe's tail
    vary across the sun nor a pixel's horizon cut through it. Subdividing the sun only near
    each mirror direction left pixels at a highlight's edge 13 % off (2.3 % RMS per pixel
    against 65,536 samples per pixel);
    the bright texels are now split for every pixel, and the reference agrees with the plain
    quadrature over the map split 8 × 8 (the same radiance) within 0.6 %."""
    from brdflab.lighting.envmap import EnvironmentMap
    from brdflab.lighting.reference_view import environment_image, pixel_relative_rmse, refined_environment_image, sphere_view

    data = np.empty((32, 64, 3), np.float32)
    data[:] = (0.2, 0.25, 0.4)
    data[16:] = (0.05, 0.04, 0.03)
    data[7, 40] = (4000.0, 3800.0, 3000.0)  # a sun, one texel, 40° up
    small = EnvironmentMap(data, "sun")
    material = AnalyticMaterial("paint", "Linear", 3, [Lobe(get_model("Lambertian"), {}, [0.2] * 3),
                                                      Lobe(get_model("BlinnPhong"), {"Exponent": 300.0}, [0.5] * 3)])
    inside = sphere_view(24, 24).inside
    split = EnvironmentMap(np.repeat(np.repeat(data, 8, axis=0), 8, axis=1), "split")
    truth = environment_image(material, split, 24, 24)
    # before: 1.35 %; what is left (0.37 %) is the dim sky's texels crossing the horizon, at their centres
    assert pixel_relative_rmse(refined_environment_image(material, small, 24, 24, subdivision=8), truth, inside) < 0.006


def test_maps_are_reduced_evenly_or_refused():
    assert lighting.reduced(constant(1.0, 1000, 500)).data.shape == (50, 125, 3)
    assert lighting.reduced(constant(1.0, 97, 31)).data.shape == (31, 97, 3)  # small: kept as it is
    with pytest.raises(BRDFLabError, match="cannot be reduced evenly"):
        lighting.reduced(constant(1.0, 1021, 512))  # 1021 is prime
