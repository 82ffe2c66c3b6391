"""The main window: the current material document, its lobes and its XML."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtGui import QAction, QFont, QKeySequence
from PySide6.QtWidgets import (
    QDockWidget,
    QFileDialog,
    QMainWindow,
    QMessageBox,
    QPlainTextEdit,
    QTreeWidget,
    QTreeWidgetItem,
)

from .. import xmlio
from ..errors import BRDFLabError
from ..resources import data_dir

DEFAULT_MATERIAL = "fig2_lambertian_lafortune.xml"


class MainWindow(QMainWindow):
    """Shows one BRDFDocument; the document (core) holds all state, the widgets show it."""

    def __init__(self) -> None:
        super().__init__()
        self.resize(1200, 800)
        self.document: xmlio.BRDFDocument | None = None

        self.xml_view = QPlainTextEdit(readOnly=True)
        self.xml_view.setFont(QFont("monospace"))
        self.setCentralWidget(self.xml_view)

        self.lobe_tree = QTreeWidget()
        self.lobe_tree.setHeaderLabels(["Lobe / parameter", "Value"])
        dock = QDockWidget("Material", self)
        dock.setObjectName("material-dock")
        dock.setWidget(self.lobe_tree)
        self.addDockWidget(Qt.LeftDockWidgetArea, dock)

        self._build_menus()
        self.open_path(data_dir("materials") / DEFAULT_MATERIAL)

    def _build_menus(self) -> None:
        menu = self.menuBar().addMenu("&File")
        for text, shortcut, slot in (
            ("&Open…", QKeySequence.Open, self.open_dialog),
            ("Save &As…", QKeySequence.SaveAs, self.save_as_dialog),
            ("&Quit", QKeySequence.Quit, self.close),
        ):
            action = QAction(text, self)
            action.setShortcut(shortcut)
            action.triggered.connect(slot)
            menu.addAction(action)

    # --- documents ------------------------------------------------------------------
    def open_path(self, path: Path) -> bool:
        try:
            doc = xmlio.load(path)
        except BRDFLabError as e:
            self.show_error(str(e))
            return False
        self.document = doc
        self.refresh()
        for w in doc.warnings:
            self.statusBar().showMessage(f"{path.name}: {w}", 10000)
        return True

    def open_dialog(self) -> None:
        name, _ = QFileDialog.getOpenFileName(self, "Open material", "", "BRDF materials (*.xml)")
        if name:
            self.open_path(Path(name))

    def save_as_dialog(self) -> None:
        if self.document is None:
            return
        name, _ = QFileDialog.getSaveFileName(self, "Save material", "", "BRDF materials (*.xml)")
        if name:
            try:
                xmlio.save(self.document, Path(name))
            except BRDFLabError as e:
                self.show_error(str(e))
            self.refresh()

    def show_error(self, message: str) -> None:
        self.statusBar().showMessage(message, 15000)
        QMessageBox.warning(self, "BRDFLab", message)

    def refresh(self) -> None:
        doc = self.document
        title = doc.path.name if doc and doc.path else "untitled"
        self.setWindowTitle(f"{title} — BRDFLab")
        self.xml_view.setPlainText(xmlio.to_bytes(doc).decode() if doc else "")
        self.lobe_tree.clear()
        if doc is None or not hasattr(doc.material, "lobes"):
            return
        for k, lobe in enumerate(doc.material.lobes):
            item = QTreeWidgetItem([f"{k}: {lobe.model.name}", ", ".join(f"{s:.4g}" for s in lobe.scale)])
            for name, value in lobe.params.items():
                item.addChild(QTreeWidgetItem([name, f"{value:.6g}"]))
            self.lobe_tree.addTopLevelItem(item)
        self.lobe_tree.expandAll()
