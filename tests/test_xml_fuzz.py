"""Fuzzing the XML reader: whatever the bytes, it parses or raises BRDFLabError."""

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brdflab.io import xmlio
from brdflab.errors import BRDFLabError
from brdflab.io.resources import example_materials
from test_xml import ORIGINAL

SEEDS = [ORIGINAL] + [p.read_bytes() for p in example_materials()]
TAGS = ["BRDF", "Info", "Material", "Name", "Type", "LobeCombination", "Parameters", "ScalingFactors",
        "Lobe", "Model", "Fitting", "Checksum", "FitStatistics", "Unknown"]
ATTRS = ["nChannels", "nLobes", "channel", "channel0", "channel1", "channel2", "Cxy", "Cz", "Exponent",
         "ax", "ay", "value", "error", "readOnly", "nu", "F0", "m"]
TEXTS = ["Analytic", "Linear", "Fixed", "Lambertian", "Ward", "LafortuneIso", "Isotropic", "0", "1", "-1",
         "3", "nan", "1e400", "", "MERLBRDFDatabase", "x.binary"]


def parse_or_documented_error(data: bytes) -> None:
    try:
        doc = xmlio.parse_bytes(data, "fuzz.xml")
    except BRDFLabError as e:
        assert str(e).startswith("fuzz.xml: ") and "\n" not in str(e)
        return
    # whatever parses must also write and read back
    xmlio.parse_bytes(xmlio.to_bytes(doc), "again.xml")


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(SEEDS), st.lists(st.tuples(st.integers(0, 10_000), st.integers(0, 8), st.binary(max_size=6)), max_size=6))
def test_mutated_files(seed, edits):
    data = bytearray(seed)
    for pos, cut, insert in edits:
        pos %= max(len(data), 1)
        data[pos:pos + cut] = insert
    parse_or_documented_error(bytes(data))


@st.composite
def trees(draw, depth=0):
    tag = draw(st.sampled_from(TAGS))
    attrs = draw(st.dictionaries(st.sampled_from(ATTRS), st.sampled_from(TEXTS), max_size=3))
    attr_text = "".join(f' {k}="{v}"' for k, v in attrs.items())
    children = draw(st.lists(trees(depth + 1), max_size=0 if depth > 3 else 4))
    text = draw(st.sampled_from(TEXTS))
    return f"<{tag}{attr_text}>{text}{''.join(children)}</{tag}>"


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(trees())
def test_structured_random_documents(body):
    parse_or_documented_error(f"<BRDF>{body}</BRDF>".encode())
