"""Every registered model through GLSL (transform feedback) and NumPy must agree."""

import zlib

import numpy as np
import pytest

from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.models import all_models
from brdflab.render.glsl import GLSL_VERSION, lobe_uniforms, material_source, set_uniforms
from brdflab.io.resources import shader_path
from conftest import random_upper

VERTEX = """
in vec3 in_wi;
in vec3 in_wo;
out vec3 out_f;
out float out_pdf;
out vec3 out_sample;
uniform vec2 u_xi;
void main() {
    out_f = material_eval(in_wi, in_wo);
    out_pdf = material_pdf(in_wi, in_wo);
    out_sample = material_sample(0, in_wo, fract(in_wi.xy * 0.5 + 0.5));
}
"""


@pytest.fixture(scope="module")
def ctx():
    from brdflab.render.context import create_context

    return create_context()


def random_params(model, rng):
    """Parameters inside the bounds, away from regimes where float32 pow/exp cannot agree."""
    out = {}
    for p in model.parameters:
        lo, hi = p.lower, p.upper
        if p.log:
            hi = min(hi, 200.0 if hi > 10 else 0.8)
            lo = max(lo, 0.05 if hi < 10 else 1.0)
            out[p.name] = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
        else:
            out[p.name] = float(rng.uniform(lo, min(hi, 0.95 if p.name == "smoothness" else hi)))
    return out


def run_glsl(ctx, material, wi, wo):
    prog = ctx.program(vertex_shader=GLSL_VERSION + material_source(tuple(l.model.name for l in material.lobes), n_channels=material.n_channels) + VERTEX,
                       varyings=["out_f", "out_pdf", "out_sample"])
    set_uniforms(prog, lobe_uniforms(material, np.array([1.0])))
    data = np.hstack([wi, wo]).astype("f4")
    vbo = ctx.buffer(data.tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "3f 3f", "in_wi", "in_wo")])
    out = ctx.buffer(reserve=len(wi) * 7 * 4)
    vao.transform(out, vertices=len(wi))
    res = np.frombuffer(out.read(), "f4").reshape(-1, 7).astype(float)
    for obj in (vao, vbo, out, prog):
        obj.release()
    return res[:, 0], res[:, 3], res[:, 4:7]


def test_every_model_has_its_shader():
    for model in all_models():
        text = shader_path(f"{model.name}.glsl").read_text()
        assert f"brdf_{model.name}(" in text
        if model.samplable:
            assert f"sample_{model.name}(" in text and f"pdf_{model.name}(" in text


@pytest.mark.parametrize("model", all_models(), ids=lambda m: m.name)
def test_glsl_matches_numpy(ctx, model):
    rng = np.random.default_rng(zlib.crc32(model.name.encode()))
    wi, wo = random_upper(rng, 4000), random_upper(rng, 4000)
    wi32, wo32 = wi.astype("f4").astype(float), wo.astype("f4").astype(float)
    for trial in range(3):
        params = random_params(model, rng)
        material = AnalyticMaterial("t", "Linear", 1, [Lobe.create(model.name, [1.0], **params)])
        f_glsl, pdf_glsl, sample_glsl = run_glsl(ctx, material, wi32, wo32)
        f_np = model.evaluate(wi32, wo32, params)
        big = f_np > 1e-3 * max(f_np.max(), 1e-30)
        np.testing.assert_allclose(f_glsl[big], f_np[big], rtol=1e-4, err_msg=f"{model.name} {params}")
        np.testing.assert_allclose(f_glsl[~big], f_np[~big], atol=2e-3 * max(f_np.max(), 1e-30))
        if model.samplable:
            pdf_np = model.pdf(wi32, wo32, params)
            ok = pdf_np > 1e-3 * pdf_np.max()
            np.testing.assert_allclose(pdf_glsl[ok], pdf_np[ok], rtol=1e-3, err_msg=f"pdf {model.name} {params}")
            u = np.stack([wi32[:, 0] * 0.5 + 0.5, wi32[:, 1] * 0.5 + 0.5], axis=1)
            u = u - np.floor(u)
            s_np = model.sample(wo32, u, params)
            good = np.all(np.isfinite(s_np), axis=1)
            close = np.linalg.norm(sample_glsl[good] - s_np[good], axis=1) < 1e-3
            assert close.mean() > 0.995, f"{model.name}: {close.mean()}"
