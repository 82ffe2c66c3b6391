"""Auto SH tables in the window (issue 13): the label under "SH table" shows the core's pick.
(A file of its own: the window tests run first, before any headless EGL context exists.)"""

import os

import pytest

from brdflab.lighting.sh_table_auto import choose_table


@pytest.mark.skipif(not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") != "offscreen",
                    reason="needs a display (CI runs the suite under xvfb-run)")
def test_the_window_shows_autos_pick(qtbot, tmp_path):
    from PySide6.QtCore import QSettings

    from brdflab.gui.main_window import MainWindow

    w = MainWindow(QSettings(str(tmp_path / "settings.ini"), QSettings.IniFormat))
    w.maybe_save = lambda: True
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    qtbot.waitUntil(lambda: w.object_view.ctx is not None, timeout=60000)
    controls, view = w.object_controls, w.object_view
    assert controls.sh_table.currentText() == "auto"
    controls.sh_order.setValue(3)
    controls.mode.setCurrentText("sh")
    qtbot.waitUntil(lambda: controls.sh_table_note.text() != "" and view.samples_done >= 1, timeout=120000)
    r = view.renderer
    source = r.source if r.source is not None else r.material
    direct = choose_table(source, 3)  # the core function, here, not the worker's remembered pick
    assert controls.sh_table_note.text() == direct.label
    assert r._sh_state[0] == (3, direct.setting)
    controls.sh_table.setCurrentText("128² standard")
    qtbot.waitUntil(lambda: controls.sh_table_note.text().startswith("128² texels × 2^"), timeout=120000)
    if os.environ.get("BRDFLAB_SCREENSHOTS"):  # the docs' picture: the whole options panel beside the view
        from PySide6.QtGui import QPainter, QPixmap

        controls.sh_table.setCurrentText("auto")
        qtbot.waitUntil(lambda: controls.sh_table_note.text() == direct.label and view.samples_done >= 1, timeout=60000)
        qtbot.wait(300)
        panel, picture = controls.grab(), view.grab()
        out = QPixmap(panel.width() + picture.width(), max(panel.height(), picture.height()))
        out.fill()
        painter = QPainter(out)
        painter.drawPixmap(0, 0, panel)
        painter.drawPixmap(panel.width(), 0, picture)
        painter.end()
        out.save(os.path.join(os.environ["BRDFLAB_SCREENSHOTS"], "gui_sh_table_auto.png"))
