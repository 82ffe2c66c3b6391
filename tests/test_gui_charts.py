"""The Charts dock (issue 12): a study part measured on the window's own material and map,
in a worker process, with Stop; the charts are shown and the window stays responsive."""

import json
import os
import time

import pytest

from test_gui import window  # noqa: F401  (the fixture)

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)


def choose(panel, part: str) -> None:
    panel.part.setCurrentIndex(panel.part.findData(part))


def test_the_charts_dock_measures_the_current_material(window, qtbot, tmp_path):
    from PySide6.QtCore import QTimer

    dock = window._docks["Charts"]
    dock.show()
    dock.raise_()
    panel = window.charts
    choose(panel, "viewer")
    ticks = []
    timer = QTimer(interval=10)
    timer.timeout.connect(lambda: ticks.append(time.monotonic()))
    timer.start()
    with qtbot.waitSignal(panel.measured, timeout=120_000) as result:
        panel.run_button.click()
        assert panel.busy and not panel.run_button.isEnabled() and panel.stop_button.isEnabled()
    timer.stop()
    rows = result.args[0]["numbers"]["rows"]
    assert {r["material"] for r in rows} == {"current material"}  # the window's scene, not the test matrix
    assert panel._pixmaps and all(not p.isNull() and p.width() > 300 for _, p in panel._pixmaps)
    assert all(label.pixmap().width() <= panel.scroll.viewport().width() for label, _ in panel._pixmaps)
    assert "subdivision" in panel.status.text() and panel.lesson.text()
    gaps = [b - a for a, b in zip(ticks, ticks[1:])]
    assert max(gaps) < 1.0  # the measuring ran elsewhere: the event loop kept turning
    window.grab().save(str(tmp_path / "charts.png"))


def test_stop_ends_the_measurement_early(window, qtbot):
    panel = window.charts
    choose(panel, "viewer")
    with qtbot.waitSignal(panel.measured, timeout=120_000) as result:
        panel.run_button.click()
        qtbot.waitUntil(lambda: "level" in panel.status.text(), timeout=60_000)
        panel.stop_button.click()
    assert result.args[0]["stopped"]
    assert len(result.args[0]["numbers"]["rows"]) < 4  # quick runs four levels; it stopped before the end
    assert panel.run_button.isEnabled() and not panel.stop_button.isEnabled()
