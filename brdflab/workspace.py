"""What the desktop window works on, without Qt: the document, its source and fits.

The GUI only shows and edits this object; saving, fitting and rendering read it, so no
widget ever holds the only copy of anything a file or a fit needs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import os
from pathlib import Path

from brdflab.errors import BRDFLabError
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.sources.measured import read_measured
from brdflab.sources.files import is_xml, resolve_measured
from brdflab.io.xmlio import BRDFDocument, Fitting, MeasuredReference, SimulatedReference, load, save

OPEN_FILTER = "Materials and measurements (*.xml *.binary *.slice *.txt *.csv *.carpaint *.bin);;All files (*)"


def default_material() -> AnalyticMaterial:
    """The embedded default scene's material: Lambertian + isotropic Lafortune (BRDFLab Fig. 2)."""
    from brdflab.io.resources import data_dir

    return load(data_dir("materials") / "fig2_lambertian_lafortune.xml").material


@dataclass
class Workspace:
    document: BRDFDocument
    path: Path | None = None
    source: object | None = None  # the measured data of a measured document
    shown_fit: int | None = None
    guess: AnalyticMaterial | None = None  # the next fit's initial guess (measured documents)
    dirty: bool = False
    messages: list[str] = field(default_factory=list)

    # --- files --------------------------------------------------------------------------------
    @classmethod
    def new(cls) -> "Workspace":
        return cls(BRDFDocument(default_material()))

    @classmethod
    def open(cls, path: Path) -> "Workspace":
        """An XML material (its data too, when it names some) or a bare measured file."""
        path = Path(path)
        if not path.exists():
            raise BRDFLabError("no such file", path)
        if is_xml(path):
            doc = load(path)
            ws = cls(doc, path, messages=list(doc.warnings))
            if isinstance(doc.material, MeasuredReference):
                try:
                    ws.source = resolve_measured(doc.material)
                except BRDFLabError as e:
                    ws.messages.append(str(e))  # the fits stay usable without the data
                else:
                    ref = doc.material
                    if ref.sha256 and ref.current_sha256() != ref.sha256:
                        ws.messages.append(f"{ref.path}: the data file changed since its fits were made (sha256 differs)")
            if isinstance(doc.material, SimulatedReference):
                from brdflab.simulation.material import open_simulated

                ws.source = open_simulated(doc.material, path)  # from the cache when `simulate` made it
            if doc.fittings:
                ws.shown_fit = len(doc.fittings) - 1
            return ws
        data = read_measured(path)
        ref = MeasuredReference(data.source_type, path.name, path.parent)
        ref.sha256 = ref.current_sha256()
        return cls(BRDFDocument(ref), None, data, dirty=True)

    @classmethod
    def simulated(cls, spec) -> "Workspace":
        """A new, unsaved document holding the simulated material `spec` (its table built or cached)."""
        from brdflab.simulation.material import reference_of, simulated_material

        return cls(BRDFDocument(reference_of(spec)), None, simulated_material(spec), dirty=True)

    @property
    def data_missing(self) -> bool:
        """A measured material whose data file could not be loaded (its fits still work)."""
        return isinstance(self.document.material, MeasuredReference) and self.source is None

    def locate_data(self, data_path: Path) -> None:
        """Point a measured material at its data file found elsewhere, and load it."""
        ref = self.document.material
        if not isinstance(ref, MeasuredReference):
            raise BRDFLabError("this material names no measured data file")
        base = self.path.parent if self.path else None
        name = os.path.relpath(Path(data_path).resolve(), base.resolve()) if base else str(Path(data_path).resolve())
        moved = MeasuredReference(ref.type, Path(name).as_posix(), base, ref.sha256, ref.extra, ref.source)
        source = resolve_measured(moved)
        self.document.material, self.source = moved, source
        self.messages = []
        if ref.sha256 and moved.current_sha256() != ref.sha256:
            self.messages.append(f"{moved.path}: not the data file its fits were made from (sha256 differs)")
        self.dirty = True

    def save(self, path: Path | None = None) -> Path:
        target = Path(path) if path else self.path
        if target is None:
            raise BRDFLabError("choose a file name to save to")
        empty = self.analytic.channels_without_lobes() if self.analytic is not None and self.analytic.lobes else []
        if empty:  # the reader refuses such a file: say so now, not when it is opened again
            raise BRDFLabError(f"a Fixed material needs a lobe for every channel; add one for channel "
                               f"{', '.join(map(str, empty))} before saving")
        save(self.document, target)
        self.path = target
        self.dirty = False
        return target

    # --- what is shown --------------------------------------------------------------------------
    @property
    def origin(self) -> Path | None:
        """The file this document came from: its XML, or the bare measured file it opened
        (an export never writes over it); None for a new document."""
        if self.path is not None:
            return self.path
        material = self.document.material
        return material.path if isinstance(material, MeasuredReference) else None

    @property
    def title(self) -> str:
        """The file's name; before a measured file's material is saved, the data's name."""
        ref = self.document.material
        if self.path:
            name = self.path.name
        elif isinstance(ref, MeasuredReference):
            name = f"untitled ({Path(ref.name).name})"
        else:
            name = "untitled"
        return name + (" *" if self.dirty else "")

    @property
    def analytic(self) -> AnalyticMaterial | None:
        m = self.document.material
        return m if isinstance(m, AnalyticMaterial) else None

    def original(self):
        """The source every view shows as 'original': the analytic material or the data."""
        return self.analytic if self.analytic is not None else self.source

    def editable(self) -> AnalyticMaterial | None:
        """What the material editor edits: the analytic material, or for measured data the
        initial guess of the next fit."""
        return self.analytic if self.analytic is not None else self.guess

    def fitted(self) -> AnalyticMaterial | None:
        if self.shown_fit is None or not (0 <= self.shown_fit < len(self.document.fittings)):
            return None
        return self.document.fittings[self.shown_fit].material

    # --- edits (each replaces whole values, so undo can swap them back) -----------------------------
    def replace_material(self, material: AnalyticMaterial) -> None:
        """Replace what the editor edits (the guess of a measured document is not saved)."""
        material.validate()
        if self.analytic is None:
            self.guess = material
            return
        self.document.material = material
        self.dirty = True

    def replace_fittings(self, fittings: list[Fitting], shown: int | None) -> None:
        self.document.fittings = fittings
        self.shown_fit = shown
        self.dirty = True


def with_parameter(material: AnalyticMaterial, lobe: int, name: str, value: float) -> AnalyticMaterial:
    out = material.copy()
    out.lobes[lobe].params[name] = float(value)
    return out


def with_scale(material: AnalyticMaterial, lobe: int, channel: int, value: float) -> AnalyticMaterial:
    out = material.copy()
    out.lobes[lobe].scale[channel] = float(value)
    return out


def with_lobe_added(material: AnalyticMaterial, model_name: str) -> AnalyticMaterial:
    out = material.copy()
    if out.combination == "Linear":
        out.lobes.append(Lobe.create(model_name, [0.1] * out.n_channels))
    else:
        out.lobes.extend(Lobe.create(model_name, [0.1], c) for c in range(out.n_channels))
    return out


def with_lobe_removed(material: AnalyticMaterial, index: int) -> AnalyticMaterial:
    out = material.copy()
    del out.lobes[index]
    return out


def with_lobe_moved(material: AnalyticMaterial, index: int, delta: int) -> AnalyticMaterial:
    out = material.copy()
    j = max(0, min(len(out.lobes) - 1, index + delta))
    out.lobes.insert(j, out.lobes.pop(index))
    return out


def with_combination(material: AnalyticMaterial, combination: str) -> AnalyticMaterial:
    """Linear ↔ Fixed: Linear lobes become one lobe per channel (scale → value) and back
    (the channel-0 lobes, each channel's value as its scale)."""
    if combination == material.combination:
        return material.copy()
    if combination == "Fixed":
        lobes = [Lobe(l.model, dict(l.params), [l.scale[c]], c) for c in range(material.n_channels) for l in material.lobes]
    else:
        # the i-th lobe of every channel becomes one Linear lobe (channel 0's parameters)
        per_channel = [[l for l in material.lobes if l.channel == c] for c in range(material.n_channels)]
        lobes = []
        for i, lobe in enumerate(per_channel[0]):
            scale = [ch[i].scale[0] if i < len(ch) else 0.0 for ch in per_channel]
            lobes.append(Lobe(lobe.model, dict(lobe.params), scale))
    return AnalyticMaterial(material.name, combination, material.n_channels, lobes, list(material.extra),
                            material.source)


def with_channels(material: AnalyticMaterial, n: int) -> AnalyticMaterial:
    if n < 1:
        raise BRDFLabError("a material needs at least one channel")
    out = material.copy()
    out.n_channels = n
    if out.combination == "Linear":
        for lobe in out.lobes:
            lobe.scale = (lobe.scale + [lobe.scale[-1]] * n)[:n]
    else:  # new channels start with copies of the last channel's lobes, as Linear copies its scale
        last = max(l.channel for l in out.lobes) if out.lobes else 0
        out.lobes = [l for l in out.lobes if l.channel < n] + [
            Lobe(l.model, dict(l.params), list(l.scale), c) for c in range(last + 1, n)
            for l in material.lobes if l.channel == last]
    return out
