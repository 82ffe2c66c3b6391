"""Compare original and fit (issue 9): split and difference on the object, the slices of the fit
and of the error, and the running fit's convergence plot."""

import os

import numpy as np
import pytest

from test_gui import open_and_wait, window  # noqa: F401  (the fixture)
from test_gui_layout import view_rgb

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)


def _materials():
    from brdflab.material.analytic import AnalyticMaterial, Lobe

    original = AnalyticMaterial("t", "Linear", 3, [Lobe.create("Lambertian", [0.05] * 3),
                                                   Lobe.create("CookTorrance", [0.5] * 3, m=0.2, F0=0.3)])
    dull = AnalyticMaterial("f", "Linear", 3, [Lobe.create("Lambertian", [0.25] * 3)])  # a poor "fit"
    return original, dull


def test_plots_compare_slices_and_show_convergence():
    from brdflab.gui.panels import draw_plots

    original, fit = _materials()
    alone = draw_plots((original, None, 30.0, [], (900, 220)))
    both = draw_plots((original, fit, 30.0, [(0, 1.0), (1, 0.5), (2, 0.2)], (900, 440)))
    assert alone.shape == (220, 900, 4) and both.shape == (440, 900, 4)
    bottom = both[240:, :, :3].astype(int)  # the second row: three slices (original, fit, error)
    assert bottom.std() > 20
    # the error slice (right third) is coloured where fit and original differ: not all white
    error = bottom[:, 600:850]
    assert (np.abs(error - 255).max(axis=2) > 60).mean() > 0.2


def test_split_and_difference_show_the_fit_beside_the_original(window, qtbot, tmp_path):
    from brdflab.gui.commands import ReplaceFittings
    from brdflab.io.xmlio import Fitting
    from brdflab.sources.measured import tabulate, write_merl_binary

    original, fit = _materials()
    path = tmp_path / "truth.binary"
    write_merl_binary(tabulate(original), path)
    open_and_wait(qtbot, window, window.open_path, path)
    ws, view = window.workspace, window.object_view
    window.undo_stack.push(ReplaceFittings(window, ((), None), ((Fitting(fit, 0.1),), 0), "fit"))
    window.object_controls.mode.setCurrentText("point")

    def settled():
        return view._progressive is not None and view.samples_done >= 1 and (
            not view.comparing or (view._progressive_b is not None and view._progressive_b.samples >= 1))

    window.object_controls.shown.setCurrentText("original")
    qtbot.waitUntil(settled, timeout=30000)
    qtbot.wait(300)
    plain = view_rgb(view).astype(int)
    window.object_controls.shown.setCurrentText("original | fit")
    assert view.comparing and view.compare_source is fit
    qtbot.waitUntil(settled, timeout=30000)
    qtbot.wait(300)
    split = view_rgb(view).astype(int)
    w = split.shape[1]
    left, right = slice(0, w // 2 - 2), slice(w // 2 + 2, w)
    assert np.abs(split[:, left] - plain[:, left]).mean() < 2  # the original on the left …
    assert np.abs(split[:, right] - plain[:, right]).mean() > 2  # … the fit on the right
    assert (split[:, w // 2 - 1: w // 2 + 1] == 255).all(axis=2).mean() > 0.9  # a white line between them
    window.object_controls.shown.setCurrentText("difference")
    qtbot.waitUntil(settled, timeout=30000)
    qtbot.wait(300)
    diff = view_rgb(view).astype(int)
    covered = np.abs(diff - [31, 31, 36]).max(axis=2) > 10  # not the flat background of a point light
    reds = (diff[..., 0] > 150) & (diff[..., 2] < 80)  # the heat ramp: large differences are red to white
    assert reds[covered].mean() > 0.05  # 0.11 measured: the dull fit misses the highlight


def test_the_difference_view_waits_for_a_sample_set_instead_of_showing_noise(window, qtbot):  # noqa: F811
    """Issue 37 §4: lit by a map, the difference of two images of a few samples each was
    their noise (~33 % of the pixels red to white for the first ~10 s). A fit that differs
    from the original by a few per cent must not look like that at any time."""
    from brdflab.gui.commands import ReplaceFittings
    from brdflab.io.xmlio import Fitting
    from brdflab.render.object_view import PREVIEW

    view, ws = window.object_view, window.workspace
    close = ws.analytic.copy()
    close.lobes[1].params["Exponent"] *= 1.05  # within a few per cent of the original
    window.object_controls.mode.setCurrentText("fis")
    window.object_controls.samples.setValue(4096)  # a first set that takes many steps
    window.undo_stack.push(ReplaceFittings(window, ((), None), ((Fitting(close, 0.01),), 0), "fit"))
    window.object_controls.shown.setCurrentText("difference")
    qtbot.waitUntil(lambda: view.comparing and view._progressive_b is not None and view._progressive_b.samples >= 8
                    and view.samples_done < 1024, timeout=60000)
    qtbot.wait(100)
    early = view_rgb(view).astype(int)
    from test_gui_trust import shot

    shot(view, "difference_early")
    reds = (early[..., 0] > 150) & (early[..., 2] < 80)  # heat ≥ ~33 %: red to white
    assert reds.mean() < 0.01, f"{reds.mean():.1%} of the view red: noise"  # before: a third of the object
    assert view.difference_pending()[1] == 4096 + PREVIEW  # said over the view: what it waits for (a preview set first)
