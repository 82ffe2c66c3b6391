"""Saving an XML material gives back the file it was read from, byte for byte, where
nothing changed; an edit of one value changes that value's text and nothing else.

The files are hand-made variants of the layout BRDFLab's (2009) Qt writer produces: a
bare <!DOCTYPE BRDF> line, one-space indentation, several <Fitting>s, each variant adding
one thing a reader must keep (comments, processing instructions, unknown elements and
attributes, a second <Info>, another quote style, indentation or encoding, numbers
spelled as a person or another program wrote them).
"""

from __future__ import annotations

import difflib
import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brdflab.errors import BRDFLabError
from brdflab.io import xmlio
from conftest import DATA, needs_shared
from test_xml_fuzz import SEEDS, trees
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.workspace import with_parameter, with_scale

BASE = """<!DOCTYPE BRDF>
<BRDF>
 <Info>
  <Program>BRDFLab</Program>
  <Version>1.0</Version>
 </Info>
 <Material>
  <Name>blue paint</Name>
  <Type>Analytic</Type>
  <LobeCombination>Linear</LobeCombination>
  <Parameters nChannels="3" nLobes="3">
   <ScalingFactors channel0="0.0191" channel1="0.0244" channel2="0.0802"/>
   <Lobe>
    <Model>Lambertian</Model>
    <Type>Isotropic</Type>
    <Parameters/>
   </Lobe>
   <ScalingFactors channel0="0.31" channel1="0.35" channel2="0.42"/>
   <Lobe>
    <Model>LafortuneIso</Model>
    <Type>Isotropic</Type>
    <Parameters Cxy="-0.573" Cz="0.522" Exponent="43.1"/>
   </Lobe>
   <ScalingFactors channel0="0.2" channel1="0.2" channel2="0.2"/>
   <Lobe>
    <Model>Ward</Model>
    <Type>Isotropic</Type>
    <Parameters ax="0.12"/>
   </Lobe>
  </Parameters>
 </Material>
 <Fitting error="0.0123" readOnly="0" optimizerName="Levenberg-Marquardt">
  <Material>
   <Name>fit 0</Name>
   <Type>Analytic</Type>
   <LobeCombination>Linear</LobeCombination>
   <Parameters nChannels="3" nLobes="1">
    <ScalingFactors channel0="0.05" channel1="0.04" channel2="0.03"/>
    <Lobe>
     <Model>Lambertian</Model>
     <Type>Isotropic</Type>
     <Parameters/>
    </Lobe>
   </Parameters>
  </Material>
 </Fitting>
</BRDF>
"""


def _insert_before(anchor: str, text: str, count: int = 1):
    return lambda s: s.replace(anchor, text + anchor, count)


def _single_quotes(s: str) -> str:
    return re.sub(r'(\w+)="([^"]*)"', r"\1='\2'", s)


def _tabs(s: str) -> str:
    return re.sub(r"(?m)^( +)", lambda m: "\t" * len(m.group(1)), s)


def _compact(s: str) -> str:
    return re.sub(r">\s+<", "><", s).strip()


# each variant: a change of BASE (text) and the encoding it is written in
VARIANTS = {
    "as BRDFLab writes it": (lambda s: s, "utf-8"),
    "unknown element before the first lobe": (
        _insert_before('   <ScalingFactors channel0="0.0191"', '   <Preview size="64" cached="yes"/>\n'), "utf-8"),
    "unknown elements between lobes and in a lobe": (
        lambda s: s.replace("   <ScalingFactors channel0=\"0.2\"", "   <Note>glossy coat</Note>\n   <ScalingFactors channel0=\"0.2\"")
        .replace("<Parameters ax=\"0.12\"/>\n", "<Parameters ax=\"0.12\"/>\n    <Measured by=\"gonio\"/>\n"), "utf-8"),
    "comments and processing instructions outside <Info>": (
        lambda s: s.replace("<!DOCTYPE BRDF>\n", "<!-- exported by BRDFLab -->\n<!DOCTYPE BRDF>\n<?viewer zoom='2'?>\n")
        .replace(" <Material>\n  <Name>blue", " <!-- the material -->\n <?brdflab keep?>\n <Material>\n  <Name>blue")
        .replace("   <ScalingFactors channel0=\"0.31\"", "   <!-- the specular lobe -->\n   <ScalingFactors channel0=\"0.31\"")
        + "<!-- end of file -->\n", "utf-8"),
    "unknown attributes on <BRDF>, <Material>, <Parameters>, <Lobe>": (
        lambda s: s.replace("<BRDF>", '<BRDF version="2.1">').replace(" <Material>\n  <Name>blue", ' <Material id="m1" >\n  <Name>blue')
        .replace('<Parameters nChannels="3" nLobes="3">', '<Parameters nChannels="3" nLobes="3" units="1/sr">')
        .replace("   <Lobe>\n    <Model>Ward", '   <Lobe label="coat">\n    <Model>Ward'), "utf-8"),
    "a second <Info>": (
        lambda s: s.replace("</BRDF>", " <Info>\n  <Author>someone else</Author>\n </Info>\n</BRDF>"), "utf-8"),
    "an XML declaration in single quotes, ISO-8859-1": (
        lambda s: "<?xml version='1.0' encoding='ISO-8859-1'?>\n" + s.replace("blue paint", "peinture bleue \u00e9tal\u00e9e"),
        "latin-1"),
    "single-quoted attributes": (_single_quotes, "utf-8"),
    "tab indentation and CRLF line ends": (lambda s: _tabs(s).replace("\n", "\r\n"), "utf-8"),
    "one line, no layout": (_compact, "utf-8"),
    "numbers as another program spelled them": (
        lambda s: s.replace('channel0="0.0191"', 'channel0="1.910e-2"').replace('Cz="0.522"', 'Cz=" .5220"')
        .replace('Exponent="43.1"', 'Exponent="43.10"').replace('ax="0.12"', 'ax="+0.120"')
        .replace('error="0.0123"', 'error="1.23E-02"'), "utf-8"),
    "character references, CDATA, open empty elements": (
        lambda s: s.replace("blue paint", "blue &amp; <![CDATA[<green>]]> &#233;").replace("<Parameters/>", "<Parameters></Parameters>", 1)
        .replace(' <Info>', ' <Info note="a&#10;b &quot;c&quot;">', 1), "utf-8"),
}


def variant(name: str) -> bytes:
    change, encoding = VARIANTS[name]
    return change(BASE).encode(encoding)


def everything() -> bytes:
    """Every variant that can be combined, in one file."""
    text = BASE
    for name in VARIANTS:
        if VARIANTS[name][1] == "utf-8" and name not in ("one line, no layout", "tab indentation and CRLF line ends",
                                                         "single-quoted attributes"):
            text = VARIANTS[name][0](text)
    return _single_quotes(text).encode()


FILES = dict({name: variant(name) for name in VARIANTS}, **{"all of them at once": everything()})


def saved(doc, tmp_path, name="saved.xml") -> bytes:
    path = tmp_path / name
    xmlio.save(doc, path)
    return path.read_bytes()


def changed_lines(before: bytes, after: bytes, encoding="utf-8") -> list[tuple[str, str]]:
    """(old, new) for each replaced line; fails on inserted or deleted lines."""
    a = before.decode(encoding).splitlines(keepends=True)
    b = after.decode(encoding).splitlines(keepends=True)
    out = []
    for op, i1, i2, j1, j2 in difflib.SequenceMatcher(None, a, b, autojunk=False).get_opcodes():
        if op == "equal":
            continue
        assert op == "replace" and i2 - i1 == j2 - j1, (op, a[i1:i2], b[j1:j2])
        out += list(zip(a[i1:i2], b[j1:j2]))
    return out


def respelled(line: str, attribute: str, value: str) -> set[str]:
    """`line` with the value of one `attribute` (in whatever quotes) replaced by `value`:
    one answer per occurrence (a file on one line holds many)."""
    pattern = re.compile(rf"\b{attribute}=([\"'])[^\"']*\1")
    return {line[:m.start()] + f"{attribute}={m[1]}{value}{m[1]}" + line[m.end():] for m in pattern.finditer(line)}


# --- nothing changed: the same bytes ---------------------------------------------------

@pytest.mark.parametrize("name", sorted(FILES))
def test_open_and_save_gives_the_same_bytes(name, tmp_path):
    data = FILES[name]
    original = tmp_path / "in.xml"
    original.write_bytes(data)
    doc = xmlio.load(original)
    assert saved(doc, tmp_path) == data
    again = xmlio.load(tmp_path / "saved.xml")
    assert again.describe()["material"] == doc.describe()["material"]
    assert [f.describe() for f in again.fittings] == [f.describe() for f in doc.fittings]


def test_what_the_variants_hold_is_read_as_well_as_kept():
    """The variants are real tests of the reader too: the values come out as written."""
    for name, data in FILES.items():
        doc = xmlio.parse_bytes(data, f"{name}.xml")
        lobes = doc.material.lobes
        assert [l.model.name for l in lobes] == ["Lambertian", "LafortuneIso", "Ward"], name
        assert lobes[0].scale[0] == 0.0191 and lobes[1].params["Cz"] == 0.522, name
        assert lobes[2].params == {"ax": 0.12, "ay": 0.12}, name
        assert doc.fittings[0].error == 0.0123, name
        assert doc.info.findtext("Program") == "BRDFLab", name  # the first <Info>, not the second
    assert "second <Info>" in " ".join(xmlio.parse_bytes(FILES["a second <Info>"]).warnings)


def test_a_document_built_in_memory_is_written_afresh_and_then_kept(tmp_path):
    doc = xmlio.parse_bytes(variant("as BRDFLab writes it"))
    fresh = xmlio.BRDFDocument(doc.material.copy(), list(doc.fittings), doctype="BRDF")
    first = saved(fresh, tmp_path, "a.xml")
    assert first.startswith(b"<?xml") and b"<!DOCTYPE BRDF>" in first
    assert saved(xmlio.load(tmp_path / "a.xml"), tmp_path, "b.xml") == first


def test_values_read_from_a_file_still_go_to_other_processes():
    """The GUI sends materials to a worker process (pickle); the link to the file's
    elements stays behind and nothing else changes."""
    import pickle

    doc = xmlio.parse_bytes(FILES["all of them at once"])
    for value in (doc.material, doc.fittings[0], doc):
        back = pickle.loads(pickle.dumps(value))
        assert back.source is None
        assert (back.describe() if hasattr(back, "describe") else back) == (
            value.describe() if hasattr(value, "describe") else value)
    material = pickle.loads(pickle.dumps(doc.material))
    assert material.lobes[2].params == {"ax": 0.12, "ay": 0.12}
    # the unknown elements travel too: the material written afresh still holds them
    text = xmlio.to_bytes(xmlio.BRDFDocument(material))
    assert b"<Preview" in text and b"<Note>glossy coat</Note>" in text and b"<Measured" in text


# --- one edit: one value's text ------------------------------------------------------------

EDITS = {
    "a lobe parameter": (lambda m: with_parameter(m, 1, "Cz", 0.6), "Cz", "0.6"),
    "a scaling factor": (lambda m: with_scale(m, 1, 2, 0.45), "channel2", "0.45"),
    "Ward's lone ax, ay following": (
        lambda m: with_parameter(with_parameter(m, 2, "ax", 0.2), 2, "ay", 0.2), "ax", "0.2"),
}


@pytest.mark.parametrize("edit", sorted(EDITS))
@pytest.mark.parametrize("name", sorted(FILES))
def test_an_edit_changes_only_that_value(name, edit, tmp_path):
    data = FILES[name]
    encoding = VARIANTS.get(name, (None, "utf-8"))[1]
    change, attribute, text = EDITS[edit]
    doc = xmlio.parse_bytes(data)
    doc.material = change(doc.material)
    after = saved(doc, tmp_path)
    lines = changed_lines(data, after, encoding)
    assert len(lines) == 1
    old, new = lines[0]
    assert new in respelled(old, attribute, text)
    assert new != old


def test_an_edit_inside_a_stored_fit(tmp_path):
    data = FILES["all of them at once"]
    doc = xmlio.parse_bytes(data)
    doc.fittings[0].material = with_scale(doc.fittings[0].material, 0, 1, 0.25)
    doc.fittings[0].error = 0.01
    lines = changed_lines(data, saved(doc, tmp_path))
    assert len(lines) == 2
    assert lines[0][1] in respelled(lines[0][0], "error", "0.01")
    assert lines[1][1] in respelled(lines[1][0], "channel1", "0.25")


def test_an_edit_undone_gives_the_file_back(tmp_path):
    data = FILES["numbers as another program spelled them"]
    doc = xmlio.parse_bytes(data)
    before = doc.material
    doc.material = with_parameter(before, 1, "Cz", 0.7)
    assert saved(doc, tmp_path) != data
    doc.material = with_parameter(doc.material, 1, "Cz", 0.522)
    assert saved(doc, tmp_path) == data


def test_a_file_the_map_cannot_follow_keeps_its_content(tmp_path):
    """Namespaced content is written by lxml from the same patched tree: a declaration is
    added, the rest is the file with its one edit."""
    data = BASE.replace("<BRDF>", '<BRDF xmlns:x="urn:x">').replace(
        " <Material>\n  <Name>blue", ' <x:Extra x:a="1"/>\n <Material>\n  <Name>blue').encode()
    doc = xmlio.parse_bytes(data)
    assert not doc.source.mappable
    doc.material = with_parameter(doc.material, 1, "Cz", 0.6)
    declaration, rest = saved(doc, tmp_path).split(b"\n", 1)
    assert declaration.startswith(b"<?xml")
    lines = changed_lines(data, rest)
    assert len(lines) == 1 and lines[0][1] in respelled(lines[0][0], "Cz", "0.6")


# --- Ward's <Type>: what the file said ------------------------------------------------------

def ward_file(type_: str, params: str) -> bytes:
    return BASE.replace("<Type>Isotropic</Type>\n    <Parameters ax=\"0.12\"/>",
                        f"<Type>{type_}</Type>\n    <Parameters {params}/>").encode()


@pytest.mark.parametrize("type_,params", [
    ("Isotropic", 'ax="0.12"'), ("Isotropic", 'ax="0.12" ay="0.12"'), ("Anisotropic", 'ax="0.12" ay="0.12"'),
    ("Anisotropic", 'ax="0.05" ay="0.2"'),
])
def test_a_ward_lobe_keeps_the_type_its_file_gave(type_, params, tmp_path):
    data = ward_file(type_, params)
    doc = xmlio.parse_bytes(data)
    assert saved(doc, tmp_path) == data
    # an edit that keeps ax = ay keeps the Type, whichever it was
    if 'ay="0.2"' not in params:
        doc.material = with_parameter(with_parameter(doc.material, 2, "ax", 0.3), 2, "ay", 0.3)
        out = saved(doc, tmp_path)
        assert f"<Type>{type_}</Type>".encode() in out and xmlio.load(tmp_path / "saved.xml").material.lobes[2].params == {
            "ax": 0.3, "ay": 0.3}


def test_an_edit_that_makes_ward_anisotropic_says_so(tmp_path):
    data = ward_file("Isotropic", 'ax="0.12"')
    doc = xmlio.parse_bytes(data)
    doc.material = with_parameter(doc.material, 2, "ay", 0.3)
    lines = changed_lines(data, saved(doc, tmp_path))
    assert [new.strip() for _, new in lines] == ["<Type>Anisotropic</Type>", '<Parameters ax="0.12" ay="0.3"/>']
    assert xmlio.load(tmp_path / "saved.xml").material.lobes[2].params == {"ax": 0.12, "ay": 0.3}


def test_the_type_of_a_new_lobe_follows_its_parameters():
    """Ward, anisotropic Lafortune, Ashikhmin–Shirley and Kurt are isotropic when their pair
    of parameters is equal; the model says which pair (brdflab.models)."""
    def written(model, **params):
        mat = AnalyticMaterial("m", "Linear", 1, [Lobe.create(model, [1.0], **params)])
        return xmlio.parse_bytes(xmlio.to_bytes(xmlio.BRDFDocument(mat))).source.root.findtext(".//Lobe/Type")

    assert written("Ward", ax=0.1, ay=0.1) == "Isotropic"
    assert written("Ward", ax=0.1, ay=0.2) == "Anisotropic"
    assert written("LafortuneAniso", Cx=-0.5, Cy=-0.5) == "Isotropic"
    assert written("LafortuneAniso", Cx=-0.5, Cy=-0.4) == "Anisotropic"
    assert written("AshikhminShirley", nu=10.0, nv=10.0) == "Isotropic"
    assert written("Kurt", mx=0.1, my=0.3) == "Anisotropic"
    assert written("LafortuneIso") == "Isotropic"


# --- structure edits keep the file's layout -------------------------------------------------

def test_a_new_fit_is_inserted_with_the_files_indentation(tmp_path):
    data = FILES["all of them at once"]
    doc = xmlio.parse_bytes(data)
    fit = xmlio.Fitting(with_scale(doc.fittings[0].material, 0, 0, 0.5), 0.02)
    doc.fittings.append(fit)
    after = saved(doc, tmp_path)
    a, b = data.decode().splitlines(True), after.decode().splitlines(True)
    ops = [op for op in difflib.SequenceMatcher(None, a, b, autojunk=False).get_opcodes() if op[0] != "equal"]
    assert len(ops) == 1 and ops[0][0] == "insert"
    inserted = b[ops[0][3]:ops[0][4]]
    assert inserted[0].startswith(" <Fitting ") and inserted[-1] == " </Fitting>\n"
    assert all(re.match(r"^ +<", line) for line in inserted)
    again = xmlio.load(tmp_path / "saved.xml")
    assert len(again.fittings) == 2 and again.fittings[1].material.lobes[0].scale[0] == 0.5


def test_inserted_text_gets_the_files_indentation_and_line_ends(tmp_path):
    data = FILES["tab indentation and CRLF line ends"]
    doc = xmlio.parse_bytes(data)
    doc.fittings.append(xmlio.Fitting(doc.fittings[0].material.copy(), 0.5))
    out = saved(doc, tmp_path)
    assert out.count(b"\n") == out.count(b"\r\n") > data.count(b"\r\n")
    assert b'\r\n\t<Fitting error="0.5"' in out and b"\r\n\t\t\t\t<ScalingFactors" in out
    assert out.startswith(data[: data.rindex(b"</BRDF>")].rsplit(b"\t</Fitting>", 1)[0])


# each: the file's bytes (its BOM, declaration and line ends), its BOM and its codec
ENCODED = {
    "UTF-8 with a BOM": (lambda s: b"\xef\xbb\xbf" + s.encode(), b"\xef\xbb\xbf", "utf-8"),
    "UTF-16LE, a BOM, no declaration": (lambda s: b"\xff\xfe" + s.encode("utf-16-le"), b"\xff\xfe", "utf-16-le"),
    "UTF-16BE, a BOM, declared UTF-16": (
        lambda s: b"\xfe\xff" + ('<?xml version="1.0" encoding="UTF-16"?>\n' + s).encode("utf-16-be"), b"\xfe\xff",
        "utf-16-be"),
    "UTF-16BE, declared, no BOM": (
        lambda s: ('<?xml version="1.0" encoding="UTF-16BE"?>\n' + s).encode("utf-16-be"), b"", "utf-16-be"),
    "UTF-32LE with a BOM": (
        lambda s: ('<?xml version="1.0" encoding="UTF-32"?>\n' + s).encode("utf-32"), b"\xff\xfe\x00\x00", "utf-32-le"),
    "UTF-32BE with a BOM": (
        lambda s: b"\x00\x00\xfe\xff" + ('<?xml version="1.0" encoding="UTF-32"?>\n' + s).encode("utf-32-be"),
        b"\x00\x00\xfe\xff", "utf-32-be"),
    "CR line ends (classic Mac)": (lambda s: s.replace("\n", "\r").encode(), b"", "utf-8"),
}


@pytest.mark.parametrize("namespaced", [False, True], ids=["mapped", "written by lxml"])
@pytest.mark.parametrize("name", sorted(ENCODED))
def test_a_save_keeps_the_files_encoding_bom_and_line_ends(name, namespaced, tmp_path):
    """A new <Fitting> in a UTF-16/32 file (either byte order, with or without a BOM or a
    declaration), a UTF-8 file with a BOM or a CR-only file: the save keeps the BOM, the
    encoding and the line ends, and the lab reads its own file back (it wrote UTF-16BE and
    UTF-32 files it could not read, and UTF-8 for a UTF-16LE file, without the BOM)."""
    make, bom, codec = ENCODED[name]
    text = BASE.replace("<BRDF>", '<BRDF xmlns:x="urn:x">\n <x:Extra x:a="1"/>') if namespaced else BASE
    doc = xmlio.parse_bytes(make(text))
    doc.fittings.append(xmlio.Fitting(doc.fittings[0].material.copy(), 0.5))
    out = saved(doc, tmp_path)
    assert out.startswith(bom) and '<Fitting error="0.5"' in out[len(bom):].decode(codec)
    again = xmlio.load(tmp_path / "saved.xml")
    assert len(again.fittings) == 2 and again.fittings[1].error == 0.5
    if name.startswith("CR "):
        assert b"\n" not in out and out.count(b"\r") > text.count("\n")


def test_removing_and_moving_lobes_keeps_everything_else(tmp_path):
    from brdflab.workspace import with_lobe_moved, with_lobe_removed

    data = FILES["all of them at once"]
    doc = xmlio.parse_bytes(data)
    doc.material = with_lobe_moved(doc.material, 2, -1)
    moved = saved(doc, tmp_path).decode()
    assert moved.index("<Model>Ward") < moved.index("<Model>LafortuneIso")
    assert xmlio.load(tmp_path / "saved.xml").material.lobes[1].model.name == "Ward"
    for keep in ("<!-- the specular lobe -->", "<Lobe label='coat'>", "<Preview size=", "<Note>glossy coat</Note>",
                 "<?brdflab keep?>", "<!-- end of file -->", "<Author>someone else</Author>"):
        assert keep in moved
    doc.material = with_lobe_removed(doc.material, 1)
    removed = saved(doc, tmp_path)
    back = xmlio.load(tmp_path / "saved.xml").material
    assert [l.model.name for l in back.lobes] == ["Lambertian", "LafortuneIso"]
    assert re.search(rb"nLobes=['\"]2['\"]", removed)
    kept_lines = set(data.decode().splitlines())
    assert all(line in kept_lines for line in removed.decode().splitlines() if "nLobes" not in line)


# --- numbers read back bit for bit ----------------------------------------------------------

FLOATS = st.floats(min_value=0.0, max_value=10.0, allow_nan=False, allow_infinity=False)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scale=FLOATS, cz=st.floats(min_value=0.001, max_value=1.0), ax=st.floats(min_value=0.001, max_value=1.0),
       error=st.floats(min_value=0.0, max_value=1e6))
def test_values_written_read_back_bit_for_bit(scale, cz, ax, error):
    doc = xmlio.parse_bytes(FILES["all of them at once"])
    doc.material = with_parameter(with_scale(doc.material, 1, 0, scale), 1, "Cz", cz)
    doc.material = with_parameter(doc.material, 2, "ax", ax)
    doc.fittings[0].error = error
    for written in (doc, xmlio.BRDFDocument(doc.material, doc.fittings)):  # patched and written afresh
        back = xmlio.parse_bytes(xmlio.to_bytes(written))
        lobes = back.material.lobes
        got = (lobes[1].scale[0], lobes[1].params["Cz"], lobes[2].params["ax"], back.fittings[0].error)
        assert [math.copysign(1, g) for g in got] == [math.copysign(1, w) for w in (scale, cz, ax, error)]
        assert got == (scale, cz, ax, error)


def _same_bytes_if_it_parses(data: bytes) -> None:
    try:
        doc = xmlio.parse_bytes(data, "fuzz.xml")
    except BRDFLabError:
        return
    assert doc.source.mappable
    assert xmlio.to_bytes(doc) == data


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(SEEDS + list(FILES.values())),
       st.lists(st.tuples(st.integers(0, 10_000), st.integers(0, 8), st.binary(max_size=6)), max_size=4))
def test_mutated_files_that_parse_are_written_back_unchanged(seed, edits):
    data = bytearray(seed)
    for pos, cut, insert in edits:
        pos %= max(len(data), 1)
        data[pos:pos + cut] = insert
    _same_bytes_if_it_parses(bytes(data))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(trees())
def test_random_documents_that_parse_are_written_back_unchanged(body):
    _same_bytes_if_it_parses(f"<BRDF>{body}</BRDF>".encode())


# --- as a user meets it: the command line (the window: test_xml_roundtrip_gui.py) ------------

@needs_shared("merl_slices", "gold-metallic-paint3.slice")
def test_fit_out_adds_its_fit_and_changes_nothing_else(tmp_path):
    """`brdflab fit paint.xml --out fitted.xml`, run from another folder, on a measured
    material with comments and unknown content: fitted.xml is paint.xml plus one <Fitting>."""
    shutil.copy(DATA / "merl_slices" / "gold-metallic-paint3.slice", tmp_path / "gold-paint.slice")
    measured = FILES["all of them at once"].decode()
    start = measured.index(" <Material")
    end = measured.index(" </Material>", start) + len(" </Material>\n")
    measured = (measured[:start] + ' <Material id="m1" >\n  <Name>gold-paint.slice</Name>\n  <Type>BivariateSlice</Type>\n'
                '  <Scanner model="x"/>\n </Material>\n' + measured[end:]).encode()
    (tmp_path / "paint.xml").write_bytes(measured)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    proc = subprocess.run([sys.executable, "-m", "brdflab", "fit", str(tmp_path / "paint.xml"), "--lobes", "Lambertian",
                           "--out", str(tmp_path / "fitted.xml"), "--json"], capture_output=True, text=True, cwd=elsewhere,
                          env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    error = json.loads(proc.stdout.strip().splitlines()[-1])["error"]
    after = (tmp_path / "fitted.xml").read_bytes()
    a, b = measured.decode().splitlines(True), after.decode().splitlines(True)
    ops = [op for op in difflib.SequenceMatcher(None, a, b, autojunk=False).get_opcodes() if op[0] != "equal"]
    assert len(ops) == 1 and ops[0][0] == "insert", ops
    inserted = "".join(b[ops[0][3]:ops[0][4]])
    assert inserted.startswith(" <Fitting error=") and inserted.endswith(" </Fitting>\n")
    assert xmlio.load(tmp_path / "fitted.xml").fittings[-1].error == error
