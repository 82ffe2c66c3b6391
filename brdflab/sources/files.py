"""Open any file the lab understands as a BRDF source.

A source has `evaluate(wi, wo) → (N, C)`, `n_channels`, `isotropic` and `describe()`:
analytic materials, measured tables, raw samples and simulated materials all qualify.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

import numpy as np

from brdflab.material.albedo import check_cost, energy_check
from brdflab.errors import BRDFLabError
from brdflab.io.bounded import kind_problem
from brdflab.material.analytic import AnalyticMaterial
from brdflab.sources.measured import read_measured
from brdflab.io.xmlio import BRDFDocument, MeasuredReference, SimulatedReference, load

Warn = Callable[[str], None]
# `info` checks energy for at most this many lobe evaluations per file (≈ 10 anisotropic or
# 120 isotropic lobes, a few seconds); a material or fit beyond what is left is reported
# as not checked, never silently truncated.
ENERGY_CHECK_BUDGET = 12_000_000


def is_xml(path: Path) -> bool:
    return path.suffix.lower() == ".xml"


def resolve_measured(ref: MeasuredReference, warn: Warn | None = None):
    """Load the data a measured XML material names, or say exactly what is missing or refused
    (a file outside the material's folder); `warn` hears when the data no longer matches the
    checksum the material records."""
    if not os.path.exists(ref.path):  # False, not an error, for a name too long for the system
        raise BRDFLabError("the measured data file named in the material is missing", ref.path)
    check_openable(ref)
    table = read_measured(ref.path, ref.type)
    problem = ref.checksum_problem()
    if problem and warn is not None:
        warn(problem)
    return table


def check_openable(ref: MeasuredReference) -> None:
    """Raise, naming the data file, what every command (`info` too) says of one that is there
    but may not be opened: not a regular file, or refused by the folder policy."""
    try:
        problem = kind_problem(os.stat(ref.path).st_mode) or ref.confinement_problem()
    except OSError:  # not there (a name too long for the system): the caller says it is missing
        return
    if problem:
        raise BRDFLabError(problem, ref.path)


def is_model_file(path: Path) -> bool:
    """A BRDF Explorer `.brdf` or a BRDFLab model descriptor: a model, not a material."""
    from brdflab.models.files.library import is_model_path

    return is_model_path(path)


def model_file_material(path: Path) -> AnalyticMaterial:
    """A model file standing where a material does: one lobe at the file's defaults, scale 1
    in each of three channels (Linear)."""
    from brdflab.material.analytic import Lobe
    from brdflab.models.files.library import load_model_file

    model = load_model_file(path)
    return AnalyticMaterial(model.xml_name, "Linear", 3, [Lobe(model, model.defaults(), [1.0, 1.0, 1.0])])


def load_source(path: Path, fitting: int | None = None, warn: Warn | None = None):
    """The source in `path`; with `fitting`, the K-th stored fit of an XML material. `warn`
    hears problems that do not stop the work (a measured file that fails its checksum). A
    model file (.brdf, model descriptor) is one lobe of its model at its defaults."""
    path = Path(path)
    if not path.exists():
        raise BRDFLabError("no such file", path)
    if is_model_file(path):
        if fitting is not None:
            raise BRDFLabError("a model file stores no fittings", path)
        material = model_file_material(path)
        undefined = material.lobes[0].model.undefined
        if undefined and warn is not None:
            warn(undefined)  # where the file is undefined (its values taken as 0 there)
        return material
    if not is_xml(path):
        if fitting is not None:
            raise BRDFLabError("only XML materials store fittings", path)
        return read_measured(path)
    doc = load(path)
    for message in doc.model_warnings if warn is not None else ():
        warn(f"{path}: {message}")
    if fitting is not None:
        if not 0 <= fitting < len(doc.fittings):
            raise BRDFLabError(f"--fitting {fitting}: the file stores {len(doc.fittings)} fitting(s)", path)
        return doc.fittings[fitting].material
    if isinstance(doc.material, MeasuredReference):
        return resolve_measured(doc.material, warn)
    if isinstance(doc.material, SimulatedReference):
        from brdflab.simulation.material import open_simulated

        return open_simulated(doc.material, path)
    return doc.material


def evaluate_in_chunks(source, wi: np.ndarray, wo: np.ndarray, chunk: int = 1 << 18) -> np.ndarray:
    """source.evaluate over (N, 3) pairs a chunk at a time, so temporaries stay small for any N."""
    if len(wi) <= chunk:
        return source.evaluate(wi, wo)
    return np.concatenate([source.evaluate(wi[s:s + chunk], wo[s:s + chunk]) for s in range(0, len(wi), chunk)])


def describe_file(path: Path) -> dict:
    """What `brdflab info` prints: the material, its fittings, energy and warnings.

    Energy checks share ENERGY_CHECK_BUDGET; what does not fit says so (and a warning
    says how many were skipped), so a 20,000-lobe file is described in seconds."""
    path = Path(path)
    if not path.exists():
        raise BRDFLabError("no such file", path)
    if is_model_file(path):
        material = model_file_material(path)
        model = material.lobes[0].model
        return {"file": str(path), "model": model.describe(), "material": material.describe(),
                "energy": energy_check(material).as_dict(), "fittings": [], "warnings": list(model.warnings)}
    if not is_xml(path):
        return {"file": str(path), "material": read_measured(path).describe()}
    doc: BRDFDocument = load(path)
    if isinstance(doc.material, MeasuredReference):
        check_openable(doc.material)  # as the other commands do, before a byte of it is hashed
    info = doc.describe()
    budget = EnergyBudget(ENERGY_CHECK_BUDGET)
    if isinstance(doc.material, AnalyticMaterial):
        info["energy"] = budget.check(doc.material)
    if isinstance(doc.material, SimulatedReference):
        from brdflab.simulation.material import describe_stored

        info["material"] = describe_stored(doc.material, path)
    if isinstance(doc.material, MeasuredReference):
        problem = doc.material.checksum_problem()
        if problem:
            info["warnings"].append(problem)
    for k, fit in enumerate(doc.fittings):
        info["fittings"][k]["energy"] = budget.check(fit.material)
    if budget.skipped:
        info["warnings"].append(f"energy check skipped for {budget.skipped} of {budget.asked} materials "
                                f"(more lobes than the check covers in one file; see \"energy\")")
    return info


class EnergyBudget:
    """Energy checks until their summed cost (lobe evaluations) would exceed `total`."""

    def __init__(self, total: int) -> None:
        self.left = total
        self.asked = 0
        self.skipped = 0

    def check(self, material: AnalyticMaterial) -> dict:
        self.asked += 1
        cost = check_cost(material)
        if cost > self.left:
            self.skipped += 1
            return {"checked": False,
                    "reason": f"not checked: {len(material.lobes):,} lobes need {cost:,} lobe evaluations, "
                              f"more than the {self.left:,} left of the {ENERGY_CHECK_BUDGET:,} that info "
                              "spends per file"}
        self.left -= cost
        return energy_check(material).as_dict()
