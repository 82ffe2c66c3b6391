"""File → Export: choose a file and a format, then write the shown material with the core exporter.

The renderers' formats (Mitsuba 3, MaterialX, glTF) may fit Principled on the way out, which
takes seconds: they are written by a worker process (a fit holds the GIL), with a progress
dialog that can cancel, and what the export could not carry is shown when it is done.
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QFileDialog, QMessageBox, QProgressDialog, QWidget

from brdflab.errors import BRDFLabError
from brdflab.export import PRINCIPLED_FORMATS, SUFFIXES, export_source, run_export
from brdflab.gui.background import ChildJob

FILTERS = {
    "MERL table (*.binary)": "merl",
    "BRDF Explorer (*.brdf)": "brdf-explorer",
    "GLSL function (*.glsl)": "glsl",
    "Mitsuba 3 scene, principled BSDF (*.xml)": "mitsuba",
    "MaterialX, Standard Surface and OpenPBR (*.mtlx)": "mtlx",
    "glTF 2.0 sphere (*.gltf *.glb)": "gltf",
}


class ExportJob(ChildJob):
    """An export in a worker process; `finished` carries the warnings, `failed` the reason."""

    what = "export"

    def __init__(self, parent: QWidget, source, fmt: str, path: Path, env, origin: Path | None = None) -> None:
        super().__init__(run_export, (source, fmt, str(path), env, origin), parent)
        self.path = path
        self.dialog = QProgressDialog(f"Exporting to {path.name}…", "Cancel", 0, 0, parent)
        self.dialog.setWindowModality(Qt.WindowModality.WindowModal)
        self.dialog.setMinimumDuration(0)
        self.dialog.canceled.connect(self.cancel.set)
        self.finished.connect(lambda warnings: self._done(parent, warnings))
        self.failed.connect(lambda message: self._done(parent, None, message))

    def _done(self, parent: QWidget, warnings: list[str] | None, message: str = "") -> None:
        self.dialog.reset()
        if warnings is None:
            if not self.cancel.is_set():
                QMessageBox.warning(parent, "Export", message)
        elif warnings:
            QMessageBox.information(parent, "Export", f"Wrote {self.path.name}. What it could not carry:\n\n"
                                    + "\n".join(f"• {w}" for w in warnings))


def export_dialog(parent: QWidget, source, folder: str = "", env=None,
                  origin: Path | None = None) -> Path | ExportJob | None:
    """Ask where and in which format to export `source` (a fit, else the material); write it.

    Returns the written path, the running job for the renderers' formats (`env`: the map of a
    Mitsuba scene), or None when cancelled or refused (the reason is shown). `origin`, the
    document's own file, is never written over, nor any file it reads (its measured data, its
    model files), whatever the file dialog allowed."""
    if source is None:
        QMessageBox.information(parent, "Export", "Nothing to export: open or fit a material first.")
        return None
    name, chosen = QFileDialog.getSaveFileName(parent, "Export", folder, ";;".join(FILTERS))
    if not name:
        return None
    fmt = FILTERS.get(chosen, "merl")
    path = Path(name)
    if not path.suffix:
        path = path.with_suffix("." + SUFFIXES[fmt])
    if fmt in PRINCIPLED_FORMATS:
        job = ExportJob(parent, source, fmt, path, env, origin)
        job.start()
        return job
    try:
        export_source(source, fmt, path, origin=origin)
    except (BRDFLabError, OSError) as e:
        QMessageBox.warning(parent, "Export", str(e))
        return None
    return path
