"""Start the desktop application."""

from __future__ import annotations

import gc
import sys
from pathlib import Path


def freeze_startup_objects() -> None:
    """Exempt what exists once the window is built (Qt, NumPy, the window itself: ~100k
    objects) from the cyclic garbage collector. A full collection walked them all, 44 ms of
    GUI thread each time one ran (200 ms in a test process); after this, a few ms at most."""
    gc.collect()
    gc.freeze()


def run(path: str | None = None) -> int:
    """Open the main window on `path`, or on the embedded default scene."""
    from PySide6.QtWidgets import QApplication

    from brdflab.gui.main_window import MainWindow

    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("BRDFLab")
    app.setOrganizationName("brdflab")
    window = MainWindow()
    if path:
        window.open_path(Path(path))
    window.show()
    freeze_startup_objects()
    return app.exec()
