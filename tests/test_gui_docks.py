"""The window's panels and the document they show (issue 37 §4)."""

import os

import pytest
from PySide6.QtCore import QEvent, QPointF, Qt
from PySide6.QtGui import QMouseEvent
from PySide6.QtWidgets import QApplication

from test_gui import window  # noqa: F401  (the fixture)
from test_gui_trust import shot

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)


def double_click_title(dock) -> None:
    """A double-click on a floating panel's title bar, as the window manager reports it."""
    event = QMouseEvent(QEvent.NonClientAreaMouseButtonDblClick, QPointF(10, -10), QPointF(dock.mapToGlobal(dock.pos())),
                        Qt.LeftButton, Qt.LeftButton, Qt.NoModifier)
    QApplication.sendEvent(dock, event)


@pytest.mark.parametrize("name", ["Plots", "Charts"])
def test_a_floating_panel_double_clicked_docks_in_front_of_its_tabs(window, qtbot, name):  # noqa: F811
    window.resize(1366, 740)
    dock = window._docks[name]
    dock.setFloating(True)
    window._docks["XML"].raise_()  # another tab of its group in front meanwhile
    qtbot.wait(200)
    double_click_title(dock)
    qtbot.waitUntil(lambda: not dock.isFloating(), timeout=3000)
    qtbot.wait(200)
    shot(window, f"docked_{name}")
    assert not dock.visibleRegion().isEmpty()  # before: docked as a hidden tab behind XML


def test_a_run_stopped_with_its_document_is_not_said_in_another_documents_panel(window, qtbot, tmp_path):  # noqa: F811
    from test_gui import open_and_wait
    from test_gui_trust import _measured

    first, second = _measured(tmp_path, "first", 0.2), _measured(tmp_path, "second", 0.4)
    open_and_wait(qtbot, window, window.open_path, first)
    window.fitting.fit_button.click()
    qtbot.waitUntil(lambda: window._candidate is not None, timeout=30000)
    said = []
    window.statusBar().messageChanged.connect(said.append)
    open_and_wait(qtbot, window, window.open_path, second)  # the fit of `first` is stopped
    qtbot.waitUntil(lambda: window._thread is None, timeout=60000)
    assert any("first" in m and "was closed" in m for m in said)  # said once, naming its document
    assert "closed" not in window.fitting.status.text()  # before: "Fit stopped (its document was closed)"
    window.fitting.status.setText("Ngan error 0.1 after 9 iterations")  # the result of a run of `second`
    open_and_wait(qtbot, window, window.open_path, first)
    assert window.fitting.status.text() == ""  # before: kept under the next document


def test_the_plots_never_show_the_previous_document_after_an_open(window, qtbot, tmp_path):  # noqa: F811
    from test_gui import open_and_wait
    from test_gui_trust import _measured

    plots = window.plots
    qtbot.waitUntil(lambda: plots.image.pixmap() is not None and not plots.image.pixmap().isNull(), timeout=60000)
    measured = _measured(tmp_path, "measured", 0.3)
    open_and_wait(qtbot, window, window.open_path, measured)
    shot(plots, "plots_after_open")
    assert plots.image.pixmap().isNull()  # before: the default material's plots, for 14–45 s
    assert plots.image.text().startswith("plotting") and "measured.binary" in plots.image.text()
    qtbot.waitUntil(lambda: not plots.image.pixmap().isNull(), timeout=120000)  # then the new document's
    assert plots._last[0] is window.workspace.original()


def test_views_follow_the_document_through_its_events(window, qtbot):  # noqa: F811
    """The document is evented (gui/document.py): an edit replaced through it reaches the
    views, and another document shown clears what belonged to the last one, without the
    window pushing into each view."""
    from brdflab.workspace import Workspace

    material = window.workspace.analytic.copy()
    material.lobes[1].params["Exponent"] = 12.0
    window.document.replace_material(material)
    assert window.editor.material is material
    assert window.lobe_view.viewer._layers[0].source is material
    window.fitting.status.setText("Ngan error 0.1 after 9 iterations")
    other = Workspace.new()
    window.document.show(other)
    assert window.workspace is other
    assert window.fitting.status.text() == "" and window.plots.image.text().startswith("plotting")
