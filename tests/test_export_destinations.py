"""Where exports go (issue 37 §1): a name that says the format, never over the source, and a
Mitsuba scene's map beside the scene it belongs to, never over a file it did not write. Through
the real command line, as a user meets it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CAR_PAINT = ROOT / "materials" / "principled_car_paint.xml"  # Principled already: no fit on the way out


def brdflab(*args, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "brdflab", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


def refused(r: subprocess.CompletedProcess, named: str, words: str) -> bool:
    """Exit status 2 and one stderr line that names the file and says the problem."""
    lines = r.stderr.strip().splitlines()
    return r.returncode == 2 and len(lines) == 1 and named in lines[0] and words in lines[0] and "Traceback" not in r.stderr


@pytest.mark.parametrize("fmt, suffix", [("merl", ".binary"), ("glsl", ".glsl"), ("brdf-explorer", ".brdf"),
                                         ("mitsuba", ".xml"), ("mtlx", ".mtlx")])
def test_each_format_is_refused_under_a_name_of_another(tmp_path, fmt, suffix):
    """`--out x.txt` wrote a MERL table, GLSL, a .brdf or a scene to a file nothing opens by its
    name; refused in one line before any work, nothing written; the format's own name works."""
    wrong = tmp_path / "paint.txt"
    r = brdflab("export", CAR_PAINT, "--format", fmt, "--out", wrong)
    assert refused(r, "paint.txt", f"is named {suffix}"), r.stderr
    assert os.listdir(tmp_path) == []
    right = tmp_path / f"paint{suffix}"
    r = brdflab("export", CAR_PAINT, "--format", fmt, "--out", right)
    assert r.returncode == 0 and right.is_file(), r.stderr


@pytest.mark.parametrize("spelling", ["same", "other spelling", "link as --out", "link as source"])
def test_an_export_never_replaces_its_source(tmp_path, spelling):
    """`export m.xml --format mitsuba --out m.xml` replaced the material with a scene (and a
    MERL table could replace the table it was read from): refused in one line however the two
    paths are spelled, the source unchanged and nothing written beside it."""
    (tmp_path / "sub").mkdir()
    source = tmp_path / "m.xml"
    shutil.copy(CAR_PAINT, source)
    (tmp_path / "link.xml").symlink_to("m.xml")
    src, out = {"same": ("m.xml", "m.xml"), "other spelling": ("m.xml", "sub/../m.xml"),
                "link as --out": ("m.xml", "link.xml"), "link as source": ("link.xml", "./m.xml")}[spelling]
    before = source.read_bytes()
    r = brdflab("export", src, "--format", "mitsuba", "--out", out, cwd=tmp_path)
    assert refused(r, out.removeprefix("./"), "never replaces its source"), r.stderr
    assert source.read_bytes() == before and sorted(os.listdir(tmp_path)) == ["link.xml", "m.xml", "sub"]


def test_a_merl_table_is_never_exported_over_itself(tmp_path):
    table = tmp_path / "t.binary"
    assert brdflab("export", CAR_PAINT, "--format", "merl", "--out", table).returncode == 0
    before = table.stat().st_mtime_ns, table.read_bytes()[:64]
    r = brdflab("export", table, "--format", "merl", "--out", table)
    assert refused(r, "t.binary", "never replaces its source"), r.stderr
    assert (table.stat().st_mtime_ns, table.read_bytes()[:64]) == before


def test_a_mitsuba_scene_written_through_a_link_has_its_map_beside_the_linked_scene(tmp_path):
    """The map went beside the link, named after it, while the linked scene named it: Mitsuba
    could not load the scene the link leads to. Now it lies beside that scene, named after it."""
    (tmp_path / "real").mkdir()
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "s.xml").symlink_to("../real/scene.xml")
    r = brdflab("export", CAR_PAINT, "--format", "mitsuba", "--out", tmp_path / "other" / "s.xml")
    assert r.returncode == 0, r.stderr
    assert sorted(os.listdir(tmp_path / "real")) == ["scene.xml", "scene_env.exr"]
    assert os.listdir(tmp_path / "other") == ["s.xml"] and (tmp_path / "other" / "s.xml").is_symlink()
    assert 'value="scene_env.exr"' in (tmp_path / "real" / "scene.xml").read_text()
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    mi.load_file(str(tmp_path / "real" / "scene.xml"))  # finds its map


def test_a_mitsuba_map_never_replaces_a_file_it_did_not_write(tmp_path):
    """`--out studio.xml` silently replaced an unrelated `studio_env.exr`: refused in one line
    naming it, before any work, nothing written. Exporting again over a scene the lab wrote
    replaces the scene and its map, and says so."""
    mine = tmp_path / "studio_env.exr"
    mine.write_bytes(b"someone's own map")
    r = brdflab("export", CAR_PAINT, "--format", "mitsuba", "--out", tmp_path / "studio.xml")
    assert refused(r, "studio_env.exr", "not the map of a scene being replaced"), r.stderr
    assert mine.read_bytes() == b"someone's own map" and os.listdir(tmp_path) == ["studio_env.exr"]
    scene = tmp_path / "paint.xml"
    first = brdflab("export", CAR_PAINT, "--format", "mitsuba", "--out", scene)
    assert first.returncode == 0 and first.stderr == "", first.stderr
    again = brdflab("export", CAR_PAINT, "--format", "mitsuba", "--out", scene)
    assert again.returncode == 0 and "replaced" in again.stderr and "paint_env.exr" in again.stderr, again.stderr
    assert len(again.stderr.strip().splitlines()) == 1


def measured_fit(folder: Path) -> tuple[Path, Path]:
    """A MERL table (tabulated from the shipped Lambertian example) and a fit saved beside it,
    as `brdflab fit TABLE --out FIT.xml` saves one: the material reads the table."""
    from brdflab.io.xmlio import load
    from brdflab.sources.measured import tabulate, write_merl_binary

    table = folder / "lambert.binary"
    write_merl_binary(tabulate(load(ROOT / "materials" / "lambertian.xml").material), table)
    fit = folder / "fit.xml"
    r = brdflab("fit", table, "--lobes", "Lambertian", "--samples", "subset", "--size", "500", "--out", fit)
    assert r.returncode == 0, r.stderr
    return table, fit


def test_an_export_never_replaces_the_data_its_source_reads(tmp_path):
    """A user's trial: `export fit.xml --fitting 0 --format merl --out TABLE.binary` replaced the
    very table the material names, silently; `info` then said the table had changed."""
    table, fit = measured_fit(tmp_path)
    before = table.read_bytes()
    r = brdflab("export", fit, "--fitting", "0", "--format", "merl", "--out", table)
    assert refused(r, "lambert.binary", "the measured data file that the material being exported reads"), r.stderr
    assert table.read_bytes() == before
    link = tmp_path / "other.binary"
    link.symlink_to(table)
    r = brdflab("export", fit, "--fitting", "0", "--format", "merl", "--out", link)
    assert refused(r, "other.binary", "that the material being exported reads"), r.stderr
    assert table.read_bytes() == before


def test_an_export_says_its_model_file_changed_as_every_command_does(tmp_path):
    """`info`, `eval`, `render` and `fit` of a material whose model file was edited since the save
    say so; `export` was silent."""
    models = tmp_path / "models"
    models.mkdir()
    shutil.copy(ROOT.parent / "shared" / "data" / "models" / "brdf_explorer" / "lambert.brdf", models / "flat.brdf")
    material = tmp_path / "m.xml"
    r = brdflab("fit", "example:lambertian", "--lobes", f"{models / 'flat.brdf'}", "--samples", "subset", "--size", "300",
                "--out", material)
    assert r.returncode == 0, r.stderr
    with open(models / "flat.brdf", "a") as f:
        f.write("\n# edited after the save\n")
    r = brdflab("export", material, "--fitting", "0", "--format", "glsl", "--out", tmp_path / "m.glsl")
    assert r.returncode == 0 and "is not the one the material was saved with" in r.stderr, r.stderr


def test_an_export_of_a_material_that_stores_a_principled_fit_points_to_it(tmp_path):
    """A user's trial: `export fit.xml` of a file holding a Principled fit fitted the source again
    (minutes) and never said that `--fitting 0` exports the stored fit exactly."""
    from test_fit_cache import ward_samples

    source = tmp_path / "ward.txt"
    ward_samples(source)
    fit = tmp_path / "fit.xml"
    r = brdflab("fit", source, "--lobes", "Principled", "--max-iterations", "3", "--no-restarts", "--out", fit)
    assert r.returncode == 0, r.stderr
    r = brdflab("export", fit, "--format", "mtlx", "--out", tmp_path / "again.mtlx")
    assert r.returncode == 0 and "stores a Principled fit (--fitting 0), which exports exactly" in r.stderr, r.stderr
    r = brdflab("export", fit, "--fitting", "0", "--format", "mtlx", "--out", tmp_path / "stored.mtlx")
    assert r.returncode == 0 and "stores a Principled fit" not in r.stderr and "fitted to Principled" not in r.stderr
