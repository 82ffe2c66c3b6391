"""What the wheel and the keyboard do to the panels' fields (spin boxes, combo boxes, sliders).

A panel scrolls under the wheel: a field that passes under the cursor must not take the
wheel (scrolling the Fitting panel turned its samples from 50,000 to 90,000). And the
window's shortcuts work while a number field has the focus: a spin box took Ctrl+E and
Ctrl+Z for its own line edit (Ctrl+Z right after Enter undid nothing)."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import QCoreApplication, QEvent, QObject, QPointF, Qt
from PySide6.QtGui import QKeySequence, QWheelEvent
from PySide6.QtWidgets import (QAbstractScrollArea, QAbstractSlider, QAbstractSpinBox, QComboBox, QLineEdit, QScrollBar,
                               QWidget)

FIELD_EDITING = (QKeySequence.Undo, QKeySequence.Redo)  # a field's own while it holds typed text


def is_field(obj: QObject) -> bool:
    """A widget whose value the wheel would change (a scroll bar is not one: it scrolls)."""
    return isinstance(obj, (QAbstractSpinBox, QComboBox, QAbstractSlider)) and not isinstance(obj, QScrollBar)


def typing(spin: QAbstractSpinBox) -> bool:
    """Whether `spin` holds typed text not yet entered (its text is not its value's)."""
    text_from_value = getattr(spin, "textFromValue", None)
    return text_from_value is not None and spin.cleanText() != text_from_value(spin.value())


def _spin_of(obj: QObject) -> QAbstractSpinBox | None:
    """The spin box `obj` is, or whose line edit it is."""
    if isinstance(obj, QAbstractSpinBox):
        return obj
    parent = obj.parent() if isinstance(obj, QLineEdit) else None
    return parent if isinstance(parent, QAbstractSpinBox) else None


def _scroll_instead(field: QWidget, event: QWheelEvent) -> None:
    """Give the wheel that turned over `field` to the scroll area around it, if any."""
    area = field.parentWidget()
    while area is not None and not isinstance(area, QAbstractScrollArea):
        area = area.parentWidget()
    if area is None:
        return
    viewport = area.viewport()
    position = QPointF(field.mapTo(viewport, event.position().toPoint()))
    QCoreApplication.sendEvent(viewport, QWheelEvent(position, event.globalPosition(), event.pixelDelta(),
                                                     event.angleDelta(), event.buttons(), event.modifiers(),
                                                     event.phase(), event.inverted()))


class FieldGuard(QObject):
    """An application event filter: fields take focus by click or Tab, never by the wheel,
    and leave the wheel to the panel unless focused; a number field leaves the window's
    shortcuts (`shortcuts()`: its actions' key sequences as text) to the window, except Undo
    and Redo while it holds typed text."""

    def __init__(self, shortcuts: Callable[[], set], parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._shortcuts = shortcuts

    def eventFilter(self, obj: QObject, event: QEvent) -> bool:
        kind = event.type()
        if kind == QEvent.Polish and is_field(obj):
            obj.setFocusPolicy(Qt.StrongFocus)  # not Qt.WheelFocus: the wheel gave the focus, then the value
        elif kind == QEvent.Wheel and is_field(obj) and not obj.hasFocus():
            _scroll_instead(obj, event)
            return True
        elif kind == QEvent.ShortcutOverride and isinstance(obj, QWidget):
            return self._leave_to_window(obj, event)
        return False

    def _leave_to_window(self, obj: QWidget, event) -> bool:
        """True (the override refused, so the shortcut fires) for a window shortcut typed into a number field."""
        spin = _spin_of(obj)
        if spin is None:
            return False
        typed = QKeySequence(event.keyCombination())
        if typed.toString() not in self._shortcuts():
            return False
        if typing(spin) and any(typed.matches(QKeySequence(k)) == QKeySequence.ExactMatch for k in FIELD_EDITING):
            return False
        event.ignore()
        return True
