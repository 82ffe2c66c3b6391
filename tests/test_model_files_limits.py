"""Model files where they are undefined, and what the probe decides (issue 37 §2): a file's
value where it is NaN is its limit or said to be undefined, valid GLSL directives and licence
comments are read, folders with two files of one model name stay usable, and the probe's
verdict does not depend on the machine's load. The real CLI in a subprocess, as a user meets it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).resolve().parent / "data" / "brdf_explorer"  # BRDF Explorer's own files (its licence there)
SHARED = ROOT.parent / "shared" / "data" / "models"

BRDF = ("analytic\n::begin parameters\nfloat k 0 1 0.5\n::end parameters\n::begin shader\n{head}"
        "vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)\n{{\n    {body}\n}}\n::end shader\n")
# Schlick's Fresnel alone, 1 at its default (f0 = 1), times a unit vector's squared length
# whose vector is normalize(L − V): undefined (0/0) at wi = wo alone, 1 everywhere else
SCHLICK_DIFFERENCE = ("analytic\n::begin parameters\nfloat f0 0 1 1\n::end parameters\n::begin shader\n"
                      "vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)\n{\n"
                      "    vec3 H = normalize(L + V);\n    vec3 D = normalize(L - V);\n"
                      "    float F = f0 + (1.0 - f0) * pow(1.0 - dot(L, H), 5.0);\n"
                      "    return vec3(F * dot(D, D));\n}\n::end shader\n")


def brdflab(*args, cwd=None, env=None):
    return subprocess.run([sys.executable, "-m", "brdflab", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, env={**os.environ, **(env or {})}, timeout=600)


def same_directions(n: int = 64) -> np.ndarray:
    """n pairs with wi = wo, spread over the hemisphere (the normal among them)."""
    rng = np.random.default_rng(3)
    w = rng.normal(size=(n, 3))
    w[:, 2] = np.abs(w[:, 2]) + 0.05
    w[0] = [0.0, 0.0, 1.0]
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    return np.hstack([w, w])


def evaluate(model: Path, pairs: np.ndarray, tmp_path: Path, *more) -> tuple[np.ndarray, subprocess.CompletedProcess]:
    np.save(tmp_path / "pairs.npy", pairs)
    done = brdflab("eval", model, "--pairs", tmp_path / "pairs.npy", "--out", tmp_path / "out.npy", *more)
    assert done.returncode == 0, done.stderr
    return np.load(tmp_path / "out.npy"), done


@pytest.mark.parametrize("name", ["schlick.brdf", "schlick_difference.brdf"])
def test_a_removable_nan_is_its_limit_at_wi_equal_wo(name, tmp_path):
    """BRDF Explorer's schlick.brdf is a constant 1 at its defaults (f0 = 1), but at wi = wo
    rounding puts L·H above 1 and pow of a negative is NaN: it was 0 there. The hand-written
    file divides 0 by 0 at wi = wo. Both are 1 there now (the mean of their values a hundredth
    of a radian around), silently: neither is undefined anywhere else."""
    path = DATA / name
    if name == "schlick_difference.brdf":
        path = tmp_path / name
        path.write_text(SCHLICK_DIFFERENCE)
    values, done = evaluate(path, same_directions(), tmp_path)
    np.testing.assert_allclose(values, 1.0, atol=1e-3)
    assert done.stderr == ""


def test_schlick_in_the_reference_view_has_no_black_speckles(tmp_path):
    """The default light is +Z, so every pixel of the reference view has wi = wo: 27-31 % of
    the sphere's pixels were black, now none is, and each is f · cos θ = n·L (f = 1)."""
    from brdflab.lighting.envmap import read_exr

    out = tmp_path / "schlick.exr"
    done = brdflab("render", DATA / "schlick.brdf", "--view", "reference", "--size", "48,48", "--out", out)
    assert done.returncode == 0, done.stderr
    image = read_exr(out)[..., 0]
    y, x = np.mgrid[0:48, 0:48]
    px, py = (x + 0.5) / 48 * 2 - 1, 1 - (y + 0.5) / 48 * 2
    inside = px * px + py * py < 0.95
    expected = np.sqrt(1.0 - px[inside] ** 2 - py[inside] ** 2)  # n·L with L = +Z
    assert (image[inside] > 0).all()
    np.testing.assert_allclose(image[inside], expected, atol=2e-3)


def test_a_descriptor_s_formula_takes_the_same_limit_as_its_glsl(tmp_path):
    """A descriptor's <Equation> (what fits and plots evaluate) and its <Equation_GLSL> (what
    renders) are both value · d / d with d = |wi − wo|², 0/0 at wi = wo: the formula was 0
    there (NaN zeroed) while the GLSL takes its limit; both are `value` now."""
    d = "((ux-vx)^2 + (uy-vy)^2 + (uz-vz)^2)"
    path = tmp_path / "ratio.xml"
    path.write_text('<!DOCTYPE BRDFModel>\n<AnalyticBRDFModel name="Ratio" type="Isotropic">\n <Parameters>\n'
                    '  <Parameter name="value" defaultVal="0.3" lowBound="0" highBound="1"/>\n </Parameters>\n'
                    f" <Equation>value * {d} / {d}</Equation>\n <Equation_GLSL>\n"
                    " float RatioBRDF(vec3 u, vec3 v, int j) { float d = dot(u - v, u - v); return params[j] * d / d; }\n"
                    " </Equation_GLSL>\n</AnalyticBRDFModel>\n")
    values, done = evaluate(path, same_directions(), tmp_path)
    np.testing.assert_allclose(values, 0.3, rtol=1e-6)
    assert done.stderr == ""


@pytest.mark.parametrize("name, share", [("dAniso.brdf", 0.098), ("edwards06.brdf", 0.107)])
def test_brdf_explorer_files_undefined_in_places_open_with_one_warning(name, share, tmp_path):
    """dAniso (pow of a negative where L and V face apart about the tangent) and edwards06 (a
    negative base at grazing light) were refused for NaN at ~10 % of pairs; BRDF Explorer shows
    them. They open, and one warning says at what share of pairs and where they are undefined
    (their values there are 0); the values elsewhere are finite and non-negative."""
    rng = np.random.default_rng(5)
    w = rng.normal(size=(2, 500, 3))
    w[..., 2] = np.abs(w[..., 2]) + 0.02
    w /= np.linalg.norm(w, axis=-1, keepdims=True)
    values, done = evaluate(DATA / name, np.hstack([w[0], w[1]]), tmp_path)
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "warning" in lines[0] and name in lines[0] and "undefined" in lines[0], done.stderr
    assert f"{share:.1%}" in lines[0] and "θi" in lines[0] and "θo" in lines[0]
    assert np.isfinite(values).all() and (values >= 0).all() and (values > 0).mean() > 0.5
    info = brdflab("info", DATA / name, "--json")
    assert info.returncode == 0 and "undefined" in " ".join(json.loads(info.stdout.splitlines()[-1])["warnings"])


def test_a_model_undefined_at_most_pairs_is_still_refused(tmp_path):
    path = tmp_path / "mostly_nan.brdf"
    path.write_text(BRDF.format(head="", body="return vec3(sqrt(L.x - 0.9));"))  # defined where L.x ≥ 0.9 alone
    np.save(tmp_path / "pairs.npy", same_directions(4))
    done = brdflab("eval", path, "--pairs", tmp_path / "pairs.npy", "--out", tmp_path / "out.npy")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert str(path) in done.stderr and "NaN or infinity at" in done.stderr


@pytest.mark.parametrize("kind", ["brdf", "xml"])
def test_a_define_is_read_as_glsl(kind, tmp_path):
    """`#define MYPI …` was refused ("`MYPI' undeclared": a .brdf's `#` lines were all
    dropped as comments); GLSL directives are kept, other `#` lines stay comments."""
    if kind == "brdf":
        path = tmp_path / "define.brdf"
        path.write_text(BRDF.format(head="# a comment line\n#define MYPI 3.14159265\n  #ifdef MYPI\n"
                                         "float twice(float x) { return 2.0 * x; }\n  #endif\n",
                                    body="return vec3(twice(k) * MYPI);"))
    else:
        path = tmp_path / "define.xml"
        path.write_text('<!DOCTYPE BRDFModel>\n<AnalyticBRDFModel name="Defined" type="Isotropic">\n <Parameters>\n'
                        '  <Parameter name="k" defaultVal="0.5" lowBound="0" highBound="1"/>\n </Parameters>\n'
                        " <Equation_GLSL>\n#define MYPI 3.14159265\n"
                        " float DefinedBRDF(vec3 u, vec3 v, int j) { return 2.0 * params[j] * MYPI; }\n"
                        " </Equation_GLSL>\n</AnalyticBRDFModel>\n")
    values, done = evaluate(path, same_directions(4), tmp_path)
    np.testing.assert_allclose(values, np.pi, rtol=1e-5)


def test_a_descriptor_with_a_long_licence_comment_is_a_model(tmp_path):
    """More than 4 KB before the root element (a licence comment) made a descriptor "not a
    model" (read as a material: "the root element must be <BRDF>"; left out of a folder)."""
    licence = "<!--\n" + "\n".join(f"  Licence line {k}: permission is granted to ..." for k in range(200)) + "\n-->\n"
    assert len(licence) > 8192
    folder = tmp_path / "models"
    folder.mkdir()
    text = (SHARED / "brdflab" / "BlinnPhong.xml").read_text()
    head, rest = text.split("<AnalyticBRDFModel", 1)
    path = folder / "licensed.xml"
    path.write_text(head + licence + "<AnalyticBRDFModel" + rest.replace("BlinnPhong", "Licensed"))
    values, done = evaluate(path, same_directions(4), tmp_path)
    assert values.shape == (4, 3) and (values > 0).all()
    listed = brdflab("models", "--json", "--models", folder)
    assert listed.returncode == 0, listed.stderr
    assert "Licensed" in {m["id"] for m in json.loads(listed.stdout.splitlines()[-1])["models"]}


def test_two_files_of_one_model_name_in_a_folder_are_skipped_and_the_rest_is_usable(tmp_path):
    """A pair of files defining one model made every command that named the folder fail; the
    pair is skipped now, said in one line naming both, and the folder's other models work."""
    lambert = (SHARED / "brdf_explorer" / "lambert.brdf").read_text()
    folder = tmp_path / "models"
    folder.mkdir()
    (folder / "twin.brdf").write_text(lambert)
    other = tmp_path / "more"
    other.mkdir()
    (other / "twin.brdf").write_text(lambert.replace("float reflectance 0.0 1.0 1.0", "float reflectance 0.0 1.0 0.5"))
    (folder / "walter.brdf").write_text((SHARED / "brdf_explorer" / "walter.brdf").read_text())
    listed = brdflab("models", "--json", "--models", folder, "--models", other)
    assert listed.returncode == 0, listed.stderr
    ids = {m["id"] for m in json.loads(listed.stdout.splitlines()[-1])["models"]}
    assert "walter" in ids and "twin" not in ids
    lines = listed.stderr.strip().splitlines()
    said = [l for l in lines if "'twin'" in l]
    assert len(said) == 1 and str(folder / "twin.brdf") in said[0] and str(other / "twin.brdf") in said[0]
    assert "skipped" in said[0]
    values, done = evaluate(folder / "walter.brdf", same_directions(4), tmp_path, "--models", folder, "--models", other)
    assert np.isfinite(values).all()


def test_the_probe_speed_verdict_is_cpu_time_not_the_machine_s_load(monkeypatch):
    """On a loaded machine a probe waits without computing: 2.5 s of wall clock with no CPU
    was "too slow" (refused), and the same file passed on an idle machine. The verdict counts
    the probe's CPU time, so waiting changes nothing."""
    from brdflab.models.files.library import load_model_file
    from brdflab.render import model_probe

    model = load_model_file(SHARED / "brdf_explorer" / "lambert.brdf")
    real = type(model)._gl_values

    def waiting(self, wi, wo, p):
        if len(wi) > 8:
            time.sleep(2.5)  # the machine is busy elsewhere
        return real(self, wi, wo, p)

    monkeypatch.setattr(type(model), "_gl_values", waiting)
    assert "took" not in str(model_probe.problem(model))


def test_a_probe_that_computes_past_its_cpu_budget_is_refused(tmp_path, monkeypatch, capsys):
    """The probe child's limit is CPU time (RLIMIT_CPU), so a file that computes too long is
    refused whatever else the machine runs (here a child that spins, with a 1 s budget)."""
    from brdflab.cli import main
    from brdflab.render import model_eval

    monkeypatch.setattr(model_eval, "CHECK_CPU_SECONDS", 1)
    monkeypatch.setattr(model_eval, "probe_command", lambda model: [sys.executable, "-c", "while True: pass"])
    path = tmp_path / "spins.brdf"
    path.write_text(BRDF.format(head="", body="return vec3(k * 0.25);"))
    np.save(tmp_path / "pairs.npy", same_directions(2))
    assert main(["eval", str(path), "--pairs", str(tmp_path / "pairs.npy"), "--out", str(tmp_path / "o.npy")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "1 s of CPU time" in err and str(path) in err


def test_a_file_named_gl_something_opens(tmp_path):
    """A model's GLSL names start with its file's stem: `gl_lambert.brdf` gave names with GLSL's
    reserved gl_ prefix ("identifier … uses reserved `gl_' prefix"), refused as a GLSL error."""
    path = tmp_path / "gl_lambert.brdf"
    path.write_text(BRDF.format(head="", body="return vec3(k / 3.14159265);"))
    values, done = evaluate(path, same_directions(4), tmp_path)
    np.testing.assert_allclose(values, 0.5 / np.pi, rtol=1e-5)
