"""Auto in the fitting panel (issue 13): the window's Auto run stores the same pick as
`auto_fit` called directly, shows the ladder, stays live, and Stop ends it with the best kept."""

import os
import time

import pytest

from conftest import DATA, needs_shared
from test_gui import open_and_wait, window  # noqa: F401  (the fixture)
from test_gui_live import GapProbe

pytestmark = [
    pytest.mark.skipif(not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
                       reason="needs a display (CI runs the suite under xvfb-run)"),
    needs_shared("merl_slices", "blue-fabric.slice"),
]

SLICE = DATA / "merl_slices" / "blue-fabric.slice"
MODELS = ["BlinnPhong", "CookTorrance"]


def _label(lobes) -> str:
    return "+".join(("Lambertian", *lobes))


def test_auto_stores_what_auto_fit_picks_and_shows_the_ladder(window, qtbot):
    from brdflab.fitting.auto import auto_fit
    from brdflab.fitting.samples import samples_of
    from brdflab.sources.measured import read_slice

    open_and_wait(qtbot, window, window.open_path, SLICE)
    panel = window.fitting
    panel.auto_models.setText(", ".join(MODELS))
    panel.auto_split.setValue(1000)
    panel.tolerance.setValue(5.0)
    qtbot.wait(300)
    with GapProbe() as probe:
        panel.auto_button.click()
        assert not panel.auto_button.isEnabled() and panel.stop_button.isEnabled()
        qtbot.waitUntil(lambda: "held back" in panel.status.text(), timeout=60000)  # progress arrives
        assert panel.progress.text().startswith("candidate ") and panel.progress.maximum() > 1
        qtbot.waitUntil(lambda: window._thread is None, timeout=120000)
    assert len(probe.gaps) > 20
    # starting the worker once waited 0.15–0.22 s for it to read a 200 KB slice from its pipe
    probe.assert_within_budget("during Auto")

    # the independent route: auto_fit on the slice read here, with the same settings
    direct = auto_fit(samples_of(read_slice(SLICE)), 0.05, panel.metric_box.currentText(),
                      panel.strategy.currentText(), split=1000, models=MODELS)
    (stored,) = window.workspace.document.fittings
    lobes = [l.model.name for l in stored.material.lobes if l.channel in (None, 0)]
    assert lobes == ["Lambertian", *direct.chosen.lobes]
    assert stored.statistics["heldBackError"] == direct.chosen.error_held_back
    assert stored.error == direct.error  # the pick's error over every sample of the slice (issue 30 §5)
    assert direct.samples > direct.fitted_samples
    assert window.workspace.shown_fit == 0 and window.undo_stack.undoText() == "Auto fit"
    assert f"Auto chose {_label(direct.chosen.lobes)}" in panel.status.text()
    assert panel.fits.item(0).text().startswith(f"0: {_label(direct.chosen.lobes)}  ")  # every lobe named

    # the ladder: a row per candidate, the chosen one marked, the reason above
    view = window.ladder
    assert window._docks["Auto ladder"].isVisible()
    assert view.table.rowCount() == len(direct.candidates)
    for row, candidate in enumerate(direct.candidates):
        assert view.table.item(row, 1).text().endswith(_label(candidate.lobes))
    chosen_row = direct.candidates.index(direct.chosen)
    assert view.chosen_row == chosen_row and view.table.item(chosen_row, 1).text().startswith("★")
    assert view.table.item(chosen_row, 4).text() == f"{direct.chosen.error_held_back:.5g}"
    assert view.reason.text() == "Chosen: " + direct.reason

    window.undo_stack.undo()  # stored the undoable way a fit is
    assert window.workspace.document.fittings == []


def test_stop_ends_auto_promptly_keeping_the_best_fully_fitted(window, qtbot):
    open_and_wait(qtbot, window, window.open_path, SLICE)
    material = window.workspace.document.material
    panel = window.fitting
    panel.auto_models.setText("")  # every model, the default split: far longer than the test waits
    panel.auto_button.click()
    qtbot.waitUntil(lambda: "screened" in panel.status.text(), timeout=60000)  # climbing rung 1
    panel.stop_button.click()
    stopped = time.perf_counter()
    assert panel.status.text().startswith("stopping")
    qtbot.waitUntil(lambda: window._thread is None, timeout=60000)
    stop_s = time.perf_counter() - stopped
    print(f"Auto answered Stop in {stop_s:.2f} s")
    assert stop_s < 20.0  # within one sample chunk of the running fit (well under 1 s on a quiet machine)
    assert panel.status.text().endswith("(cancelled); see the Auto ladder"), panel.status.text()
    ladder = window.ladder.ladder
    assert ladder.reason.startswith("cancelled in rung")
    assert window.ladder.reason.text().startswith("Chosen: cancelled")
    assert ladder.chosen.fitted
    statuses = [window.ladder.table.item(r, 7).text() for r in range(window.ladder.table.rowCount())]
    assert any(s == "cancelled" or s.startswith("not reached") for s in statuses)  # the climb was cut short
    # the document is intact: its material, and one new fitting (the pick among the fully fitted)
    assert window.workspace.document.material is material
    (stored,) = window.workspace.document.fittings
    assert stored.statistics["heldBackError"] == ladder.chosen.error_held_back
    assert panel.auto_button.isEnabled() and not panel.stop_button.isEnabled()


def test_auto_refuses_unknown_models_and_never_lands_in_another_document(window, qtbot, tmp_path):
    from brdflab.gui.auto_ladder import EMPTY_TEXT
    from brdflab.io import xmlio
    from brdflab.workspace import default_material

    open_and_wait(qtbot, window, window.open_path, SLICE)
    window.fitting.auto_models.setText("BlinnPhong, NoSuchModel")
    window.fitting.auto_button.click()  # an unknown model is said at once, nothing runs
    assert window._thread is None and "NoSuchModel" in window.statusBar().currentMessage()
    window.fitting.auto_models.setText("")
    window.fitting.auto_button.click()
    qtbot.waitUntil(lambda: "held back" in window.fitting.status.text(), timeout=60000)
    other = tmp_path / "other.xml"
    xmlio.save(xmlio.BRDFDocument(default_material()), other)
    said = []
    window.statusBar().messageChanged.connect(said.append)
    open_and_wait(qtbot, window, window.open_path, other)  # while Auto runs: it is stopped
    qtbot.waitUntil(lambda: window._thread is None, timeout=60000)
    assert window.workspace.path == other
    assert window.workspace.document.fittings == [] and not window.workspace.dirty
    assert window.ladder.summary.text() == EMPTY_TEXT and not window.fitting.ladder_button.isEnabled()
    assert any("document was closed" in m for m in said)  # said in the status bar, not kept in the panel
    assert window.fitting.status.text() == ""
