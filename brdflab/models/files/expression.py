"""BRDFLab's formula language, compiled to vectorised NumPy by a parser of our own.

BRDFLab 0.8.2 evaluated a model descriptor's `<Equation>` with muParser (the version it
bundles). What this reads is that language: statements separated by `;`, `name = expr`
assignments (and `+= -= *= /=`), the value of the last statement is the lobe's value;
operators by muParser's precedence, lowest first: `and or xor`, `< > <= >= == !=`, `+ -`,
`* /` and the sign `-x`, then `^` (left-associative, above the sign: `-x^2` is −(x²));
functions `sin cos tan asin acos atan sinh cosh tanh asinh acosh atanh log2 log10 ln exp
sqrt sign rint abs`, `log` (base 10, as that muParser defines it), `if(c, a, b)`, and `min
max sum avg` with any number of arguments; constants `_pi`, `_e`; the directions
`ux uy uz` (incident) and `vx vy vz` (outgoing) and their angles `theta_i phi_i theta_o
phi_o`. Nothing from the file is handed to Python's `eval`: the text is tokenised and
parsed here, names are looked up in the whitelist above and the model's parameters, and
the result is a tree of NumPy calls. Every error names the line and column.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from brdflab.errors import BRDFLabError

MAX_FORMULA_CHARS = 65_536
MAX_DEPTH = 200  # nesting of parentheses and operators: a hostile file cannot exhaust the stack

Values = Mapping[str, "np.ndarray | float"]
Node = Callable[[dict], np.ndarray]

DIRECTIONS = ("ux", "uy", "uz", "vx", "vy", "vz", "theta_i", "phi_i", "theta_o", "phi_o")
CONSTANTS = {"_pi": math.pi, "_e": math.e}

_UNARY = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "asin": np.arcsin, "acos": np.arccos, "atan": np.arctan,
    "sinh": np.sinh, "cosh": np.cosh, "tanh": np.tanh, "asinh": np.arcsinh, "acosh": np.arccosh,
    "atanh": np.arctanh, "log2": np.log2, "log10": np.log10, "log": np.log10, "ln": np.log, "exp": np.exp,
    "sqrt": np.sqrt, "sign": np.sign, "rint": np.rint, "abs": np.abs,
}
_VARIADIC = {
    "min": lambda a: np.minimum.reduce(np.broadcast_arrays(*a)),
    "max": lambda a: np.maximum.reduce(np.broadcast_arrays(*a)),
    "sum": lambda a: np.add.reduce(np.broadcast_arrays(*a)),
    "avg": lambda a: np.add.reduce(np.broadcast_arrays(*a)) / len(a),
}
FUNCTIONS = tuple(sorted({*_UNARY, *_VARIADIC, "if"}))

_BINARY = {
    "+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "^": np.power,
    "<": lambda a, b: (a < b) * 1.0, ">": lambda a, b: (a > b) * 1.0,
    "<=": lambda a, b: (a <= b) * 1.0, ">=": lambda a, b: (a >= b) * 1.0,
    "==": lambda a, b: (a == b) * 1.0, "!=": lambda a, b: (a != b) * 1.0,
    "and": lambda a, b: np.logical_and(a != 0, b != 0) * 1.0,
    "or": lambda a, b: np.logical_or(a != 0, b != 0) * 1.0,
    "xor": lambda a, b: np.logical_xor(a != 0, b != 0) * 1.0,
}
_LEVELS = (("and", "or", "xor"), ("<=", ">=", "==", "!=", "<", ">"), ("+", "-"), ("*", "/"))

_TOKEN = re.compile(r"""
    (?P<space>\s+)
  | (?P<number>(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?)
  | (?P<name>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<op>\+=|-=|\*=|/=|<=|>=|==|!=|[-+*/^<>=(),;])
""", re.VERBOSE)


@dataclass(frozen=True)
class Token:
    kind: str  # number, name, op, end
    text: str
    pos: int


class FormulaError(BRDFLabError):
    """A formula that does not parse; `pos` is the offset in the formula text."""

    def __init__(self, message: str, pos: int) -> None:
        super().__init__(message)
        self.pos = pos


def tokenize(text: str) -> list[Token]:
    if len(text) > MAX_FORMULA_CHARS:
        raise FormulaError(f"the formula has {len(text):,} characters (at most {MAX_FORMULA_CHARS:,})", 0)
    out, pos = [], 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            raise FormulaError(f"unexpected character {text[pos]!r}", pos)
        if m.lastgroup != "space":
            out.append(Token(m.lastgroup, m.group(), pos))
        pos = m.end()
    out.append(Token("end", "", len(text)))
    return out


@dataclass
class Formula:
    """A compiled formula: `evaluate(values)` → the value of its last statement."""

    statements: list[tuple[str | None, Node]]
    variables: tuple[str, ...]  # names it assigns

    def evaluate(self, values: Values) -> np.ndarray:
        env = dict(CONSTANTS)
        env.update(values)
        result: np.ndarray | float = 0.0
        with np.errstate(all="ignore"):
            for target, node in self.statements:
                result = node(env)
                if target is not None:
                    env[target] = result
        return np.asarray(result, float)


class _Parser:
    def __init__(self, text: str, inputs: tuple[str, ...]) -> None:
        self.tokens = tokenize(text)
        self.i = 0
        self.defined = set(inputs) | set(CONSTANTS)
        self.assigned: list[str] = []
        self.depth = 0

    # --- helpers
    @property
    def tok(self) -> Token:
        return self.tokens[self.i]

    def take(self) -> Token:
        t = self.tokens[self.i]
        self.i += 1
        return t

    def expect(self, text: str) -> Token:
        if self.tok.text != text:
            raise FormulaError(f"expected {text!r}, found {self._shown(self.tok)}", self.tok.pos)
        return self.take()

    @staticmethod
    def _shown(t: Token) -> str:
        return "the end of the formula" if t.kind == "end" else repr(t.text)

    # --- grammar
    def formula(self) -> Formula:
        statements = []
        while True:
            while self.tok.text == ";":
                self.take()
            if self.tok.kind == "end":
                break
            statements.append(self.statement())
            if self.tok.kind != "end" and self.tok.text != ";":
                raise FormulaError(f"expected ';' or the end of the formula, found {self._shown(self.tok)}", self.tok.pos)
        if not statements:
            raise FormulaError("the formula is empty", 0)
        if statements[-1][0] is not None:
            target = statements[-1][0]
            statements.append((None, lambda env, t=target: env[t]))
        return Formula(statements, tuple(dict.fromkeys(self.assigned)))

    def statement(self) -> tuple[str | None, Node]:
        nxt = self.tokens[self.i + 1]
        if self.tok.kind == "name" and nxt.text in ("=", "+=", "-=", "*=", "/="):
            name = self.take()
            if name.text in _UNARY or name.text in _VARIADIC or name.text == "if" or name.text in CONSTANTS:
                raise FormulaError(f"cannot assign to {name.text!r}", name.pos)
            op = self.take().text
            value = self.expression()
            if op != "=":
                if name.text not in self.defined:
                    raise FormulaError(f"{name.text!r} is used before it is assigned", name.pos)
                f = _BINARY[op[0]]
                value = (lambda env, f=f, n=name.text, v=value: f(env[n], v(env)))
            self.defined.add(name.text)
            self.assigned.append(name.text)
            return name.text, value
        return None, self.expression()

    def expression(self, level: int = 0) -> Node:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise FormulaError(f"the formula nests deeper than {MAX_DEPTH} levels", self.tok.pos)
        try:
            if level == len(_LEVELS):
                return self.signed()
            left = self.expression(level + 1)
            while self.tok.text in _LEVELS[level]:
                f = _BINARY[self.take().text]
                right = self.expression(level + 1)
                left = (lambda env, f=f, a=left, b=right: f(a(env), b(env)))
            return left
        finally:
            self.depth -= 1

    def signed(self) -> Node:
        if self.tok.text in ("-", "+"):
            sign = self.take().text
            self.depth += 1
            if self.depth > MAX_DEPTH:
                raise FormulaError(f"the formula nests deeper than {MAX_DEPTH} levels", self.tok.pos)
            inner = self.signed()
            self.depth -= 1
            return (lambda env, a=inner: np.negative(a(env))) if sign == "-" else inner
        return self.power()

    def power(self) -> Node:
        left = self.atom()
        while self.tok.text == "^":
            self.take()
            right = self.atom_or_signed_exponent()
            left = (lambda env, a=left, b=right: np.power(a(env), b(env)))
        return left

    def atom_or_signed_exponent(self) -> Node:
        if self.tok.text == "-":  # x^-2, as muParser reads it
            self.take()
            inner = self.atom()
            return lambda env, a=inner: np.negative(a(env))
        return self.atom()

    def atom(self) -> Node:
        t = self.take()
        if t.kind == "number":
            value = float(t.text)
            return lambda env, v=value: v
        if t.text == "(":
            inner = self.expression()
            self.expect(")")
            return inner
        if t.kind == "name":
            if self.tok.text == "(":
                return self.call(t)
            if t.text in _UNARY or t.text in _VARIADIC or t.text == "if":
                raise FormulaError(f"function {t.text!r} needs arguments in parentheses", t.pos)
            if t.text not in self.defined:
                raise FormulaError(f"unknown name {t.text!r} (not a parameter, a direction, a constant "
                                   "or a variable assigned before)", t.pos)
            return lambda env, n=t.text: env[n]
        raise FormulaError(f"unexpected {self._shown(t)}", t.pos)

    def call(self, name: Token) -> Node:
        if name.text not in _UNARY and name.text not in _VARIADIC and name.text != "if":
            raise FormulaError(f"unknown function {name.text!r} (known: {', '.join(FUNCTIONS)})", name.pos)
        self.expect("(")
        args = [self.expression()]
        while self.tok.text == ",":
            self.take()
            args.append(self.expression())
        self.expect(")")
        if name.text in _UNARY:
            if len(args) != 1:
                raise FormulaError(f"{name.text}() takes one argument, not {len(args)}", name.pos)
            f = _UNARY[name.text]
            return lambda env, f=f, a=args[0]: f(a(env))
        if name.text == "if":
            if len(args) != 3:
                raise FormulaError(f"if() takes three arguments (condition, then, else), not {len(args)}", name.pos)
            c, a, b = args
            return lambda env, c=c, a=a, b=b: np.where(np.asarray(c(env)) != 0, a(env), b(env))
        f = _VARIADIC[name.text]
        return lambda env, f=f, a=tuple(args): f([x(env) for x in a])


def compile_formula(text: str, inputs: tuple[str, ...]) -> Formula:
    """Parse a formula whose free names are `inputs` (parameters and directions)."""
    return _Parser(text, inputs).formula()


def direction_values(wi: np.ndarray, wo: np.ndarray) -> dict[str, np.ndarray]:
    """The names a formula reads for a batch of direction pairs (u = wi, v = wo); angles as
    BRDFLab's cart2spherical gives them (φ in [0, 2π))."""
    out = {}
    for prefix, w, angle in (("u", wi, "i"), ("v", wo, "o")):
        for k, axis in enumerate("xyz"):
            out[prefix + axis] = w[..., k]
        out[f"theta_{angle}"] = np.arccos(np.clip(w[..., 2], -1.0, 1.0))
        out[f"phi_{angle}"] = np.mod(np.arctan2(w[..., 1], w[..., 0]), 2.0 * math.pi)
    return out
