"""Open any file the lab understands as a BRDF source.

A source has `evaluate(wi, wo) → (N, C)`, `n_channels`, `isotropic` and `describe()`:
analytic materials, measured tables, raw samples and simulated materials all qualify.
"""

from __future__ import annotations

from pathlib import Path

from brdflab.material.albedo import energy_check
from brdflab.errors import BRDFLabError
from brdflab.material.analytic import AnalyticMaterial
from brdflab.sources.measured import read_measured
from brdflab.io.xmlio import BRDFDocument, MeasuredReference, SimulatedReference, load


def is_xml(path: Path) -> bool:
    return path.suffix.lower() == ".xml"


def resolve_measured(ref: MeasuredReference):
    """Load the data a measured XML material names, or say exactly what is missing."""
    if ref.missing:
        raise BRDFLabError(f"the measured data file {ref.name!r} named in the material is missing", ref.path)
    return read_measured(ref.path, ref.type)


def load_source(path: Path, fitting: int | None = None):
    """The source in `path`; with `fitting`, the K-th stored fit of an XML material."""
    path = Path(path)
    if not path.exists():
        raise BRDFLabError("no such file", path)
    if not is_xml(path):
        if fitting is not None:
            raise BRDFLabError("only XML materials store fittings", path)
        return read_measured(path)
    doc = load(path)
    if fitting is not None:
        if not 0 <= fitting < len(doc.fittings):
            raise BRDFLabError(f"--fitting {fitting}: the file stores {len(doc.fittings)} fitting(s)", path)
        return doc.fittings[fitting].material
    if isinstance(doc.material, MeasuredReference):
        return resolve_measured(doc.material)
    if isinstance(doc.material, SimulatedReference):
        from brdflab.simulation.material import open_simulated

        return open_simulated(doc.material, path)
    return doc.material


def describe_file(path: Path) -> dict:
    """What `brdflab info` prints: the material, its fittings, energy and warnings."""
    path = Path(path)
    if not path.exists():
        raise BRDFLabError("no such file", path)
    if not is_xml(path):
        return {"file": str(path), "material": read_measured(path).describe()}
    doc: BRDFDocument = load(path)
    info = doc.describe()
    if isinstance(doc.material, AnalyticMaterial):
        info["energy"] = energy_check(doc.material).as_dict()
    if isinstance(doc.material, SimulatedReference):
        from brdflab.simulation.material import describe_stored

        info["material"] = describe_stored(doc.material, path)
    for k, fit in enumerate(doc.fittings):
        info["fittings"][k]["energy"] = energy_check(fit.material).as_dict()
    return info
