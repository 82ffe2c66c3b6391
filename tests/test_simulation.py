"""Simulated materials as sources: specs, tables, files, the command line, SCATMECH."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdflab.errors import BRDFLabError
from brdflab.io.xmlio import BRDFDocument, load, save
from brdflab.simulation import scatmech
from brdflab.simulation.material import (SimulationSpec, compute_table, reference_of, simulated_material, spec_of)
from brdflab.simulation.registry import KINDS
from brdflab.sources.files import load_source

ROOT = Path(__file__).resolve().parents[1]
SMALL = dict(seed=5, samples=4000, resolution=8)


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("BRDFLAB_CACHE", str(tmp_path / "cache"))


def test_every_kind_declares_its_parameters_once_with_bounds_and_units():
    assert {"SubsurfaceParticle", "Microroughness", "Facet", "DiffuseSubsurface",
            "GaussianHeightField", "VGrooves", "SpheresOnPlane"} <= set(KINDS)
    for kind in KINDS.values():
        names = [p.name for p in kind.parameters]
        assert len(names) == len(set(names)), kind.name
        for p in kind.parameters:
            assert p.doc
            if not p.choices:
                assert p.lower <= p.default <= p.upper
        assert kind.complete({}) == {p.name: p.default for p in kind.parameters}


def test_bad_parameters_are_refused_with_the_reason():
    with pytest.raises(BRDFLabError, match=r"rms_slope=9 is outside \[0.02, 1.5\]"):
        SimulationSpec("GaussianHeightField", {"rms_slope": "9"})
    with pytest.raises(BRDFLabError, match="expected one of mirror, lambertian"):
        SimulationSpec("VGrooves", {"facet": "velvet"})
    with pytest.raises(BRDFLabError, match="unknown simulated kind"):
        SimulationSpec("Nope")


def test_ray_bounce_tables_are_deterministic_for_a_seed_whatever_the_workers():
    spec = SimulationSpec("SpheresOnPlane", {"facet": "lambertian", "max_bounces": 2}, seed=5, samples=1000, resolution=8)
    seen = []
    one = compute_table(spec, workers=1).values
    two = compute_table(spec, progress=lambda f, message: seen.append(f), workers=2).values
    assert seen == sorted(seen) and seen[-1] == 1.0 and len(seen) == 4  # one report per incident angle
    assert np.array_equal(one, two)
    other = compute_table(SimulationSpec("SpheresOnPlane", {"facet": "lambertian", "max_bounces": 2}, seed=6, samples=1000,
                                         resolution=8), workers=1).values
    assert not np.array_equal(one, other)


def test_lambertian_height_field_table_has_the_albedo_it_should():
    """Flat-ish Lambertian facets (slope 0.05) reflect ρ/π with little interreflection:
    the table must give 0.8/π within Monte Carlo noise (4 000 rays over 4 × 4 bins)."""
    spec = SimulationSpec("GaussianHeightField", {"facet": "lambertian", "rms_slope": 0.05}, **SMALL)
    material = simulated_material(spec, workers=1)
    wi = np.array([[np.sin(0.6), 0.0, np.cos(0.6)]] * 3)
    wo = np.array([[0.0, 0.0, 1.0], [-np.sin(0.6), 0.0, np.cos(0.6)], [0.0, np.sin(0.9), np.cos(0.9)]])
    values = material.evaluate(wi, wo)
    assert values.shape == (3, 3)
    assert np.allclose(values, 0.8 / np.pi, rtol=0.12)
    assert np.all(material.evaluate(wi, -wo) == 0.0)  # below the horizon


def test_the_file_stores_everything_that_reproduces_the_material(tmp_path):
    spec = SimulationSpec("VGrooves", {"groove_angle": 40, "facet": "lambertian", "albedo_g": 0.5}, **SMALL, name="grooves")
    path = tmp_path / "v.xml"
    save(BRDFDocument(reference_of(spec)), path)
    again = spec_of(load(path).material)
    assert (again.kind, again.params, again.seed, again.samples, again.resolution, again.name) == \
        (spec.kind, spec.params, spec.seed, spec.samples, spec.resolution, spec.name)
    text = path.read_text().replace("</Simulation>", "</Simulation><Note>kept</Note>")
    path.write_text(text)
    doc = load(path)
    assert any("Note" in w for w in doc.warnings)
    save(doc, path)
    assert "<Note>kept</Note>" in path.read_text()  # unknown elements survive a save
    source = load_source(path)
    assert source.n_channels == 3 and source.isotropic
    assert np.array_equal(source.table.values, compute_table(spec, workers=1).values)


def _cli(*args, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "brdflab", *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def test_cli_simulate_list_write_info_eval_and_refuse_bad_input(tmp_path):
    listing = json.loads(_cli("simulate", "--list", "--json", cwd=tmp_path).stdout.splitlines()[-1])
    gh = next(k for k in listing["kinds"] if k["kind"] == "GaussianHeightField")
    assert {"name": "rms_slope", "default": 0.3, "lower": 0.02, "upper": 1.5} .items() <= gh["parameters"][0].items()
    r = _cli("simulate", "GaussianHeightField", "--set", "rms_slope=0.2", "--seed", "2", "--samples", "4000",
             "--resolution", "8", "--out", "hf.xml", "--json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    info = json.loads(_cli("info", "hf.xml", "--json", cwd=tmp_path).stdout.splitlines()[-1])
    assert info["material"]["parameters"]["rms_slope"] == 0.2 and info["material"]["cached"]
    pairs = np.array([[0.3, 0.0, 0.954, -0.3, 0.0, 0.954], [0.3, 0.0, 0.954, 0.6, 0.0, 0.8]])
    np.save(tmp_path / "pairs.npy", pairs)
    r = _cli("eval", "hf.xml", "--pairs", "pairs.npy", "--out", "v.npy", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    values = np.load(tmp_path / "v.npy")
    assert values[0, 0] > 0.03 and values[0, 0] > 5 * values[1, 0]  # specular peak (F ≈ 0.04) ≫ backscatter
    bad = _cli("simulate", "VGrooves", "--set", "groove_angle=80", "--out", "x.xml", cwd=tmp_path)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr and "groove_angle=80" in bad.stderr
    (tmp_path / "broken.xml").write_text((tmp_path / "hf.xml").read_text().replace('rms_slope="0.2"', 'rms_slope="-1"'))
    bad = _cli("info", "broken.xml", cwd=tmp_path)
    assert bad.returncode == 2 and "broken.xml" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    (tmp_path / "huge.xml").write_text((tmp_path / "hf.xml").read_text().replace('resolution="8"', 'resolution="100000"'))
    bad = _cli("eval", "huge.xml", "--pairs", "pairs.npy", "--out", "w.npy", cwd=tmp_path)
    assert bad.returncode == 2 and "huge.xml" in bad.stderr and "resolution 100000" in bad.stderr


@pytest.mark.skipif(scatmech.available(), reason="pySCATMECH is installed")
def test_without_pyscatmech_a_scatmech_material_says_what_is_missing(tmp_path):
    r = _cli("simulate", "SubsurfaceParticle", "--out", "p.xml", cwd=tmp_path)
    assert r.returncode == 2 and "needs pySCATMECH" in r.stderr and len(r.stderr.strip().splitlines()) == 1


@pytest.mark.skipif(not scatmech.available(), reason="pySCATMECH is not installed")
def test_scatmech_diffuse_subsurface_is_lambertian_times_fresnel_transmission():
    """Diffuse_Subsurface: a diffuse layer of reflectance R under a smooth dielectric. At
    normal incidence and view both Fresnel transmissions are 1 − ((n−1)/(n+1))²; with
    internal reflection it is R·T²/(π n² (1 − R·ri)) — checked only for its order:
    between R·T²/(π n²) and R/π."""
    spec = SimulationSpec("DiffuseSubsurface", {"reflectance": 0.5}, resolution=4)
    wi = np.array([[0.0, 0.0, 1.0]])
    v = scatmech.evaluate_chunk("DiffuseSubsurface", spec.params, wi, wi)
    t = 1 - (0.5 / 2.5) ** 2
    assert 0.5 * t * t / (np.pi * 1.5**2) * 0.99 < v[0, 0] < 0.5 / np.pi


@pytest.mark.skipif(not scatmech.available(), reason="pySCATMECH is not installed")
def test_scatmech_facet_peak_is_fresnel_times_gaussian_slopes_and_the_table_holds_it():
    """Facet model at normal incidence and view: f = R(0) · P(0) / 4 with P(0) = 1/(π s²)
    for a Gaussian slope distribution of RMS slope s and R(0) = ((n−1)/(n+1))² (1 %)."""
    spec = SimulationSpec("Facet", {"rms_slope": 0.3}, resolution=4)
    normal = np.array([[0.0, 0.0, 1.0]])
    v = scatmech.evaluate_chunk("Facet", spec.params, normal, normal)
    assert v[0] == pytest.approx([0.04 / (4 * np.pi * 0.09)] * 3, rel=0.01)
    table = compute_table(spec, workers=2)
    from brdflab.simulation.table import node_directions

    wi, wo = node_directions(4)
    assert np.allclose(table.evaluate(wi, wo), scatmech.evaluate_chunk("Facet", spec.params, wi, wo), rtol=1e-5, atol=1e-9)
