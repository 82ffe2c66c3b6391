"""Models from files (issue 28): BRDFLab's model descriptors and BRDF Explorer's .brdf files,
read from the shared corpora exactly as those tools shipped them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from brdflab.models import get_model
from brdflab.models.files.library import load_model_file, probe_pairs
from brdflab.io.resources import shared_data_dir

SHARED = shared_data_dir()
pytestmark = pytest.mark.skipif(SHARED is None or not (SHARED / "models").is_dir(),
                                reason="needs ../shared/data/models")
EXPLORER = sorted((SHARED / "models" / "brdf_explorer").glob("*.brdf")) if SHARED else []
DESCRIPTORS = sorted(p for p in (SHARED / "models" / "brdflab").glob("*.xml")) if SHARED else []


def _pairs(n=4000, seed=11):
    return probe_pairs(n, seed)


@pytest.mark.parametrize("path", EXPLORER + DESCRIPTORS, ids=lambda p: p.name)
def test_every_corpus_file_opens_and_its_cpu_value_is_its_gpu_value(path):
    """Every file opens; the CPU evaluation equals the GLSL's within 1e-4 (relative, where
    the value is above 1e-6): for a descriptor its <Equation> against its <Equation_GLSL>,
    for a .brdf the values fits use against the material shader's (transform feedback)."""
    model = load_model_file(path)
    wi, wo = _pairs()
    params = model.defaults()
    cpu = model.evaluate_rgb(wi, wo, params) if model.colour else model.evaluate(wi, wo, params)[:, None]
    gpu = _material_shader_values(model, wi, wo, params)
    if not model.colour:
        gpu = gpu[:, :1]
    big = np.abs(gpu) > 1e-6
    assert big.mean() > 0.05 or path.stem.startswith(("f_", "g_", "show")), "probe pairs miss the lobe"
    rel = np.abs(cpu[big] - gpu[big]) / np.abs(gpu[big])
    assert rel.max(initial=0.0) <= 1e-4, f"{path.name}: CPU and GPU differ by {rel.max():.2e}"


def _material_shader_values(model, wi, wo, params):
    """The lobe's value through the renderers' own GLSL (render.glsl.material_source) in a
    transform-feedback program: the path the object view and lobe viewer take."""
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.render.context import create_context
    from brdflab.render.glsl import GLSL_VERSION, lobe_uniforms, material_source, set_uniforms

    material = AnalyticMaterial("m", "Linear", 3, [Lobe(model, dict(params), [1.0, 1.0, 1.0])])
    ctx = create_context()
    src = (GLSL_VERSION + "in vec3 in_wi; in vec3 in_wo; out vec3 out_f;\n" + material_source((model.name,))
           + "void main() { out_f = material_eval(in_wi, in_wo); }\n")
    prog = ctx.program(vertex_shader=src, varyings=["out_f"])
    set_uniforms(prog, lobe_uniforms(material))
    content = [(ctx.buffer(np.ascontiguousarray(a, np.float32).tobytes()), "3f", name)
               for a, name in ((wi, "in_wi"), (wo, "in_wo")) if name in prog]
    out = ctx.buffer(reserve=len(wi) * 12)
    ctx.vertex_array(prog, content).transform(out, vertices=len(wi))
    return np.frombuffer(out.read(), np.float32).reshape(-1, 3).astype(float)


# --- file models against the built-in twins -----------------------------------------------------

def _builtin(name, wi, wo, **params):
    return get_model(name).evaluate(wi, wo, params)


def _explorer(stem, wi, wo, **params):
    model = load_model_file(SHARED / "models" / "brdf_explorer" / f"{stem}.brdf")
    p = model.defaults()
    p.update(params)
    return model.evaluate_rgb(wi, wo, p)


def _close(a, b, tol=1e-4):
    big = np.abs(b) > 1e-6
    return np.abs(a[big] - b[big]).max(initial=0.0) <= tol * np.abs(b[big]).max(initial=1.0) and \
        np.all(np.abs(a[big] - b[big]) <= tol * np.abs(b[big]) + 1e-6 * np.abs(b[big]).max())


def test_brdf_explorer_files_equal_their_built_in_twins_after_the_documented_mapping():
    wi, wo = _pairs()
    cases = {
        # lambert(reflectance ρ) = ρ/π = Lambertian × ρ/π
        "lambert": (_explorer("lambert", wi, wo, reflectance=0.7)[:, 0], 0.7 / math.pi * _builtin("Lambertian", wi, wo)),
        # blinnphong(n, divide_by_NdotL = 0) = cos^n θh = BlinnPhong(n) × 2π / (n + 2)
        "blinnphong": (_explorer("blinnphong", wi, wo, n=40.0, divide_by_NdotL=0.0)[:, 0],
                       2 * math.pi / 42.0 * _builtin("BlinnPhong", wi, wo, Exponent=40.0)),
        # phong(n, divide_by_NdotL = 0) = cos^n(r·wo) = Phong(n) × 2π / (n + 2)
        "phong": (_explorer("phong", wi, wo, n=30.0, divide_by_NdotL=0.0)[:, 0],
                  2 * math.pi / 32.0 * _builtin("Phong", wi, wo, Exponent=30.0)),
        # ward(αx, αy, Cs = 1, Cd = 0) = Ward(ax, ay) (Walter's "Notes on the Ward BRDF")
        "ward": (_explorer("ward", wi, wo, alpha_x=0.2, alpha_y=0.35, Cd_r=0.0, Cd_g=0.0, Cd_b=0.0)[:, 0],
                 _builtin("Ward", wi, wo, ax=0.2, ay=0.35)),
        # ashikhman_shirley(Rs, Rd = 0, nu, nv, isotropic = 0) = AshikhminShirley(nu, nv, F0 = Rs)
        "ashikhman_shirley": (_explorer("ashikhman_shirley", wi, wo, Rs=0.3, Rd=0.0, nu=40.0, nv=200.0,
                                        isotropic=0.0)[:, 0],
                              _builtin("AshikhminShirley", wi, wo, nu=40.0, nv=200.0, F0=0.3)),
        # walter(Kd = 0, Ks = 1, αG, useFresnel = 0) = CookTorranceGGX(m = αG, F0 = 1)
        "walter": (_explorer("walter", wi, wo, Kd=0.0, Ks=1.0, alphaG=0.3, useFresnel=0.0)[:, 0],
                   _builtin("CookTorranceGGX", wi, wo, m=0.3, F0=1.0)),
    }
    for name, (file_value, builtin) in cases.items():
        assert _close(file_value, builtin), name


def test_brdf_explorer_cook_torrance_differs_from_the_published_formula_as_its_source_does():
    """cooktorrance.brdf's Beckmann D has no 1/π and its value no 1/4: it is 4π × the
    published Cook–Torrance; and its include_G switch is inverted (`if (include_G) G =
    1/NdotV` drops G), so include_G = 0 is the one that has the geometric term."""
    wi, wo = _pairs()
    with_g = _explorer("cooktorrance", wi, wo, m=0.2, f0=0.4, include_F=1.0, include_G=0.0)[:, 0]
    builtin = _builtin("CookTorrance", wi, wo, m=0.2, F0=0.4)
    assert _close(with_g, 4 * math.pi * builtin)
    without_g = _explorer("cooktorrance", wi, wo, m=0.2, f0=0.4, include_F=1.0, include_G=1.0)[:, 0]
    assert not _close(without_g, 4 * math.pi * builtin)


def test_brdf_explorer_oren_nayar_is_the_full_model_the_built_in_simplifies():
    """orennayar.brdf is Oren & Nayar's full model (C1, C2 with its β term, C3 and the
    interreflection L2); the built-in is their qualitative model. They agree where both are
    Lambertian (σ = 0), and the file equals the full model computed here."""
    wi, wo = _pairs()
    flat = _explorer("orennayar", wi, wo, rho=0.8, sigma=0.0)[:, 0]
    assert _close(flat, 0.8 / math.pi * _builtin("OrenNayar", wi, wo, sigma=0.0))
    sigma = math.radians(30.0)
    s2 = sigma**2
    ti, to = np.arccos(wi[:, 2]), np.arccos(wo[:, 2])
    alpha, beta = np.maximum(ti, to), np.minimum(ti, to)
    pi_ = wi[:, :2] / np.linalg.norm(wi[:, :2], axis=1, keepdims=True)
    po = wo[:, :2] / np.linalg.norm(wo[:, :2], axis=1, keepdims=True)
    cphi = (pi_ * po).sum(1)
    c1 = 1 - 0.5 * s2 / (s2 + 0.33)
    c2 = 0.45 * s2 / (s2 + 0.09) * np.where(cphi >= 0, np.sin(alpha), np.sin(alpha) - (2 * beta / math.pi) ** 3)
    c3 = 0.125 * s2 / (s2 + 0.09) * (4 * alpha * beta / math.pi**2) ** 2
    l1 = 0.8 / math.pi * (c1 + cphi * c2 * np.tan(beta) + (1 - np.abs(cphi)) * c3 * np.tan((alpha + beta) / 2))
    l2 = 0.17 * 0.64 / math.pi * s2 / (s2 + 0.13) * (1 - cphi * (2 * beta / math.pi) ** 2)
    assert _close(_explorer("orennayar", wi, wo, rho=0.8, sigma=30.0)[:, 0], l1 + l2)


def _descriptor(name, wi, wo, **params):
    model = load_model_file(SHARED / "models" / "brdflab" / f"{name}.xml")
    p = model.defaults()
    p.update(params)
    return model.evaluate(wi, wo, p)


def test_brdflab_descriptors_equal_their_built_in_twins():
    wi, wo = _pairs()
    assert _close(_descriptor("BlinnPhong", wi, wo, Exponent=25.0), _builtin("BlinnPhong", wi, wo, Exponent=25.0))
    assert _close(_descriptor("LafortuneIso", wi, wo, Cxy=-0.9, Cz=0.8, Exponent=12.0),
                  _builtin("LafortuneIso", wi, wo, Cxy=-0.9, Cz=0.8, Exponent=12.0))
    assert _close(_descriptor("Lambertian", wi, wo, value=0.4), 0.4 * _builtin("Lambertian", wi, wo))


def test_brdflab_descriptors_that_differ_from_the_published_formulas_say_how():
    """BRDFLab's CookTorrance.xml drops the 1/4 of the published denominator (its value is
    4 × the built-in); its Ward.xml divides inside the exponential by 4π ax² instead of
    outside (the file's formula, computed here, is what it evaluates to)."""
    wi, wo = _pairs()
    assert _close(_descriptor("CookTorrance", wi, wo, m=0.25, F0=0.3), 4 * _builtin("CookTorrance", wi, wo, m=0.25, F0=0.3))
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    tan2 = (1 - h[:, 2] ** 2) / h[:, 2] ** 2
    ax = 0.3
    as_written = np.exp(-tan2 / ax**2 / (4 * math.pi * ax**2)) / np.sqrt(wi[:, 2] * wo[:, 2])
    ward = _descriptor("Ward", wi, wo, ax=ax)
    assert _close(ward, as_written)
    assert not _close(ward, _builtin("Ward", wi, wo, ax=ax, ay=ax))


def test_a_built_in_exported_to_brdf_explorer_opens_as_the_same_model(tmp_path):
    """`brdflab export --format brdf-explorer`, opened again as a model: the same values (1e-5)."""
    from brdflab.cli import main
    from brdflab.io.resources import resolve_material
    from brdflab.sources.files import load_source

    out = tmp_path / "fig2.brdf"
    assert main(["export", "example:fig2", "--format", "brdf-explorer", "--out", str(out)]) == 0
    material = load_source(resolve_material("example:fig2"))
    model = load_model_file(out)
    wi, wo = _pairs()
    assert np.allclose(model.evaluate_rgb(wi, wo), material.evaluate(wi, wo)[:, :3], rtol=1e-5, atol=1e-7)


def test_a_file_model_is_a_registry_peer_named_apart_from_a_built_in_of_the_same_name():
    ward = load_model_file(SHARED / "models" / "brdflab" / "Ward.xml")
    assert ward.name == "Ward [Ward.xml]" and ward.xml_name == "Ward"
    assert get_model("Ward").origin is None and get_model("Ward [Ward.xml]") is ward
    disney = load_model_file(SHARED / "models" / "brdf_explorer" / "disney.brdf")
    assert get_model("disney") is disney and disney.colour
    assert [p.name for p in disney.parameters][:3] == ["baseColor_r", "baseColor_g", "baseColor_b"]


def test_two_files_defining_one_model_name_are_refused_naming_both(tmp_path):
    from brdflab.errors import BRDFLabError

    text = (SHARED / "models" / "brdf_explorer" / "lambert.brdf").read_text()
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    (a / "twin.brdf").write_text(text)
    (b / "twin.brdf").write_text(text.replace("float reflectance 0.0 1.0 1.0", "float reflectance 0.0 1.0 0.5"))
    load_model_file(a / "twin.brdf")
    with pytest.raises(BRDFLabError) as e:
        load_model_file(b / "twin.brdf")
    assert str(a / "twin.brdf") in str(e.value) and str(b / "twin.brdf") in str(e.value)


def test_the_generic_sampler_is_exact_for_its_own_density():
    """χ² of the tabulated sampler against its own pdf, on the Disney lobe at grazing view."""
    from scipy.stats import chi2

    model = load_model_file(SHARED / "models" / "brdf_explorer" / "disney.brdf")
    params = model.defaults()
    params["roughness"] = 0.2
    wo = np.array([math.sin(1.2), 0.0, math.cos(1.2)])
    u = np.random.default_rng(4).random((100_000, 2))
    wi = model.sample(wo, u, params)
    nt, nphi = 16, 32  # bins aligned with the sampler's cells (64 × 128)
    t = np.arccos(np.clip(wi[:, 2], 0, 1))
    ph = np.mod(np.arctan2(wi[:, 1], wi[:, 0]), 2 * math.pi)
    counts = np.histogram2d(t, ph, [np.linspace(0, math.pi / 2, nt + 1), np.linspace(0, 2 * math.pi, nphi + 1)])[0]
    # expected counts: the pdf integrated over each cell (8 × 8 midpoint rule)
    tt = (np.arange(nt * 8) + 0.5) / (nt * 8) * math.pi / 2
    pp = (np.arange(nphi * 8) + 0.5) / (nphi * 8) * 2 * math.pi
    T, P = np.meshgrid(tt, pp, indexing="ij")
    d = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    dens = model.pdf(d, np.broadcast_to(wo, d.shape), params).reshape(T.shape) * np.sin(T)
    expected = dens.reshape(nt, 8, nphi, 8).sum((1, 3)) * (math.pi / 2 / (nt * 8)) * (2 * math.pi / (nphi * 8)) * len(u)
    keep = expected > 5
    stat = ((counts[keep] - expected[keep]) ** 2 / expected[keep]).sum()
    assert expected[keep].sum() > 0.97 * len(u)
    assert chi2.sf(stat, keep.sum() - 1) > 1e-4, stat


def test_a_sampler_whose_tables_are_built_as_views_come_draws_as_one_built_at_once():
    """The tabulated sampler searches one array of all its tables' CDFs: built view by view as
    draws need them (from two threads, as Auto's twins draw), it must draw exactly the directions
    of a sampler whose tables were all built first."""
    from concurrent.futures import ThreadPoolExecutor

    from brdflab.material.analytic import Lobe
    from brdflab.models.files.sampler import TabulatedSampler

    lobe = Lobe.create("CookTorranceGGX", [1.0], m=0.2, F0=0.9)
    full = TabulatedSampler(lobe.model, lobe.params)
    full.ensure_all()
    lazy = TabulatedSampler(lobe.model, lobe.params)
    rng = np.random.default_rng(5)
    views = [np.array([math.sin(t), 0.0, math.cos(t)]) for t in np.radians([5.0, 40.0, 63.0, 80.0, 20.0, 86.0])]
    points = [rng.random((4000, 2)) for _ in views]
    with ThreadPoolExecutor(2) as pool:
        drawn = list(pool.map(lambda k: lazy.sample(views[k], points[k]), range(len(views))))
    for wo, u, wi in zip(views, points, drawn):
        np.testing.assert_array_equal(wi, full.sample(wo, u))
    assert not lazy._built.all()  # the lazy sampler built only the tables around those views


def test_the_readme_s_ten_line_model_works_as_written(tmp_path):
    """The README's example `.brdf` (Minnaert's lobe) loads, renders its formula, and fits."""
    from brdflab.io.resources import checkout_root

    readme = (checkout_root() / "README.md").read_text()
    block = readme.split("```glsl\n", 1)[1].split("```", 1)[0]
    assert len(block.strip().splitlines()) == 10
    path = tmp_path / "minnaert.brdf"
    path.write_text(block)
    model = load_model_file(path)
    wi, wo = _pairs()
    expected = 0.8 / math.pi * np.maximum(wi[:, 2] * wo[:, 2], 1e-6) ** (0.7 - 1.0)
    assert np.allclose(model.evaluate_rgb(wi, wo), expected[:, None], rtol=1e-4)


@pytest.fixture(scope="module")
def renderers():
    from brdflab.lighting.envmap import load_environment
    from brdflab.render.context import create_context
    from brdflab.render.lobe_view import LobeViewer
    from brdflab.render.object_view import ObjectRenderer
    from brdflab.io.resources import data_dir

    ctx = create_context()
    renderer = ObjectRenderer(ctx)
    venice = load_environment(data_dir("resources") / "envmaps" / "venice_sunset_1k.hdr").downsampled(128, 64)
    renderer.set_environment(venice)
    return renderer, LobeViewer(ctx), venice


@pytest.mark.parametrize("path", EXPLORER + DESCRIPTORS, ids=lambda p: p.name)
def test_every_corpus_model_draws_in_the_lobe_viewer_and_renders_in_every_mode(path, renderers):
    """The lobe viewer draws it (pixels of the lobe's colour), and the object view renders it
    in point, FIS, MIS, prefiltered and SH lighting with finite values."""
    from brdflab.lighting.sh_tables import parse_setting
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.render.object_view import RenderSettings

    renderer, viewer, venice = renderers
    renderer.set_environment(venice)
    model = load_model_file(path)
    params = model.defaults()
    if path.stem == "showVectors":
        params["show_N"] = 1.0  # at its defaults this debugging model is zero everywhere
    material = AnalyticMaterial(path.stem, "Linear", 3, [Lobe(model, params, [1.0, 1.0, 1.0])])
    viewer.set_fitted(None)
    viewer.set_original(AnalyticMaterial("zero", "Linear", 3, [Lobe.create("Lambertian", [0.0, 0.0, 0.0])]))
    empty = viewer.render(96, 96)
    viewer.set_original(material)
    lobe = viewer.render(96, 96)
    assert (np.abs(lobe.astype(int) - empty.astype(int)).max(axis=2) > 30).sum() > 50, "no lobe drawn"
    renderer.set_source(material)
    renderer.set_sh_table(parse_setting("16x6"))
    for mode in ("point", "fis", "mis", "prefiltered", "sh"):
        image = renderer.render(RenderSettings(mode=mode, width=16, height=16, samples=4, reference_view=True,
                                               light=(0.3, 0.2, 0.9)))
        assert np.isfinite(image).all(), mode
        assert image.max() > 0, mode
    # a white furnace: prefiltered lighting is the albedo factor alone, against quadrature
    from brdflab.lighting.envmap import EnvironmentMap
    from brdflab.lighting.reference_view import environment_image, relative_rmse, sphere_view

    furnace = EnvironmentMap(np.ones((32, 64, 3), np.float32))
    renderer.set_environment(furnace)
    image = renderer.render(RenderSettings(mode="prefiltered", width=12, height=12, reference_view=True))
    inside = sphere_view(12, 12).inside & (sphere_view(12, 12).normal[..., 2] > math.cos(math.radians(70)))
    assert relative_rmse(image, environment_image(material, furnace, 12, 12), inside) < 0.02


@pytest.mark.parametrize("name", ["disney.brdf", "walter.brdf"])
def test_the_renderers_sample_a_file_lobe_from_the_same_tables_as_numpy(name, renderers):
    """shaders/tabulated.glsl draws the directions and gives the densities of the NumPy
    sampler (same tables): the densities agree to float precision, the directions drawn from
    the same uniforms fall in the same cells, and a FIS render converges to quadrature."""
    from brdflab.lighting.envmap import load_environment
    from brdflab.lighting.reference_view import environment_image, relative_rmse, sphere_view
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.io.resources import data_dir
    from brdflab.render.glsl import GLSL_VERSION, lobe_uniforms, material_source, set_uniforms
    from brdflab.render.object_view import RenderSettings
    from brdflab.render.tabulated import TabulatedTextures

    renderer, _, _ = renderers
    renderer.ctx.extra["default_fbo"].use()  # Mesa runs no transform feedback without a bound framebuffer
    model = load_model_file(SHARED / "models" / "brdf_explorer" / name)
    params = model.defaults()
    if name == "disney.brdf":
        params.update(roughness=0.25, anisotropic=0.6, metallic=0.5)
    material = AnalyticMaterial("m", "Linear", 3, [Lobe(model, params, [1.0, 1.0, 1.0])])
    ctx = renderer.ctx
    src = (GLSL_VERSION + "in vec3 in_wi; in vec3 in_wo; out vec4 out_v;\n" + material_source((model.name,))
           + "void main() { out_v = vec4(material_sample(0, in_wo, in_wi.xy), material_pdf(in_wi, in_wo)); }\n")
    prog = ctx.program(vertex_shader=src, varyings=["out_v"])
    set_uniforms(prog, lobe_uniforms(material, np.ones(1)))
    TabulatedTextures(ctx).bind(prog, material)
    wi, wo = _pairs(3000, seed=5)
    u = np.random.default_rng(6).random((3000, 2))
    gpu_in = np.concatenate([wi[:, :2] * 0 + u, wi[:, 2:]], axis=1)  # in_wi.xy carries u for the sampler
    out = ctx.buffer(reserve=3000 * 16)
    both = [(ctx.buffer(np.ascontiguousarray(a, np.float32).tobytes()), "3f", n) for a, n in ((wi, "in_wi"), (wo, "in_wo"))]
    ctx.vertex_array(prog, both).transform(out, vertices=3000)
    v = np.frombuffer(out.read(), np.float32).reshape(-1, 4).astype(float)
    pdf_cpu = model.pdf(wi, wo, params)
    assert np.allclose(v[:, 3], pdf_cpu, rtol=2e-4, atol=1e-6)
    # directions drawn from the same uniforms (the GPU reads u from in_wi.xy: draw again)
    ctx.vertex_array(prog, [(ctx.buffer(np.ascontiguousarray(gpu_in, np.float32).tobytes()), "3f", "in_wi"),
                            both[1]]).transform(out, vertices=3000)
    drawn = np.frombuffer(out.read(), np.float32).reshape(-1, 4)[:, :3].astype(float)
    # the same cell (1.4° × 2.8°); within it float32 CDFs place the point a little differently
    same = np.linalg.norm(drawn - model.sample(wo, u, params), axis=1) < 0.05
    assert same.mean() > 0.99  # the rest: a neighbouring cell or view, at a float32 boundary
    env = load_environment(data_dir("resources") / "envmaps" / "venice_sunset_1k.hdr").downsampled(128, 64)
    renderer.set_environment(env)
    renderer.set_source(material)
    image = renderer.render(RenderSettings("fis", 24, 24, samples=1024, reference_view=True))
    reference = environment_image(material, env, 24, 24)
    assert relative_rmse(image, reference, sphere_view(24, 24).inside) < 0.05
