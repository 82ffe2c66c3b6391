"""Files exactly as BRDFLab (2009) writes them open everywhere; entity tricks on them do not.

BRDFLab's Qt DOM writer starts every file with a bare `<!DOCTYPE BRDF>` line (model
descriptors: `<!DOCTYPE BRDFModel>`), so such a line is accepted and kept, while anything
that can declare or load entities is still refused with a one-line error.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdflab.errors import BRDFLabError
from brdflab.io import xmlio

FITTING = """<Fitting error="{err}" readOnly="0" optimizerName="Levenberg-Marquardt">
  <Material>
   <Name>fit {k}</Name>
   <Type>Analytic</Type>
   <LobeCombination>Linear</LobeCombination>
   <Parameters nChannels="3" nLobes="2">
    <ScalingFactors channel0="0.05" channel1="0.04" channel2="0.03"/>
    <Lobe>
     <Model>Lambertian</Model>
     <Type>Isotropic</Type>
     <Parameters/>
    </Lobe>
    <ScalingFactors channel0="{s}" channel1="{s}" channel2="{s}"/>
    <Lobe>
     <Model>Ward</Model>
     <Type>Isotropic</Type>
     <Parameters ax="{ax}"/>
    </Lobe>
   </Parameters>
  </Material>
 </Fitting>
"""

BRDFLAB_FILE = ("""<!DOCTYPE BRDF>
<BRDF>
 <Info>
  <Program>BRDFLab</Program>
  <Version>1.0</Version>
 </Info>
 <Material>
  <Name>blue-metallic-paint.binary</Name>
  <Type>MERLBRDFDatabase</Type>
 </Material>
 """ + FITTING.format(err="0.0123", k=0, s="0.8", ax="0.12")
    + FITTING.format(err="0.0101", k=1, s="0.6", ax="0.2") + "</BRDF>\n").encode()


@pytest.fixture
def brdflab_file(tmp_path) -> Path:
    path = tmp_path / "paint.xml"
    path.write_bytes(BRDFLAB_FILE)
    return path


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "brdflab", *map(str, args)], capture_output=True, text=True, cwd=cwd)


def test_a_brdflab_file_opens_in_info_and_keeps_its_doctype(brdflab_file, tmp_path):
    proc = cli("info", brdflab_file, "--json")
    assert proc.returncode == 0, proc.stderr
    info = json.loads(proc.stdout.strip().splitlines()[-1])
    assert len(info["fittings"]) == 2
    doc = xmlio.load(brdflab_file)
    assert doc.doctype == "BRDF"
    xmlio.save(doc, tmp_path / "again.xml")
    assert (tmp_path / "again.xml").read_bytes() == BRDFLAB_FILE  # the same file, DOCTYPE line first
    assert xmlio.load(tmp_path / "again.xml").doctype == "BRDF"


def test_eval_of_a_stored_fitting_of_a_brdflab_file(brdflab_file, tmp_path):
    wi = np.array([[0.3, 0.1, 0.948683], [0.0, 0.0, 1.0]])
    wo = np.array([[-0.2, 0.2, 0.959166], [0.5, 0.0, 0.866025]])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    np.save(tmp_path / "pairs.npy", np.hstack([wi, wo]))
    proc = cli("eval", brdflab_file, "--pairs", tmp_path / "pairs.npy", "--out", tmp_path / "out.npy", "--fitting", 1)
    assert proc.returncode == 0, proc.stderr
    got = np.load(tmp_path / "out.npy")
    # Lambertian + isotropic Ward (ax = 0.2), written out independently.
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    tan2 = (1 - h[:, 2] ** 2) / h[:, 2] ** 2
    ward = np.exp(-tan2 / 0.2**2) / (4 * np.pi * 0.2 * 0.2 * np.sqrt(wi[:, 2] * wo[:, 2]))
    expect = np.array([0.05, 0.04, 0.03])[None, :] + 0.6 * ward[:, None]
    np.testing.assert_allclose(got, expect, rtol=1e-6)


def test_brdfmodel_doctype_is_accepted_too():
    doc = xmlio.parse_bytes(BRDFLAB_FILE.replace(b"<!DOCTYPE BRDF>", b"<!DOCTYPE BRDFModel>"), "m.xml")
    assert doc.doctype == "BRDFModel"


@pytest.mark.parametrize("doctype", [
    b'<!DOCTYPE BRDF [<!ENTITY x SYSTEM "file:///etc/passwd">]>',   # XXE
    b'<!DOCTYPE BRDF [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]>',  # billion laughs
    b'<!DOCTYPE BRDF SYSTEM "http://example.invalid/brdf.dtd">',
    b'<!DOCTYPE BRDF PUBLIC "-//x//y" "brdf.dtd">',
    b"<!DOCTYPE BRDF []>",
])
def test_doctypes_that_can_bring_entities_are_refused(doctype, tmp_path):
    data = BRDFLAB_FILE.replace(b"<!DOCTYPE BRDF>", doctype).replace(b"<Version>1.0", b"<Version>&x;1.0")
    if b"ENTITY b" in doctype:
        data = data.replace(b"&x;", b"&b;")
    with pytest.raises(BRDFLabError):
        xmlio.parse_bytes(data, "evil.xml")
    path = tmp_path / "evil.xml"
    path.write_bytes(data)
    proc = cli("info", path)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "evil.xml" in proc.stderr and "Traceback" not in proc.stderr
