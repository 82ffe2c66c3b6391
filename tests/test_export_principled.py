"""Exports to the renderers' family (Mitsuba 3, MaterialX, glTF), tried as a user would:
through the command line, read back with each format's own library, and (Mitsuba) rendered
by Mitsuba 3 against the lab's renders of the same material."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from khronos import assert_valid_gltf

from brdflab.io import xmlio
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.models.principled import specular_eta

ROOT = Path(__file__).resolve().parent.parent
CAR_PAINT = ROOT / "materials" / "principled_car_paint.xml"
FITS = ROOT / "docs" / "bench" / "principled_fits"
MERL_FITS = ("red-specular-plastic", "nickel", "blue-fabric")  # a plastic, a metal, a fabric


def principled(name: str, **params) -> AnalyticMaterial:
    return AnalyticMaterial(name, "Linear", 3, [Lobe.create("Principled", [1.0, 1.0, 1.0], **params)])


ANALYTIC = {
    "car paint": lambda: xmlio.load(CAR_PAINT).material,
    "gold": lambda: principled("gold", base_color_r=1.0, base_color_g=0.71, base_color_b=0.29, metallic=1.0, roughness=0.35),
    "velvet": lambda: principled("velvet", base_color_r=0.3, base_color_g=0.05, base_color_b=0.25, roughness=0.9,
                                 subsurface=0.6, sheen=1.0, sheen_tint=0.5, specular=0.3),
}


def brdflab(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "brdflab", *args], check=False, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def small_env():
    from brdflab.io.resources import default_environment_path
    from brdflab.lighting.envmap import load_environment

    return load_environment(default_environment_path()).downsampled(256, 128)


@pytest.mark.parametrize("name", [*ANALYTIC, *MERL_FITS])
def test_mitsuba_renders_the_export_as_the_lab_does(name, small_env):
    pytest.importorskip("mitsuba")
    from brdflab.study.mitsuba_check import compare

    material = ANALYTIC[name]() if name in ANALYTIC else xmlio.load(FITS / f"{name}.xml").material
    c = compare(name, material, small_env, size=24, spp=1024, lab_samples=512)
    assert c.mitsuba_noise < 0.05 and c.lab_noise < 0.05  # enough samples for the comparison to mean something
    assert c.renderer_rmse <= 0.02, c.as_dict()
    if name in ANALYTIC:  # lobes wider than the map's texels: the quadrature is exact there too
        assert c.quadrature_rmse <= 0.02, c.as_dict()


def test_the_mitsuba_scene_names_what_it_was_fitted_from(tmp_path):
    """A material that is not principled goes out fitted, and the command says what that costs."""
    out = tmp_path / "fig2.xml"
    r = brdflab("export", "example:fig2", "--format", "mitsuba", "--out", str(out), "--json")
    assert r.returncode == 0, r.stderr
    payload = json.loads(r.stdout.splitlines()[-1])
    assert any("fitted to Principled on the way out: Ngan error" in w for w in payload["warnings"])
    assert "fitted to Principled" in r.stderr
    text = out.read_text()
    assert '<bsdf type="principled" id="material">' in text and "fitted to Principled" in text
    assert (tmp_path / "fig2_env.exr").is_file()


def test_a_principled_material_goes_to_mitsuba_unchanged(tmp_path):
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    out = tmp_path / "paint.xml"
    r = brdflab("export", str(CAR_PAINT), "--format", "mitsuba", "--out", str(out))
    assert r.returncode == 0 and r.stderr == "", r.stderr  # exact: nothing to say
    params = mi.traverse(mi.load_file(str(out)))
    lobe = xmlio.load(CAR_PAINT).material.lobes[0].params
    assert params["material.clearcoat.value"] == pytest.approx(lobe["clearcoat"])
    assert params["material.roughness.value"] == pytest.approx(lobe["roughness"])


def test_materialx_export_validates_and_carries_the_parameters(tmp_path):
    import MaterialX as mx

    out = tmp_path / "paint.mtlx"
    r = brdflab("export", str(CAR_PAINT), "--format", "mtlx", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "clear coat is carried approximately" in r.stderr
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(out))
    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    doc.setDataLibrary(lib)
    ok, message = doc.validate()
    assert ok, message
    lobe = xmlio.load(CAR_PAINT).material.lobes[0].params
    shaders = {node.getCategory(): node for node in doc.getNodes() if node.getType() == "surfaceshader"}
    assert set(shaders) == {"standard_surface", "open_pbr_surface"}
    std = shaders["standard_surface"]
    colour = std.getInputValue("base_color")
    assert [colour[0], colour[1], colour[2]] == pytest.approx([lobe["base_color_r"], lobe["base_color_g"], lobe["base_color_b"]])
    assert std.getInputValue("metalness") == pytest.approx(lobe["metallic"])
    assert std.getInputValue("specular_roughness") == pytest.approx(lobe["roughness"])
    assert std.getInputValue("specular_IOR") == pytest.approx(float(specular_eta(lobe["specular"])), rel=1e-6)
    assert shaders["open_pbr_surface"].getInputValue("coat_weight") == pytest.approx(0.25 * lobe["clearcoat"])
    assert len(doc.getMaterialNodes()) == 2


@pytest.mark.parametrize("suffix", [".gltf", ".glb"])
def test_gltf_export_loads_back_with_the_parameters_written(tmp_path, suffix):
    import pygltflib
    import trimesh

    out = tmp_path / f"velvet{suffix}"
    xmlio.save(xmlio.BRDFDocument(ANALYTIC["velvet"]()), tmp_path / "velvet.xml")
    r = brdflab("export", str(tmp_path / "velvet.xml"), "--format", "gltf", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "gltf: subsurface not carried: Ngan" in r.stderr
    doc = pygltflib.GLTF2().load(str(out))
    material = doc.materials[0]
    assert material.pbrMetallicRoughness.baseColorFactor == pytest.approx([0.3, 0.05, 0.25, 1.0])
    assert material.pbrMetallicRoughness.roughnessFactor == pytest.approx(0.9)
    assert material.pbrMetallicRoughness.metallicFactor == pytest.approx(0.0)
    assert material.extensions["KHR_materials_ior"]["ior"] == pytest.approx(float(specular_eta(0.3)))
    assert "KHR_materials_sheen" in material.extensions and "KHR_materials_sheen" in doc.extensionsUsed
    assert "KHR_materials_clearcoat" not in material.extensions  # no coat: the extension does not apply
    assert_valid_gltf(out)
    mesh = trimesh.load(str(out), force="mesh")  # another reader opens the sphere
    assert len(mesh.faces) > 1000
    assert np.allclose(np.linalg.norm(mesh.vertices, axis=1), 1.0, atol=1e-5)


def test_an_export_that_cannot_be_written_is_one_line(tmp_path):
    r = brdflab("export", str(CAR_PAINT), "--format", "gltf", "--out", str(tmp_path / "missing" / "x.gltf"))
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr


def test_a_gltf_export_named_neither_gltf_nor_glb_is_refused_before_any_fit(tmp_path):
    """The container follows the name (.glb binary, .gltf JSON): `--out x.txt` wrote JSON to
    x.txt, a file no viewer opens by its name. Refused in one line, nothing written."""
    r = brdflab("export", str(CAR_PAINT), "--format", "gltf", "--out", str(tmp_path / "car.txt"))
    assert r.returncode == 2 and "named .gltf" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "car.txt").exists()


def test_a_mitsuba_scene_takes_a_light_probe_pair_as_its_map(tmp_path):
    """--env with a dual-paraboloid half finds its other half; the scene gets the pair as lat-long."""
    from brdflab.io.resources import shared_data_dir
    from brdflab.lighting.envmap import read_exr

    shared = shared_data_dir()
    front = shared / "envmaps" / "probes" / "campus-front.hdr" if shared else None
    if front is None or not front.is_file():
        pytest.skip("the shared light probes are not here")
    out = tmp_path / "paint.xml"
    r = brdflab("export", str(CAR_PAINT), "--format", "mitsuba", "--env", str(front), "--out", str(out))
    assert r.returncode == 0, r.stderr
    env = read_exr(tmp_path / "paint_env.exr")
    assert env.shape[1] == 2 * env.shape[0] and np.isfinite(env).all() and env.max() > 0
    lone = brdflab("export", str(CAR_PAINT), "--format", "mitsuba", "--env-back", str(front), "--out", str(out))
    assert lone.returncode == 2 and len(lone.stderr.strip().splitlines()) == 1


def test_the_mitsuba_scene_says_what_it_changed_and_only_that(tmp_path):
    """A fit's specular of 0 (η = 1, where Mitsuba drops its main lobe) is written as the floor
    and said; a trace of anisotropy (1e-5) is not worth a warning."""
    from brdflab.export.mitsuba import MIN_SPECULAR, export_mitsuba
    from brdflab.export.principled import PrincipledExport
    from brdflab.lighting.envmap import constant

    params = {**ANALYTIC["gold"]().lobes[0].params, "specular": 0.0, "anisotropic": 1e-5}
    warnings = export_mitsuba(PrincipledExport(params, exact=True), tmp_path / "s.xml", constant(1.0), "gold")
    assert len(warnings) == 1 and f"written as {MIN_SPECULAR:g}" in warnings[0]
    assert f'name="specular" value="{MIN_SPECULAR:g}"' in (tmp_path / "s.xml").read_text()


def mtlx_shaders(path: Path) -> dict[str, dict]:
    """The surface shaders of a MaterialX file by category: each node's name and its inputs'
    values (colours as tuples)."""
    import MaterialX as mx

    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(path))
    value = lambda inp: tuple(inp.getValue()[i] for i in range(3)) if inp.getType() == "color3" else inp.getValue()
    return {node.getCategory(): {"name": node.getName(), **{inp.getName(): value(inp) for inp in node.getInputs()}}
            for node in doc.getNodes() if node.getType() == "surfaceshader"}


def exported(tmp_path: Path, material: AnalyticMaterial, fmt: str, suffix: str) -> tuple[Path, str]:
    """`material` saved and exported through the command line: the export and its stderr."""
    source, out = tmp_path / f"{material.name}.xml", tmp_path / f"{material.name}{suffix}"
    xmlio.save(xmlio.BRDFDocument(material), source)
    r = brdflab("export", str(source), "--format", fmt, "--out", str(out))
    assert r.returncode == 0, r.stderr
    return out, r.stderr


@pytest.mark.parametrize("name", ["alum-bronze", "gold-metallic-paint3", "white-fabric", "blue-fabric"])
def test_gltf_exports_of_real_fits_pass_the_khronos_validator(tmp_path, name):
    """sheen × its tint reached 1.6 (alum-bronze) and 1.13 (gold-metallic-paint3): a
    sheenColorFactor above 1, which the Khronos validator refuses. Now the sheen is written
    within range, hue kept, and what that costs is said."""
    import pygltflib

    out = tmp_path / f"{name}.glb"
    r = brdflab("export", str(FITS / f"{name}.xml"), "--format", "gltf", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert_valid_gltf(out)
    sheen = pygltflib.GLTF2().load(str(out)).materials[0].extensions.get("KHR_materials_sheen")
    if name in ("alum-bronze", "gold-metallic-paint3"):
        assert max(sheen["sheenColorFactor"]) == pytest.approx(1.0)
        assert "gltf: the sheen's colour (sheen × its tint) reaches" in r.stderr and "hue kept: Ngan" in r.stderr


def test_gltf_carries_disneys_anisotropy(tmp_path):
    """KHR_materials_anisotropy exists and was not used ("anisotropic not carried"). glTF's
    αb = roughness², αt = mix(αb, 1, strength²) must be Disney's αy, αx, along the sphere's
    tangents (the lab's frame), and the file must pass the Khronos validator."""
    import pygltflib

    from brdflab.models.principled import alphas

    out, stderr = exported(tmp_path, principled("brushed", metallic=1.0, roughness=0.5, anisotropic=0.84), "gltf", ".gltf")
    assert "anisotropic" not in stderr
    assert_valid_gltf(out)
    doc = pygltflib.GLTF2().load(str(out))
    material = doc.materials[0]
    aniso = material.extensions["KHR_materials_anisotropy"]
    assert "KHR_materials_anisotropy" in doc.extensionsUsed and aniso["anisotropyRotation"] == 0.0
    ab = material.pbrMetallicRoughness.roughnessFactor ** 2
    at = ab + aniso["anisotropyStrength"] ** 2 * (1.0 - ab)
    ax, ay = alphas(0.5, 0.84)
    assert (at, ab) == pytest.approx((float(ax), float(ay)), rel=1e-9)
    assert doc.meshes[0].primitives[0].attributes.TANGENT is not None


def test_materialx_anisotropy_has_disneys_aspect(tmp_path):
    """Standard Surface's aspect is √(1 − a) (mx_roughness_anisotropy), Disney's √(1 − 0.9 a):
    `anisotropic` 0.84 written as is gave αx / αy = 6.3 where Disney has 4.1. OpenPBR's
    αx = r² √(2 / (1 + (1 − a)²)), αy = (1 − a) αx (NG_open_pbr_anisotropy) must give both αs."""
    from brdflab.models.principled import alphas

    out, _ = exported(tmp_path, principled("brushed", metallic=1.0, roughness=0.5, anisotropic=0.84), "mtlx", ".mtlx")
    shaders = mtlx_shaders(out)
    ax, ay = (float(v) for v in alphas(0.5, 0.84))
    std = shaders["standard_surface"]
    r2, a = std["specular_roughness"] ** 2, std["specular_anisotropy"]
    assert (r2 / np.sqrt(1.0 - a), r2 * np.sqrt(1.0 - a)) == pytest.approx((ax, ay), rel=1e-5)  # MaterialX writes 6 digits
    assert ax / ay == pytest.approx(4.1, abs=0.05)
    opr = shaders["open_pbr_surface"]
    r2, a = opr["specular_roughness"] ** 2, opr["specular_roughness_anisotropy"]
    x = r2 * np.sqrt(2.0 / (1.0 + (1.0 - a) ** 2))
    assert (x, (1.0 - a) * x) == pytest.approx((ax, ay), rel=1e-5)  # MaterialX writes 6 digits


def test_materialx_colours_stay_in_range_and_the_sheen_is_said(tmp_path):
    """blue-fabric's specular tint and sheen tint reach 2.25 and 7.6 in blue: every colour was
    written as is, above Standard Surface's and OpenPBR's 0–1. Now each colour's brightest
    channel is at most 1: the specular colour's excess goes into the IOR (the same reflectance
    at normal incidence per channel), the sheen's into its weight. The sheen, another lobe
    there, is said as the clear coat is."""
    from brdflab.export.principled import PrincipledExport

    out = tmp_path / "blue-fabric.mtlx"
    r = brdflab("export", str(FITS / "blue-fabric.xml"), "--format", "mtlx", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "mtlx: the sheen is carried approximately" in r.stderr
    p = xmlio.load(FITS / "blue-fabric.xml").material.lobes[0].params
    export = PrincipledExport(p, exact=True)
    shaders = mtlx_shaders(out)
    colours = {(c, k): v for c, inputs in shaders.items() for k, v in inputs.items() if isinstance(v, tuple)}
    assert len(colours) == 6 and all(0.0 <= min(v) and max(v) <= 1.0 + 1e-6 for v in colours.values()), colours
    std = shaders["standard_surface"]
    eta = std["specular_IOR"]
    f0 = ((eta - 1.0) / (eta + 1.0)) ** 2 * np.array(std["specular_color"])
    r0 = ((specular_eta(p["specular"]) - 1.0) / (specular_eta(p["specular"]) + 1.0)) ** 2
    assert f0 == pytest.approx(r0 * export.tinted("specular_tint"), rel=1e-5)
    sheen = std["sheen"] * np.array(std["sheen_color"])
    assert sheen == pytest.approx(p["sheen"] * export.tinted("sheen_tint"), rel=1e-5)  # 0.101 × 1: nothing lost


def test_an_exported_fit_is_named_after_its_source(tmp_path):
    """A stored fit's material is "fit" (the fitter's name for every fit): the MaterialX nodes
    were fit_standard_surface; now they are named after the file the fit came from."""
    fit = xmlio.load(FITS / "nickel.xml").material.copy()
    fit.name = "fit"
    source = tmp_path / "nickel_fits.xml"
    xmlio.save(xmlio.BRDFDocument(ANALYTIC["gold"](), fittings=[xmlio.Fitting(fit)]), source)
    out = tmp_path / "exported.mtlx"
    r = brdflab("export", str(source), "--fitting", "0", "--format", "mtlx", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert set(mtlx_shaders(out)) == {"standard_surface", "open_pbr_surface"}
    assert {shader["name"] for shader in mtlx_shaders(out).values()} == {
        "nickel_fits_standard_surface", "nickel_fits_open_pbr_surface"}


@pytest.mark.parametrize("fmt, suffix", [("gltf", ".gltf"), ("mtlx", ".mtlx")])
def test_what_costs_nothing_is_not_said(tmp_path, fmt, suffix):
    """A metal has no diffuse to flatten: "subsurface not carried: Ngan 0 (0.0 %)" said a loss
    of nothing. A loss is said only where it is at least 0.05 % of the material."""
    out, stderr = exported(tmp_path, principled("steel", metallic=1.0, roughness=0.3, subsurface=0.5), fmt, suffix)
    assert stderr == "", stderr
    _, stderr = exported(tmp_path, principled("plaster", roughness=0.8, subsurface=0.5), fmt, suffix)
    assert "subsurface" in stderr and "(0.0 %" not in stderr


@pytest.mark.parametrize("fmt, suffix", [("gltf", ".glb"), ("mtlx", ".mtlx")])
def test_a_stretch_beyond_the_formats_alpha_is_said(tmp_path, fmt, suffix):
    """glTF (αt = mix(αb, 1, strength²)) and Standard Surface (min(αx, 1)) hold αx at 1;
    Disney's rough, strongly anisotropic lobe goes past it (roughness 0.9, anisotropic 1:
    αx = 2.6). The export says what holding it costs, and the glTF still validates."""
    out, stderr = exported(tmp_path, principled("felt", roughness=0.9, anisotropic=1.0), fmt, suffix)
    assert "αx = 2.56 along the tangent is held at the format's 1" in stderr and "% of the material)" in stderr
    if fmt == "gltf":
        assert_valid_gltf(out)
