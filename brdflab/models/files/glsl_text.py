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

import ast
import operator
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
  | (?P<number>0[xX][0-9a-fA-F]+[uU]?|(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?[fFuU]?)
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
    return s if s[0].isalpha() and not s.startswith("gl_") else "m" + s  # gl_ names are GLSL's own


_DIRECTIVE = re.compile(r"\s*#\s*(?:(?:define|undef|ifdef|ifndef)\s+[A-Za-z_]\w*(?:\W.*)?|(?:else|endif)\s*(?://.*)?)$")


def is_directive(line: str) -> bool:
    """Whether a line is a GLSL preprocessor directive a model may use (`#define NAME …`,
    `#undef`, `#ifdef`, `#ifndef`, `#else`, `#endif`) rather than a `#` comment."""
    return bool(_DIRECTIVE.fullmatch(line))


def line_of(text: str, offset: int) -> int:
    """The 1-based line of character `offset` in `text`."""
    return text.count("\n", 0, offset) + 1


STEPS = "0steps"  # suffixes of the loop counter, its flag and its step function (a file's names,
OVER = "0over"   # prefix + identifier, never have a digit there)
STEP = "0step"


def guarded_loops(text: str, prefix: str) -> str:
    """`text` with every loop's condition (`for (…; COND; …)`, `while (COND)`, a do-while's
    tail) made `<prefix>0step() && (COND)`: each check of a loop condition counts a step, and
    past the bound the loop ends and a flag says so (model.glsl_source declares both). So a
    loop is never stopped silently by the driver (llvmpipe ends any loop at 65,536 iterations)
    and what a file's loops cost is counted by the GLSL itself."""
    toks = tokens(text)
    out: list[str] = []
    i = 0
    step = f"{prefix}{STEP}()"
    while i < len(toks):
        kind, t = toks[i]
        if kind == "name" and t in ("for", "while"):
            j = i + 1
            while j < len(toks) and toks[j][0] in ("space", "comment"):
                j += 1
            end = _closing(toks, j) if j < len(toks) and toks[j][1] == "(" else None
            if end is not None:
                inner = "".join(v for _, v in toks[j + 1:end])
                if t == "while":
                    inner = f"{step} && ({inner})"
                else:
                    parts = _split_top(toks[j + 1:end], ";")
                    if len(parts) == 3:
                        cond = parts[1].strip()
                        parts[1] = f" {step} && ({cond})" if cond else f" {step}"
                        inner = ";".join(parts)
                out.append(t + "".join(v for _, v in toks[i + 1:j]) + "(" + inner + ")")
                i = end + 1
                continue
        out.append(t)
        i += 1
    return "".join(out)


def _closing(toks: list[tuple[str, str]], start: int) -> int | None:
    """The index of the ')' that closes the '(' at `start`, or None."""
    depth = 0
    for k in range(start, len(toks)):
        if toks[k][1] == "(":
            depth += 1
        elif toks[k][1] == ")":
            depth -= 1
            if depth == 0:
                return k
    return None


def _split_top(toks: list[tuple[str, str]], sep: str) -> list[str]:
    """The tokens' text split at `sep` outside parentheses."""
    parts, depth, cur = [], 0, []
    for _, t in toks:
        depth += (t == "(") - (t == ")")
        if t == sep and depth == 0:
            parts.append("".join(cur))
            cur = []
        else:
            cur.append(t)
    return parts + ["".join(cur)]


_DEFINE_VALUE = re.compile(r"#\s*define\s+([A-Za-z_]\w*)[ \t]+([^\n]+)")
_CONST = re.compile(r"\bconst\s+(?:u?int|float)\s+([A-Za-z_]\w*)\s*=\s*([^;]+);")
MAX_CONSTANT_TOKENS = 64
_OPERATORS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
              ast.Mod: operator.mod}
_BIG = 1 << 62  # past this a size is only "too large" (no big-integer arithmetic on a file's say-so)


def array_elements(text: str, positioned: list | None = None) -> tuple[int | None, int]:
    """The elements all the arrays the code declares hold together (a declaration's
    `[SIZE]`, after a type or after a declared name; `a[N][M]` holds N·M), and the line of the
    largest; None for the count where a size is not a number the lab can read (literals,
    `const int` and `#define` names, + − × ÷ %, int()/float() casts). Read before compiling:
    Mesa takes tens of seconds and gigabytes to compile a large array. `positioned`: the
    text's `_positioned` tokens, where the caller has them."""
    consts: dict[str, float] = {}
    for m in [*_CONST.finditer(text), *_DEFINE_VALUE.finditer(text)]:
        value = _constant(tokens(m.group(2)), consts)
        if value is not None:
            consts[m.group(1)] = value
    toks = [tok[:3] for tok in positioned or _positioned(text) if tok[0] not in ("space", "comment", "pre")]
    types = set(TYPES) | set(re.findall(r"\bstruct\s+([A-Za-z_]\w*)", text))
    total, worst, worst_line = 0, -1, 1
    close, after = [len(toks)] * len(toks), len(toks)  # the next "]" at or after each token (one pass)
    for e in range(len(toks) - 1, -1, -1):
        after = e if toks[e][1] == "]" else after
        close[e] = after
    k = 0
    while k < len(toks):
        t, offset = toks[k][1], toks[k][2]
        prev = toks[k - 1][1] if k else ""
        named = k > 1 and toks[k - 1][0] == "name"
        certain = prev in types or (named and toks[k - 2][1] in types)  # float[N] …, float a[N]
        if t != "[" or not (certain or (named and toks[k - 2][1] == ",")):  # …, b[N]: a declaration or a call
            k += 1
            continue
        count = 1
        while k < len(toks) and toks[k][1] == "[":
            end = close[k]
            size = _constant([(a, b) for a, b, _ in toks[k + 1:end]], consts) if end > k + 1 else 0.0
            if size is None and certain:
                return None, line_of(text, offset)
            count = min(count * max(int(size or 0), 0), _BIG)
            k = end + 1
        total = min(total + count, _BIG)
        if count > worst:
            worst, worst_line = count, line_of(text, offset)
    return total, worst_line


def _positioned(text: str) -> list[tuple[str, str, int, bool]]:
    """The code's tokens with their offsets and whether they are a macro's; a `#define`'s
    replacement text is read as code where the directive stands (`#define ARR float
    a[100000000]` declares that array)."""
    out, offset = [], 0
    for kind, t in tokens(text):
        m = _DEFINE_VALUE.match(t) if kind == "pre" else None
        out += [(k, v, offset, True) for k, v in tokens(m.group(2))] if m else [(kind, t, offset, False)]
        offset += len(t)
    return out


def _constant(toks, consts: dict[str, float]) -> float | None:
    """The value of a constant integer expression, or None where it is not one the lab reads
    (nor one longer than MAX_CONSTANT_TOKENS: a size is a short expression)."""
    if len(toks) > MAX_CONSTANT_TOKENS:
        return None
    text = []
    for kind, t in toks:
        if kind in ("space", "comment"):
            continue
        if kind == "number":
            t = t.rstrip("uUfF") if not t.lower().startswith("0x") else t.rstrip("uU")
        elif kind == "name":
            if t in ("int", "uint", "float"):
                t = "float" if t == "float" else "int"
            elif t in consts:
                t = repr(consts[t])
            else:
                return None
        elif t not in "+-*/%()":
            return None
        text.append(t)
    try:
        tree = ast.parse(" ".join(text) or "x", mode="eval")
    except (SyntaxError, RecursionError, MemoryError):
        return None

    def ev(node):
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
            return node.value
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            v = ev(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.BinOp) and type(node.op) in _OPERATORS:
            a, b = ev(node.left), ev(node.right)
            if isinstance(node.op, (ast.Div, ast.Mod)) and b == 0:
                raise ValueError
            return max(-_BIG, min(_BIG, _OPERATORS[type(node.op)](a, b)))
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and len(node.args) == 1
                and not node.keywords):
            v = ev(node.args[0])
            return float(v) if node.func.id == "float" else int(max(-_BIG, min(_BIG, v)))
        raise ValueError

    try:
        return float(ev(tree.body))
    except (ValueError, OverflowError, RecursionError):
        return None


def code_problem(text: str, max_array_elements: int) -> tuple[int, str] | None:
    """What the lab refuses in a model's GLSL before compiling it, with its line (1-based in
    `text`): a loop inside a `#define` (guarded_loops guards loops where they are written), a
    `gl_` built-in variable, or arrays larger than `max_array_elements` together (or of a size
    the lab cannot read)."""
    positioned = _positioned(text)
    for kind, t, offset, macro in positioned:
        if macro and kind == "name" and t in ("for", "while", "do"):
            return line_of(text, offset), (f"a loop ({t}) inside a #define: the lab counts a loop's steps where "
                                           "the loop is written, so write it there")
        builtin = re.search(r"\bgl_\w*", t) if kind in ("name", "pre") else None
        if builtin:
            return line_of(text, offset), (f"{builtin.group()[:40]}: GLSL's gl_ variables belong to the shaders the "
                                           "lab compiles a model into; a model only computes its value from its "
                                           "directions and parameters")
    total, line = array_elements(text, positioned)
    if total is None:
        return line, "an array size the lab cannot read (write a number, or a const int or #define of one)"
    if total > max_array_elements:
        return line, (f"its arrays hold {total:,} elements (at most {max_array_elements:,}: a driver takes "
                      "minutes and gigabytes to compile a large array)")
    return None
