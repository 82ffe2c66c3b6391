"""GLSL from model files, made safe to link beside other models: every name a file declares
at its top level is given the model's own prefix.

BRDF Explorer's files were written for the desktop GLSL of their day and each was compiled
alone: they define `const float PI`, `sqr`, `smithG_GGX` … again and again, and helpers
whose names shadow built-ins. Linked into one shader with the lab's library and other
models, those names would clash; prefixed (`disney_3f2a_sqr`), they cannot. Nothing is
parsed beyond what finding top-level declarations needs: comments and numbers are skipped,
brace and parenthesis depth are tracked, and a name that follows a type at depth 0 (or a
comma in such a declaration) is declared there.
"""

from __future__ import annotations

import re

TYPES = frozenset(
    "void bool int uint float double".split()
    + [f"{p}vec{n}" for p in ("", "b", "i", "u", "d") for n in (2, 3, 4)]
    + [f"{p}mat{n}" for p in ("", "d") for n in (2, 3, 4)]
    + [f"{p}mat{a}x{b}" for p in ("", "d") for a in (2, 3, 4) for b in (2, 3, 4)]
)
_TOKEN = re.compile(r"""
    (?P<comment>//[^\n]*|/\*.*?\*/)
  | (?P<pre>\#[^\n]*)
  | (?P<number>(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?[fFuU]?|0[xX][0-9a-fA-F]+[uU]?)
  | (?P<name>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<space>\s+)
  | (?P<other>.)
""", re.VERBOSE | re.DOTALL)
_DEFINE = re.compile(r"#\s*define\s+([A-Za-z_]\w*)")


def tokens(text: str) -> list[tuple[str, str]]:
    return [(m.lastgroup, m.group()) for m in _TOKEN.finditer(text)]


def declared_names(text: str) -> list[str]:
    """Names declared at the top level: functions, globals, constants, structs, macros."""
    found: dict[str, None] = {}
    types = set(TYPES)
    depth = paren = 0
    in_decl = False
    prev = ""
    for kind, t in tokens(text):
        if kind in ("comment", "space"):
            continue
        if kind == "pre":
            m = _DEFINE.match(t)
            if m:
                found[m.group(1)] = None
            continue
        if kind == "name" and depth == 0 and paren == 0:
            if prev == "struct":
                types.add(t)
                found[t] = None
            elif prev in types or (in_decl and prev == ","):
                if t not in types:
                    found[t] = None
            if t in types:
                in_decl = True
        elif t == "{":
            depth += 1
        elif t == "}":
            depth = max(0, depth - 1)
        elif t == "(":
            paren += 1
        elif t == ")":
            paren = max(0, paren - 1)
        elif t == ";" and depth == 0:
            in_decl = False
        prev = t
    return list(found)


def prefixed(text: str, names, prefix: str) -> str:
    """`text` with every use of `names` (not a field or swizzle after '.') as prefix + name."""
    names = set(names)
    out = []
    prev = ""
    for kind, t in tokens(text):
        if kind == "name" and t in names and prev != ".":
            out.append(prefix + t)
        elif kind == "pre":
            out.append(re.sub(r"[A-Za-z_]\w*", lambda m: prefix + m.group() if m.group() in names else m.group(), t))
        else:
            out.append(t)
        if kind not in ("comment", "space"):
            prev = t
    return "".join(out)


PRECISE = {"acos": "precise_acos", "asin": "precise_asin", "atan": "precise_atan"}


def precise_calls(text: str) -> str:
    """Calls of acos/asin/atan made to the lab's full-precision versions (shaders/common.glsl):
    drivers may approximate them far below float precision, and a file model's render must
    agree with its CPU evaluation. Apply after `prefixed`: a file's own acos is then
    <prefix>acos, and keeps being called."""
    return "".join(PRECISE.get(t, t) if kind == "name" else t for kind, t in tokens(text))


def identifier(text: str) -> str:
    """A GLSL identifier made from any text (a model's name)."""
    s = re.sub(r"[^A-Za-z0-9]", "_", text).strip("_") or "model"
    s = re.sub(r"_+", "_", s)
    return s if s[0].isalpha() else "m" + s
