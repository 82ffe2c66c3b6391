"""Numbers as the lab's files write them: ASCII digits only.

Python's float() and int() also take other scripts' digits ("３", "１.５"), underscores
("4_0" is 40) and, through str.strip(), any Unicode space around the number ("0.5\\u00a0"
is 0.5), which no format the lab reads means; these parsers refuse them. Their errors say
what is wrong without quoting the text (an error never carries bytes of a refused file).
"""

from __future__ import annotations

import re
import unicodedata

ASCII_SPACE = " \t\r\n\f\v"  # what may surround a number; str.strip() would also drop U+00A0, U+2009 …
DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[+-]?[0-9]+")
_SPECIAL = re.compile(r"[+-]?(?:inf|infinity|nan)", re.IGNORECASE)  # kept so a reader can say "not finite"


def ascii_number(text: str) -> float:
    """float(text) for a decimal number in ASCII digits (or inf/nan); ValueError saying why not."""
    t = text.strip(ASCII_SPACE)
    if DECIMAL.fullmatch(t) or _SPECIAL.fullmatch(t):
        return float(t)
    raise ValueError(refusal(t, "a number"))


def ascii_integer(text: str) -> int:
    """int(text) for a whole number in ASCII digits; ValueError saying why not."""
    t = text.strip(ASCII_SPACE)
    if _INTEGER.fullmatch(t):
        return int(t)
    raise ValueError(refusal(t, "an integer"))


def refusal(text: str, what: str) -> str:
    """'not a number' (`what`), and where the first non-ASCII character is and what kind it
    is (a space, a digit), which is invisible or looks like ASCII on screen; never the text."""
    if not text:
        return f"not {what} (empty)"
    k = next((i for i, c in enumerate(text) if not c.isascii()), None)
    if k is None:
        return f"not {what}"
    c = text[k]
    kind = "space" if c.isspace() or unicodedata.category(c).startswith("Z") else (
        "digit" if unicodedata.category(c) == "Nd" else "character")
    return f"not {what}: its character {k + 1} is a non-ASCII {kind} (numbers are written in ASCII)"
