"""Bad model files (issue 28, point 5): each is refused in one line that names the file and
the problem, exit status 2, no traceback, nothing registered, in bounded time."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from brdflab.cli import main
from brdflab.models import model_names

BRDF_HEAD = "analytic\n::begin parameters\n{params}\n::end parameters\n::begin shader\n"
GOOD_BODY = "vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)\n{{\n    {line}\n}}\n::end shader\n"


def brdf(params="float k 0 1 .5", line="return vec3(k);"):
    return BRDF_HEAD.format(params=params) + GOOD_BODY.format(line=line)


def descriptor(equation="value", glsl=None, params='<Parameter name="value" defaultVal="1." lowBound="0." highBound="5."/>',
               head="<!DOCTYPE BRDFModel>\n", root="AnalyticBRDFModel"):
    glsl = glsl if glsl is not None else ("<Equation_GLSL>\n float BadBRDF(vec3 u, vec3 v, int j) { return params[j]; }\n"
                                          "</Equation_GLSL>")
    return (f'{head}<{root} name="Bad" type="Isotropic">\n  <Parameters>\n    {params}\n  </Parameters>\n'
            f"  <Equation>\n    {equation}\n  </Equation>\n  {glsl}\n</{root}>\n")


CASES = {
    # BRDF Explorer files
    "glsl-syntax.brdf": (brdf(line="return vec3(k) +;"), "line 8: GLSL error"),
    "glsl-unknown-name.brdf": (brdf(line="return vec3(k * nothing);"), "line 8: GLSL error: `nothing' undeclared"),
    "glsl-nan.brdf": (brdf(line="return vec3(sqrt(-1.0 - k));"), "gives NaN or infinity"),
    "glsl-negative.brdf": (brdf(line="return vec3(-k);"), "negative values"),
    "no-shader.brdf": ("analytic\n::begin parameters\nfloat k 0 1 .5\n::end parameters\n", "no ::begin shader section"),
    "no-function.brdf": (brdf(line="return vec3(k);").replace("BRDF(", "Other("), "defines no vec3 BRDF"),
    "unclosed.brdf": (brdf().replace("::end shader\n", ""), "the shader section is never closed"),
    "min-above-max.brdf": (brdf(params="float k 1 0 .5"), "its minimum 1 is above its maximum 0"),
    "default-outside.brdf": (brdf(params="float k 0 1 2"), "its default 2 is outside [0, 1]"),
    "duplicate.brdf": (brdf(params="float k 0 1 .5\nfloat k 0 1 .5"), "parameter 'k' is declared twice"),
    "too-many.brdf": (brdf(params="\n".join(f"float k{i} 0 1 .5" for i in range(40)), line="return vec3(k0);"),
                      "40 parameters (counting each colour as three) is more than the 32"),
    "unicode-digit.brdf": (brdf(params="float k 0 1 \uff13"), "is not a number"),
    "bool-two.brdf": (brdf(params="bool k 2", line="return vec3(k ? 1.0 : 0.5);"), "its default must be 0 or 1"),
    "int-type.brdf": (brdf(params="int k 0 1 0"), "unknown parameter type (float, bool or color)"),
    "keyword-name.brdf": (brdf(params="float return 0 1 .5"), "must be 1-64 letters"),
    "not-utf8.brdf": (b"analytic\n\xff\xfe::begin parameters\n", "not UTF-8 text"),
    "huge.brdf": ("# " + "x" * (2 << 20) + "\n" + brdf(), "a model file has at most"),
    "measured.brdf": (brdf().replace("analytic", "measured"), "only analytic BRDF Explorer files are models"),
    # BRDFLab model descriptors
    "formula-syntax.xml": (descriptor("x = ;\n    value"), "line 7, column 9: <Equation>: unexpected ';'"),
    "formula-function.xml": (descriptor("foo(value)"), "unknown function 'foo'"),
    "formula-name.xml": (descriptor("value + zz"), "unknown name 'zz'"),
    "formula-nan.xml": (descriptor("sqrt(-1 - value)"), "<Equation> gives NaN or infinity"),
    "formula-negative.xml": (descriptor("-value"), "<Equation> gives negative values"),
    "formula-deep.xml": (descriptor("(" * 400 + "value" + ")" * 400), "nests deeper than 200 levels"),
    "no-glsl.xml": (descriptor(glsl=""), "no <Equation_GLSL>"),
    "entity.xml": (descriptor(head='<!DOCTYPE BRDFModel [<!ENTITY e "7">]>\n'), "entity"),
    "wrong-root.xml": (descriptor(root="AnalyticBRDFModelX").replace("AnalyticBRDFModelX", "Model", 2)
                       .replace("<!DOCTYPE BRDFModel>", "<!-- AnalyticBRDFModel -->"),
                       "the root element must be <BRDF>"),  # a comment naming a model makes no model
    "formula-glsl-disagree.xml": (descriptor(glsl="<Equation_GLSL>\n float BadBRDF(vec3 u, vec3 v, int j)\n"
                                             " { return 2.0 * params[j]; }\n</Equation_GLSL>"),
                                  "its <Equation> and <Equation_GLSL> disagree by up to 50.00%"),
    "bom.brdf": (b"\xef\xbb\xbf" + brdf(params="float k 1 0 .5").encode(), "its minimum 1 is above its maximum 0"),
    "descriptor-min-max.xml": (descriptor(params='<Parameter name="value" defaultVal="1" lowBound="5" highBound="0"/>'),
                               "its minimum 5 is above its maximum 0"),
    "descriptor-glsl-error.xml": (descriptor(glsl="<Equation_GLSL>\n float BadBRDF(vec3 u, vec3 v, int j)\n"
                                             " { return params[j] * missing; }\n</Equation_GLSL>"),
                                  "line 11: GLSL error: `missing' undeclared"),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_bad_model_file_is_one_line_exit_2_and_nothing_loaded(name, tmp_path, capsys):
    content, expected = CASES[name]
    path = tmp_path / name
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    pairs = tmp_path / "pairs.npy"
    np.save(pairs, np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]]))
    before = set(model_names())
    status = main(["eval", str(path), "--pairs", str(pairs), "--out", str(tmp_path / "out.npy")])
    err = capsys.readouterr().err
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert str(path) in lines[0] and expected in lines[0], lines[0]
    assert set(model_names()) == before  # nothing half-loaded
    assert not (tmp_path / "out.npy").exists()


def test_glsl_that_runs_away_is_stopped_not_waited_for(tmp_path, capsys, monkeypatch):
    """The probe evaluation runs in a child process with a time limit: one that does not
    answer (here a child that sleeps) is refused when its wall-clock backstop expires."""
    from brdflab.render import model_eval

    monkeypatch.setattr(model_eval, "HANG_SECONDS", 2.0)
    monkeypatch.setattr(model_eval, "probe_command", lambda model: [sys.executable, "-c", "import time; time.sleep(60)"])
    path = tmp_path / "runaway.brdf"
    path.write_text(brdf(line="float s = 0.0; for (int i = 0; i < 100000000; i++) s += sin(s + k); return vec3(abs(s));"))
    pairs = tmp_path / "pairs.npy"
    np.save(pairs, np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]]))
    assert main(["eval", str(path), "--pairs", str(pairs), "--out", str(tmp_path / "o.npy")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "did not finish evaluating" in err and str(path) in err
