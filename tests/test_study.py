"""`brdflab study`: the framework, and the lobe viewer part (subdivision against shape)."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import psutil
import pytest

from brdflab.cli import main
from brdflab.errors import BRDFLabError
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.render.lobe_view import LobeSettings
from brdflab.study.framework import check_finite
from brdflab.geometry.lobe_surface import auto_level, surface_error
from conftest import ROOT, SHARED, needs_shared


def test_a_non_finite_number_anywhere_is_refused():
    check_finite({"rows": [{"ms": 1.0, "error": None}]}, "part")
    with pytest.raises(BRDFLabError, match=r"part\.rows\[1\]\.error"):
        check_finite({"rows": [{"error": 0.1}, {"error": float("nan")}]}, "part")


def test_the_drawn_lobe_converges_to_the_exact_one():
    """A diffuse lobe is a sphere: flat triangles miss it by O(h²), a quarter per level. Its
    rim must not fold to the origin (a BRDF is 0 at z = 0 exactly; the rim sits above it)."""
    lambertian = AnalyticMaterial("d", "Linear", 3, [Lobe.create("Lambertian", [0.5] * 3)])
    errors = [surface_error(lambertian, LobeSettings(transfer="linear").shape, level)[0] for level in (2, 3, 4)]
    assert errors[2] < 0.01
    assert 3.0 < errors[0] / errors[1] < 5.0 and 3.0 < errors[1] / errors[2] < 5.0


def test_a_sharp_lobe_needs_more_levels_than_a_broad_one():
    def glossy(n):
        return AnalyticMaterial("g", "Linear", 3, [Lobe.create("BlinnPhong", [0.5] * 3, Exponent=n)])

    shape = LobeSettings().shape
    assert surface_error(glossy(1000.0), shape, 4)[0] > 4 * surface_error(glossy(20.0), shape, 4)[0]


def test_auto_subdivision_is_the_lowest_level_within_the_tolerance():
    """Auto (issue 13): the lowest level whose drawn lobe stays within 1 % of the peak radius,
    checked against the exhaustive sweep of every level; sharp lobes need more levels."""
    from brdflab.geometry.lobe_surface import LEVELS

    shape = LobeSettings().shape
    for n in (20.0, 1000.0):
        material = AnalyticMaterial("g", "Linear", 3, [Lobe.create("BlinnPhong", [0.5] * 3, Exponent=n)])
        sweep = {level: surface_error(material, shape, level)[0] for level in LEVELS}
        within = [level for level, error in sweep.items() if error <= 0.01]
        assert auto_level([material], shape, 0.01) == (min(within), sweep[min(within)])
    broad = AnalyticMaterial("g", "Linear", 3, [Lobe.create("BlinnPhong", [0.5] * 3, Exponent=20.0)])
    sharp = AnalyticMaterial("g", "Linear", 3, [Lobe.create("BlinnPhong", [0.5] * 3, Exponent=1000.0)])
    assert auto_level([broad], shape)[0] < auto_level([broad, sharp], shape)[0]  # the fit counts too


def test_study_quick_writes_charts_and_finite_numbers(tmp_path, capsys):
    assert main(["study", "--quick", "--part", "viewer", "--out", str(tmp_path), "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["charts"]["viewer"] == ["viewer_subdivision.png"]
    assert (tmp_path / "viewer_subdivision.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    study = json.loads((tmp_path / "study.json").read_text())
    rows = study["parts"]["viewer"]["rows"]
    assert {r["level"] for r in rows} == {2, 3, 4, 5}
    assert all(np.isfinite(r["ms"]) and r["ms"] > 0 for r in rows)


def test_an_unknown_part_is_a_one_line_error(tmp_path, capsys):
    assert main(["study", "--part", "nope", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "unknown study part nope" in err and "viewer" in err


def test_study_quick_runs_every_part_from_another_folder(quick_study):
    """What CI runs: `brdflab study --quick`, as a user would (a subprocess, another folder):
    every part registered writes its charts, and every number in study.json is finite."""
    import math

    from brdflab.study.framework import load_parts

    out, payload, study = quick_study
    assert set(payload["charts"]) == set(load_parts())
    for part, files in payload["charts"].items():
        pngs = [f for f in files if f.endswith(".png")]
        assert pngs, f"{part} wrote no chart"
        for name in pngs:
            assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    numbers = []
    stack = [study]
    while stack:
        value = stack.pop()
        if isinstance(value, dict):
            stack.extend(value.values())
        elif isinstance(value, list):
            stack.extend(value)
        elif isinstance(value, float):
            numbers.append(value)
    assert len(numbers) > 100 and all(math.isfinite(v) for v in numbers)


@needs_shared("merl_slices")
def test_stop_after_starts_no_fit_past_its_time_and_says_how_to_go_on(tmp_path, capsys):
    assert main(["study", "--quick", "--part", "fitting", "--stop-after", "0", "--out", str(tmp_path), "--json"]) == 0
    err = capsys.readouterr().err
    assert "fitting: stopped with 0 of " in err and "run again into the same folder to go on" in err
    study = json.loads((tmp_path / "study.json").read_text())["parts"]["fitting"]
    assert study["fits_done"] == 0 < study["fits_planned"]


@needs_shared("merl_slices")
def test_sigterm_stops_the_study_and_its_worker_processes(tmp_path):
    """`kill` (SIGTERM) of a study that is fitting on a process pool: one line, exit status
    143, and no worker process left fitting on its own."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "BRDFLAB_SHARED": str(SHARED)}
    proc = subprocess.Popen([sys.executable, "-m", "brdflab", "study", "--quick", "--part", "fitting", "--out", "s"],
                            cwd=tmp_path, env=env, stderr=subprocess.PIPE, text=True)
    parent = psutil.Process(proc.pid)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(parent.children(recursive=True)) < 2:
        time.sleep(0.2)  # the spawned pool (and its resource tracker) is up
    workers = parent.children(recursive=True)
    assert len(workers) >= 2 and proc.poll() is None
    time.sleep(1.0)  # the workers are fitting
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143 and err.strip().splitlines()[-1] == "brdflab study: terminated"
    gone, alive = psutil.wait_procs(workers, timeout=10)
    assert not alive, [p.cmdline() for p in alive]
