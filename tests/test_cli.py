"""The command line as scripts use it: JSON on the last line, one-line errors, exit 2."""

import hashlib
import json
import subprocess
import sys

import numpy as np
import pytest

from brdflab.cli import main
from brdflab.models import model_names
from brdflab.io.resources import data_dir
from brdflab.io.xmlio import load
from test_xml import ORIGINAL, directions

FIG2 = data_dir("materials") / "fig2_lambertian_lafortune.xml"


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def last_json(out):
    return json.loads(out.strip().splitlines()[-1])


def test_models_json_lists_every_model(capsys):
    code, out, _ = run(capsys, "models", "--json")
    assert code == 0
    models = {m["id"]: m for m in last_json(out)["models"]}
    assert set(models) == set(model_names())
    ward = models["Ward"]
    assert ward["xml_name"] == "Ward" and ward["isotropic"] is False and ward["samplable"] is True
    assert [p["name"] for p in ward["parameters"]] == ["ax", "ay"]
    assert all({"name", "default", "lower", "upper"} <= set(p) for m in models.values() for p in m["parameters"])
    assert models["Strauss"]["samplable"] is False
    assert models["Lambertian"]["parameters"] == []


def test_info_reports_material_and_energy(capsys):
    code, out, _ = run(capsys, "info", str(FIG2), "--json")
    assert code == 0
    info = last_json(out)
    assert info["material"]["combination"] == "Linear"
    assert [l["model"] for l in info["material"]["lobes"]] == ["Lambertian", "LafortuneIso"]
    assert info["energy"]["conserves_energy"] is True


def test_eval_matches_the_material(capsys, tmp_path):
    wi, wo = directions(500)
    pairs = tmp_path / "pairs.npy"
    np.save(pairs, np.concatenate([wi, wo], axis=1))
    out_path = tmp_path / "out.npy"
    code, out, _ = run(capsys, "eval", str(FIG2), "--pairs", str(pairs), "--out", str(out_path), "--json")
    assert code == 0 and last_json(out)["pairs"] == 500
    values = np.load(out_path)
    np.testing.assert_allclose(values, load(FIG2).material.evaluate(wi, wo))


def test_eval_of_a_stored_fitting(capsys, tmp_path):
    xml = tmp_path / "m.xml"
    xml.write_bytes(ORIGINAL)
    wi, wo = directions(20)
    pairs = tmp_path / "p.npy"
    np.save(pairs, np.concatenate([wi, wo], axis=1))
    code, _, _ = run(capsys, "eval", str(xml), "--pairs", str(pairs), "--out", str(tmp_path / "o.npy"), "--fitting", "1")
    assert code == 0
    np.testing.assert_allclose(np.load(tmp_path / "o.npy"), np.tile([0.01, 0.02, 0.03], (20, 1)))
    code, _, err = run(capsys, "eval", str(xml), "--pairs", str(pairs), "--out", str(tmp_path / "o.npy"), "--fitting", "2")
    assert code == 2 and "stores 2 fitting(s)" in err


def sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("edit", [
    (b"<Model>Ward</Model>", b"<Model>Nope</Model>"),
    (b'Exponent="43.1"', b'Exponent="nan"'),
    (b'ax="0.12"', b'ax="-1"'),
    (b"</BRDF>", b""),
])
def test_bad_material_one_line_error_file_untouched(capsys, tmp_path, edit):
    bad = tmp_path / "bad.xml"
    bad.write_bytes(ORIGINAL.replace(*edit))
    before = sha(bad)
    code, _, err = run(capsys, "info", str(bad), "--json")
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and str(bad) in err and "Traceback" not in err
    assert sha(bad) == before


@pytest.mark.parametrize("array, message", [
    (np.zeros((5, 5)), "expected an (N, 6) array"),
    (np.zeros(6), "expected an (N, 6) array"),
    (np.full((2, 6), np.nan), "NaN or Inf"),
    (np.zeros((2, 6)), "zero length"),
])
def test_eval_rejects_bad_pairs(capsys, tmp_path, array, message):
    pairs = tmp_path / "p.npy"
    np.save(pairs, array)
    out = tmp_path / "o.npy"
    code, _, err = run(capsys, "eval", str(FIG2), "--pairs", str(pairs), "--out", str(out))
    assert code == 2 and message in err and str(pairs) in err
    assert not out.exists()


def test_eval_rejects_a_file_that_is_not_npy(capsys, tmp_path):
    pairs = tmp_path / "p.npy"
    pairs.write_text("not numpy")
    code, _, err = run(capsys, "eval", str(FIG2), "--pairs", str(pairs), "--out", str(tmp_path / "o.npy"))
    assert code == 2 and str(pairs) in err


def test_console_script_runs_without_traceback(tmp_path):
    missing = tmp_path / "nothing.xml"
    proc = subprocess.run([sys.executable, "-m", "brdflab", "info", str(missing)], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"brdflab info: {missing}: no such file"


def test_gui_without_a_display_says_what_to_do():
    import os

    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    proc = subprocess.run([sys.executable, "-m", "brdflab"], capture_output=True, text=True, env=env, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "xvfb-run" in proc.stderr and "Traceback" not in proc.stderr


def test_output_piped_into_a_reader_that_leaves_ends_quietly(tmp_path):
    """`brdflab models | head -1`: the reader leaves before the command writes; the command
    must end without a traceback (exit 141, as a writer killed by SIGPIPE). The read end is
    closed before the child has started Python, so its first write meets a closed pipe."""
    proc = subprocess.Popen([sys.executable, "-m", "brdflab", "models"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, cwd=tmp_path)
    proc.stdout.close()
    stderr = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 141 and "Traceback" not in stderr and "BrokenPipe" not in stderr, stderr
