"""Defects a new user met in the window (issue 9): each is driven here as a person would."""

import os

import numpy as np
import pytest

from test_gui import lobe_image, open_and_wait, window  # noqa: F401  (the fixture)

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)


def lit_pixels(img: np.ndarray) -> int:
    """Pixels brighter than the viewer's background (0.12 grey ≈ 31)."""
    rgb = img.reshape(-1, 4)[:, :3].astype(int)
    return int((rgb.max(axis=1) > 60).sum())


def test_moving_the_lobe_viewer_to_another_window_keeps_the_lobe_and_survives_edits(window, qtbot):
    """A view moved to another window (what floating a dock did) once got a new GL context
    from Qt, which emptied the viewer and crashed the next edit. The views now own their
    context for life: moving keeps it, and everything in it."""
    from PySide6.QtWidgets import QWidget

    view = window.lobe_view
    qtbot.waitUntil(lambda: lit_pixels(lobe_image(window)) > 2000, timeout=10000)
    inits, ctx = view.gl_inits, view.ctx
    own_window = QWidget()
    qtbot.addWidget(own_window)
    view.setParent(own_window)
    own_window.resize(700, 600)
    view.resize(700, 600)
    own_window.show()
    view.show()
    qtbot.wait(300)
    assert view.gl_inits == inits and view.ctx is ctx
    layer = view.viewer._layers[0]
    assert layer is not None and layer.source is window.workspace.analytic  # the lobe survives
    for value in (30.0, 60.0, 90.0):  # edits after the re-parenting must not crash
        window.editor.parameter_edited.emit(1, "Exponent", value)
        qtbot.wait(50)
    qtbot.waitUntil(lambda: lit_pixels(lobe_image(window)) > 2000, timeout=10000)
    window.views.insertWidget(0, view)  # and back into the main window
    view.show()
    qtbot.wait(300)
    window.editor.parameter_edited.emit(1, "Exponent", 20.0)
    qtbot.waitUntil(lambda: view.ctx is not None and lit_pixels(lobe_image(window)) > 2000, timeout=10000)
    assert window.workspace.analytic.lobes[1].params["Exponent"] == 20.0


def test_removing_every_lobe_is_a_valid_state(window, qtbot):
    n = len(window.workspace.analytic.lobes)
    qtbot.waitUntil(lambda: lit_pixels(lobe_image(window)) > 2000, timeout=10000)
    full = lit_pixels(lobe_image(window))
    for _ in range(n):
        window.editor.lobe_removed.emit(0)
        qtbot.wait(50)
    assert window.workspace.analytic.lobes == []
    qtbot.wait(200)
    assert window.lobe_view.viewer._layers == [None, None]
    assert lit_pixels(lobe_image(window)) < full / 4  # only the axes: no stale lobe
    assert "array size" not in window.statusBar().currentMessage()
    window.editor.lobe_added.emit("BlinnPhong")  # Add still works
    assert [l.model.name for l in window.workspace.analytic.lobes] == ["BlinnPhong"]
    qtbot.waitUntil(lambda: lit_pixels(lobe_image(window)) > full / 4, timeout=10000)
    window.undo_stack.undo()
    assert window.workspace.analytic.lobes == []
    for _ in range(n):
        window.undo_stack.undo()
    assert len(window.workspace.analytic.lobes) == n


def test_undo_then_redo_leaves_the_document_dirty(window, qtbot, tmp_path):
    path = tmp_path / "mine.xml"
    assert window._save_to(path)
    assert not window.workspace.dirty
    window.editor.parameter_edited.emit(1, "Exponent", 55.0)
    assert window.workspace.dirty
    window.undo_stack.undo()
    assert not window.workspace.dirty  # back to what the file holds
    window.undo_stack.redo()
    assert window.workspace.dirty and window.windowTitle().startswith("mine.xml *")


def _measured_file(tmp_path):
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.sources.measured import tabulate, write_merl_binary

    truth = AnalyticMaterial("t", "Linear", 3, [Lobe.create("Lambertian", [0.05] * 3),
                                                Lobe.create("CookTorrance", [0.5] * 3, m=0.2, F0=0.3)])
    path = tmp_path / "truth.binary"
    write_merl_binary(tabulate(truth), path)
    return path


def test_a_running_fit_never_lands_in_another_document(window, qtbot, tmp_path):
    data = _measured_file(tmp_path)
    open_and_wait(qtbot, window, window.open_path, data)
    window.fitting.lobes.setCurrentText("Lambertian,CookTorrance")
    window.fitting.sample_kind.setCurrentText("all")
    window.fitting.fit_button.click()
    qtbot.waitUntil(lambda: "iteration" in window.fitting.status.text(), timeout=30000)
    other = tmp_path / "other.xml"
    from brdflab.io import xmlio
    from brdflab.workspace import default_material

    xmlio.save(xmlio.BRDFDocument(default_material()), other)
    open_and_wait(qtbot, window, window.open_path, other)  # while the fit runs
    qtbot.waitUntil(lambda: window._thread is None, timeout=60000)
    assert window.workspace.path == other
    assert window.workspace.document.fittings == []  # the fit went nowhere near it
    assert not window.workspace.dirty


def test_missing_data_file_is_said_and_can_be_located(window, qtbot, tmp_path):
    from brdflab.io import xmlio
    from brdflab.io.xmlio import BRDFDocument, MeasuredReference

    data = _measured_file(tmp_path)
    moved = tmp_path / "elsewhere"
    moved.mkdir()
    ref = MeasuredReference("MERLBRDFDatabase", "gone.binary", tmp_path)
    xml = tmp_path / "measured.xml"
    xmlio.save(BRDFDocument(ref), xml)
    open_and_wait(qtbot, window, window.open_path, xml)
    qtbot.wait(100)
    assert "missing" in window.statusBar().currentMessage()  # not overwritten by "opened …"
    assert window.locate_button.isVisible()
    assert window.lobe_view.viewer._layers[0] is None  # the previous material is not left on screen
    assert window.object_view.blank
    target = moved / "found.binary"
    data.rename(target)
    window.locate_data(target)
    assert window.workspace.source is not None and not window.locate_button.isVisible()
    assert not window.object_view.blank and window.workspace.dirty
    assert window._save_to(xml)
    assert xmlio.load(xml).material.path.resolve() == target.resolve()
