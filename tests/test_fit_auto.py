"""Auto fitting (issue 13): the ladder's decisions are deterministic, stop where more lobes
no longer pay on held-back samples, honour the tolerance, and the CLI stores the pick."""

import json
import os
import re
import subprocess
import sys
import threading

import numpy as np
import pytest

from brdflab.errors import BRDFLabError
from brdflab.fitting.auto import SCREEN_KEEP, auto_fit, improves, split_samples
from brdflab.fitting.samples import ArraySampleSet, analytic_grid, samples_of
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.sources.measured import read_slice
from conftest import DATA, ROOT, needs_shared

MODELS = ["BlinnPhong", "CookTorrance", "Ward"]
SLICE = DATA / "merl_slices" / "blue-fabric.slice"


def noisy_samples(lobes: list[Lobe], noise: float = 0.03, seed: int = 5) -> ArraySampleSet:
    """A synthetic source's grid samples with multiplicative noise (what fitting must not chase)."""
    grid = analytic_grid(AnalyticMaterial("truth", "Linear", 3, lobes), density=14)
    values = grid.values * (1.0 + noise * np.random.default_rng(seed).normal(size=grid.values.shape))
    return ArraySampleSet(grid.wi, grid.wo, values, grid.weight)


def test_split_is_disjoint_seeded_and_halves():
    samples = noisy_samples([Lobe.create("Lambertian", [0.3, 0.2, 0.1])])
    a, b = split_samples(samples, 1000)
    a2, _ = split_samples(samples, 1000)
    assert a.size == b.size == 1000
    assert np.array_equal(a.wi, a2.wi)
    pairs = {tuple(np.round(np.r_[w, o], 12)) for w, o in zip(a.wi, a.wo)}
    assert not any(tuple(np.round(np.r_[w, o], 12)) in pairs for w, o in zip(b.wi, b.wo))


def test_one_known_lobe_is_found_and_the_climb_stops():
    truth = [Lobe.create("Lambertian", [0.2, 0.15, 0.1]), Lobe.create("CookTorrance", [0.6, 0.6, 0.6], m=0.25, F0=0.3)]
    ladder = auto_fit(noisy_samples(truth), split=1500, models=MODELS)
    assert ladder.chosen.lobes == ("CookTorrance",)
    assert max(c.rung for c in ladder.candidates) == 2  # rung 2 tried, did not pay, nothing beyond
    assert "not more than the tolerance" in ladder.reason
    lambertian = ladder.candidates[0]
    assert improves(lambertian.error_held_back, ladder.chosen.error_held_back, 0.5)


def test_lambertian_source_stops_at_the_first_rung():
    ladder = auto_fit(noisy_samples([Lobe.create("Lambertian", [0.5, 0.4, 0.3])]), split=1500, models=MODELS)
    assert ladder.chosen.lobes == ()
    assert {c.rung for c in ladder.candidates} == {0, 1}


@needs_shared("merl_slices", "blue-fabric.slice")
@pytest.mark.parametrize("tolerance", [0.05, 0.3])
def test_tolerance_is_honoured_and_runs_are_deterministic(tolerance):
    samples = samples_of(read_slice(SLICE))
    first = auto_fit(samples, tolerance, split=1500, models=MODELS, max_lobes=2)
    again = auto_fit(samples, tolerance, split=1500, models=MODELS, max_lobes=2)
    assert first.chosen.lobes == again.chosen.lobes
    assert [c.error_held_back for c in first.candidates] == [c.error_held_back for c in again.candidates]
    fitted = [c for c in first.candidates if c.fitted]
    best = min(c.error_held_back for c in fitted)
    assert not improves(first.chosen.error_held_back, best, tolerance)
    # nothing with fewer parameters among those fully fitted was within the tolerance of the best
    cheaper = [c for c in fitted if c.parameters < first.chosen.parameters]
    assert all(improves(c.error_held_back, best, tolerance) for c in cheaper)


@needs_shared("merl_slices", "blue-fabric.slice")
def test_screening_keeps_fits_identical_to_the_exhaustive_run():
    samples = samples_of(read_slice(SLICE))
    models = [*MODELS, "Phong", "OrenNayar", "Schwenk", "Strauss"]  # more than SCREEN_KEEP: some are dropped
    auto = auto_fit(samples, split=1500, models=models, max_lobes=1)
    full = auto_fit(samples, split=1500, models=models, max_lobes=1, exhaustive=True)
    reference = {c.lobes: c.error_held_back for c in full.candidates}
    assert all(c.fitted for c in full.candidates)
    assert [c.lobes for c in auto.candidates] == [c.lobes for c in full.candidates]
    for c in auto.candidates:
        if c.fitted:
            assert c.error_held_back == reference[c.lobes]
        else:
            assert c.status == "screened out" and np.isfinite(c.screen_error)
    assert any(not c.fitted for c in auto.candidates)
    assert auto.chosen.lobes == full.chosen.lobes



@needs_shared("merl_slices", "blue-fabric.slice")
def test_progress_hears_every_screen_and_full_fit_and_changes_nothing():
    samples = samples_of(read_slice(SLICE))
    reports = []
    ladder = auto_fit(samples, split=1000, models=MODELS, max_lobes=2, progress=reports.append)
    quiet = auto_fit(samples, split=1000, models=MODELS, max_lobes=2)
    assert [c.error_held_back for c in ladder.candidates] == [c.error_held_back for c in quiet.candidates]
    assert ladder.chosen.lobes == quiet.chosen.lobes and ladder.reason == quiet.reason
    screens = [c for c in ladder.candidates if np.isfinite(c.screen_error)]
    fitted = [c for c in ladder.candidates if c.fitted]
    assert [r.step for r in reports] == list(range(1, len(screens) + len(fitted) + 1))
    assert [r.stage for r in reports].count("screened") == len(screens)
    assert all(r.expected >= r.step for r in reports)
    # rung 1: screens, then full fits of the kept; rung 2: full fits only
    assert reports[0].expected == 1 + len(MODELS) + min(len(MODELS), SCREEN_KEEP) + len(MODELS)
    assert all(c.rung == 1 for c in screens) and all(c.fitted for c in ladder.candidates if c.rung == 2)
    best = min(fitted, key=lambda c: c.error_held_back)
    assert reports[-1].best_error == best.error_held_back
    assert reports[-1].best == "+".join(("Lambertian", *best.lobes))
    assert "of about" in reports[-1].describe()


@needs_shared("merl_slices", "blue-fabric.slice")
def test_cancel_keeps_the_ladder_so_far_and_picks_among_the_fully_fitted():
    samples = samples_of(read_slice(SLICE))
    cancel = threading.Event()

    def stop_after_the_first_lobe_fit(report):
        if report.stage == "fitted" and report.step > 1:
            cancel.set()  # the next fit (a full fit in rung 1) is cancelled at its first sample pass

    ladder = auto_fit(samples, split=1000, models=MODELS, max_lobes=2, progress=stop_after_the_first_lobe_fit,
                      cancel=cancel)
    whole = auto_fit(samples, split=1000, models=MODELS, max_lobes=2)
    assert ladder.reason.startswith("cancelled in rung 1")
    assert {c.rung for c in ladder.candidates} == {0, 1} and len(ladder.candidates) == 1 + len(MODELS)
    statuses = [c.status for c in ladder.candidates]
    assert statuses.count("cancelled") == 1
    fitted = [c for c in ladder.candidates if c.fitted]
    assert len(fitted) == 2  # the Lambertian and one lobe: nothing after the cancel counts as fitted
    reference = {c.lobes: c.error_held_back for c in whole.candidates}
    assert all(c.error_held_back == reference[c.lobes] for c in fitted)  # the same fits as uncancelled
    lambertian, lobe = fitted
    expected = lobe if improves(lambertian.error_held_back, lobe.error_held_back, 0.05) else lambertian
    assert ladder.chosen is expected and ladder.chosen.result is not None


def test_cancel_before_anything_is_fitted_keeps_the_lambertian_start():
    cancel = threading.Event()
    cancel.set()
    ladder = auto_fit(noisy_samples([Lobe.create("Lambertian", [0.5, 0.4, 0.3])]), split=500, models=MODELS,
                      cancel=cancel)
    (only,) = ladder.candidates
    assert ladder.chosen is only and only.status == "cancelled" and not only.fitted
    assert only.result is not None and np.isfinite(only.error_held_back)
    assert "cancelled during the Lambertian's fit" in ladder.reason

def test_bad_tolerance_is_refused():
    samples = noisy_samples([Lobe.create("Lambertian", [0.5, 0.4, 0.3])])
    for bad in (-0.1, 1.0, float("nan")):
        with pytest.raises(BRDFLabError, match="tolerance"):
            auto_fit(samples, bad)


def _cli(*args, cwd):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "brdflab", *args], capture_output=True, text=True, cwd=cwd,
                          env=env, timeout=300)


@needs_shared("merl_slices", "blue-fabric.slice")
def test_cli_auto_out_writes_a_fitting_that_info_lists(tmp_path):
    out = tmp_path / "auto.xml"
    proc = _cli("fit", str(SLICE), "--auto", "--models", "BlinnPhong,CookTorrance", "--size", "1000",
                "--out", str(out), "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    ladder = json.loads(proc.stdout)
    chosen = ladder["candidates"][ladder["chosen"]]
    assert ladder["held_back_samples"] == 1000 and ladder["reason"]
    info = json.loads(_cli("info", str(out), cwd=tmp_path).stdout)
    (fitting,) = info["fittings"]
    models = [l["model"] for l in fitting["material"]["lobes"]]
    assert models == ["Lambertian", *chosen["lobes"]]
    assert fitting["statistics"]["heldBackError"] == chosen["error_held_back"]  # stored with the pick
    assert fitting["statistics"]["heldBackSamples"] == 1000
    text = _cli("fit", str(SLICE), "--auto", "--models", "BlinnPhong", "--size", "500", cwd=tmp_path)
    assert text.returncode == 0 and "held back" in text.stdout and "*" in text.stdout
    # a screened candidate that was then fitted fully shows its screening's error in brackets, as the header says
    rows = [l for l in text.stdout.splitlines() if re.match(r"^\*?\s+1\s+Lambertian\+BlinnPhong ", l)]
    assert len(rows) == 1 and re.search(r"\([\d.e-]+\)$", rows[0]), text.stdout
    # progress: a line on stderr per screen and full fit, with rung, candidate, best so far and elapsed time
    lines = [l for l in proc.stderr.splitlines() if l.startswith("brdflab fit: auto: ")]
    fitted = [c for c in ladder["candidates"] if c["fitted"]]
    screened = [c for c in ladder["candidates"] if c["screen_error"] is not None]
    assert len(lines) == len(fitted) + len(screened)
    assert all(re.search(r"rung \d, candidate \d+ of about \d+: (screened|fitted) Lambertian.*best so far "
                         r"Lambertian\S* [\d.e-]+ \(\d+\.\d s\)$", l) for l in lines), lines
    assert {int(re.search(r"rung (\d)", l).group(1)) for l in lines} == {c["rung"] for c in ladder["candidates"]}


@pytest.mark.parametrize("args", [["--tolerance", "-0.5"], ["--tolerance", "inf"], ["--tolerance", "x"],
                                  ["--lobes", "Lambertian"]])
def test_cli_bad_auto_options_exit_2_with_one_line(tmp_path, args):
    proc = _cli("fit", "example:lambertian", "--auto", *args, cwd=tmp_path)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr
