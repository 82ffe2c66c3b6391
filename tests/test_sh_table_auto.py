"""Auto SH tables (issue 13): the cheapest table within a stated error, checked against a
converged table computed here; the renderer, the CLI and the window honour the pick."""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdflab.lighting.sh_table_auto import (AutoTable, build_cost, choose_table, error_views, known_choice, ladder,
                                            luminance, relative_rms, table_error)
from brdflab.lighting.sh_tables import (STANDARD, TableSetting, cached_table, is_cached, sampling_proxy, table_for,
                                        view_integrals)
from brdflab.material.analytic import AnalyticMaterial, Lobe

ROOT = Path(__file__).resolve().parents[1]


def blinn_phong(n: float) -> AnalyticMaterial:
    return AnalyticMaterial(f"n={n:g}", "Linear", 3, [Lobe.create("BlinnPhong", [0.5] * 3, Exponent=n)])


def lambertian() -> AnalyticMaterial:
    return AnalyticMaterial("diffuse", "Linear", 3, [Lobe.create("Lambertian", [0.25] * 3)])


def converged(source, order: int, views: np.ndarray) -> np.ndarray:
    """The integrals at views with 2^14 samples in four independent scramblings (none the table's)."""
    proxy = sampling_proxy(source)
    return np.mean([view_integrals(source, proxy, views, order, 12, seed=s) for s in (71, 72, 73, 74)], axis=0)


def random_views(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    z = rng.uniform(math.cos(math.radians(80.0)), 1.0, n)
    phi = rng.uniform(0.0, 2 * math.pi, n)
    return np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], axis=1)


def test_the_decision_is_deterministic():
    material = blinn_phong(30.0)
    a, b = choose_table(material, 3), choose_table(material.copy(), 3)
    assert (a.setting, a.estimated_error, a.weighed) == (b.setting, b.estimated_error, b.weighed)
    assert a.within and a.estimated_error <= 0.01


@pytest.mark.parametrize("make, order, tolerance", [(lambertian, 4, 0.01), (lambda: blinn_phong(60.0), 3, 0.01),
                                                    (lambda: blinn_phong(10.0), 4, 0.005)])
def test_the_pick_is_within_the_tolerance_of_a_converged_table(make, order, tolerance):
    material = make()
    choice = choose_table(material, order, tolerance)
    assert choice.within
    views = random_views(48, seed=order)
    truth = converged(material, order, views)
    true_error = table_error(table_for(material, order, choice.setting), truth, views)
    assert true_error <= tolerance
    # the estimate tracks the truth (not merely a safe overstatement)
    assert true_error > 0.3 * choice.estimated_error
    # and Auto did not stop early: every cheaper rung is estimated above the tolerance
    cheaper = [s for s in ladder(material) if build_cost(material, s) < build_cost(material, choice.setting)]
    weighed = dict(choice.weighed)
    assert all(weighed.get(s.label) is None or weighed[s.label] > tolerance for s in cheaper)


def test_a_sharper_lobe_never_gets_a_coarser_table():
    """Coarser = fewer texels. The sample count need not follow the sharpness: a sharp lobe is
    importance-sampled almost exactly (n = 100 takes fewer samples than n = 10)."""
    for order in (3, 4):
        sizes = [choose_table(m, order).setting.size for m in (lambertian(), blinn_phong(10.0), blinn_phong(100.0))]
        assert sizes == sorted(sizes) and sizes[2] > sizes[0], (order, sizes)


def test_the_stated_error_is_the_rms_over_views_of_the_luminance_vectors():
    truth = np.zeros((2, 4, 3))
    truth[:, 0, :] = 1.0
    estimate = truth.copy()
    estimate[0, 3, :] = 0.1  # one coefficient off by 0.1 in one of two views: √(0.01 / 2)
    assert relative_rms(estimate, truth) == pytest.approx(math.sqrt(0.01 / 2))
    assert luminance(truth).shape == (2, 4)
    views = error_views(200)
    assert np.allclose(np.linalg.norm(views, axis=1), 1) and views[:, 2].min() >= math.cos(math.radians(80)) - 1e-12


def test_the_cache_keeps_each_setting_apart():
    material = blinn_phong(20.0)
    small, other = TableSetting(8, 6), TableSetting(16, 6)
    assert cached_table(material, 2, small).shape[:2] == (8, 8)
    assert is_cached(material, 2, small) and not is_cached(material, 2, other) and not is_cached(material, 2, STANDARD)
    assert cached_table(material, 2, other).shape[:2] == (16, 16)


def test_the_renderer_draws_with_autos_pick():
    from brdflab.lighting.envmap import EnvironmentMap
    from brdflab.render.context import create_context
    from brdflab.render.object_view import ObjectRenderer, RenderSettings

    ctx = create_context()
    material = blinn_phong(40.0)
    env = EnvironmentMap(np.random.default_rng(2).uniform(0.2, 2.0, (16, 32, 3)).astype(np.float32))
    settings = RenderSettings(mode="sh", width=24, height=24, reference_view=True)
    images = {}
    for table in (AutoTable(), None, STANDARD):
        r = ObjectRenderer(ctx)
        r.set_source(material)
        r.set_environment(env)
        r.set_sh_order(3)
        r.set_sh_table(known_choice(material, 3, AutoTable()).setting if table is None else table)
        images[table] = r.render(settings)
    assert known_choice(material, 3, AutoTable()).setting != STANDARD.of(material)
    np.testing.assert_array_equal(images[AutoTable()], images[None])
    assert np.abs(images[AutoTable()] - images[STANDARD]).max() > 0


def test_cli_renders_with_an_auto_table_and_refuses_a_bad_one(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = [sys.executable, "-m", "brdflab", "render", "example:fig2", "--mode", "sh", "--sh-order", "3",
           "--view", "reference", "--size", "16,16", "--out", str(tmp_path / "a.exr")]
    done = subprocess.run(run + ["--sh-table", "auto", "--json"], capture_output=True, text=True, cwd=tmp_path, env=env,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    table = json.loads(done.stdout.strip().splitlines()[-1])["settings"]["sh_table"]
    assert table["auto"] and table["within"] and table["estimated_error"] <= 0.01
    assert (table["size"], table["samples_log2"]) != (128, 12)
    bad = subprocess.run(run + ["--sh-table", "64by10"], capture_output=True, text=True, cwd=tmp_path, env=env, timeout=120)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "--sh-table" in bad.stderr
