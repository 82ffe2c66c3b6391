"""BRDFLab XML: lossless round trips, the original layout, unknown elements, safety."""

import math
import os

import numpy as np
import pytest

from brdflab.io import xmlio
from brdflab.errors import BRDFLabError
from brdflab.models import get_model
from brdflab.io.resources import example_materials
from brdflab.geometry.vec import spherical_to_cartesian

# A file as the original BRDFLab (2009) wrote it, following its description: empty
# <Parameters/> on a Linear Lambertian lobe, Ward with ax alone, Ashikhmin–Shirley with
# Exponent, several <Fitting>s, and elements this version does not know.
ORIGINAL = b"""<?xml version="1.0" encoding="UTF-8"?>
<BRDF>
  <Info>
    <Author>BRDFLab</Author>
    <Date>2009-04-20</Date>
  </Info>
  <Material>
    <Name>blue-metallic-paint</Name>
    <Type>Analytic</Type>
    <LobeCombination>Linear</LobeCombination>
    <Parameters nChannels="3" nLobes="4">
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
      <ScalingFactors channel0="0.5" channel1="0.5" channel2="0.5"/>
      <Lobe>
        <Model>AshikhminShirley</Model>
        <Type>Isotropic</Type>
        <Parameters Exponent="120" F0="0.04"/>
      </Lobe>
    </Parameters>
    <ViewerSettings zoom="1.5"/>
  </Material>
  <Fitting error="24.074" readOnly="1" optimizerName="LevenbergMarquardt">
    <Material>
      <Name>fit-1</Name>
      <Type>Analytic</Type>
      <LobeCombination>Linear</LobeCombination>
      <Parameters nChannels="3" nLobes="1">
        <ScalingFactors channel0="0.02" channel1="0.03" channel2="0.08"/>
        <Lobe><Model>Lambertian</Model><Type>Isotropic</Type><Parameters/></Lobe>
      </Parameters>
    </Material>
  </Fitting>
  <Fitting error="12.5" readOnly="0" optimizerName="LevenbergMarquardt">
    <Material>
      <Name>fit-2</Name>
      <Type>Analytic</Type>
      <LobeCombination>Fixed</LobeCombination>
      <Parameters nChannels="3" nLobes="3">
        <Lobe channel="0"><Model>Lambertian</Model><Type>Isotropic</Type><Parameters value="0.01"/></Lobe>
        <Lobe channel="1"><Model>Lambertian</Model><Type>Isotropic</Type><Parameters value="0.02"/></Lobe>
        <Lobe channel="2"><Model>Lambertian</Model><Type>Isotropic</Type><Parameters value="0.03"/></Lobe>
      </Parameters>
    </Material>
  </Fitting>
  <Notes>kept through load and save</Notes>
</BRDF>
"""


def directions(n=200, seed=3):
    rng = np.random.default_rng(seed)
    t = rng.uniform(0, 1.45, (2, n))
    p = rng.uniform(0, 2 * np.pi, (2, n))
    return spherical_to_cartesian(t[0], p[0]), spherical_to_cartesian(t[1], p[1])


def test_original_layout_opens_and_evaluates():
    doc = xmlio.parse_bytes(ORIGINAL, "original.xml")
    mat = doc.material
    assert mat.combination == "Linear" and mat.n_channels == 3 and len(mat.lobes) == 4
    assert mat.lobes[2].params == {"ax": 0.12, "ay": 0.12}
    assert mat.lobes[3].params == {"nu": 120.0, "nv": 120.0, "F0": 0.04}
    assert len(doc.fittings) == 2
    assert doc.fittings[0].error == 24.074 and doc.fittings[0].read_only
    assert doc.fittings[1].material.combination == "Fixed"
    assert any("ViewerSettings" in w for w in doc.warnings)
    assert any("Notes" in w for w in doc.warnings)

    wi, wo = directions()
    expected = (
        np.outer(np.ones(len(wi)), [0.0191, 0.0244, 0.0802])
        + np.outer(get_model("LafortuneIso").evaluate(wi, wo, {"Cxy": -0.573, "Cz": 0.522, "Exponent": 43.1}), [0.31, 0.35, 0.42])
        + np.outer(get_model("Ward").evaluate(wi, wo, {"ax": 0.12, "ay": 0.12}), [0.2] * 3)
        + np.outer(get_model("AshikhminShirley").evaluate(wi, wo, {"nu": 120.0, "nv": 120.0, "F0": 0.04}), [0.5] * 3)
    )
    np.testing.assert_allclose(mat.evaluate(wi, wo), expected, rtol=1e-12)
    fixed = doc.fittings[1].material.evaluate(wi, wo)
    np.testing.assert_allclose(fixed, np.outer(np.ones(len(wi)), [0.01, 0.02, 0.03]))


def test_unknown_elements_survive_a_save(tmp_path):
    doc = xmlio.parse_bytes(ORIGINAL, "original.xml")
    out = tmp_path / "copy.xml"
    xmlio.save(doc, out)
    text = out.read_text()
    assert '<ViewerSettings zoom="1.5"/>' in text
    assert "<Notes>kept through load and save</Notes>" in text
    assert "<Author>BRDFLab</Author>" in text
    again = xmlio.load(out)
    assert again.describe()["material"] == doc.describe()["material"]


@pytest.mark.parametrize("path", example_materials(), ids=lambda p: p.name)
def test_round_trip_is_lossless(path, tmp_path):
    doc = xmlio.load(path)
    first = tmp_path / "a.xml"
    xmlio.save(doc, first)
    doc2 = xmlio.load(first)
    second = tmp_path / "b.xml"
    xmlio.save(doc2, second)
    assert first.read_bytes() == second.read_bytes()
    assert doc2.describe()["material"] == doc.describe()["material"]
    wi, wo = directions()
    np.testing.assert_array_equal(doc.material.evaluate(wi, wo), doc2.material.evaluate(wi, wo))
    # and the shipped file itself is already in canonical form
    assert path.read_bytes() == first.read_bytes()


def test_example_materials_cover_every_model():
    from brdflab.models import model_names

    used = {l.model.name for p in example_materials() for l in xmlio.load(p).material.lobes}
    assert set(model_names()) <= used


def test_measured_material_with_missing_data_still_opens(tmp_path):
    xml = b"""<BRDF><Info/><Material><Name>data/gone.binary</Name><Type>MERLBRDFDatabase</Type>
    <Checksum algorithm="sha256">abc</Checksum></Material>""" + ORIGINAL.split(b"</Material>\n", 1)[1]
    path = tmp_path / "m.xml"
    path.write_bytes(xml)
    doc = xmlio.load(path)
    assert doc.material.missing
    assert doc.material.path == tmp_path / "data" / "gone.binary"
    assert len(doc.fittings) == 2
    desc = doc.describe()["material"]
    assert desc["missing"] is True and desc["data_file"] == "data/gone.binary"


def test_fittings_keep_statistics(tmp_path):
    doc = xmlio.parse_bytes(ORIGINAL)
    doc.fittings[1].statistics = {"metric": "L2", "seconds": 0.5, "iterations": 12}
    xmlio.save(doc, tmp_path / "s.xml")
    again = xmlio.load(tmp_path / "s.xml")
    assert again.fittings[1].statistics == {"metric": "L2", "seconds": 0.5, "iterations": 12}


def test_entities_and_doctypes_are_refused(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("TOP SECRET")
    xxe = f"""<?xml version="1.0"?><!DOCTYPE BRDF [<!ENTITY x SYSTEM "file://{secret}">]>
    <BRDF><Material><Name>&x;</Name><Type>Analytic</Type></Material></BRDF>""".encode()
    with pytest.raises(BRDFLabError, match="entity"):
        xmlio.parse_bytes(xxe, "evil.xml")
    bomb = b"""<?xml version="1.0"?><!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;&lol;">]>
    <BRDF>&lol2;</BRDF>"""
    with pytest.raises(BRDFLabError):
        xmlio.parse_bytes(bomb, "bomb.xml")


def test_save_is_atomic(tmp_path, monkeypatch):
    path = tmp_path / "keep.xml"
    path.write_bytes(ORIGINAL)
    doc = xmlio.parse_bytes(ORIGINAL)

    def broken_replace(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(BRDFLabError, match="No space left"):
        xmlio.save(doc, path)
    assert path.read_bytes() == ORIGINAL
    assert [p.name for p in tmp_path.iterdir()] == ["keep.xml"]


BAD = {
    "malformed": (b"<BRDF><Material>", "malformed XML"),
    "NUL byte (found by the fuzzer; libxml2's message spans two lines)": (b"<\x00BRDF>", "malformed XML"),
    "unknown model": (ORIGINAL.replace(b"<Model>Ward</Model>", b"<Model>Wardd</Model>"), "unknown lobe model 'Wardd'"),
    "missing parameter": (ORIGINAL.replace(b'Cxy="-0.573" ', b""), "missing parameter(s) Cxy"),
    "extra parameter": (ORIGINAL.replace(b'Cz="0.522"', b'Cz="0.522" Cw="1"'), "no parameter(s) Cw"),
    "out of bounds": (ORIGINAL.replace(b'ax="0.12"', b'ax="7"'), "ax=7 is outside"),
    "NaN": (ORIGINAL.replace(b'Exponent="43.1"', b'Exponent="NaN"'), "Exponent is NaN"),
    "Inf": (ORIGINAL.replace(b'channel1="0.35"', b'channel1="inf"'), "channel1 is inf"),
    "not a number": (ORIGINAL.replace(b'Cz="0.522"', b'Cz="abc"'), "Cz is not a number"),
    "wrong channel count": (ORIGINAL.replace(b'nChannels="3" nLobes="4"', b'nChannels="2" nLobes="4"'), "channel2"),
    "wrong lobe count": (ORIGINAL.replace(b'nLobes="4"', b'nLobes="5"'), "nLobes=5 but 4"),
    "fixed channel out of range": (ORIGINAL.replace(b'<Lobe channel="2">', b'<Lobe channel="5">'), "channel 5"),
    "no material": (b"<BRDF><Info/></BRDF>", "no <Material>"),
    "wrong root": (b"<Material/>", "root element must be <BRDF>"),
    "bad combination": (ORIGINAL.replace(b"<LobeCombination>Linear", b"<LobeCombination>Mixed", 1), "Linear or Fixed"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_gets_a_clear_error(case):
    data, message = BAD[case]
    with pytest.raises(BRDFLabError) as err:
        xmlio.parse_bytes(data, "bad.xml")
    text = str(err.value)
    assert text.startswith("bad.xml: ")
    assert message in text
    assert "\n" not in text


def test_new_files_get_the_usual_permissions(tmp_path):
    umask = os.umask(0o022)
    try:
        xmlio.atomic_write(tmp_path / "new.xml", b"<BRDF/>")
        assert (tmp_path / "new.xml").stat().st_mode & 0o777 == 0o644
    finally:
        os.umask(umask)
