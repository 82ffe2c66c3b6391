"""File → Export: choose a file and a format, then write the shown material with the core exporter."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import QFileDialog, QMessageBox, QWidget

from brdflab.errors import BRDFLabError
from brdflab.export import export_source

FILTERS = {
    "MERL table (*.binary)": "merl",
    "BRDF Explorer (*.brdf)": "brdf-explorer",
    "GLSL function (*.glsl)": "glsl",
}


def export_dialog(parent: QWidget, source, folder: str = "") -> Path | None:
    """Ask where and in which format to export `source` (a fit, else the material); write it.

    Returns the written path, or None when cancelled or refused (the reason is shown)."""
    if source is None:
        QMessageBox.information(parent, "Export", "Nothing to export: open or fit a material first.")
        return None
    name, chosen = QFileDialog.getSaveFileName(parent, "Export", folder, ";;".join(FILTERS))
    if not name:
        return None
    fmt = FILTERS.get(chosen, "merl")
    path = Path(name)
    if not path.suffix:
        path = path.with_suffix("." + {"merl": "binary", "brdf-explorer": "brdf", "glsl": "glsl"}[fmt])
    try:
        export_source(source, fmt, path)
    except (BRDFLabError, OSError) as e:
        QMessageBox.warning(parent, "Export", str(e))
        return None
    return path
