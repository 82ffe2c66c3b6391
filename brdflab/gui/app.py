"""Start the desktop application."""

from __future__ import annotations

import sys
from pathlib import Path


def run(path: str | None = None) -> int:
    """Open the main window on `path`, or on the embedded default scene."""
    from PySide6.QtWidgets import QApplication

    from brdflab.gui.gl_views import set_default_surface_format
    from brdflab.gui.main_window import MainWindow

    set_default_surface_format()
    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("BRDFLab")
    app.setOrganizationName("brdflab")
    window = MainWindow()
    if path:
        window.open_path(Path(path))
    window.show()
    return app.exec()
