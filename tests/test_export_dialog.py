"""File → Export in the GUI: the dialog's choice of format reaches the core exporter."""

from pathlib import Path

from PySide6.QtWidgets import QFileDialog, QWidget

from brdflab.gui.export_dialog import export_dialog
from brdflab.io.xmlio import load

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
