"""One XML document per source holding every batch fit of it as a <Fitting>.

Each batch fitting carries its pair key in <FitStatistics batch_key="..">, so a rerun finds
the fits of earlier runs whatever the file names, and replaces a pair's fit instead of
adding a second one.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from brdflab.batch.tasks import stored_key
from brdflab.io.xmlio import BRDFDocument, Fitting, MeasuredReference, load, save
from brdflab.sources.files import is_xml

KEY = "batch_key"


class FitStore:
    """The fits by pair key, and the XML file name of each source."""

    def __init__(self, folder: Path, sources: list[str]) -> None:
        self.folder = folder
        self.fittings: dict[str, Fitting] = {}
        self.own: set[str] = set()  # keys fitted by this process: they win over the stored fits
        self.names = _file_names(sources)
        self.source_types: dict[str, str | None] = {}

    def load_existing(self, warn) -> None:
        """Collect the batch fittings stored in the folder by earlier runs (or, when called
        again under the folder's lock, by a batch running beside this one), keeping this
        process's own."""
        for path in sorted(self.folder.glob("*.xml")):
            try:
                doc = load(path)
            except Exception as e:  # an unreadable old file only loses its fits, which are then redone
                warn(f"{path}: ignored ({e})")
                continue
            for fitting in doc.fittings:
                if fitting.statistics.get(KEY) in (None, ""):
                    continue
                key = fitting.statistics[KEY] = stored_key(fitting.statistics[KEY])
                if key not in self.own:
                    self.fittings[key] = fitting
            if isinstance(doc.material, MeasuredReference) and doc.path is not None:
                source = str(doc.material.path.resolve())
                self.source_types.setdefault(source, doc.material.type)

    def add(self, key: str, source: str, fitting: Fitting, source_type: str | None) -> None:
        fitting.statistics[KEY] = key
        self.fittings[key] = fitting
        self.own.add(key)
        if source_type:
            self.source_types[source] = source_type

    def write(self, source: str, rows: list[dict], sha256: str) -> Path | None:
        """Rewrite the source's XML with the fits of its finished rows (atomically)."""
        fits = [self.fittings[r["key"]] for r in rows if r["status"] != "failed" and r["key"] in self.fittings]
        if not fits:
            return None
        path = Path(source)
        if is_xml(path):
            doc = load(path)
            doc.fittings = [f for f in doc.fittings if KEY not in f.statistics] + fits
        else:
            ref = MeasuredReference(self.source_types.get(source) or "MERLBRDFDatabase", path.name, path.parent, sha256)
            doc = BRDFDocument(ref, fits)
        out = self.folder / self.names[source]
        save(doc, out)
        return out


def _file_names(sources: list[str]) -> dict[str, str]:
    """`stem.xml`, or `stem-<parent folder>.xml` when two sources share a stem."""
    stems: dict[str, int] = {}
    for s in sources:
        stems[Path(s).stem] = stems.get(Path(s).stem, 0) + 1
    names = {}
    for s in sources:
        p = Path(s)
        names[s] = f"{p.stem}.xml" if stems[p.stem] == 1 else f"{p.stem}-{p.parent.name}-{hashlib.sha256(s.encode()).hexdigest()[:6]}.xml"
    return names
