"""Fits a user can trust: one (ωi, ωo) measure for every source, MERL bin centres, a fitter
that never gets worse, and the command line's stops (time limit, Ctrl-C)."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdflab.cli import main
from brdflab.fitting.diagnosis import bound_warnings
from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
from brdflab.fitting.metrics import grid_error, metric_error
from brdflab.fitting.samples import analytic_grid, samples_of
from brdflab.geometry.halfdiff import from_half_diff, phi_d_of_bin, theta_d_of_bin, theta_h_edge, theta_h_of_bin
from brdflab.io.xmlio import load
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.sources.measured import read_merl_binary, read_slice, tabulate, write_merl_binary
from conftest import DATA, needs_shared

ROOT = Path(__file__).resolve().parents[1]
SHARP = AnalyticMaterial("sharp", "Linear", 3, [Lobe.create("BlinnPhong", [1.0, 1.0, 1.0], Exponent=2000.0)])
TRUTH = AnalyticMaterial("truth", "Linear", 3, [
    Lobe.create("Lambertian", [0.05, 0.03, 0.02]),
    Lobe.create("CookTorrance", [0.6, 0.5, 0.4], m=0.18, F0=0.35),
])


# --- where a MERL bin's value sits ------------------------------------------------------------

def test_a_table_written_from_a_lobe_holds_its_values_at_bin_centres(tmp_path):
    path = tmp_path / "sharp.binary"
    write_merl_binary(tabulate(SHARP), path)
    table = read_merl_binary(path)
    x, y, z = np.array([0, 1, 3, 7, 20]), np.array([10, 30, 45, 60, 5]), np.array([0, 45, 90, 135, 179])
    th, td, pd = theta_h_of_bin(x), theta_d_of_bin(y), phi_d_of_bin(z)
    np.testing.assert_allclose(th, ((x + 0.5) / 90) ** 2 * np.pi / 2)
    np.testing.assert_allclose(td, (y + 0.5) / 90 * np.pi / 2)
    np.testing.assert_allclose(pd, (z + 0.5) / 180 * np.pi)
    wi, wo = from_half_diff(th, 0.0, td, pd)
    exact = SHARP.evaluate(wi, wo)
    np.testing.assert_allclose(table.evaluate(wi, wo), exact, rtol=1e-5)  # interpolation hits the centres
    # MERL's lookup: any θh inside bin X reads bin X's value
    table.interpolation = "nearest"
    rng = np.random.default_rng(3)
    inside = theta_h_edge(x) + rng.uniform(0.01, 0.99, x.size) * (theta_h_edge(x + 1) - theta_h_edge(x))
    wi2, wo2 = from_half_diff(inside, 0.0, td, pd)
    np.testing.assert_allclose(table.evaluate(wi2, wo2), exact, rtol=1e-5)


def test_the_highlight_of_a_sharp_table_is_where_the_lobe_is():
    """With lower-edge placement the half-bin shift moves a sharp lobe's values by tens of %."""
    table = tabulate(SHARP)
    th = np.linspace(0.0, 0.04, 200)
    wi, wo = from_half_diff(th, 0.0, np.full_like(th, 0.3), np.full_like(th, 1.0))
    exact, got = SHARP.evaluate(wi, wo)[:, 0], table.evaluate(wi, wo)[:, 0]
    assert np.abs(got - exact).max() < 0.03 * exact.max()


# --- one measure for every source -------------------------------------------------------------

def quick(material_lobes=("Lambertian", "LafortuneIso")):
    return material_from_lobes(list(material_lobes), "Linear", 3), FitOptions(restarts=False)


@needs_shared("merl_slices", "blue-fabric.slice")
@pytest.mark.parametrize("name", ["blue-fabric", "green-latex", "beige-fabric", "nickel"])
def test_a_slice_and_its_full_table_fit_alike_and_match_the_independent_grid(name):
    table = read_slice(DATA / "merl_slices" / f"{name}.slice")
    start, options = quick()
    by_slice = fit(start, samples_of(table), options)
    by_table = fit(start, samples_of(table.to_full()), options)
    assert by_slice.error == pytest.approx(by_table.error, rel=0.01)
    for a, b in zip(by_slice.material.lobes, by_table.material.lobes):
        np.testing.assert_allclose(a.scale, b.scale, rtol=0.01)
        for k in a.params:
            assert a.params[k] == pytest.approx(b.params[k], rel=0.01, abs=1e-3), k
    # the reported error is the direct sum over the samples ...
    assert by_slice.error == pytest.approx(metric_error(by_slice.material, samples_of(table), "Ngan"), rel=1e-9)
    # ... and BRDFLab's own 16 θi × 16 θo × 64 φo grid agrees where it resolves the lobe
    # (diffuse and glossy materials; it cannot see a highlight narrower than its 5° cells)
    if name != "nickel":
        assert grid_error(table, by_slice.material) == pytest.approx(by_slice.error, rel=0.02)


def test_an_exact_fit_reports_zero_and_a_refit_never_gets_worse():
    samples = analytic_grid(TRUTH, 24)
    start = TRUTH.copy()
    start.lobes[1].params.update(m=0.25, F0=0.5)
    r = fit(start, samples, FitOptions(restarts=False, ftol=1e-12))
    assert r.error < 1e-7  # no floor from the accumulation
    again = fit(r.material, samples, FitOptions(restarts=False))
    assert again.error <= r.error
    if again.error == r.error:  # nothing better: the start comes back unchanged
        assert again.material.lobes[1].params == r.material.lobes[1].params


def test_a_parameter_starting_on_its_bound_can_move():
    samples = analytic_grid(TRUTH, 24)
    start = TRUTH.copy()
    start.lobes[1].params.update(F0=0.0)  # on the lower bound: no gradient in the bounded map
    before = metric_error(start, samples, "Ngan")
    r = fit(start, samples, FitOptions(restarts=False))
    assert r.material.lobes[1].params["F0"] == pytest.approx(0.35, rel=1e-3)
    assert r.error < 1e-3 * before
    assert any("F0 = 0 is on its lower bound" in w for w in bound_warnings(start))
    assert not bound_warnings(r.material)


@needs_shared("merl_slices", "nickel.slice")
def test_more_lobes_never_end_worse_and_start_apart():
    two = material_from_lobes(["Lambertian", "CookTorrance", "CookTorrance"], "Linear", 3)
    assert two.lobes[1].params["m"] != two.lobes[2].params["m"]
    samples = samples_of(read_slice(DATA / "merl_slices" / "nickel.slice")).subset(40_000)
    options = FitOptions(restarts=False)
    one = fit(material_from_lobes(["Lambertian", "CookTorrance"], "Linear", 3), samples, options)
    assert fit(two, samples, options).error <= one.error * (1 + 1e-9)


# --- the command line -------------------------------------------------------------------------

@needs_shared("merl_slices", "blue-fabric.slice")
def test_subset_fits_report_the_error_on_all_samples(capsys):
    path = DATA / "merl_slices" / "blue-fabric.slice"
    code = main(["fit", str(path), "--lobes", "Lambertian,BlinnPhong", "--samples", "subset", "--size", "5000",
                 "--no-restarts", "--json"])
    assert code == 0
    payload = json.loads(capsys.readouterr().out.splitlines()[-1])
    table = read_slice(path)
    assert payload["samples"] == 5000 and str(samples_of(table).size) in payload["scoredOn"]
    material = AnalyticMaterial("m", "Linear", 3, [Lobe.create(p["model"], p["scale"], **p["parameters"])
                                                   for p in payload["parameters"]])
    assert payload["error"] == pytest.approx(metric_error(material, samples_of(table), "Ngan"), rel=1e-9)


@pytest.mark.parametrize("limit", ["0", "-1", "nan"])
def test_zero_and_negative_time_limits_are_refused(tmp_path, capsys, limit):
    assert main(["fit", str(tmp_path / "x.slice"), "--lobes", "Lambertian", "--time-limit", limit]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "time-limit" in err


@pytest.fixture(scope="module")
def big_table(tmp_path_factory):
    path = tmp_path_factory.mktemp("stop") / "truth.binary"
    write_merl_binary(tabulate(TRUTH), path)
    return path


def run_fit(args, cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen([sys.executable, "-m", "brdflab", "fit", *args], cwd=cwd, env=env,
                            stdout=stdout, stderr=stderr, text=True)


def _interrupted_at_progress(args, cwd) -> tuple[int, str]:
    """`brdflab fit ARGS` with its stderr on a terminal: SIGINT as soon as a progress line
    shows an iteration; (exit status, everything it wrote on the terminal)."""
    import pty
    import select

    master, slave = pty.openpty()
    proc = run_fit(args, cwd, stdout=subprocess.DEVNULL, stderr=slave)
    os.close(slave)
    text, sent = b"", False
    while True:
        ready, _, _ = select.select([master], [], [], 300)
        if not ready:
            proc.kill()
            raise AssertionError(f"no output for 300 s: {text.decode(errors='replace')}")
        try:
            piece = os.read(master, 4096)
        except OSError:  # the child closed the terminal
            break
        if not piece:
            break
        text += piece
        if not sent and b"iteration" in text:
            proc.send_signal(signal.SIGINT)
            sent = True
    os.close(master)
    assert sent, text.decode(errors="replace")
    return proc.wait(timeout=300), text.decode(errors="replace")


def test_time_limit_stops_within_a_few_passes_and_ctrl_c_saves_the_best(tmp_path, big_table):
    args = [str(big_table), "--lobes", "Lambertian,CookTorrance,CookTorrance", "--json"]
    proc = run_fit([*args, "--time-limit", "0.5"], tmp_path)
    out, err = proc.communicate(timeout=300)
    payload = json.loads(out.splitlines()[-1])
    assert proc.returncode == 0 and payload["status"] == "time-limit"
    assert payload["seconds"] < 0.5 + 30 * 1.0  # generous on a loaded machine; see docs for typical numbers
    # Ctrl-C, pressed as a user at a terminal does, once the progress line shows the fit running:
    # the best parameters so far are saved, exit status 130, one line on stderr
    out_xml = tmp_path / "fit.xml"
    code, err = _interrupted_at_progress([str(big_table), "--lobes", "Lambertian,CookTorrance,CookTorrance",
                                          "--out", str(out_xml)], tmp_path)
    assert code == 130, err
    assert "Traceback" not in err and "best parameters so far are saved" in err
    doc = load(out_xml)
    assert len(doc.fittings) == 1 and doc.fittings[0].statistics["status"] == "cancelled"


@needs_shared("merl_slices", "pvc.slice")
@pytest.mark.parametrize("argv, what, second", [
    (["--lobes", "Lambertian,CookTorrance"], "the fit", "image"),
    (["--auto", "--models", "CookTorrance", "--size", "2000"], "the pick", "image"),
    (["--auto", "--env", str(DATA / "envmaps" / "forest.exr"), "--models", "CookTorrance", "--tolerance", "0.5"],
     "the pick", "sample"),
], ids=["fit", "auto", "scene-auto"])
def test_ctrl_c_while_the_second_error_is_measured_keeps_the_finished_fit(tmp_path, capsys, monkeypatch, argv, what,
                                                                          second):
    """A fit (or Auto's pick) that has ended is measured once more by the other metric (seconds
    on a full table); Ctrl-C there used to lose the whole fit, or a climb of minutes
    ("interrupted", nothing saved)."""
    import brdflab.fitting.second_error as second_error

    def pressed(*_, **__):
        raise KeyboardInterrupt

    monkeypatch.setattr(second_error, "second_error", pressed)
    out = tmp_path / "fit.xml"
    code = main(["fit", str(DATA / "merl_slices" / "pvc.slice"), *argv, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 130 and "Traceback" not in err
    assert f"interrupted while its {second} error was measured; {what} is saved in {out} without it" in err
    stats = load(out).fittings[0].statistics
    assert stats["status"] == "converged" and not {"imageError", "sampleError"} & set(stats)


@needs_shared("merl_slices", "nickel.slice")
def test_a_table_is_fitted_at_its_bin_centres_with_its_values():
    """Every sample a fit runs over is a valid bin's centre (θh, θd, φd), above the surface,
    with that bin's measured values: recomputed from the half/difference angles of the
    directions, apart from how `TableSampleSet` builds them."""
    from brdflab.geometry.halfdiff import N_PD, N_TD, to_half_diff

    table = read_slice(DATA / "merl_slices" / "nickel.slice").to_full()
    seen = 0
    for wi, wo, y, weight in samples_of(table).chunks():
        th, _, td, pd = to_half_diff(wi, wo)
        x = np.rint(np.sqrt(th / (0.5 * np.pi)) * 90 - 0.5).astype(int)
        yb = np.rint(td / (0.5 * np.pi) * N_TD - 0.5).astype(int)
        zb = np.rint(np.mod(pd, np.pi) / np.pi * N_PD - 0.5).astype(int) % N_PD
        np.testing.assert_allclose(th, theta_h_of_bin(x), atol=1e-9)
        np.testing.assert_allclose(td, theta_d_of_bin(yb), atol=1e-9)
        assert table.valid[x, yb, zb].all() and (wi[:, 2] > 0).all() and (wo[:, 2] > 0).all() and (weight > 0).all()
        np.testing.assert_array_equal(y, table.values[:, x, yb, zb].T)
        seen += y.shape[0]
    assert seen == samples_of(table).size > 1_000_000
