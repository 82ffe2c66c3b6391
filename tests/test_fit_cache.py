"""A fit is made once (fitting/fit_cache.py): the same lobes, samples, options and fitter read
it back from the user's cache; anything else, or an entry that cannot be used, fits again."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdflab.fitting import fit_cache
from brdflab.fitting.fit_cache import fit_key, fit_once
from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
from brdflab.fitting.samples import analytic_grid
from brdflab.io.user_cache import cache_folder
from brdflab.io.xmlio import load

ROOT = Path(__file__).resolve().parent.parent
WARD = ROOT / "materials" / "ward.xml"


@pytest.fixture
def counted(monkeypatch):
    calls = []

    def counting(*args, **kwargs):
        calls.append(1)
        return fit(*args, **kwargs)

    monkeypatch.setattr(fit_cache, "fit", counting)
    return calls


def setting(density: int = 12):
    samples = analytic_grid(load(WARD).material, density)
    return material_from_lobes(["Lambertian", "BlinnPhong"], "Linear", 3), samples


def test_the_same_fit_is_read_back_and_equals_the_first(counted):
    start, samples = setting()
    options = FitOptions(restarts=False, max_iterations=30)
    first, cached_first = fit_once(start, samples, options)
    again, cached_again = fit_once(start, samples, options)
    assert (cached_first, cached_again) == (False, True) and len(counted) == 1
    assert again.error == first.error and again.zero_error == first.zero_error and again.status == first.status
    for a, b in zip(again.material.lobes, first.material.lobes):
        assert a.params == b.params and a.scale == b.scale


def test_other_samples_options_or_start_fit_again(counted):
    start, samples = setting()
    options = FitOptions(restarts=False, max_iterations=30)
    fit_once(start, samples, options)
    other_samples = setting(13)[1]
    moved = start.copy()
    moved.lobes[1].params["Exponent"] = 2 * moved.lobes[1].params["Exponent"]
    fit_once(start, other_samples, options)
    fit_once(start, samples, FitOptions(restarts=False, max_iterations=30, metric="L2"))
    fit_once(moved, samples, options)
    assert len(counted) == 4
    samples.values[0, 0] *= 1.5  # one value changed: another digest
    assert fit_key(start, samples, options) != fit_key(start, setting()[1], options)


@pytest.mark.parametrize("damage", ["garbage", "out-of-bounds", "missing-field"])
def test_an_entry_that_cannot_be_used_is_fitted_again_and_rewritten(counted, damage):
    start, samples = setting()
    options = FitOptions(restarts=False, max_iterations=30)
    first, _ = fit_once(start, samples, options)
    (entry,) = cache_folder("fits").glob("*.json")
    data = json.loads(entry.read_text())
    if damage == "garbage":
        entry.write_bytes(b"\x00\xff{not json")
    elif damage == "out-of-bounds":
        data["lobes"][1]["params"]["Exponent"] = -5.0
        entry.write_text(json.dumps(data))
    else:
        del data["zero_error"]
        entry.write_text(json.dumps(data))
    again, cached = fit_once(start, samples, options)
    assert not cached and len(counted) == 2 and again.error == first.error
    assert json.loads(entry.read_text())["error"] == first.error  # rewritten whole
    assert fit_once(start, samples, options)[1] and len(counted) == 2  # and read back now


def test_a_cancelled_fit_is_not_kept(counted):
    import threading

    start, samples = setting()
    stop = threading.Event()
    stop.set()
    result, _ = fit_once(start, samples, FitOptions(restarts=False), cancel=stop)
    assert result.status == "cancelled" and not list(cache_folder("fits").glob("*.json"))


CONCURRENT = """
import sys
sys.path.insert(0, {tests!r})
from test_fit_cache import setting
from brdflab.fitting.fit_cache import fit_once
from brdflab.fitting.lm import FitOptions
start, samples = setting()
result, cached = fit_once(start, samples, FitOptions(restarts=False, max_iterations=30))
print(repr(result.error))
"""


def test_processes_fitting_at_once_leave_one_entry_that_reads(tmp_path):
    script = CONCURRENT.format(tests=str(ROOT / "tests"))
    runs = [subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            for _ in range(3)]
    outputs = [r.communicate(timeout=600) for r in runs]
    assert all(r.returncode == 0 for r in runs), outputs
    assert len({out for out, _ in outputs}) == 1
    (entry,) = cache_folder("fits").glob("*.json")
    start, samples = setting()
    result, cached = fit_once(start, samples, FitOptions(restarts=False, max_iterations=30))
    assert cached and repr(result.error) == outputs[0][0].strip()
    assert not list(cache_folder("fits").glob("*.tmp*")) and not [p for p in entry.parent.iterdir() if p != entry]


def brdflab(*args, cwd):
    return subprocess.run([sys.executable, "-m", "brdflab", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=600)


def ward_samples(path: Path, n: int = 150) -> None:
    """A raw sample file of the shipped Ward material: a measured source small enough that its
    principled fit takes seconds (a grid of the material takes minutes)."""
    rng = np.random.default_rng(5)
    ti, to = np.arccos(rng.uniform(0.05, 1.0, (2, n)))
    pi, po = rng.uniform(0.0, 2 * np.pi, (2, n))
    wi = np.stack([np.sin(ti) * np.cos(pi), np.sin(ti) * np.sin(pi), np.cos(ti)], 1)
    wo = np.stack([np.sin(to) * np.cos(po), np.sin(to) * np.sin(po), np.cos(to)], 1)
    values = load(WARD).material.evaluate(wi, wo)
    np.savetxt(path, np.column_stack([ti, pi, to, po, values]))


def test_a_second_export_in_any_format_does_not_fit_again(tmp_path):
    """As a user meets it: Mitsuba, then MaterialX and glTF of the same measured file."""
    source = tmp_path / "ward_samples.txt"
    ward_samples(source)
    first = brdflab("export", str(source), "--format", "mitsuba", "--out", str(tmp_path / "w.xml"), "--json", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    said = [w for w in json.loads(first.stdout.splitlines()[-1])["warnings"] if "fitted to Principled" in w]
    assert said and "on the way out" in said[0]
    error = said[0].split("Ngan error ")[1].split(",")[0]
    image = said[0].split("; image error ")[1].split(" ")[0]  # both numbers, the image error kept with the fit
    weighed = sorted(cache_folder("export_losses").glob("*.json"))
    assert weighed  # the losses every format says, weighed while the fit was made
    for fmt, name in (("mtlx", "w.mtlx"), ("gltf", "w.gltf")):
        again = brdflab("export", str(source), "--format", fmt, "--out", str(tmp_path / name), "--json", cwd=tmp_path)
        assert again.returncode == 0, again.stderr
        (line,) = [w for w in json.loads(again.stdout.splitlines()[-1])["warnings"] if "fitted to Principled" in w]
        assert "by an earlier export (read from the cache)" in line and f"Ngan error {error}," in line
        assert f"; image error {image} under sun-high-small" in line
    assert len(list(cache_folder("fits").glob("*.json"))) == 1
    assert sorted(cache_folder("export_losses").glob("*.json")) == weighed  # read back, none weighed again


def test_an_exports_losses_are_weighed_once(monkeypatch):
    """What a format cannot carry is weighed over a grid of the principled material once per
    parameters (issue 35 goal 4: a second export weighed them again, most of its time); a
    damaged entry is weighed again."""
    from brdflab.export import principled
    from brdflab.fitting import metrics
    from brdflab.models import get_model

    params = {**get_model("Principled").defaults(), "subsurface": 0.4, "clearcoat": 0.3, "sheen": 0.6}
    weighed = []
    real = metrics.metric_errors
    monkeypatch.setattr(metrics, "metric_errors", lambda *a: weighed.append(1) or real(*a))

    def warnings():
        export = principled.PrincipledExport(dict(params), exact=True)
        return principled.approximation_warnings(export, "MaterialX", "no subsurface", "no coat", "no sheen")

    first = warnings()
    assert len(first) == 3 and len(weighed) == 3 and all("% of the material)" in w for w in first)
    assert warnings() == first and len(weighed) == 3  # read back: no grid, no weighing
    for entry in cache_folder(principled.LOSSES).glob("*.json"):
        entry.write_text('{"loss": [1.0, "x"]}')
    assert warnings() == first and len(weighed) == 6
