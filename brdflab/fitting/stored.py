"""Fits as documents: start materials, sources, and <Fitting> elements in XML files."""

from __future__ import annotations

from pathlib import Path

from brdflab.errors import BRDFLabError
from brdflab.fitting.lm import FitResult, check_fit_size, material_from_lobes
from brdflab.material.analytic import AnalyticMaterial
from brdflab.sources.measured import MeasuredTable, RawSamples
from brdflab.sources.files import is_xml
from brdflab.io.xmlio import BRDFDocument, Fitting, MeasuredReference, load


def initial_material(lobes: list[str] | None, combination: str, n_channels: int,
                     init: Path | None, init_fitting: int | None) -> AnalyticMaterial:
    """The starting point of a fit: an --init file (its chosen or last fitting, else its
    material), or the named lobes at their model defaults."""
    if init is not None:
        doc = load(init)
        if init_fitting is not None:
            if not 0 <= init_fitting < len(doc.fittings):
                raise BRDFLabError(f"the file stores {len(doc.fittings)} fitting(s), not {init_fitting + 1}", init)
            start = doc.fittings[init_fitting].material
        elif doc.fittings:
            start = doc.fittings[-1].material
        elif isinstance(doc.material, AnalyticMaterial):
            start = doc.material
        else:
            raise BRDFLabError("--init needs an analytic material or a stored fitting", init)
        check_fit_size(len(start.lobe_models()), init)
        if lobes and start.lobe_models() != lobes:
            raise BRDFLabError(f"--lobes {','.join(lobes)} differ from the lobes of the initial guess", init)
        if start.n_channels != n_channels:
            raise BRDFLabError(f"the initial guess has {start.n_channels} channels, the source {n_channels}", init)
        return start.copy()
    if not lobes:
        raise BRDFLabError("name the lobes to fit (--lobes A,B,...) or give an initial guess (--init FILE)")
    return material_from_lobes(lobes, combination, n_channels)


def document_for(source_path: Path, source) -> BRDFDocument:
    """The document a fit of `source_path` is stored in: the XML file itself, or a new
    measured material that names the data file (with its sha256)."""
    if is_xml(source_path):
        return load(source_path)
    if isinstance(source, (MeasuredTable, RawSamples)):
        ref = MeasuredReference(source.source_type, source_path.name, source_path.parent)
        ref.sha256 = ref.current_sha256()
        return BRDFDocument(ref, path=None)
    raise BRDFLabError("cannot store a fit of this source", source_path)


def fitting_of(result: FitResult, optimizer: str = "LevenbergMarquardt") -> Fitting:
    """The <Fitting> that stores a fit result."""
    return Fitting(result.material, result.error, False, optimizer, result.statistics())


def append_fitting(doc: BRDFDocument, result: FitResult) -> Fitting:
    fitting = fitting_of(result)
    doc.fittings.append(fitting)
    return fitting

