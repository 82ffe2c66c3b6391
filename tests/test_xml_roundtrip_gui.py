"""The window saves a file it opened byte for byte, and one edit as one changed value
(a real window under Xvfb; the files are those of test_xml_roundtrip.py)."""

import os

import pytest

from test_xml_roundtrip import FILES, changed_lines, respelled, variant

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)


def test_the_window_saves_one_edit_as_one_changed_value(qtbot, tmp_path):
    from PySide6.QtCore import QSettings

    from brdflab.gui.main_window import MainWindow

    data = FILES["all of them at once"]
    path = tmp_path / "paint.xml"
    path.write_bytes(data)
    w = MainWindow(QSettings(str(tmp_path / "settings.ini"), QSettings.IniFormat))
    w.maybe_save = lambda: True
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    w.open_path(path)
    qtbot.waitUntil(lambda: not w.loading, timeout=30000)
    assert w.workspace.path == path
    # the energy check runs in a worker process: the material read from the file gets there
    qtbot.waitUntil(lambda: w.editor.energy.text().startswith("Energy"), timeout=60000)
    assert "failed" not in w.editor.energy.text()
    assert w.save()  # Ctrl+S with nothing changed
    assert path.read_bytes() == data
    w.editor.parameter_edited.emit(1, "Exponent", 55.0)
    assert w.save()
    lines = changed_lines(data, path.read_bytes())
    assert len(lines) == 1 and lines[0][1] in respelled(lines[0][0], "Exponent", "55.0")


def test_the_xml_view_shows_a_latin1_file(qtbot, tmp_path):
    """A file in ISO-8859-1 is shown as text in the XML view (not decoded as UTF-8)."""
    from PySide6.QtCore import QSettings

    from brdflab.gui.main_window import MainWindow

    path = tmp_path / "latin.xml"
    path.write_bytes(variant("an XML declaration in single quotes, ISO-8859-1"))
    w = MainWindow(QSettings(str(tmp_path / "settings.ini"), QSettings.IniFormat))
    w.maybe_save = lambda: True
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    w._docks["XML"].show()
    w.open_path(path)
    qtbot.waitUntil(lambda: not w.loading, timeout=30000)
    qtbot.waitUntil(lambda: "peinture bleue \u00e9tal\u00e9e" in w.xml.toPlainText(), timeout=5000)
    assert w.save()
    assert path.read_bytes() == variant("an XML declaration in single quotes, ISO-8859-1")
