"""File → Export in the GUI: the dialog's choice of format reaches the core exporter."""

from pathlib import Path

import numpy as np
import pytest
from PySide6.QtWidgets import QFileDialog, QWidget

from brdflab.gui.export_dialog import export_dialog
from brdflab.io.xmlio import load
from test_gui import window  # noqa: F401  (the fixture)

MATERIAL = Path(__file__).resolve().parents[1] / "materials" / "ward.xml"


def test_export_dialog_writes_the_chosen_format(qtbot, tmp_path, monkeypatch):
    parent = QWidget()
    qtbot.addWidget(parent)
    target = tmp_path / "ward"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: (str(target), "GLSL function (*.glsl)"))
    written = export_dialog(parent, load(MATERIAL).material)
    assert written == tmp_path / "ward.glsl"
    assert "vec3 brdflab_brdf(vec3 wi, vec3 wo)" in written.read_text() and "brdf_Ward(" in written.read_text()


def test_export_dialog_cancel_writes_nothing(qtbot, tmp_path, monkeypatch):
    parent = QWidget()
    qtbot.addWidget(parent)
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: ("", ""))
    assert export_dialog(parent, load(MATERIAL).material) is None
    assert not list(tmp_path.iterdir())


def test_a_renderer_export_fits_in_a_worker_and_says_what_it_cost(qtbot, tmp_path, monkeypatch):
    """Ward is not principled: the export fits Principled on the way out, in a worker process,
    while the window keeps answering; then it says the error that cost."""
    import time

    from PySide6.QtCore import QTimer
    from PySide6.QtWidgets import QMessageBox

    from brdflab.gui.export_dialog import ExportJob

    parent = QWidget()
    qtbot.addWidget(parent)
    target = tmp_path / "ward"
    monkeypatch.setattr(QFileDialog, "getSaveFileName",
                        lambda *a, **k: (str(target), "Mitsuba 3 scene, principled BSDF (*.xml)"))
    shown = []
    monkeypatch.setattr(QMessageBox, "information", lambda _p, _t, text: shown.append(text))
    ticks = []
    timer = QTimer(interval=10)
    timer.timeout.connect(lambda: ticks.append(time.monotonic()))
    timer.start()
    job = export_dialog(parent, load(MATERIAL).material)
    assert isinstance(job, ExportJob)
    with qtbot.waitSignal(job.finished, timeout=900_000):
        pass
    timer.stop()
    assert (tmp_path / "ward.xml").is_file() and (tmp_path / "ward_env.exr").is_file()
    assert shown and "fitted to Principled on the way out: Ngan error" in shown[0]
    # the fit on the way out takes 5–20 s: on the GUI thread the timer would stop that long;
    # a bound this loose holds on a loaded machine too (no budget for a shared CI runner)
    gaps = np.diff(ticks)
    assert len(ticks) > 20 and gaps.max() < 5.0


def test_a_renderer_export_cancelled_writes_nothing(qtbot, tmp_path, monkeypatch):
    parent = QWidget()
    qtbot.addWidget(parent)
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: (str(tmp_path / "ward.gltf"), "glTF 2.0 sphere (*.gltf *.glb)"))
    job = export_dialog(parent, load(MATERIAL).material)
    with qtbot.waitSignal(job.started, timeout=60_000):
        pass
    from PySide6.QtWidgets import QPushButton

    job.dialog.findChild(QPushButton).click()  # the dialog's Cancel, as a user clicks it
    with qtbot.waitSignal(job.failed, timeout=120_000):
        pass
    assert not (tmp_path / "ward.gltf").exists()


def test_file_export_never_writes_over_the_document_or_what_it_reads(qtbot, tmp_path, monkeypatch):
    """The window's File → Export passes the document's file: the file dialog's overwrite
    question was all that stood between an export and the material's own XML, or the measured
    table it reads (a user who answers yes lost them)."""
    from PySide6.QtWidgets import QMessageBox

    from brdflab.gui.export_dialog import ExportJob
    from brdflab.sources.measured import tabulate, write_merl_binary
    from brdflab.workspace import Workspace

    table = tmp_path / "ward.binary"
    write_merl_binary(tabulate(load(MATERIAL).material), table)
    Workspace.open(table).save(tmp_path / "measured.xml")
    saved_table, document = table.read_bytes(), (tmp_path / "measured.xml").read_bytes()
    parent = QWidget()
    qtbot.addWidget(parent)
    said = []
    monkeypatch.setattr(QMessageBox, "warning", lambda _p, _t, text: said.append(text))

    def export(origin, target, chosen):
        monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: (str(target), chosen))
        ws = Workspace.open(origin)
        job = export_dialog(parent, ws.original(), origin=ws.origin)
        if isinstance(job, ExportJob):
            with qtbot.waitSignal(job.failed, timeout=120_000):
                pass
        elif job is not None:
            pytest.fail(f"wrote {job}")
        return said.pop()

    merl, mitsuba = "MERL table (*.binary)", "Mitsuba 3 scene, principled BSDF (*.xml)"
    assert "never replaces what its source reads" in export(tmp_path / "measured.xml", table, merl)
    assert "never replaces its source" in export(tmp_path / "measured.xml", tmp_path / "measured.xml", mitsuba)
    assert "never replaces its source" in export(table, table, merl)  # the bare table opened
    assert table.read_bytes() == saved_table and (tmp_path / "measured.xml").read_bytes() == document


def test_the_windows_export_passes_the_document(window, qtbot, tmp_path, monkeypatch):  # noqa: F811
    from PySide6.QtWidgets import QMessageBox

    from brdflab.sources.measured import tabulate, write_merl_binary
    from test_gui import open_and_wait

    table = tmp_path / "ward.binary"
    write_merl_binary(tabulate(load(MATERIAL).material), table)
    before = table.read_bytes()
    open_and_wait(qtbot, window, window.open_path, table)
    said = []
    monkeypatch.setattr(QMessageBox, "warning", lambda _p, _t, text: said.append(text))
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: (str(table), "MERL table (*.binary)"))
    (action,) = [a for a in window.menuBar().actions()[0].menu().actions() if a.text() == "E&xport…"]
    action.trigger()
    assert said and "never replaces its source" in said[0] and table.read_bytes() == before
