"""Models from files on the command line (issue 28, point 1): folders (--models, BRDFLAB_MODELS),
model files as materials and as lobes, fits whose materials name their model file, and a
model file that went missing."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
from lxml import etree

from brdflab.io.resources import shared_data_dir

SHARED = shared_data_dir()
pytestmark = pytest.mark.skipif(SHARED is None or not (SHARED / "models").is_dir(), reason="needs ../shared/data")
EXPLORER = SHARED / "models" / "brdf_explorer" if SHARED else None
SLICE = SHARED / "merl_slices" / "red-specular-plastic.slice" if SHARED else None


def brdflab(*args, env=None, cwd=None):
    """The command as a user runs it: a new process, so nothing is registered beforehand."""
    full = {**os.environ, **(env or {})}
    return subprocess.run([sys.executable, "-m", "brdflab", *map(str, args)], capture_output=True, text=True,
                          env=full, cwd=cwd, timeout=600)


def test_models_lists_the_files_of_a_folder_given_by_option_or_environment(tmp_path):
    folder = tmp_path / "mine"
    folder.mkdir()
    shutil.copy(EXPLORER / "walter.brdf", folder)
    shutil.copy(SHARED / "models" / "brdflab" / "Ward.xml", folder)
    for how in (["--models", folder], []):
        env = {} if how else {"BRDFLAB_MODELS": str(folder)}
        done = brdflab("models", "--json", *how, env=env)
        assert done.returncode == 0, done.stderr
        models = {m["id"]: m for m in json.loads(done.stdout.splitlines()[-1])["models"]}
        assert models["walter"]["file"] == str((folder / "walter.brdf").resolve())
        assert models["Ward [Ward.xml]"]["xml_name"] == "Ward" and models["Ward"].get("file") is None
        assert "its own importance sampling is not used" in done.stderr  # Ward.xml's sampler


def test_a_model_file_stands_where_a_material_does(tmp_path):
    pairs = tmp_path / "pairs.npy"
    rng = np.random.default_rng(2)
    w = rng.normal(size=(2, 50, 3))
    w[..., 2] = np.abs(w[..., 2])
    w /= np.linalg.norm(w, axis=-1, keepdims=True)
    np.save(pairs, np.concatenate([w[0], w[1]], axis=1))
    done = brdflab("eval", EXPLORER / "orennayar.brdf", "--pairs", pairs, "--out", tmp_path / "v.npy", "--json")
    assert done.returncode == 0, done.stderr
    values = np.load(tmp_path / "v.npy")
    assert values.shape == (50, 3) and (values > 0).all() and np.allclose(values[:, 0], values[:, 2])
    for mode in ("point", "auto"):
        done = brdflab("render", EXPLORER / "disney.brdf", "--mode", mode, "--view", "reference", "--size", "32,32",
                       "--out", tmp_path / f"d-{mode}.exr", "--json")
        assert done.returncode == 0, done.stderr


def test_a_fit_with_a_file_lobe_saves_its_file_and_reopens_elsewhere(tmp_path):
    work = tmp_path / "work"
    (work / "models").mkdir(parents=True)
    shutil.copy(EXPLORER / "walter.brdf", work / "models" / "walter.brdf")
    done = brdflab("fit", SLICE, "--lobes", "Lambertian,models/walter.brdf", "--samples", "subset", "--size", "3000",
                   "--out", "fit.xml", "--json", cwd=work)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.splitlines()[-1])
    ref = etree.parse(str(work / "fit.xml")).find(".//Fitting//ModelFile")
    assert ref.get("path") == "models/walter.brdf" and len(ref.get("sha256")) == 64
    # the folder moves: the material finds its model file beside it, and evaluates the same
    moved = tmp_path / "moved"
    shutil.move(work, moved)
    done = brdflab("info", moved / "fit.xml", "--json")
    assert done.returncode == 0, done.stderr
    lobes = json.loads(done.stdout.splitlines()[-1])["fittings"][0]["material"]["lobes"]
    assert [l["model"] for l in lobes] == ["Lambertian", "walter"]
    assert result["error"] > 0
    # a model file edited since the fit was saved: used, and every command says so
    edited = moved / "models" / "walter.brdf"
    edited.write_text(edited.read_text().replace("float Ks 0 1 .1", "float Ks 0 1 .2"))
    done = brdflab("render", moved / "fit.xml", "--fitting", 0, "--size", "16,16", "--out", tmp_path / "e.png")
    assert done.returncode == 0 and "is not the one the material was saved with" in done.stderr
    # without the model file: one line naming it, exit status 2
    (moved / "models" / "walter.brdf").unlink()
    done = brdflab("info", moved / "fit.xml")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert "'walter' from models/walter.brdf is not available" in done.stderr and "Traceback" not in done.stderr


def test_a_fit_saved_in_another_folder_uses_its_edited_model_file_and_says_so(tmp_path):
    """The documented workflow: `fit SLICE --lobes Lambertian,models/minnaert.brdf --out
    saved/fit.xml`, then an edit of the model file. The fit names ../models/minnaert.brdf (outside
    its folder) with the sha256 it was saved with; every command said "its model file is
    missing". Now each uses the edited file and says it changed since the save."""
    (tmp_path / "models").mkdir()
    (tmp_path / "saved").mkdir()
    model = tmp_path / "models" / "minnaert.brdf"
    model.write_text("analytic\n::begin parameters\nfloat k 0 2 0.7\ncolor albedo 0.8 0.8 0.8\n::end parameters\n"
                     "::begin shader\nvec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y) {\n"
                     "    return albedo / 3.14159265 * pow(max(dot(N, L) * dot(N, V), 1e-6), k - 1.0);\n}\n"
                     "::end shader\n")
    done = brdflab("fit", SLICE, "--lobes", "Lambertian,models/minnaert.brdf", "--samples", "subset", "--size", "500",
                   "--max-iterations", "5", "--out", "saved/fit.xml", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert etree.parse(str(tmp_path / "saved" / "fit.xml")).find(".//ModelFile").get("path") == "../models/minnaert.brdf"
    model.write_text(model.read_text().replace("float k 0 2 0.7", "float k 0 2 0.9"))
    info = brdflab("info", "saved/fit.xml", "--json", cwd=tmp_path)
    assert info.returncode == 0, info.stderr
    assert "is not the one the material was saved with" in info.stderr and "missing" not in info.stderr
    lobes = json.loads(info.stdout.splitlines()[-1])["fittings"][0]["material"]["lobes"]
    assert [l["model"] for l in lobes] == ["Lambertian", "minnaert"]
    render = brdflab("render", "saved/fit.xml", "--fitting", 0, "--size", "8,8", "--out", "r.png", cwd=tmp_path)
    assert render.returncode == 0 and "is not the one the material was saved with" in render.stderr, render.stderr


def test_auto_and_batch_climb_and_fit_with_file_models(tmp_path):
    done = brdflab("fit", SLICE, "--auto", "--models", f"CookTorranceGGX,{EXPLORER / 'walter.brdf'}", "--size", "2000",
                   "--max-iterations", "30", "--json")
    assert done.returncode == 0, done.stderr
    ladder = json.loads(done.stdout.splitlines()[-1])
    tried = {lobe for rung in ladder["candidates"] for lobe in rung["lobes"]}
    assert "walter" in tried
    data = tmp_path / "data"
    data.mkdir()
    shutil.copy(SLICE, data)
    done = brdflab("batch", data, "--lobes", f"Lambertian,{EXPLORER / 'walter.brdf'}", "--workers", "1",
                   "--max-iterations", "20", "--out", tmp_path / "out", "--json")
    assert done.returncode == 0, done.stderr
    table = (tmp_path / "out" / "results.csv").read_text()
    assert "walter" in table and "failed" not in table


@pytest.mark.parametrize("slice_name", ["red-specular-plastic", "nickel"])
def test_disney_from_its_file_fits_a_plastic_and_a_metal_and_the_saved_fit_scores_the_same_elsewhere(slice_name, tmp_path):
    """disney.brdf fitted through the CLI (5,000 samples, scored on all), saved, and the saved
    fit evaluated again by `brdflab eval` in another process at every sample of the slice: the
    Ngan error computed here from those values (plain NumPy, no Gram matrices, no fitter)
    is the one the fit reported; the fit renders."""
    from brdflab.fitting.samples import samples_of
    from brdflab.fitting.metrics import NGAN_MAX_COS
    from brdflab.sources.files import load_source

    source_path = SHARED / "merl_slices" / f"{slice_name}.slice"
    out = tmp_path / "fit.xml"
    done = brdflab("fit", source_path, "--lobes", EXPLORER / "disney.brdf", "--samples", "subset", "--size", "5000",
                   "--out", out, "--json")
    assert done.returncode == 0, done.stderr
    reported = json.loads(done.stdout.splitlines()[-1])["error"]
    chunks = list(samples_of(load_source(source_path)).chunks())
    wi, wo, y, measure = (np.concatenate(c) for c in zip(*chunks))
    inside = (wi[:, 2] >= NGAN_MAX_COS) & (wo[:, 2] >= NGAN_MAX_COS)
    wi, wo, y, measure = wi[inside], wo[inside], y[inside], measure[inside]
    pairs = tmp_path / "pairs.npy"
    np.save(pairs, np.concatenate([wi, wo], axis=1))
    done = brdflab("eval", out, "--fitting", 0, "--pairs", pairs, "--out", tmp_path / "f.npy")
    assert done.returncode == 0, done.stderr
    f = np.load(tmp_path / "f.npy")
    error = np.sqrt((measure[:, None] * (wi[:, 2:3] * (f - y)) ** 2).sum() / (measure.sum() * y.shape[1]))
    assert error == pytest.approx(reported, rel=1e-3)  # float32 GLSL against the fitter's own pass
    done = brdflab("render", out, "--fitting", 0, "--mode", "fis", "--size", "32,32", "--samples", "16",
                   "--out", tmp_path / "r.exr")
    assert done.returncode == 0, done.stderr
