"""Every simulated kind, declared once: its library (the XML <Type>), parameters and doc."""

from __future__ import annotations

from dataclasses import dataclass

from brdflab.errors import BRDFLabError
from brdflab.simulation import microgeometry, scatmech
from brdflab.simulation.params import SimParameter, complete


@dataclass(frozen=True)
class SimulatedKind:
    name: str
    library: str  # "SCATMECH" or "RayBounce": what BRDFLab files name in <Type>
    doc: str
    parameters: tuple[SimParameter, ...]

    @property
    def available(self) -> bool:
        return self.library != scatmech.LIBRARY or scatmech.available()

    @property
    def uses_rays(self) -> bool:
        """Whether the seed and the ray count matter (the ray-bounce simulator)."""
        return self.library == microgeometry.LIBRARY

    def complete(self, given: dict) -> dict:
        return complete(self.parameters, given, self.name)

    def describe(self) -> dict:
        return {"kind": self.name, "library": self.library, "doc": self.doc, "available": self.available,
                "parameters": [p.describe() for p in self.parameters]}


KINDS: dict[str, SimulatedKind] = {
    **{name: SimulatedKind(name, scatmech.LIBRARY, doc, params + scatmech.WAVELENGTHS)
       for name, (_, params, doc) in scatmech.MODELS.items()},
    **{name: SimulatedKind(name, microgeometry.LIBRARY, microgeometry.DOCS[name], geometry + microgeometry.FACET_PARAMETERS)
       for name, geometry in microgeometry.GEOMETRY_PARAMETERS.items()},
}

LIBRARIES = frozenset(k.library for k in KINDS.values())


def get_kind(name: str) -> SimulatedKind:
    try:
        return KINDS[name]
    except KeyError:
        raise BRDFLabError(f"unknown simulated kind {name!r} (one of {', '.join(KINDS)})") from None
