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
