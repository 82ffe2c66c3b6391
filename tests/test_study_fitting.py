"""`brdflab study` parts `fitting` (error against time) and `stability` (LM over starts)."""


import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brdflab.fitting.metrics import grid_error, metric_error
from brdflab.fitting.samples import samples_of
from brdflab.models import model_names
from brdflab.sources.measured import read_slice
from brdflab.study import fitting
from brdflab.study.fit_jobs import FitJob, material_of, run_job
from brdflab.study.framework import StudyContext, check_finite, journal_path, read_study, run_study
from brdflab.study.pareto import enough_point, pareto_front
from brdflab.study.stability import cell_summary, starts_of

from conftest import DATA, ROOT, needs_shared

BLUE_FABRIC = DATA / "merl_slices" / "blue-fabric.slice"


def test_the_pareto_front_keeps_only_undominated_points():
    cost = [1.0, 2.0, 2.0, 3.0, 4.0, 5.0, 0.5]
    error = [5.0, 3.0, 2.5, 4.0, 1.0, 1.0, 9.0]
    # 2 beats 1 at the same cost; 3 is dominated by 2; 5 ties 4 in error at a higher cost
    assert pareto_front(cost, error).tolist() == [6, 0, 2, 4]
    # within 5 % of the best error (1.0): 4 and 5; the cheaper is where more stops paying
    assert enough_point(cost, error, 0.05) == 4
    assert enough_point(cost, error, 2.0) == 2  # 2.5 ≤ 3 × 1.0, cheaper than 4


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(0.01, 100), st.floats(0.001, 10)), min_size=1, max_size=30))
def test_no_point_dominates_a_front_point(points):
    cost, error = map(np.array, zip(*points))
    front = pareto_front(cost, error)
    for i in front:
        dominated = (cost <= cost[i]) & (error <= error[i]) & ((cost < cost[i]) | (error < error[i]))
        assert not dominated.any()
    off = np.setdiff1d(np.arange(len(cost)), front)
    for i in off:  # every other point is dominated by (or equal to) a front point
        assert np.any((cost[front] <= cost[i]) & (error[front] <= error[i]))


def test_the_full_design_is_every_family_at_every_size_on_every_slice():
    slices = [f"m{k:02d}" for k in range(31)]
    plan = fitting.design(slices, fitting.FULL)
    from brdflab.models import get_model

    others = [get_model(m) for m in model_names() if m != "Lambertian"]
    n_families = 2 + sum(4 if m.scaled else 2 for m in others)  # 62 for the 16 models before Principled
    assert len(plan) == len(set(plan)) == 31 * n_families * 5
    assert set(plan) == {(s, f, size) for s in slices for f in fitting.families(model_names())
                         for size in (fitting.FULL.sizes if f.combination == "Linear" else fitting.FULL.fixed_sizes)}
    quick = {(s, f) for s, f, size in fitting.design(slices, fitting.QUICK) if size == fitting.QUICK.core_size}
    assert {f for _, f in quick if len({s for s, g in quick if g == f}) == len(slices)} == \
        {f for f in fitting.families(list(fitting.QUICK.models)) if f.basic}  # quick: one lobe, Linear


def test_a_sampled_tier_on_one_slice_per_model_spreads_the_models():
    slices = [f"m{k:02d}" for k in range(31)]
    plan = fitting.design(slices, fitting.Matrix(tuple(model_names()), 20_000, (5_000, None), (None,)))
    homes = {m: {s for s, f, size in plan if f.model == m and size is None} for m in model_names()}
    assert all(len(h) == 1 for h in homes.values())  # a model's families share one slice
    assert len(set.union(*homes.values())) == len(model_names())


@needs_shared("merl_slices", "blue-fabric.slice")
def test_the_error_is_on_all_samples_not_the_subset():
    """A fit on 100 samples of a diffuse material: its row's error is the result's error
    on every sample — recomputed here by the fitter's measure and, independently, by
    BRDFLab's 16 × 16 × 64 grid (which agrees within 2 % on diffuse materials) — and not
    the subset's own error, which is 20 % higher."""
    row = run_job(FitJob(str(BLUE_FABRIC), ("BlinnPhong",), size=100))
    table = read_slice(BLUE_FABRIC)
    material = material_of(row)
    assert row["samples"] == 100
    assert metric_error(material, samples_of(table), "Ngan") == pytest.approx(row["error"], rel=1e-9)
    assert grid_error(table, material) == pytest.approx(row["error"], rel=0.02)
    assert abs(row["error_fitted"] / row["error"] - 1) > 0.1
    assert metric_error(material, samples_of(table).subset(100, seed=1), "Ngan") == pytest.approx(row["error_fitted"])


def test_the_stability_fraction_on_a_synthetic_cell():
    errors = [1.004, 1.5, 1.0, 1.02, 3.0, 1.009]
    kinds = ["default", "restart", "random", "random", "random", "random"]
    cell = cell_summary(errors, kinds, on_bound=[False, True, False, False, True, False])
    assert cell["best"] == 1.0
    assert cell["fraction_within"] == pytest.approx(3 / 6)  # 1.0, 1.004, 1.009 are within 1 %
    assert cell["random_fraction_within"] == pytest.approx(2 / 4)
    assert cell["worst_over_best"] == pytest.approx(3.0)
    assert cell["median_over_best"] == pytest.approx((1.009 + 1.02) / 2)
    assert cell["default_reaches"] and cell["fitter_reaches"]
    assert (cell["missed"], cell["missed_on_bound"]) == (3, 2)
    missing = cell_summary([2.0, None, 1.0], ["default", "restart", "random"], [False] * 3)
    assert not missing["fitter_reaches"] and missing["fraction_within"] == pytest.approx(1 / 3)
    assert missing["failed"] == 1 and missing["worst_over_best"] == 2.0 and missing["median_over_best"] == 2.0


def test_the_starts_are_the_default_the_restarts_and_random_ones_in_bounds(rng):
    from brdflab.models import get_model

    for name in ("CookTorrance", "LafortuneIso", "Ward"):
        model = get_model(name)
        starts = starts_of(name, 20, rng)
        kinds = [k for k, _ in starts]
        assert kinds == ["default"] + ["restart"] * len(model.starts) + ["random"] * 20
        for _, values in starts[-20:]:
            for p in model.parameters:
                assert p.lower <= dict(values)[p.name] <= p.upper


@needs_shared("merl_slices", "nickel.slice")
def test_study_quick_writes_every_chart_with_finite_numbers(quick_study):
    """Both parts as CI runs them (the session's `brdflab study --quick`): every chart written,
    every number finite, every model of the quick matrix fitted on every quick slice."""
    out, payload, study = quick_study
    assert payload["charts"]["fitting"] == ["fitting_pareto_materials_1.png", "fitting_pareto_pooled.png"]
    assert payload["charts"]["stability"] == ["stability_lm.png"]
    for name in payload["charts"]["fitting"] + payload["charts"]["stability"]:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    check_finite(study["parts"], "study")
    fit = study["parts"]["fitting"]
    assert fit["fits_done"] == fit["fits_planned"] > 0
    assert {(r["material"], r["model"]) for r in fit["rows"] if r["core"]} == \
        {(s, m) for s in fitting.QUICK_SLICES for m in fitting.QUICK.models}
    assert all(r["seconds"] > 0 and 0 < r["error"] < r["zero_error"] for r in fit["rows"])
    assert fit["subsets"] and fit["families"] and fit["gains"]
    cells = study["parts"]["stability"]["cells"]
    assert len(cells) == 2 * 3 and all(0 < c["fraction_within"] <= 1 for c in cells)
    assert "LM breaks most" in study["parts"]["stability"]["caption"]


@needs_shared("merl_slices", "blue-fabric.slice")
def test_a_scoped_run_fits_the_current_source_in_this_process(tmp_path, monkeypatch):
    """The GUI's current measured material, with a matrix made tiny for the test."""
    monkeypatch.setattr(fitting, "SCOPED_QUICK", fitting.Matrix(("Lambertian", "BlinnPhong"), 2_000, (2_000,), (2_000,),
                                                                two_fixed=False))
    table = read_slice(BLUE_FABRIC)
    numbers = fitting.measure(StudyContext(quick=True, source=table))
    check_finite(numbers, "fitting")
    assert numbers["materials"] == [table.name] and numbers["clock"] == "wall"
    assert {(r["family"], r["size"]) for r in numbers["rows"]} == {
        ("Lambertian Linear", 2000), ("Lambertian Fixed", 2000), ("1×BlinnPhong Linear", 2000),
        ("2×BlinnPhong Linear", 2000), ("1×BlinnPhong Fixed", 2000)}
    assert fitting.draw(numbers, tmp_path) == ["fitting_pareto_materials_1.png", "fitting_pareto_pooled.png"]


@pytest.fixture
def tiny_full_run(monkeypatch):
    """The unscoped fitting part made tiny (5 fits of 2,000 samples on blue-fabric, in this
    process): what `brdflab study --part fitting --out DIR` runs, resumable."""
    monkeypatch.setattr(fitting, "QUICK", fitting.Matrix(("Lambertian", "BlinnPhong"), 2_000, (2_000,), (2_000,),
                                                         two_fixed=False))
    monkeypatch.setattr(fitting, "QUICK_SLICES", ("blue-fabric",))
    monkeypatch.setattr(fitting, "core_count", lambda: 1)
    return lambda out, **kw: run_study(out, StudyContext(quick=True, **kw), ["fitting"]).numbers["fitting"]


def _by_key(rows):
    return {(r["material"], r["family"], r["size"]): r for r in rows}


@needs_shared("merl_slices", "blue-fabric.slice")
def test_a_run_into_the_same_folder_fits_only_what_is_missing(tmp_path, tiny_full_run):
    first = tiny_full_run(tmp_path)
    assert first["fits_planned"] == first["fits_done"] == first["fits_this_run"] == 5
    stored = read_study(tmp_path)["parts"]["fitting"]  # its rows come back from fitting_rows.jsonl.gz
    assert "rows" not in json.loads((tmp_path / "study.json").read_text())["parts"]["fitting"]
    assert _by_key(stored["rows"]) == _by_key(first["rows"])
    assert not journal_path(tmp_path, "fitting").exists()

    # a run killed after two fits: no new study.json, a journal with two rows and a torn line
    (tmp_path / "study.json").unlink()
    kept = first["rows"][:2]
    journal_path(tmp_path, "fitting").write_text("".join(json.dumps(r) + "\n" for r in kept)
                                                 + '{"material": "blue-fa')
    second = fitting.measure(StudyContext(quick=True, out_dir=tmp_path))  # the part alone: its journal stays
    assert (second["fits_this_run"], second["fits_done"]) == (3, 5)
    again = _by_key(second["rows"])
    for r in kept:  # kept as measured, not fitted again
        assert again[(r["material"], r["family"], r["size"])]["seconds"] == r["seconds"]
    lines = journal_path(tmp_path, "fitting").read_text().splitlines()
    assert len(lines) == 2 + 1 + 3 and lines[2] == '{"material": "blue-fa'  # the new rows start lines of their own
    assert _by_key(json.loads(line) for line in lines[3:]) == _by_key(second["rows"][2:])

    third = tiny_full_run(tmp_path)
    assert not journal_path(tmp_path, "fitting").exists()
    assert third["fits_this_run"] == 0 and _by_key(third["rows"]) == _by_key(second["rows"])
    assert tiny_full_run(tmp_path, fresh=True)["fits_this_run"] == 5


@needs_shared("merl_slices", "blue-fabric.slice")
def test_a_stopped_run_draws_what_it_has_and_the_next_goes_on(tmp_path, tiny_full_run):
    journal = journal_path(tmp_path, "fitting")
    stop = lambda: journal.exists() and len(journal.read_text().splitlines()) >= 2  # noqa: E731
    first = tiny_full_run(tmp_path, cancelled=stop)
    assert (first["fits_done"], first["fits_planned"]) == (2, 5)
    assert (tmp_path / "fitting_pareto_pooled.png").is_file()
    second = tiny_full_run(tmp_path)
    assert (second["fits_this_run"], second["fits_done"]) == (3, 5)
    assert set(_by_key(second["rows"])) >= set(_by_key(first["rows"]))


def test_the_numbers_script_reads_the_full_matrix_and_refuses_a_smaller_one(quick_study):
    """benchmarks/fitting_study_numbers.py prints the committed study's numbers, and on a
    --quick study says in one line that it needs the full matrix (it stopped with a
    traceback: no 20 k fits)."""
    import subprocess
    import sys

    script = str(ROOT / "benchmarks" / "fitting_study_numbers.py")
    full = subprocess.run([sys.executable, script, str(ROOT / "docs" / "study" / "fitting")],
                          capture_output=True, text=True, timeout=600)
    assert full.returncode == 0, full.stderr[-2000:]
    assert full.stdout.startswith("fits 9610,") and "== subsets" in full.stdout
    out, _, _ = quick_study
    quick = subprocess.run([sys.executable, script, str(out)], capture_output=True, text=True, timeout=600)
    assert quick.returncode == 2 and quick.stdout == ""
    assert quick.stderr.count("\n") == 1 and "full matrix" in quick.stderr and "Traceback" not in quick.stderr
