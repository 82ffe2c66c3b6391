"""The document the window shows, evented: what shows part of it subscribes to its signals
(as napari's layers emit their changes) rather than being pushed into by the window, so that
a view following `switched` never goes on showing another document."""

from __future__ import annotations

from PySide6.QtCore import QObject, Signal

from brdflab.workspace import Workspace


class ShownDocument(QObject):
    """The Workspace shown, and its changes as signals."""

    switched = Signal(object)  # the Workspace now shown, another document than before
    material_changed = Signal()  # its material (for measured data, the next fit's initial guess) was replaced
    fittings_changed = Signal()  # its stored fits, or which one is shown, were replaced

    def __init__(self, workspace: Workspace, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.workspace = workspace

    def show(self, workspace: Workspace) -> None:
        """Show `workspace`: `switched` when it is another document than the one shown."""
        other = workspace is not self.workspace
        self.workspace = workspace
        if other:
            self.switched.emit(workspace)

    def replace_material(self, material) -> None:
        self.workspace.replace_material(material)
        self.material_changed.emit()

    def replace_fittings(self, fittings: list, shown: int | None) -> None:
        self.workspace.replace_fittings(fittings, shown)
        self.fittings_changed.emit()
