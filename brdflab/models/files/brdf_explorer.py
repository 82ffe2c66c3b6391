"""Disney BRDF Explorer's `.brdf` files, read as BRDF Explorer reads them.

    analytic
    ::begin parameters
    float NAME MIN MAX DEFAULT      bool NAME DEFAULT      color NAME R G B
    ::end parameters
    ::begin shader
    … vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y) { … }
    ::end shader
    ::begin isFunc  (optional: its own importance sampling)  ::end isFunc

Lines whose first non-blank character is `#` are comments everywhere, as BRDF Explorer reads
them, except in the shader the GLSL directives `#define NAME …`, `#undef`, `#ifdef`, `#ifndef`,
`#else` and `#endif` (BRDF Explorer drops those too, so a file that uses one did not compile
there; none of its files has a `#` line in its shader). A `color` becomes three parameters
NAME_r, NAME_g, NAME_b in [0, 1]; a `bool` is a switch (0 or 1) that fits leave alone. The
value is the vec3 BRDF returns (a colour lobe; the lab's renderers, fitter and plots take
its three channels, see AnalyticMaterial), L = wi and V = wo in the local frame (N = z,
X = x, Y = y).
"""

from __future__ import annotations

import re
from pathlib import Path

from brdflab.errors import BRDFLabError
from brdflab.io.numbers import ASCII_SPACE
from brdflab.models.base import Parameter
from brdflab.models.files import glsl_text
from brdflab.models.files.limits import MAX_ARRAY_ELEMENTS, check_parameters, number, parameter_name
from brdflab.models.files.model import FileModel, GlslParts, Origin, model_glsl_id

FORMAT = "BRDF Explorer"
SECTIONS = ("parameters", "shader", "isFunc")
COLOUR_COMPONENTS = ("r", "g", "b")


def read(path: Path, data: bytes, name: str | None = None) -> FileModel:
    """The model a `.brdf` file defines; BRDFLabError (one line naming the file and the line)
    if it is not a usable one. `name` is the registry name (default: the file's stem)."""
    try:
        text = data.decode("utf-8-sig")  # a byte-order mark (as Windows editors save) is not text
    except UnicodeDecodeError as e:
        raise BRDFLabError(f"not UTF-8 text (byte {e.start})", path) from None
    if "\x00" in text:
        raise BRDFLabError("not a text file (it holds NUL characters)", path)

    def fail(lineno: int, message: str) -> BRDFLabError:
        return BRDFLabError(f"line {lineno}: {message}", path)

    section = ""
    seen_sections: set[str] = set()
    params: list[Parameter] = []
    declared: list[tuple[str, str, tuple[str, ...]]] = []  # (kind, name, component names)
    shader: list[str] = []  # the file's lines, comments blanked (line numbers kept)
    shader_first_line = 0
    has_is_func = False
    kind_line = None
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if section == "shader":
            if line.startswith("::end"):
                if line.split()[1:2] != ["shader"]:
                    raise fail(lineno, "an ::end inside the shader section that is not ::end shader")
                section = ""
                continue
            shader.append("" if line.startswith("#") and not glsl_text.is_directive(line) else raw)
            continue
        if not line or line.startswith("#"):
            continue
        words = line.split()
        if words[0] == "::begin":
            if section:
                raise fail(lineno, f"::begin inside the {section} section")
            section = words[1] if len(words) > 1 else ""
            if section not in SECTIONS:
                raise fail(lineno, f"::begin names no known section ({', '.join(SECTIONS)})")
            if section in seen_sections:
                raise fail(lineno, f"a second {section} section")
            seen_sections.add(section)
            if section == "shader":
                shader_first_line = lineno + 1
            has_is_func |= section == "isFunc"
            continue
        if words[0] == "::end":
            if words[1:2] != [section]:
                raise fail(lineno, f"::end does not close the {section} section" if section else "::end outside any section")
            section = ""
            continue
        if section == "parameters":
            params.extend(_parameter(_ascii_words(raw), lambda m: fail(lineno, m), declared))
        elif section == "isFunc":
            continue
        elif kind_line is None:
            kind_line = words[0]
            if kind_line != "analytic":
                raise fail(lineno, "the first line is not 'analytic': only analytic BRDF Explorer files are models "
                                   "(measured ones are data: open them as materials)")
        else:
            raise fail(lineno, "text outside any section")
    if section:
        raise BRDFLabError(f"the {section} section is never closed (::end {section})", path)
    if "shader" not in seen_sections:
        raise BRDFLabError("no ::begin shader section", path)
    check_parameters(params, lambda m: BRDFLabError(m, path))

    code = "\n".join(shader)
    found = glsl_text.code_problem(code, MAX_ARRAY_ELEMENTS)
    if found:
        raise fail(shader_first_line + found[0] - 1, found[1])
    names = glsl_text.declared_names(code)
    if "BRDF" not in names:
        raise BRDFLabError("the shader defines no vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)", path)
    origin = Origin.of(path, data, FORMAT)
    prefix = model_glsl_id(name or path.stem, origin.sha256) + "_"
    globals_, sets = [], []
    k = 0
    for kind, pname, comps in declared:
        g = prefix + pname
        if kind == "float":
            globals_.append(f"float {g};")
            sets.append(f"{g} = p[{k}];")
        elif kind == "bool":
            globals_.append(f"bool {g};")
            sets.append(f"{g} = p[{k}] > 0.5;")
        else:
            globals_.append(f"vec3 {g};")
            sets.append(f"{g} = vec3(p[{k}], p[{k + 1}], p[{k + 2}]);")
        k += len(comps)
    renamed = glsl_text.guarded_loops(glsl_text.precise_calls(
        glsl_text.prefixed(code, names + [n for _, n, _ in declared], prefix)), prefix)
    # the globals go on the line before the shader's first, so compiler line numbers stay the file's
    library = " ".join(globals_) + "\n" + renamed
    call = " ".join(sets) + f" return {prefix}BRDF(wi, wo, vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0));"
    glsl = GlslParts(library, call, returns_colour=True, line_offset=shader_first_line - 1)
    uses_tangents = _uses_tangent_frame(code)
    warnings = []
    if has_is_func:
        warnings.append(f"{path.name}: its own importance sampling (isFunc) is not used; the lab's generic "
                        "sampler draws from the lobe's values instead")
    return FileModel(name or path.stem, path.stem, tuple(params), not uses_tangents, origin, glsl,
                     summary=f"BRDF Explorer file {path.name}", warnings=tuple(warnings))


def _ascii_words(line: str) -> list[str]:
    """A parameter line's words, split at ASCII white space only: str.split() would also split
    at (and so drop) a no-break space, and "0.5\u00a0" would be read as 0.5."""
    return [w for w in re.split(f"[{re.escape(ASCII_SPACE)}]+", line) if w]


def _parameter(words: list[str], fail, declared: list) -> list[Parameter]:
    kind = words[0]
    if kind == "float":
        if len(words) != 5:
            raise fail("a float parameter is 'float NAME MIN MAX DEFAULT'")
        name = parameter_name(words[1], fail)
        lo, hi, default = (number(w, what, fail) for w, what in zip(words[2:], ("MIN", "MAX", "DEFAULT")))
        declared.append(("float", name, (name,)))
        return [Parameter(name, default, lo, hi)]
    if kind == "bool":
        if len(words) != 3:
            raise fail("a bool parameter is 'bool NAME DEFAULT' (0 or 1)")
        name = parameter_name(words[1], fail)
        value = number(words[2], "DEFAULT", fail)
        if value not in (0.0, 1.0):
            raise fail(f"bool {name}: its default must be 0 or 1, not {words[2][:20]}")
        declared.append(("bool", name, (name,)))
        return [Parameter(name, value, 0.0, 1.0, doc="a switch: 0 or 1", kind="bool")]
    if kind == "color":
        if len(words) != 5:
            raise fail("a color parameter is 'color NAME R G B'")
        name = parameter_name(words[1], fail)
        rgb = [number(w, c.upper(), fail) for w, c in zip(words[2:], COLOUR_COMPONENTS)]
        comps = tuple(f"{name}_{c}" for c in COLOUR_COMPONENTS)
        for c, v in zip(comps, rgb):
            if not 0.0 <= v <= 1.0:
                raise fail(f"color {name}: {v:g} is outside [0, 1]")
        declared.append(("color", name, comps))
        return [Parameter(c, v, 0.0, 1.0, doc=f"{name}, {label}", kind="colour")
                for c, v, label in zip(comps, rgb, ("red", "green", "blue"))]
    raise fail("unknown parameter type (float, bool or color)")


def _uses_tangent_frame(code: str) -> bool:
    """Whether the BRDF reads its X or Y argument (else it cannot depend on φ alone: isotropic)."""
    toks = [t for k, t in glsl_text.tokens(code) if k not in ("space", "comment")]
    for i in range(len(toks) - 1):
        if toks[i] == "BRDF" and toks[i + 1] == "(" and i > 0 and toks[i - 1] == "vec3":
            j, args = i + 2, []
            while j < len(toks) and toks[j] != ")":
                if toks[j] not in ("vec3", ",", "in", "const"):
                    args.append(toks[j])
                j += 1
            if len(args) < 5:
                return True
            body_end = len(toks)
            return any(t in args[3:5] for t in toks[j:body_end])
    return True
