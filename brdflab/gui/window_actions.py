"""The main window's actions and menus: File, Edit, Fit, View, Help; image export; the help text."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QBuffer, QByteArray, QIODevice, Qt
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QFileDialog, QMenu, QMessageBox

from brdflab.errors import BRDFLabError
from brdflab.gui.export_dialog import export_dialog
from brdflab.io.atomic import atomic_write

CONTROLS_HELP = """<h3>Mouse and keyboard</h3>
<table cellspacing=4>
<tr><td><b>Lobe viewer</b></td><td></td></tr>
<tr><td>drag (left button)</td><td>orbit the camera</td></tr>
<tr><td>wheel</td><td>zoom</td></tr>
<tr><td>right-drag or Shift + drag</td><td>move the incident direction (θi, φi)</td></tr>
<tr><td><b>Object view</b></td><td></td></tr>
<tr><td>drag (left button)</td><td>orbit the camera</td></tr>
<tr><td>wheel</td><td>zoom</td></tr>
<tr><td><b>Parameters</b></td><td>drag a slider or type a value and press Enter; Ctrl+Z / Ctrl+Shift+Z undo and redo
(in a field too, once its value is entered)</td></tr>
<tr><td><b>Panels</b></td><td>the wheel scrolls a panel; a field takes the wheel only once clicked</td></tr>
<tr><td><b>Fitting</b></td><td>Ctrl+F fits, Ctrl+Shift+F fits Auto, Esc stops (the best result so far is kept)</td></tr>
<tr><td><b>Files</b></td><td>Ctrl+O open, Ctrl+S save, drop a material, mesh or map on the window</td></tr>
<tr><td><b>Layout</b></td><td>drag the bar between the two views; View → Reset layout</td></tr>
</table>"""


class WindowActions:
    """The menus and what only they do, for MainWindow (a mixin)."""

    def _build_menus(self) -> None:
        file = self.menuBar().addMenu("&File")
        self.recent_menu = None
        for text, shortcut, slot in (
            ("&New analytic material", QKeySequence.New, self.new_material),
            ("New s&imulated material…", "Ctrl+Shift+N", self.show_simulation),
            ("&Open…", QKeySequence.Open, self.open_dialog),
            ("Open &mesh…", "Ctrl+M", self.open_mesh_dialog),
            ("Open &environment…", "Ctrl+E", self.open_environment_dialog),
            ("&Save", QKeySequence.Save, self.save),
            ("Save &As…", QKeySequence.SaveAs, self.save_as),
            ("Add model from &file…", "", self.add_model_file_dialog),
            ("Model f&older…", "", self.model_folder_dialog),
        ):
            action = QAction(text, self)
            action.setShortcut(shortcut)
            action.triggered.connect(slot)
            file.addAction(action)
        export = file.addAction("E&xport…")  # the shown fit, else the material (gui/export_dialog.py)
        export.triggered.connect(self._export_dialog)
        for text, view in (("Export lobe &image…", self.lobe_view), ("Export &object image…", self.object_view)):
            action = file.addAction(text)
            action.triggered.connect(lambda _=False, v=view: self.export_image_dialog(v))
        self.recent_menu = file.addMenu("Recent files")
        file.addSeparator()
        quit_action = QAction("&Quit", self)
        quit_action.setShortcut(QKeySequence.Quit)
        quit_action.triggered.connect(self.close)
        file.addAction(quit_action)
        edit = self.menuBar().addMenu("&Edit")
        undo = self.undo_stack.createUndoAction(self, "&Undo")
        undo.setShortcut(QKeySequence.Undo)
        redo = self.undo_stack.createRedoAction(self, "&Redo")
        redo.setShortcut(QKeySequence.Redo)
        edit.addAction(undo)
        edit.addAction(redo)
        fit_menu = self.menuBar().addMenu("F&it")
        run = QAction("&Fit", self)
        run.setShortcut("Ctrl+F")
        run.triggered.connect(self.fitting._request)
        stop = QAction("&Stop", self)
        stop.setShortcut("Esc")
        stop.triggered.connect(self.stop_fit)
        auto = QAction("&Auto", self)
        auto.setShortcut("Ctrl+Shift+F")
        auto.triggered.connect(self.fitting._request_auto)
        fit_menu.addAction(run)
        fit_menu.addAction(auto)
        fit_menu.addAction(stop)
        fit_menu.addAction("Auto &ladder", self.show_ladder)
        view = self.menuBar().addMenu("&View")
        for dock in self._docks.values():
            view.addAction(dock.toggleViewAction())
        view.addSeparator()
        view.addAction("&Reset layout", self.reset_layout)
        help_menu = self.menuBar().addMenu("&Help")
        help_menu.addAction("&Mouse and keyboard", self.show_controls_help).setShortcut(QKeySequence.HelpContents)
        self._update_recent()

    def _shortcut_texts(self) -> set[str]:
        """The key sequences (as text) of the window's menu actions: a number field leaves them to the window."""
        return {k.toString() for menu in self.menuBar().findChildren(QMenu) for a in menu.actions()
                for k in a.shortcuts() if not k.isEmpty()}

    def show_controls_help(self) -> None:
        box = QMessageBox(QMessageBox.Information, "BRDFLab — controls", CONTROLS_HELP, QMessageBox.Ok, self)
        box.setAttribute(Qt.WA_DeleteOnClose)
        box.open()

    def _export_dialog(self) -> None:
        """Export the shown fit, else the material, under the object view's map."""
        export_dialog(self, self.workspace.fitted() or self.workspace.original(),
                      env=self.object_view.environment_map(), origin=self.workspace.origin)

    def export_image_dialog(self, view) -> None:
        name = "lobe" if view is self.lobe_view else "object"
        path, _ = QFileDialog.getSaveFileName(self, f"Export {name} image", str(Path(self._folder("image")) / f"{name}.png"),
                                              "PNG image (*.png);;JPEG image (*.jpg)")
        if path:
            self.export_image(view, Path(path))

    def export_image(self, view, path: Path) -> bool:
        """What the view shows, at its pixel size, saved atomically (PNG or JPEG by extension)."""
        fmt = "JPG" if path.suffix.lower() in (".jpg", ".jpeg") else "PNG"
        image = view.grabFramebuffer()
        data = QByteArray()
        buffer = QBuffer(data)
        buffer.open(QIODevice.WriteOnly)
        if image.isNull() or not image.save(buffer, fmt):
            self.show_error(f"{path}: the view has no image to export")
            return False
        try:
            atomic_write(path, bytes(data))
        except BRDFLabError as e:  # one line naming the file and the problem
            self.show_error(str(e))
            return False
        self.settings.setValue("folders/image", str(path.parent))
        self.statusBar().showMessage(f"Exported {path}", 5000)
        return True
