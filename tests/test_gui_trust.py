"""Issue 30 §1: the window shows the current document, and its controls say what they do —
in a real window (Xvfb in CI), driven as a person would."""

import os

import pytest
from test_gui import open_and_wait, window  # noqa: F401  (the fixture)

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)


def shot(widget, name: str) -> None:
    """Save what `widget` shows under $BRDFLAB_SHOTS (when set), to be looked at."""
    folder = os.environ.get("BRDFLAB_SHOTS")
    if folder:
        image = widget.grabFramebuffer() if hasattr(widget, "grabFramebuffer") else widget.grab()
        image.save(os.path.join(folder, f"{name}.png"))


def _measured(tmp_path, name: str, m: float):
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.sources.measured import tabulate, write_merl_binary

    truth = AnalyticMaterial(name, "Linear", 3, [Lobe.create("Lambertian", [0.05] * 3),
                                                 Lobe.create("CookTorrance", [0.5] * 3, m=m, F0=0.3)])
    path = tmp_path / f"{name}.binary"
    write_merl_binary(tabulate(truth), path)
    return path


def test_every_view_follows_a_document_opened_while_a_fit_runs(window, qtbot, tmp_path):
    first, second = _measured(tmp_path, "first", 0.2), _measured(tmp_path, "second", 0.4)
    open_and_wait(qtbot, window, window.open_path, first)
    window.object_controls.shown.setCurrentText("fitted")
    window.fitting.lobes.setCurrentText("Lambertian,CookTorrance,CookTorrance")
    window.fitting.sample_kind.setCurrentText("all")
    window.fitting.fit_button.click()
    qtbot.waitUntil(lambda: window._candidate is not None, timeout=30000)  # the fit has drawn its parameters
    old_fit = window._candidate
    open_and_wait(qtbot, window, window.open_path, second)  # discarding the first, the fit still running
    qtbot.waitUntil(lambda: window._thread is None, timeout=60000)
    qtbot.wait(600)  # the coalesced plot and object-view refreshes have run
    ws = window.workspace
    assert ws.document.material.name == second.name and ws.document.fittings == []
    drawn = [window.object_view.renderer.source, window.object_view.compare_source,
             *(l.source for l in window.lobe_view.viewer._layers if l is not None), window.plots._last[1]]
    assert all(s is not old_fit for s in drawn)
    assert window.object_view.renderer.source is ws.original()
    assert window.lobe_view.viewer._layers[0].source is ws.original()
    assert window.lobe_view.viewer._layers[1].source is ws.guess
    assert window.plots._last[0] is ws.original() and window.plots._last[3] == []  # no old convergence points
    from PySide6.QtCore import Qt

    window.object_view.drag(30, 10, Qt.LeftButton, Qt.NoModifier)  # orbiting draws the same
    qtbot.waitUntil(lambda: window.object_view.samples_done >= 4, timeout=20000)
    assert window.object_view.renderer.source is ws.original()
    shot(window, "a_window_after_switch")
