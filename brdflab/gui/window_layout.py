"""How the window's dock columns follow the window's size."""

from __future__ import annotations

from PySide6.QtCore import QEvent, QObject, Qt, QTimer
from PySide6.QtWidgets import QDockWidget, QMainWindow


class ColumnKeeper(QObject):
    """Gives a docked column back the width that a shrinking window took from it, once the
    window grows again: Qt gives every new pixel to the central views, and a left column
    squeezed at a small size stayed narrow (its sliders 15 px) when the window was enlarged.
    A width the user drags the column to is left alone (the window's width did not change)."""

    def __init__(self, window: QMainWindow, dock: QDockWidget) -> None:
        super().__init__(window)
        self._window, self._dock = window, dock
        self._window_width = window.width()  # at the column's last resize
        self._wanted: int | None = None  # the width the column had before a shrinking window took some
        window.installEventFilter(self)
        dock.installEventFilter(self)

    def eventFilter(self, obj: QObject, event: QEvent) -> bool:
        if event.type() != QEvent.Resize:
            return False
        if obj is self._dock:
            width, old = event.size().width(), event.oldSize().width()
            if width < old and self._window.width() < self._window_width and not self._dock.isFloating():
                self._wanted = max(self._wanted or 0, old)
            self._window_width = self._window.width()
        elif obj is self._window and event.size().width() > event.oldSize().width() and self._wanted is not None:
            QTimer.singleShot(0, self._give_back)  # once the window's layout has placed the docks
        return False

    def _give_back(self) -> None:
        if self._wanted is None or self._dock.isFloating():
            return
        if self._dock.width() < self._wanted:
            self._window.resizeDocks([self._dock], [self._wanted], Qt.Horizontal)
        if self._dock.width() >= self._wanted:
            self._wanted = None
