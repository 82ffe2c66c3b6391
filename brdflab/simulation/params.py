"""Parameters of simulated kinds, each declared once: name, default, bounds, unit and doc."""

from __future__ import annotations

import math
from dataclasses import dataclass

from brdflab.errors import BRDFLabError
from brdflab.io.numbers import ascii_number


@dataclass(frozen=True)
class SimParameter:
    """One parameter of a simulated kind. `choices` makes it a word (e.g. the facet BRDF)."""

    name: str
    default: float | str
    lower: float | None = None
    upper: float | None = None
    unit: str = ""
    doc: str = ""
    choices: tuple[str, ...] = ()
    integer: bool = False

    def parse(self, text: str | float) -> float | str:
        """The value of `text` for this parameter, or BRDFLabError saying why not."""
        if self.choices:
            word = str(text).strip()
            if word not in self.choices:
                raise BRDFLabError(f"{self.name}={text!r}: expected one of {', '.join(self.choices)}")
            return word
        try:
            value = ascii_number(text) if isinstance(text, str) else float(text)
        except TypeError:
            raise BRDFLabError(f"{self.name} is not a number") from None
        except ValueError as e:  # a file's text: ASCII digits only, and never quoted
            raise BRDFLabError(f"{self.name} is {e}") from None
        if not math.isfinite(value):
            raise BRDFLabError(f"{self.name}={value} must be finite")
        if not (self.lower <= value <= self.upper):
            raise BRDFLabError(f"{self.name}={value:g} is outside [{self.lower:g}, {self.upper:g}]")
        if self.integer:
            if value != int(value):
                raise BRDFLabError(f"{self.name}={value:g} must be an integer")
            return int(value)
        return value

    def describe(self) -> dict:
        out = {"name": self.name, "default": self.default, "unit": self.unit, "doc": self.doc}
        if self.choices:
            out["choices"] = list(self.choices)
        else:
            out.update(lower=self.lower, upper=self.upper)
        return out


def complete(parameters: tuple[SimParameter, ...], given: dict, kind: str) -> dict:
    """Every parameter's value: the given ones checked against their bounds, others at default."""
    names = {p.name for p in parameters}
    unknown = sorted(set(given) - names)
    if unknown:
        raise BRDFLabError(f"{kind} has no parameter {', '.join(unknown)} (it has {', '.join(sorted(names))})")
    return {p.name: p.parse(given[p.name]) if p.name in given else p.default for p in parameters}
