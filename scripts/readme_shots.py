"""Retake the README's screenshots of a measured material and its fit, in a real window.

    xvfb-run -a -s "-screen 0 1600x1000x24" .venv/bin/python scripts/readme_shots.py [--out DIR] [--slice FILE]

Opens MERL gold-metallic-paint3 (the shared slice) in the main window at 1366 × 740 (a
1366 × 768 laptop's free area), fits Lambertian + 2 Cook–Torrance lobes with the Ngan metric
through the Fitting panel's controls, and writes, once each view has refined:

- gui_measured_fit.png: the window, the object split original | fit;
- gui_compare_plots.png: the Plots panel's figure for that fit (as drawn for the dock);
- gui_compare_difference.png: the window, the object showing the difference.

The settings live in a temporary folder (as the tests' window does), so the layout is the
first start's whatever the user's own settings say.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SLICE = ROOT.parent / "shared" / "data" / "merl_slices" / "gold-metallic-paint3.slice"
SIZE = (1366, 740)


def wait(until, timeout: float, what: str) -> None:
    """Run the event loop until `until()` holds; fail after `timeout` seconds."""
    from PySide6.QtTest import QTest

    end = time.monotonic() + timeout
    while not until():
        if time.monotonic() > end:
            raise SystemExit(f"timed out waiting for {what}")
        QTest.qWait(20)


def settle(w, timeout: float = 300.0) -> None:
    """Every view finished: the object view's image (both halves when comparing) at its full
    sample count, the lobe viewer's refinement and auto level back, the plots drawn."""
    from PySide6.QtTest import QTest

    view = w.object_view

    def object_done() -> bool:
        return (view.image_complete and not view.busy_elsewhere()
                and (not view.comparing or (view._progressive_b is not None and view._progressive_b.complete)))

    def lobes_done() -> bool:
        feed = w.lobe_feed
        return not (feed._refine_job.busy or feed._auto_level_job.busy or w.lobe_view._pending)

    def plots_done() -> bool:
        return not w.plots._job.busy and w.plots.status.text() == "" and not w.plots._redraw.isActive()

    for _ in range(2):  # once more after a pause: a late answer may have restarted a view
        wait(lambda: not w.loading and w._thread is None, timeout, "the window to be idle")
        wait(object_done, timeout, "the object view to refine")
        wait(lobes_done, timeout, "the lobe viewer to refine")
        wait(plots_done, timeout, "the plots")
        QTest.qWait(1000)
    wait(lambda: not (view.busy_elsewhere() or w.lobe_view.busy_elsewhere()), timeout, "the frames")
    QTest.qWait(500)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "images")
    parser.add_argument("--slice", type=Path, default=SLICE)
    args = parser.parse_args()

    from PySide6.QtCore import QSettings
    from PySide6.QtWidgets import QApplication, QScrollArea

    from brdflab.gui.app import freeze_startup_objects
    from brdflab.gui.main_window import MainWindow

    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("BRDFLab")
    app.setOrganizationName("brdflab")
    with tempfile.TemporaryDirectory() as folder:
        w = MainWindow(QSettings(str(Path(folder) / "settings.ini"), QSettings.IniFormat))
        w.maybe_save = lambda: True  # no prompt on closing
        w.show()
        wait(lambda: w.object_view.ctx is not None and w.lobe_view.ctx is not None, 30, "the views' contexts")
        freeze_startup_objects()
        w.resize(*SIZE)
        wait(lambda: (w.width(), w.height()) == SIZE, 10, "the window's size")

        w.open_path(args.slice)
        wait(lambda: not w.loading, 120, "the slice to open")
        if w.workspace.source is None:
            raise SystemExit(f"{args.slice} did not open as measured data")

        f = w.fitting
        f.lobes.setCurrentText("Lambertian,CookTorrance,CookTorrance")
        f.strategy.setCurrentText("Linear")
        f.metric_box.setCurrentText("Ngan")
        f.sample_kind.setCurrentText("all")
        f.fit_button.click()
        wait(lambda: w._thread is not None, 30, "the fit to start")
        wait(lambda: w._thread is None, 1800, "the fit")
        fits = w.workspace.document.fittings
        if not fits:
            raise SystemExit(f"the fit stored nothing: {f.status.text()}")
        print("fit:", f.status.text(), flush=True)
        print("stored:", f.fits.item(len(fits) - 1).text(), flush=True)

        # Object view options in front, scrolled to its show box
        controls = w.object_controls
        w._docks["Object view options"].raise_()
        scroll = controls.parentWidget()
        while not isinstance(scroll, QScrollArea):
            scroll = scroll.parentWidget()
        controls.shown.setCurrentText("original | fit")
        scroll.ensureWidgetVisible(controls.shown)
        w._docks["Plots"].raise_()
        settle(w)
        print("banner:", w.warnings.text() if w.warnings.isVisible() else "(none)", flush=True)
        print("legend:", w.lobe_view._legend, flush=True)
        args.out.mkdir(parents=True, exist_ok=True)
        w.grab().save(str(args.out / "gui_measured_fit.png"))
        w.plots.image.pixmap().save(str(args.out / "gui_compare_plots.png"))

        controls.shown.setCurrentText("difference")
        settle(w)
        w.grab().save(str(args.out / "gui_compare_difference.png"))
        print("difference legend:", w.object_view.difference_legend() is not None, flush=True)
        w.close()
        app.processEvents()
    return 0


if __name__ == "__main__":
    sys.exit(main())
