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
    qtbot.waitUntil(lambda: window.document.running is not None, timeout=30000)
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
    other.document.material.name = "other"
    window.document.show(other)
    assert window.workspace is other
    assert window.fitting.status.text() == "" and window.plots.image.text().startswith("plotting")
    # every view shows the other document, no window call in between
    assert window.editor.material is other.analytic
    assert window.lobe_view.viewer._layers[0].source is other.analytic
    qtbot.waitUntil(lambda: window.object_view.renderer.source is other.analytic, timeout=5000)
    window._docks["XML"].raise_()
    qtbot.waitUntil(lambda: "<Name>other</Name>" in window.xml.toPlainText(), timeout=5000)


def test_each_view_subscribes_to_the_document_itself(qtbot):
    """The views need no window to follow a document (issue 37 §4's design point): the material
    editor, the fits list, the XML, the plots, the lobe viewer and the object view, each built
    alone beside one ShownDocument, show its edits, its fits, a fit chosen, a running fit and
    another document."""
    from brdflab.gui.document import ShownDocument
    from brdflab.gui.gl_views import LobeView, ObjectView
    from brdflab.gui.lobe_feed import LobeViewFeed
    from brdflab.gui.object_feed import ObjectViewFeed
    from brdflab.gui.panels import FittingPanel, LobeControls, MaterialEditor, ObjectControls, PlotsPanel, XmlView
    from brdflab.io.mesh import default_mesh
    from brdflab.io.xmlio import Fitting
    from brdflab.workspace import Workspace

    first = Workspace.new()
    document = ShownDocument(first)
    editor, fits, xml, plots = MaterialEditor(), FittingPanel(), XmlView(), PlotsPanel()
    lobe_view, object_view = LobeView(), ObjectView()
    object_controls = ObjectControls()
    object_controls.shown.setCurrentText("fitted")
    for view in (editor, fits, xml):
        view.follow(document)
    plots.follow(document, lambda: 30.0)
    LobeViewFeed(document, lobe_view, LobeControls(), pytest.fail)
    warnings = {}
    ObjectViewFeed(document, object_view, object_controls, warnings.__setitem__, pytest.fail)
    for widget in (editor, fits, xml, plots, lobe_view, object_view):
        qtbot.addWidget(widget)
        widget.resize(400, 300)
        widget.show()
    qtbot.waitUntil(lambda: object_view.ctx is not None and lobe_view.ctx is not None, timeout=10000)
    object_view.when_ready(lambda: object_view.renderer.set_mesh(default_mesh("meshes/spot.obj")))
    layers = lambda: [layer.source if layer is not None else None for layer in lobe_view.viewer._layers]  # noqa: E731

    edited = first.analytic.copy()
    edited.name = "edited"
    document.replace_material(edited)
    assert editor.material is edited and layers()[0] is edited
    qtbot.waitUntil(lambda: "<Name>edited</Name>" in xml.toPlainText(), timeout=5000)
    qtbot.waitUntil(lambda: object_view.renderer.source is edited, timeout=5000)

    fit = edited.copy()
    document.replace_fittings([Fitting(material=fit, error=0.25)], 0)
    assert fits.fits.count() == 1 and layers()[1] is fit
    qtbot.waitUntil(lambda: object_view.renderer.source is fit, timeout=5000)  # "fitted" shows the fit
    qtbot.waitUntil(lambda: plots._last is not None and plots._last[1] is fit, timeout=5000)

    running = edited.copy()
    document.start_run()
    document.show_progress(running, 3, 0.5)
    assert layers()[1] is running and lobe_view.viewer.labels[1].startswith("fit running")
    qtbot.waitUntil(lambda: object_view.renderer.source is running, timeout=5000)  # coalesced, not dropped
    qtbot.waitUntil(lambda: plots._last[1] is running and plots._last[3] == [(3, 0.5)], timeout=5000)
    document.end_run()
    assert layers()[1] is fit

    second = Workspace.new()
    document.show(second)
    assert editor.material is second.analytic and fits.fits.count() == 0
    assert layers() == [second.analytic, None] and document.running is None
    qtbot.waitUntil(lambda: object_view.renderer.source is second.analytic, timeout=5000)
    qtbot.waitUntil(lambda: plots._last[0] is second.analytic and plots._last[3] == [], timeout=5000)


def test_a_new_initial_guess_redraws_only_what_shows_it(window, qtbot, tmp_path):  # noqa: F811
    """Measured data: the Fitting panel's lobes make the next fit's initial guess, which the
    editor and the lobe viewer show. The object view (the measurement), the plots and the XML
    do not show it and keep their work: typing a lobe list restarted the object view's image
    and asked for the plots again (14–45 s of a worker for a measured table) at every keystroke."""
    from test_gui import open_and_wait
    from test_gui_trust import _measured

    open_and_wait(qtbot, window, window.open_path, _measured(tmp_path, "data", 0.3))
    qtbot.waitUntil(lambda: window.object_view.samples_done >= 4, timeout=30000)
    qtbot.waitUntil(lambda: not window.plots._redraw.isActive(), timeout=5000)
    image, xml = window.object_view._progressive, window.xml._rewrite
    window.fitting.lobes.setCurrentText("Lambertian,Ward")
    guess = window.workspace.guess
    assert guess.lobe_models() == ["Lambertian", "Ward"] and window.editor.material is guess
    window.lobe_view.catch_up()  # the viewer takes a new layer when its step thread lets go of the context
    assert window.lobe_view.viewer._layers[1].source is guess
    assert window.object_view._progressive is image and not window.plots._redraw.isActive()
    assert not xml.isActive()
