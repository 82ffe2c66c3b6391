"""What a model file may declare, checked before anything is built from it."""

from __future__ import annotations

import math
import re
from typing import Callable

from brdflab.errors import BRDFLabError
from brdflab.io.numbers import ascii_number  # ASCII digits only
from brdflab.models.base import Parameter

MAX_MODEL_BYTES = 1 << 20  # BRDF Explorer's largest file (disney.brdf) is 4 KB
FLOAT32_MAX = 3.4028234663852886e38  # numpy.finfo(numpy.float32).max, without importing NumPy here
# a model's loop-condition checks, all its loops together, per evaluation: llvmpipe ends every loop of a
# shader invocation once they have run 65,535 iterations together (measured: two loops of 40,000 gave
# 65,534; 300 × 300 nested, 65,101); the headroom is the lab's own loops around the model's
MAX_LOOP_STEPS = 65000
MAX_ARRAY_ELEMENTS = 1024  # a lobe needs small tables; Mesa compiled 10,000 floats in 19 s of CPU, 10⁸ in 40 s and 2.4 GB
MAX_PARAMETERS = 32  # scalars: the renderers pass a lobe's parameters as float p[NP], NP ≤ 32 (render.glsl)
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,63}")
_GLSL_RESERVED = frozenset("""
attribute const uniform varying layout centroid flat smooth noperspective patch sample break continue do
for while switch case default if else subroutine in out inout true false invariant discard return lowp
mediump highp precision struct common partition active asm class union enum typedef template this
resource goto inline noinline public static extern external interface long short half fixed unsigned
superp input output filter sizeof cast namespace using main
""".split())


def number(text: str | None, what: str, fail: Callable[[str], BRDFLabError]) -> float:
    """A finite number written in ASCII digits (no locale digits, underscores or Unicode
    spaces), within float32's range: the renderers pass parameters to GLSL as float, and a
    bound of ±1e308 became ±inf there (NumPy's RuntimeWarning, then a fit over an infinite range)."""
    if text is None:
        raise fail(f"missing {what}")
    try:
        v = ascii_number(text)
    except ValueError as e:
        raise fail(f"{what} is {e}") from None
    if not math.isfinite(v):
        raise fail(f"{what} is not finite")
    if abs(v) > FLOAT32_MAX:
        raise fail(f"{what} is beyond ±{FLOAT32_MAX:.3g}, the largest float the renderers' GLSL holds")
    return v


def parameter_name(text: str, fail: Callable[[str], BRDFLabError]) -> str:
    from brdflab.models.files.glsl_text import TYPES

    t = text.strip()
    if not _IDENT.fullmatch(t) or t in _GLSL_RESERVED or t in TYPES or t.startswith("gl_") or "__" in t:
        raise fail("a parameter name must be 1-64 letters, digits or '_' (not starting with a digit, "
                   "no '__'), and not a GLSL keyword")
    return t


def check_parameters(params: list[Parameter], fail: Callable[[str], BRDFLabError]) -> None:
    """Refuse duplicate names, too many parameters, min > max and defaults outside the bounds."""
    if len(params) > MAX_PARAMETERS:
        raise fail(f"{len(params)} parameters (counting each colour as three) is more than the "
                   f"{MAX_PARAMETERS} a lobe may have")
    seen = set()
    for p in params:
        if p.name in seen:
            raise fail(f"parameter {p.name!r} is declared twice")
        seen.add(p.name)
        if p.lower > p.upper:
            raise fail(f"parameter {p.name!r}: its minimum {p.lower:g} is above its maximum {p.upper:g}")
        if not p.lower <= p.default <= p.upper:
            raise fail(f"parameter {p.name!r}: its default {p.default:g} is outside [{p.lower:g}, {p.upper:g}]")
