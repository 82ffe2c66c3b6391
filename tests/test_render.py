"""Renders checked against ground truth computed independently in NumPy."""

import json

import numpy as np
import pytest

from brdflab.material.albedo import directional_albedo
from brdflab.cli import main
from brdflab.lighting.envmap import constant, load_environment, read_exr
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.sources.measured import read_slice
from brdflab.io.mesh import from_arrays, uv_sphere
from brdflab.lighting.reference_view import environment_image, point_light_image, relative_rmse, sphere_view
from brdflab.render.object_view import ObjectRenderer, RenderSettings
from conftest import DATA, needs_shared

MATERIALS = {
    "diffuse": AnalyticMaterial("d", "Linear", 3, [Lobe.create("Lambertian", [0.25, 0.2, 0.15])]),
    "glossy": AnalyticMaterial("g", "Linear", 3, [Lobe.create("Lambertian", [0.05] * 3),
                                                  Lobe.create("BlinnPhong", [0.3] * 3, Exponent=60.0)]),
    "anisotropic": AnalyticMaterial("a", "Linear", 3, [Lobe.create("Lambertian", [0.03] * 3),
                                                       Lobe.create("Ward", [0.6] * 3, ax=0.08, ay=0.3)]),
}


@pytest.fixture(scope="module")
def renderer():
    from brdflab.render.context import create_context

    return ObjectRenderer(create_context())


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_point_light_matches_numpy_pixel_by_pixel(renderer, name):
    material = MATERIALS[name]
    renderer.set_material(material)
    light = (0.3, 0.5, 0.8)
    img = renderer.render(RenderSettings(mode="point", width=64, height=48, light=light))
    ref = point_light_image(material, 64, 48, light)
    ok = ref > 1e-4 * ref.max()
    np.testing.assert_allclose(img[ok], ref[ok], rtol=1e-3)
    assert np.all(img[~sphere_view(64, 48).inside] == 0.0)


@needs_shared("envmaps", "venice_sunset_1k.hdr")
@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_environment_matches_quadrature(renderer, name):
    env = load_environment(DATA / "envmaps" / "venice_sunset_1k.hdr").downsampled(128, 64)
    material = MATERIALS[name]
    renderer.set_environment(env)
    renderer.set_material(material)
    ref = environment_image(material, env, 48, 48)
    inside = sphere_view(48, 48).inside
    errors = {n: relative_rmse(renderer.render(RenderSettings(mode="fis", width=48, height=48, samples=n)), ref, inside)
              for n in (16, 256)}
    assert errors[256] < 0.02
    assert errors[256] < errors[16]  # converges


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_furnace(renderer, name):
    """A constant environment of 1 gives the directional albedo (by quadrature)."""
    material = MATERIALS[name]
    renderer.set_environment(constant(1.0, 64, 32))
    renderer.set_material(material)
    img = renderer.render(RenderSettings(mode="fis", width=24, height=24, samples=512))
    view = sphere_view(24, 24)
    wo = view.to_local(np.array([0.0, 0.0, 1.0]))[view.inside]
    albedo = np.stack([directional_albedo(material, wo[k:k + 1])[0] for k in range(0, len(wo), 7)])
    np.testing.assert_allclose(img[view.inside][::7], albedo, rtol=0.03, atol=2e-3)


@needs_shared("merl_slices", "white-paint.slice")
def test_measured_table_renders_like_its_lookup(renderer):
    table = read_slice(DATA / "merl_slices" / "white-paint.slice").to_full()
    renderer.set_source(table)
    img = renderer.render(RenderSettings(mode="point", width=48, height=48, light=(0.3, 0.4, 1.0)))
    ref = point_light_image(table, 48, 48, (0.3, 0.4, 1.0))
    assert relative_rmse(img, ref, sphere_view(48, 48).inside) < 1e-3


def test_mesh_hidden_surfaces_are_not_summed(renderer):
    """Two stacked spheres: with sample batches, only the front one may be shaded."""
    sphere = uv_sphere(24, 48)
    renderer.set_material(MATERIALS["diffuse"])
    renderer.set_environment(constant(1.0, 32, 16))
    renderer.set_mesh(sphere)
    settings = RenderSettings(mode="fis", width=64, height=64, samples=96, reference_view=False)
    single = renderer.render(settings)
    behind = from_arrays(np.vstack([sphere.positions, sphere.positions * 0.5]),
                         np.vstack([sphere.faces, sphere.faces + len(sphere.positions)]), name="two")
    renderer.set_mesh(behind)
    nested = renderer.render(settings)
    renderer.set_mesh(None)
    assert np.abs(nested - single).max() < 1e-3 * single.max()


def test_render_command_reference_exr(tmp_path, capsys):
    out = tmp_path / "img.exr"
    from brdflab.io.resources import data_dir

    mat = data_dir("materials") / "ward.xml"
    code = main(["render", str(mat), "--mode", "point", "--view", "reference", "--light", "0,1,1",
                 "--size", "40,30", "--out", str(out), "--json"])
    assert code == 0
    payload = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert payload["settings"]["size"] == [40, 30] and payload["frame_ms"] > 0
    img = read_exr(out)
    from brdflab.io.xmlio import load

    ref = point_light_image(load(mat).material, 40, 30, (0, 1, 1))
    ok = ref > 1e-4 * ref.max()
    np.testing.assert_allclose(img[ok], ref[ok], rtol=1e-3)


def test_render_command_png_on_a_mesh(tmp_path, capsys):
    from brdflab.io.resources import data_dir

    out = tmp_path / "img.png"
    code = main(["render", str(data_dir("materials") / "fig2_lambertian_lafortune.xml"), "--mode", "fis",
                 "--mesh", str(data_dir("resources") / "meshes" / "spot.obj"), "--samples", "16", "--size", "64,64",
                 "--out", str(out)])
    assert code == 0
    from PIL import Image

    img = np.asarray(Image.open(out))
    assert img.shape == (64, 64, 3) and img.max() > 50 and img[0, 0].max() == 0


@pytest.mark.parametrize("setup, message", [
    (lambda p: p.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 64 +X 128\n" + b"\x02\x02\x00\x80" + b"\x01" * 10), "truncated"),
    (lambda p: p.write_bytes(b"not an image"), "signature"),
])
def test_bad_environment_maps(tmp_path, capsys, setup, message):
    env = tmp_path / "bad.hdr"
    setup(env)
    from brdflab.io.resources import data_dir

    code = main(["render", str(data_dir("materials") / "lambertian.xml"), "--mode", "fis", "--env", str(env),
                 "--size", "8,8", "--out", str(tmp_path / "o.png")])
    err = capsys.readouterr().err
    assert code == 2 and message in err and str(env) in err and len(err.strip().splitlines()) == 1


def test_corrupt_exr(tmp_path, capsys):
    env = tmp_path / "bad.exr"
    env.write_bytes(b"v/1\x01" + b"\0" * 64)
    from brdflab.io.resources import data_dir

    code = main(["render", str(data_dir("materials") / "lambertian.xml"), "--mode", "fis", "--env", str(env),
                 "--size", "8,8", "--out", str(tmp_path / "o.png")])
    err = capsys.readouterr().err
    assert code == 2 and str(env) in err and "Traceback" not in err


@pytest.mark.parametrize("text, message", [
    ("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "NaN"),
    ("v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n", "degenerate"),
    ("# nothing\n", "no triangles"),
])
def test_bad_meshes(tmp_path, capsys, text, message):
    mesh = tmp_path / "bad.obj"
    mesh.write_text(text)
    from brdflab.io.resources import data_dir

    code = main(["render", str(data_dir("materials") / "lambertian.xml"), "--mesh", str(mesh), "--size", "8,8",
                 "--out", str(tmp_path / "o.png")])
    err = capsys.readouterr().err
    assert code == 2 and message in err and str(mesh) in err, err


def test_mesh_without_normals_gets_them():
    tri = from_arrays([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    np.testing.assert_allclose(tri.normals, [[0, 0, 1]] * 3, atol=1e-6)
    assert np.allclose(np.linalg.norm(tri.tangents, axis=1), 1.0)


@needs_shared("envmaps", "memorial.hdr")
def test_hdr_and_exr_decode_to_the_same_values():
    a = load_environment(DATA / "envmaps" / "memorial.hdr").data
    b = load_environment(DATA / "envmaps" / "memorial.exr").data
    assert a.shape == b.shape
    assert np.abs(a - b).max() <= 1e-5 * a.max()


def test_no_opengl_is_a_clear_error(monkeypatch, tmp_path, capsys):
    import moderngl

    def broken(*args, **kwargs):
        raise Exception("libEGL not found")

    monkeypatch.setattr(moderngl, "create_standalone_context", broken)
    from brdflab.io.resources import data_dir

    code = main(["render", str(data_dir("materials") / "lambertian.xml"), "--size", "8,8", "--out", str(tmp_path / "o.png")])
    err = capsys.readouterr().err
    assert code == 2 and "no OpenGL 3.3 context available" in err


@pytest.mark.parametrize("args, named", [
    (["--env", "missing.exr"], "--env"),
    (["--env-rotation", "30"], "--env-rotation"),
    (["--env", "a-front.hdr", "--env-layout", "dual-paraboloid"], "--env, --env-layout"),
])
def test_map_options_in_point_mode_are_one_line_exit_2(tmp_path, capsys, args, named):
    """The point light ignores the map: a map option without a map mode is a mistake named on one
    line (it was silently ignored, and a missing map went unnoticed), and nothing is written."""
    from brdflab.io.resources import data_dir

    out = tmp_path / "o.png"
    code = main(["render", str(data_dir("materials") / "lambertian.xml"), *args, "--size", "8,8", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and named in err and "--mode" in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()
