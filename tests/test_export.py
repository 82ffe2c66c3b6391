"""Export: a material or stored fit written as a MERL table reads back as the same BRDF."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import random_upper

from brdflab.geometry.halfdiff import from_half_diff
from brdflab.io.xmlio import load
from brdflab.sources.measured import read_merl_binary

ROOT = Path(__file__).resolve().parents[1]
MATERIAL = ROOT / "materials" / "fig2_lambertian_lafortune.xml"


def _cli(*args, cwd):
    env = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}
    return subprocess.run([sys.executable, "-m", "brdflab", *args], cwd=cwd, env=env, capture_output=True, text=True)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    folder = tmp_path_factory.mktemp("export")
    result = _cli("export", str(MATERIAL), "--format", "merl", "--out", "out.binary", cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder / "out.binary"


def test_merl_export_reads_back_as_the_source(exported):
    source = load(MATERIAL).material
    table = read_merl_binary(exported)
    rng = np.random.default_rng(3)
    n = 4000
    # random (θh, θd, φd) away from grazing, where MERL's grid is coarse and the lobe steep
    th = rng.uniform(0.05, 0.6, n)
    td = rng.uniform(0.05, 0.9, n)
    pd = rng.uniform(0.1, np.pi - 0.1, n)
    wi, wo = from_half_diff(th, 0.0, td, pd)
    ok = (wi[:, 2] > 0.2) & (wo[:, 2] > 0.2)
    want = source.evaluate(wi[ok], wo[ok])
    got = table.evaluate(wi[ok], wo[ok])
    rel = np.abs(got - want) / np.maximum(want, 1e-3)
    # trilinear interpolation on MERL's grid: a few per cent at most for this smooth lobe
    assert np.median(rel) < 0.002 and np.percentile(rel, 99) < 0.02
    # and not trivially equal: a different material would fail
    assert not np.allclose(got, 2 * want, rtol=0.05)


def test_export_errors_are_one_line(tmp_path):
    result = _cli("export", "missing.xml", "--format", "merl", "--out", "x.binary", cwd=tmp_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "missing.xml" in result.stderr
    result = _cli("export", str(MATERIAL), "--format", "merl", "--fitting", "5", "--out", "x.binary", cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert not (tmp_path / "x.binary").exists()


VERTEX = """
in vec3 in_wi;
in vec3 in_wo;
out vec3 out_f;
void main() { out_f = brdflab_brdf(in_wi, in_wo); }
"""


def run_exported_glsl(source_text: str, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """Compile the exported text alone (no uniforms set) and evaluate it by transform feedback."""
    from brdflab.render.context import create_context

    ctx = create_context()
    prog = ctx.program(vertex_shader="#version 330 core\n" + source_text + VERTEX, varyings=["out_f"])
    assert set(prog) == {"in_wi", "in_wo", "out_f"}, "the exported function must need no uniforms"
    vbo = ctx.buffer(np.hstack([wi, wo]).astype("f4").tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "3f 3f", "in_wi", "in_wo")])
    out = ctx.buffer(reserve=len(wi) * 3 * 4)
    vao.transform(out, vertices=len(wi))
    return np.frombuffer(out.read(), "f4").reshape(-1, 3).astype(float)


@pytest.mark.parametrize("name", ["fig2_lambertian_lafortune.xml", "cook_torrance_ggx.xml", "ashikhmin_shirley.xml", "fig5_fixed_per_channel.xml"])
def test_glsl_export_matches_numpy(tmp_path, name):
    path = ROOT / "materials" / name
    result = _cli("export", str(path), "--format", "glsl", "--out", "brdf.glsl", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    source = load(path).material
    rng = np.random.default_rng(7)
    wi, wo = random_upper(rng, 3000), random_upper(rng, 3000)
    wi, wo = wi.astype("f4").astype(float), wo.astype("f4").astype(float)
    got = run_exported_glsl((tmp_path / "brdf.glsl").read_text(), wi, wo)
    want = source.evaluate(wi, wo)
    if want.shape[1] == 1:
        want = np.repeat(want, 3, axis=1)
    scale = max(want.max(), 1e-30)
    big = want > 1e-3 * scale
    np.testing.assert_allclose(got[big], want[big], rtol=1e-4)
    np.testing.assert_allclose(got[~big], want[~big], atol=1e-4 * scale)


def test_glsl_export_refuses_measured_tables(exported, tmp_path):
    result = _cli("export", str(exported), "--format", "glsl", "--out", "x.glsl", cwd=tmp_path)
    assert result.returncode == 2 and str(exported) in result.stderr and not (tmp_path / "x.glsl").exists()


def parse_brdf_explorer(text: str) -> tuple[dict[str, list[float]], str]:
    """A small reader of BRDF Explorer's format: parameters (type, name, values) and the shader."""
    params, shader, block = {}, [], None
    for line in text.splitlines():
        if line.startswith("::begin "):
            block = line.split()[1]
        elif line.startswith("::end"):
            block = None
        elif block == "parameters" and line.strip() and not line.startswith("#"):
            kind, name, *values = line.split()
            assert kind in ("float", "color", "bool"), line
            numbers = [float(v) for v in values]
            if kind == "float":
                lo, hi, default = numbers
                assert lo <= default <= hi, line
            params[name] = (kind, numbers)
        elif block == "shader":
            shader.append(line)
    return params, "\n".join(shader)


HARNESS = """
in vec3 in_wi;
in vec3 in_wo;
out vec3 out_f;
void main() {
    // a tilted, rotated frame: BRDF() must move L and V into it itself
    vec3 N = normalize(vec3(0.3, -0.2, 1.0));
    vec3 X = normalize(cross(vec3(0.0, 1.0, 0.0), N));
    vec3 Y = cross(N, X);
    vec3 L = in_wi.x * X + in_wi.y * Y + in_wi.z * N;
    vec3 V = in_wo.x * X + in_wo.y * Y + in_wo.z * N;
    out_f = BRDF(L, V, N, X, Y);
}
"""


@pytest.mark.parametrize("name", ["fig2_lambertian_lafortune.xml", "ward.xml"])
def test_brdf_explorer_file_parses_and_runs(tmp_path, name):
    from brdflab.render.context import create_context

    path = ROOT / "materials" / name
    result = _cli("export", str(path), "--format", "brdf-explorer", "--out", "m.brdf", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    text = (tmp_path / "m.brdf").read_text()
    assert text.startswith("analytic")
    params, shader = parse_brdf_explorer(text)
    assert "vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)" in shader
    decls = "".join(f"uniform {'vec3' if kind == 'color' else 'float'} {n};\n" for n, (kind, _) in params.items())
    ctx = create_context()
    prog = ctx.program(vertex_shader="#version 330 core\n" + decls + shader + HARNESS, varyings=["out_f"])
    for n, (kind, values) in params.items():
        if n in prog:
            prog[n].value = tuple(values) if kind == "color" else values[2]
    rng = np.random.default_rng(11)
    wi, wo = random_upper(rng, 2000), random_upper(rng, 2000)
    vbo = ctx.buffer(np.hstack([wi, wo]).astype("f4").tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "3f 3f", "in_wi", "in_wo")])
    out = ctx.buffer(reserve=len(wi) * 12)
    vao.transform(out, vertices=len(wi))
    got = np.frombuffer(out.read(), "f4").reshape(-1, 3).astype(float)
    want = load(path).material.evaluate(wi.astype("f4").astype(float), wo.astype("f4").astype(float))
    want = np.repeat(want, 3, axis=1) if want.shape[1] == 1 else want
    np.testing.assert_allclose(got, want, rtol=2e-3, atol=1e-4 * want.max())
