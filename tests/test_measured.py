"""Measured data: readers, writers, lookups and every bad input."""

import hashlib

import numpy as np
import pytest

from brdflab.cli import main
from brdflab.errors import BRDFLabError
from brdflab.geometry.halfdiff import from_half_diff, phi_d_of_bin, theta_d_of_bin, theta_h_of_bin
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.sources.measured import (
    MERL_SCALE,
    read_carpaint,
    read_measured,
    read_merl_binary,
    read_raw_samples,
    read_slice,
    tabulate,
    write_merl_binary,
)
from conftest import DATA, needs_shared, random_upper

GLOSSY = AnalyticMaterial("g", "Linear", 3, [
    Lobe.create("Lambertian", [0.2, 0.1, 0.05]),
    Lobe.create("BlinnPhong", [0.3, 0.3, 0.3], Exponent=30.0),
])


@pytest.fixture(scope="module")
def merl_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("merl") / "glossy.binary"
    write_merl_binary(tabulate(GLOSSY), path)
    return path


def test_binary_round_trip_and_grid_values(merl_file):
    table = read_merl_binary(merl_file)
    assert table.values.shape == (3, 90, 90, 180) and table.values.dtype == np.float32
    # values at grid positions are the analytic ones (float32 precision)
    ix, iy, iz = np.array([0, 10, 45, 70]), np.array([5, 30, 60, 20]), np.array([0, 90, 45, 170])
    wi, wo = from_half_diff(theta_h_of_bin(ix), 0.0, theta_d_of_bin(iy), phi_d_of_bin(iz))
    np.testing.assert_allclose(table.evaluate(wi, wo), GLOSSY.evaluate(wi, wo), rtol=1e-6)
    again = merl_file.with_name("again.binary")
    write_merl_binary(table, again)
    assert again.read_bytes() == merl_file.read_bytes()


def test_trilinear_lookup_follows_a_smooth_lobe(merl_file, rng):
    table = read_merl_binary(merl_file)
    wi, wo = random_upper(rng, 4000), random_upper(rng, 4000)
    keep = (wi[:, 2] > 0.2) & (wo[:, 2] > 0.2)
    exact = GLOSSY.evaluate(wi[keep], wo[keep])
    tri = table.evaluate(wi[keep], wo[keep])
    table.interpolation = "nearest"
    near = table.evaluate(wi[keep], wo[keep])
    err_tri = np.abs(tri - exact).mean() / exact.mean()
    err_near = np.abs(near - exact).mean() / exact.mean()
    assert err_tri < 0.01 and err_tri < err_near


def test_reciprocity_fold_and_isotropy(merl_file, rng):
    table = read_merl_binary(merl_file)
    wi, wo = random_upper(rng, 500), random_upper(rng, 500)
    np.testing.assert_allclose(table.evaluate(wi, wo), table.evaluate(wo, wi), rtol=1e-5)
    c, s = np.cos(0.7), np.sin(0.7)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    np.testing.assert_allclose(table.evaluate(wi @ rot.T, wo @ rot.T), table.evaluate(wi, wo), rtol=1e-5)


def test_a_slice_reads_as_its_full_table_and_new_arrays_are_read_anew(rng):
    """A slice's lookup (θh and θd from the half vector, no φd) equals the same slice repeated
    along φd and read through the full half/difference rotations; a table given new value or
    validity arrays after a lookup is read from them, not from the lookup's cache."""
    table = tabulate(GLOSSY, phi_d_samples=1)
    wi, wo = random_upper(rng, 2000), random_upper(rng, 2000)
    np.testing.assert_allclose(table.evaluate(wi, wo), table.to_full().evaluate(wi, wo), rtol=1e-9, atol=1e-12)
    before = table.evaluate(wi, wo)
    table.values = table.values * 2.0
    np.testing.assert_allclose(table.evaluate(wi, wo), 2.0 * before, rtol=1e-6)
    table.valid = np.zeros_like(table.valid)
    assert not table.evaluate(wi, wo).any()


def test_unmeasured_samples_are_masked(tmp_path):
    table = tabulate(GLOSSY)
    table.valid[:, :, :90] = False
    write_merl_binary(table, tmp_path / "holes.binary")
    back = read_merl_binary(tmp_path / "holes.binary")
    assert not back.valid[:, :, :90].any() and back.valid[:, :, 90:].any()


@needs_shared("merl_slices", "chrome-steel.slice")
def test_real_slices_load_as_documented():
    chrome = read_slice(DATA / "merl_slices" / "chrome-steel.slice")
    assert chrome.values.shape == (3, 90, 90, 1)
    peak = chrome.values[1, :, :80, 0].argmax(axis=0)  # θh bin of the maximum for each θd
    assert np.all(peak <= 3)  # θh < 0.2°: the mirror peak (the first bins are noisy)
    paint = read_slice(DATA / "merl_slices" / "white-paint.slice")
    assert 0.05 < float(np.median(paint.values[:, 30:60, 10:50])) < 0.5
    full = paint.to_full()
    assert full.values.shape == (3, 90, 90, 180) and np.all(full.values[:, :, :, 7] == full.values[:, :, :, 100])


@needs_shared("merl_slices")
def test_every_real_slice_reads():
    for path in sorted((DATA / "merl_slices").glob("*.slice")):
        t = read_slice(path)
        assert t.valid.any() and np.all(np.isfinite(t.values))


def test_raw_samples(tmp_path, rng):
    path = tmp_path / "s.txt"
    wi, wo = random_upper(rng, 300), random_upper(rng, 300)
    ti, pi = np.arccos(wi[:, 2]), np.arctan2(wi[:, 1], wi[:, 0])
    to, po = np.arccos(wo[:, 2]), np.arctan2(wo[:, 1], wo[:, 0])
    vals = GLOSSY.evaluate(wi, wo)
    lines = ["# theta_i, phi_i, theta_o, phi_o, r, g, b"] + [
        ", ".join(f"{x:.17g}" for x in row) for row in np.column_stack([ti, pi, to, po, vals])]
    path.write_text("\n".join(lines))
    raw = read_raw_samples(path)
    assert raw.n_channels == 3
    np.testing.assert_allclose(raw.evaluate(wi, wo), vals)


def test_carpaint_layout(tmp_path):
    data = np.zeros((180, 90, 90, 3), "<f4")
    data[:, 0, :, 0] = 5.0  # θh bin 0, red
    data[:, :, :, 2] = -1.0  # negative → 0
    path = tmp_path / "paint.carpaint"
    path.write_bytes(b"\0" * 84 + data.tobytes())
    t = read_carpaint(path)
    assert t.values.shape == (3, 90, 90, 180)
    assert np.all(t.values[0, 0] == 5.0) and np.all(t.values[2] == 0.0)
    path.write_bytes(b"\0" * 84 + data.tobytes()[:-4])
    with pytest.raises(BRDFLabError, match="truncated"):
        read_carpaint(path)


def merl_bytes(values=None, dims=(90, 90, 180)):
    v = np.ones(3 * 90 * 90 * 180) if values is None else values
    return np.array(dims, "<i4").tobytes() + np.asarray(v, "<f8").tobytes()


BAD_BINARY = {
    "truncated": (merl_bytes()[:-8], "truncated"),
    "oversized": (merl_bytes() + b"\0" * 8, "oversized"),
    "header": (merl_bytes(dims=(90, 90, 360)), "dimensions are not MERL's (90, 90, 180)"),
    "tiny": (b"\1\2", "truncated"),
    "all negative": (merl_bytes(-np.ones(3 * 90 * 90 * 180)), "every sample is negative"),
    "nan": (merl_bytes(np.r_[np.nan, np.ones(3 * 90 * 90 * 180 - 1)]), "NaN or Inf"),
}


@pytest.mark.parametrize("case", sorted(BAD_BINARY))
def test_bad_binary_files(tmp_path, capsys, case):
    data, message = BAD_BINARY[case]
    path = tmp_path / "bad.binary"
    path.write_bytes(data)
    with pytest.raises(BRDFLabError, match=message.replace("(", r"\(").replace(")", r"\)")):
        read_merl_binary(path)
    digest = hashlib.sha256(data).hexdigest()
    assert main(["info", str(path), "--json"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and str(path) in err and message.split(" (")[0] in err
    assert hashlib.sha256(path.read_bytes()).hexdigest() == digest


@pytest.mark.parametrize("text, message", [
    ("0.1, 0, 0.2, 3.1, 0.5, 0.5, 0.5\n0.1, 0, x, 3.1, 0.5, 0.5, 0.5", "line 2: not a number"),
    ("0.1, 0, 0.2", "line 1: expected"),
    ("0.1, 0, 0.2, 3.1, 0.5, 0.5, 0.5\n0.1, 0, 0.2, 3.1, 0.5", "line 2: 5 fields"),
    ("# only a comment\n", "no samples"),
    ("0.1, 0, 0.2, 3.1, nan, 0.5, 0.5", "NaN or Inf"),
])
def test_bad_raw_text(tmp_path, text, message):
    path = tmp_path / "raw.txt"
    path.write_text(text)
    with pytest.raises(BRDFLabError, match=message):
        read_raw_samples(path)


def test_bad_slice_size(tmp_path):
    path = tmp_path / "x.slice"
    path.write_bytes(b"\0" * 100)
    with pytest.raises(BRDFLabError, match="truncated: 100 bytes"):
        read_slice(path)


def test_unknown_extension(tmp_path):
    path = tmp_path / "x.dat"
    path.write_bytes(b"1")
    with pytest.raises(BRDFLabError, match="unknown measured data type"):
        read_measured(path)


def test_changed_data_file_is_noticed(tmp_path, merl_file, capsys):
    import json
    import shutil

    data = tmp_path / "m.binary"
    shutil.copy(merl_file, data)
    xml = tmp_path / "m.xml"
    from brdflab.io.xmlio import BRDFDocument, MeasuredReference, save

    ref = MeasuredReference("MERLBRDFDatabase", "m.binary", tmp_path)
    ref.sha256 = ref.current_sha256()
    save(BRDFDocument(ref), xml)
    assert main(["info", str(xml), "--json"]) == 0
    assert json.loads(capsys.readouterr().out.splitlines()[-1])["material"]["sha256_matches"] is True
    raw = bytearray(data.read_bytes())
    raw[-1] ^= 1
    data.write_bytes(bytes(raw))
    assert main(["info", str(xml), "--json"]) == 0
    assert json.loads(capsys.readouterr().out.splitlines()[-1])["material"]["sha256_matches"] is False


def test_merl_channel_scales_are_applied(tmp_path):
    raw = np.ones((3, 90, 90, 180))
    path = tmp_path / "ones.binary"
    path.write_bytes(merl_bytes(raw.ravel()))
    t = read_merl_binary(path)
    np.testing.assert_allclose(t.values[:, 3, 3, 3], MERL_SCALE, rtol=1e-6)


def test_sources_say_where_they_are_defined(merl_file, tmp_path):
    from brdflab.workspace import Workspace

    assert "samples measured" in read_merl_binary(merl_file).describe()["domain"]
    assert "above the surface" in GLOSSY.describe()["domain"]
    # a workspace notices a data file that changed since its fits were recorded
    import shutil

    from brdflab.io.xmlio import BRDFDocument, MeasuredReference, save

    data = tmp_path / "d.binary"
    shutil.copy(merl_file, data)
    ref = MeasuredReference("MERLBRDFDatabase", "d.binary", tmp_path)
    ref.sha256 = ref.current_sha256()
    save(BRDFDocument(ref), tmp_path / "d.xml")
    assert not any("changed" in m for m in Workspace.open(tmp_path / "d.xml").messages)
    raw = bytearray(data.read_bytes())
    raw[-1] ^= 1
    data.write_bytes(bytes(raw))
    assert any("changed since its fits were made" in m for m in Workspace.open(tmp_path / "d.xml").messages)


def test_a_measured_file_names_the_window_until_its_material_is_saved(tmp_path):
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.sources.measured import tabulate, write_merl_binary
    from brdflab.workspace import Workspace

    material = AnalyticMaterial("t", "Linear", 3, [Lobe.create("Lambertian", [0.3] * 3)])
    write_merl_binary(tabulate(material), tmp_path / "red-plastic.binary")
    ws = Workspace.open(tmp_path / "red-plastic.binary")
    assert ws.title == "untitled (red-plastic.binary) *"
    ws.save(tmp_path / "red.xml")
    ws.dirty = False
    assert ws.title == "red.xml"
