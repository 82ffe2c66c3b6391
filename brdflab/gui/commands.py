"""The window's undo commands: every material edit and every change of the stored fits swaps
whole values, so undo is exact."""

from __future__ import annotations

from typing import TYPE_CHECKING

from PySide6.QtGui import QUndoCommand

if TYPE_CHECKING:
    from brdflab.gui.main_window import MainWindow


class ReplaceMaterial(QUndoCommand):
    """Every material edit swaps whole materials, so undo is exact."""

    def __init__(self, window: "MainWindow", old, new, text: str, merge_key=None) -> None:
        super().__init__(text)
        self.window, self.old, self.new, self.merge_key = window, old, new, merge_key

    def id(self) -> int:
        return 1 if self.merge_key is not None else -1

    def mergeWith(self, other) -> bool:  # dragging a slider is one undo step
        if isinstance(other, ReplaceMaterial) and other.merge_key == self.merge_key:
            self.new = other.new
            return True
        return False

    def redo(self) -> None:
        self.window.document.replace_material(self.new)

    def undo(self) -> None:
        self.window.document.replace_material(self.old)


class ReplaceFittings(QUndoCommand):
    def __init__(self, window: "MainWindow", old: tuple, new: tuple, text: str) -> None:
        super().__init__(text)
        self.window, self.old, self.new = window, old, new

    def redo(self) -> None:
        self.window.document.replace_fittings(list(self.new[0]), self.new[1])

    def undo(self) -> None:
        self.window.document.replace_fittings(list(self.old[0]), self.old[1])
