"""The panels' fields under the wheel and the keyboard (issue 37 §4): scrolling a panel leaves
the fields that pass under the cursor alone, and the window's shortcuts work while a number
field has the focus."""

import os

import pytest
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QWheelEvent
from PySide6.QtWidgets import QApplication, QScrollArea

from test_gui import window  # noqa: F401  (the fixture)

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)


def wheel(widget, notches: int = 1) -> None:
    """Turn the wheel `notches` clicks down over the middle of `widget`, as a mouse does."""
    centre = QPointF(widget.rect().center())
    for _ in range(notches):
        event = QWheelEvent(centre, QPointF(widget.mapToGlobal(centre.toPoint())), QPoint(), QPoint(0, -120),
                            Qt.NoButton, Qt.NoModifier, Qt.NoScrollPhase, False)
        QApplication.sendEvent(widget, event)


def test_scrolling_a_panel_leaves_the_spin_box_under_the_cursor_alone(window, qtbot):  # noqa: F811
    window.resize(1024, 600)  # the Fitting panel is taller than its dock: it scrolls
    qtbot.wait(300)
    samples = window.fitting.sample_size
    area = next(a for a in window._docks["Fitting"].findChildren(QScrollArea))
    bar = area.verticalScrollBar()
    assert bar.maximum() > 0
    before = samples.value()
    wheel(samples, 4)  # where a real wheel event ends up (the line edit inside passes it on)
    assert samples.value() == before  # before: 50,000 → 90,000
    assert bar.value() > 0  # the panel scrolled instead
    assert samples.focusPolicy() == Qt.StrongFocus  # the wheel gives it no focus either
    window.activateWindow()
    samples.setFocus()  # a focused field still takes the wheel, as the user chose it
    qtbot.waitUntil(samples.hasFocus, timeout=2000)
    wheel(samples)
    assert samples.value() == before - samples.singleStep()  # wheel down: one step down


def exponent_spin(window, qtbot):
    tree = window.editor.tree
    tree.setCurrentItem(tree.topLevelItem(1))  # LafortuneIso
    qtbot.wait(100)
    spin = window.editor._rows[("param", "Exponent")].spin
    window.activateWindow()
    spin.setFocus()
    qtbot.waitUntil(spin.hasFocus, timeout=2000)
    return spin


def test_window_shortcuts_work_while_a_number_field_has_the_focus(window, qtbot, monkeypatch):  # noqa: F811
    opened = []
    monkeypatch.setattr(window, "open_environment_dialog", lambda: opened.append(True))
    for action in window.menuBar().findChildren(type(window.menuBar().actions()[0])):
        if action.shortcut().toString() == "Ctrl+E":  # the action holds the bound method: bind it again
            action.triggered.disconnect()
            action.triggered.connect(window.open_environment_dialog)
    spin = exponent_spin(window, qtbot)
    text = spin.text()
    qtbot.keyClick(spin.lineEdit(), Qt.Key_E, Qt.ControlModifier)
    assert opened and spin.text() == text  # before: the field took it, no dialog


def test_ctrl_z_right_after_enter_undoes_the_value_entered(window, qtbot):  # noqa: F811
    spin = exponent_spin(window, qtbot)
    original = window.workspace.analytic.lobes[1].params["Exponent"]
    spin.lineEdit().selectAll()
    qtbot.keyClicks(spin.lineEdit(), "42")
    qtbot.keyClick(spin.lineEdit(), Qt.Key_Return)
    assert window.workspace.analytic.lobes[1].params["Exponent"] == 42.0
    qtbot.keyClick(spin.lineEdit(), Qt.Key_Z, Qt.ControlModifier)
    assert window.workspace.analytic.lobes[1].params["Exponent"] == original  # before: still 42
    assert spin.value() == pytest.approx(original)  # the focused box shows the undone value
    qtbot.keyClick(spin.lineEdit(), Qt.Key_Z, Qt.ControlModifier | Qt.ShiftModifier)
    assert window.workspace.analytic.lobes[1].params["Exponent"] == 42.0


def test_ctrl_z_while_typing_undoes_the_typing_not_the_document(window, qtbot):  # noqa: F811
    spin = exponent_spin(window, qtbot)
    window.editor.parameter_edited.emit(1, "Cz", 0.5)  # something in the window's undo stack
    qtbot.keyClicks(spin.lineEdit(), "7")
    qtbot.keyClick(spin.lineEdit(), Qt.Key_Z, Qt.ControlModifier)
    assert window.workspace.analytic.lobes[1].params["Cz"] == 0.5  # the document's edit stays
