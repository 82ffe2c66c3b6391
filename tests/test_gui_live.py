"""The window stays live while the user edits (issue 9): values update in place, and the GUI
thread is never blocked for long, measured by a 10 ms timer probe."""

import os
import time

import pytest

from test_gui import window  # noqa: F401  (the fixture)

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)


BUDGET_S = 0.050  # the budget for one block of the GUI thread


class GapProbe:
    """A 10 ms timer on the GUI thread; the longest gap between its ticks (from the moment it
    starts: a block right after it counts) is the longest time the event loop was blocked."""

    def __init__(self):
        from PySide6.QtCore import QTimer

        self.gaps: list[float] = []
        self._last = None
        self.timer = QTimer(interval=10)
        self.timer.timeout.connect(self._tick)

    def _tick(self):
        now = time.perf_counter()
        if self._last is not None:
            self.gaps.append(now - self._last)
        self._last = now

    def __enter__(self):
        self.timer.start()
        self._last = time.perf_counter()
        return self

    def assert_within_budget(self, what: str) -> None:
        """At most 1 % of the gaps over the budget (a shared 2-core machine's scheduler may
        hold any thread that long), and none over ten times it."""
        gaps = sorted(self.gaps)
        p99 = gaps[int(0.99 * len(gaps))]
        print(f"GUI thread gaps {what}: {len(gaps)} ticks, median {1e3 * gaps[len(gaps) // 2]:.1f} ms, "
              f"p99 {1e3 * p99:.1f} ms, max {1e3 * gaps[-1]:.1f} ms")
        assert p99 < BUDGET_S, f"1 % of the GUI thread's blocks {what} took over {1e3 * p99:.0f} ms"
        assert gaps[-1] < 10 * BUDGET_S, f"the GUI thread was blocked {what} for {1e3 * gaps[-1]:.0f} ms"

    def __exit__(self, *exc):
        self.timer.stop()


def test_dragging_a_slider_updates_rows_in_place(window, qtbot):
    editor = window.editor
    editor.tree.setCurrentItem(editor.tree.topLevelItem(1))
    row = editor._rows[("param", "Exponent")]
    row.slider.setSliderDown(True)  # the user holds the slider
    for t in (200, 300, 400, 500):
        row.slider.setValue(t)
        qtbot.wait(20)
        assert editor._rows[("param", "Exponent")] is row  # not rebuilt under the user's hand
    row.slider.setSliderDown(False)
    expected = row._from_slider(500)
    assert window.workspace.analytic.lobes[1].params["Exponent"] == pytest.approx(expected)
    assert window.undo_stack.count() == 1  # one drag is one undo step


def probe_edits(w, qtbot, k: int, name: str, values) -> GapProbe:
    """Set lobe k's parameter to each value in turn, 30 ms apart, as a dragged slider does,
    and wait for the energy check, plots and text to catch up; the GUI thread's gaps."""
    qtbot.wait(500)
    with GapProbe() as probe:
        for v in values:
            w.editor.parameter_edited.emit(k, name, v)
            qtbot.wait(30)
        qtbot.waitUntil(lambda: not w.editor._energy_job.busy, timeout=60000)
        qtbot.wait(600)  # plots and text catch up
    return probe


def test_gui_thread_stays_responsive_while_editing(window, qtbot):
    window.editor.lobe_added.emit("Ward")  # anisotropic lobes once made each edit cost seconds
    k = len(window.workspace.analytic.lobes) - 1
    probe = probe_edits(window, qtbot, k, "ax", [0.05 + 0.01 * i for i in range(30)])
    assert window.workspace.analytic.lobes[k].params["ax"] == pytest.approx(0.34)
    assert "Energy" in window.editor.energy.text()
    # Before the energy check and the plots moved to worker processes, this scenario blocked
    # the GUI thread for 8.7 s at once (median gap 2.7 s); with the views as QOpenGLWidgets
    # (GL composition of the whole window per frame, the GUI thread waiting for each
    # refinement step) the median gap was 64 ms, the longest 134 ms.
    probe.assert_within_budget("while editing")


def test_gui_thread_stays_responsive_while_refining(window, qtbot):
    """The object view's steps are drawn while the GUI thread goes on (in the step thread, not waited for)."""
    view = window.object_view
    window.editor.lobe_added.emit("Ward")
    window.object_controls.mode.setCurrentText("fis")
    view.settings.samples = 100_000  # refines throughout
    view.restart()
    qtbot.waitUntil(lambda: view.samples_done >= 1, timeout=30000)
    qtbot.wait(300)
    before = view.samples_done
    with GapProbe() as probe:
        qtbot.wait(3000)
    assert view.samples_done > before + 10  # it did refine meanwhile
    probe.assert_within_budget("while refining")


def test_gui_thread_stays_responsive_while_fitting(window, qtbot, tmp_path):
    """The fit runs in a worker process: in a thread, the LM loop held the GIL and the event
    loop ran only 2–4 times during a 3–9 s fit, and Stop was handled 1.7 s late.

    The fit must still run when Stop is clicked, on any machine: two Ward lobes, Fixed, take
    13.6 s on the command line of a fast 2-core machine (one Ward lobe, Linear, which this
    test fitted until then, took 1.0 s there and converged before Stop)."""
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.sources.measured import tabulate, write_merl_binary
    from test_gui import open_and_wait

    truth = AnalyticMaterial("t", "Linear", 3, [Lobe.create("Lambertian", [0.05] * 3),
                                                Lobe.create("Ward", [0.5] * 3, ax=0.1, ay=0.3)])
    path = tmp_path / "truth.binary"
    write_merl_binary(tabulate(truth), path)
    open_and_wait(qtbot, window, window.open_path, path)
    window.fitting.strategy.setCurrentText("Fixed")
    window.fitting.lobes.setCurrentText("Lambertian,Ward,Ward")
    window.fitting.sample_kind.setCurrentText("all")
    qtbot.wait(500)
    with GapProbe() as probe:
        window.fitting.fit_button.click()
        qtbot.waitUntil(lambda: "iteration" in window.fitting.status.text(), timeout=60000)
        qtbot.wait(1500)  # fitting, with progress reports arriving
        window.fitting.stop_button.click()
        stopped = time.perf_counter()
        assert window.fitting.status.text().startswith("stopping")  # Stop is answered at once
        qtbot.waitUntil(lambda: window._thread is None, timeout=60000)
        stop_s = time.perf_counter() - stopped
    print(f"Stop answered in {stop_s:.2f} s")
    assert len(window.workspace.document.fittings) == 1  # stopped: the best so far is kept
    assert len(probe.gaps) > 20  # the event loop kept turning (a GIL-bound thread allowed 2–4 turns)
    # starting the fit pickled the measured table into the worker's pipe: 0.45 s at once
    probe.assert_within_budget("while fitting")
    # the fit stopped where it was (its scoring on every sample takes ~1.7 s on a quiet machine,
    # far longer under load: the time is printed, not asserted)
    assert window.fitting.status.text().endswith("(cancelled)"), window.fitting.status.text()


def test_an_edit_keeps_the_last_image_instead_of_grey(window, qtbot):
    """Every change once cleared the object view to grey until new samples arrived (seconds
    on a software GL): the last image now stays until the new one has its first samples."""
    import numpy as np
    from test_gui_layout import view_rgb

    view = window.object_view
    qtbot.waitUntil(lambda: view.samples_done >= 16, timeout=30000)
    before = view_rgb(view).astype(int)
    window.editor.parameter_edited.emit(1, "Exponent", 30.0)
    assert view.samples_done == 0  # restarted …
    shown = view_rgb(view).astype(int)  # … and drawn now, before any new sample
    grey = np.abs(shown - [31, 31, 36]).max(axis=2) <= 2
    assert grey.mean() < 0.9 and np.abs(shown - before).mean() < 1.0
