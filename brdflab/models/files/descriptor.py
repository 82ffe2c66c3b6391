"""BRDFLab's analytic model descriptors (`<!DOCTYPE BRDFModel>`, BRDFLab 0.8.2's
`Data/analyticModels/*.xml`).

    <AnalyticBRDFModel name=".." type="Isotropic|Anisotropic" specularLobeDirection="..">
      <Parameters><Parameter name=".." defaultVal=".." lowBound=".." highBound=".."/>…
      <Equation> formula </Equation>                       (CPU: see expression.py)
      <Equation_GLSL> float NameBRDF(vec3 u, vec3 v, int j) reading params[j + k] </…>
      <PDF_GLSL>, <ImportanceSampling_GLSL>, <ComputeMirrorDirection_GLSL>

The formula is what the CPU evaluates (fits, plots, albedo); the GLSL is what renders, with
the helpers BRDFLab's shaders provided (`fresnel`, `cart2spherical`, `spherical2cart`). The
file's own sampler (φ, θ of a half vector or of a direction about the mirror) is read but
not used: BRDFLab's samplers do not match their pdfs (its Ward sampler draws θ from the
uniform meant for φ), so the lab samples every file model with its generic sampler.
"""

from __future__ import annotations

import re
from pathlib import Path


from brdflab.errors import BRDFLabError
from brdflab.models.base import Parameter
from brdflab.models.files import glsl_text
from brdflab.models.files.expression import DIRECTIONS, FUNCTIONS, CONSTANTS, FormulaError, compile_formula
from brdflab.models.files.model import FileModel, GlslParts, Origin, model_glsl_id
from brdflab.models.files.limits import MAX_ARRAY_ELEMENTS, check_parameters, number, parameter_name

FORMAT = "BRDFLab descriptor"

_HELPERS = {
    "fresnel": "float fresnel(float F0, float dotVH) { return F0 + (1.0 - F0) * pow(max(0.0, 1.0 - dotVH), 5.0); }",
    "cart2spherical": ("vec2 cart2spherical(vec3 pos) { vec3 n = normalize(pos); float phi = atan(n.y, n.x); "
                       "phi = phi > 0.0 ? phi : 6.283185307179586 + phi; return vec2(phi, acos(n.z)); }"),
    "spherical2cart": "vec3 spherical2cart(vec2 uv) { return vec3(sin(uv.y) * cos(uv.x), sin(uv.y) * sin(uv.x), cos(uv.y)); }",
}


def read(path: Path, data: bytes, name: str | None = None) -> FileModel:
    """The model a descriptor file defines; BRDFLabError (one line, naming the file) if it
    is not a usable one. `name` is the registry name (default: the file's model name)."""
    from brdflab.io.xmlio import checked_root

    root, _ = checked_root(data, path, "model")
    if root.tag != "AnalyticBRDFModel":
        raise BRDFLabError("not a BRDFLab model descriptor (the root element must be <AnalyticBRDFModel>)", path)

    def fail(el, message: str) -> BRDFLabError:
        return BRDFLabError(f"line {el.sourceline}: {message}", path)

    model_name = (root.get("name") or "").strip()
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.\-]{0,63}", model_name):
        raise fail(root, "the model's name must be 1-64 letters, digits, '_', '.' or '-'")
    kind = root.get("type", "Isotropic")
    if kind not in ("Isotropic", "Anisotropic"):
        raise fail(root, "type must be Isotropic or Anisotropic")

    params_el = root.find("Parameters")
    params: list[Parameter] = []
    if params_el is not None:
        for el in params_el:
            if not isinstance(el.tag, str):
                continue
            if el.tag != "Parameter":
                raise fail(el, "<Parameters> holds only <Parameter> elements")
            pname = parameter_name(el.get("name") or "", lambda m: fail(el, m))
            if pname in DIRECTIONS or pname in CONSTANTS or pname in FUNCTIONS:
                raise fail(el, f"parameter {pname!r} has the name of a direction, constant or function")
            values = [number(el.get(a), a, lambda m: fail(el, m)) for a in ("defaultVal", "lowBound", "highBound")]
            params.append(Parameter(pname, values[0], values[1], values[2], doc=f"from {path.name}"))
    check_parameters(params, lambda m: BRDFLabError(m, path))

    formula = None
    eq = root.find("Equation")
    if eq is not None and (eq.text or "").strip():
        try:
            formula = compile_formula(eq.text, tuple(p.name for p in params) + DIRECTIONS)
        except FormulaError as e:
            line, col = _position(eq, e.pos, data)
            raise BRDFLabError(f"line {line}, column {col}: <Equation>: {e}", path) from None

    glsl_el = root.find("Equation_GLSL")
    if glsl_el is None or not (glsl_el.text or "").strip():
        raise BRDFLabError("no <Equation_GLSL>: the renderers need the model's GLSL", path)
    code = glsl_el.text.replace("U+003C", "<")
    found = glsl_text.code_problem(code, MAX_ARRAY_ELEMENTS)
    if found:
        raise BRDFLabError(f"line {(glsl_el.sourceline or 1) + found[0] - 1}: {found[1]}", path)
    function = f"{model_name}BRDF"
    declared = glsl_text.declared_names(code)
    if function not in declared:
        raise fail(glsl_el, f"<Equation_GLSL> defines no function {function}(vec3 u, vec3 v, int j)")
    used = {t for k, t in glsl_text.tokens(code) if k == "name"}
    helpers = [src for h, src in _HELPERS.items() if h in used and h not in declared]
    n = len(params)
    library_body = "\n".join(helpers + [code])
    origin = Origin.of(path, data, FORMAT)
    prefix = model_glsl_id(model_name, origin.sha256) + "_"
    names = glsl_text.declared_names(library_body) + ["params"]
    library = f"float {prefix}params[NP];\n" + glsl_text.guarded_loops(glsl_text.precise_calls(
        glsl_text.prefixed(library_body, names, prefix)), prefix)
    call = (f"for (int k = 0; k < {max(n, 1)}; k++) {prefix}params[k] = p[k]; "
            f"int j = 0; return {prefix}{function}(wi, wo, j);")
    glsl = GlslParts(library, call, returns_colour=False, line_offset=(glsl_el.sourceline or 1) - 1 - len(helpers))
    warnings = []
    if root.find("ImportanceSampling_GLSL") is not None:
        warnings.append(f"{path.name}: its own importance sampling is not used (BRDFLab's samplers do not match "
                        "their pdfs); the lab's generic sampler draws from the lobe's values instead")
    return FileModel(name or model_name, model_name, tuple(params), kind == "Isotropic", origin, glsl,
                     formula, summary=f"BRDFLab model descriptor {path.name}", warnings=tuple(warnings))


def _position(el, offset: int, data: bytes) -> tuple[int, int]:
    """Line and column in the file of character `offset` of the element's text (lxml gives
    the line of the start tag; the text starts right after it)."""
    before = (el.text or "")[:offset]
    line = (el.sourceline or 1) + before.count("\n")
    if "\n" in before:
        return line, offset - before.rfind("\n")
    lines = data.splitlines()
    tag_line = lines[el.sourceline - 1].decode("utf-8", "replace") if el.sourceline and el.sourceline <= len(lines) else ""
    start = tag_line.find(f"<{el.tag}>")
    return line, (start + len(el.tag) + 2 if start >= 0 else 0) + offset + 1
