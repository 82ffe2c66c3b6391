"""Numbers as the lab's files write them: ASCII digits only.

Python's float() and int() also take other scripts' digits ("３", "１.５") and underscores
("4_0" is 40), which no format the lab reads means; these parsers refuse them.
"""

from __future__ import annotations

import re

DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[+-]?[0-9]+")
_SPECIAL = re.compile(r"[+-]?(?:inf|infinity|nan)", re.IGNORECASE)  # kept so a reader can say "not finite"


def ascii_number(text: str) -> float:
    """float(text) for a decimal number in ASCII digits (or inf/nan); ValueError otherwise."""
    t = text.strip()
    if DECIMAL.fullmatch(t) or _SPECIAL.fullmatch(t):
        return float(t)
    raise ValueError(f"not an ASCII decimal number: {t[:32]!r}")


def ascii_integer(text: str) -> int:
    """int(text) for a whole number in ASCII digits; ValueError otherwise."""
    t = text.strip()
    if _INTEGER.fullmatch(t):
        return int(t)
    raise ValueError(f"not an ASCII whole number: {t[:32]!r}")
