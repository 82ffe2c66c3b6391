"""Issue 30 §1, the lobe viewer: the translucent fit drawn over the original without speckle
or a saw-toothed rim — in a real window."""

import numpy as np
import test_gui
from test_gui import open_and_wait
from test_gui_trust import _measured, pytestmark, shot  # noqa: F401  (needs a display)

from brdflab.gui.gl_views import BACKGROUND
from brdflab.material.analytic import AnalyticMaterial, Lobe

window = test_gui.window  # the fixture: a main window, shown

LINES = np.array([[0.9, 0.2, 0.2], [0.2, 0.8, 0.2], [0.3, 0.4, 1.0], [1.0, 1.0, 0.2]]) * 255  # the view's axes, wi


def _truth() -> AnalyticMaterial:  # what _measured tabulates (m = 0.2)
    return AnalyticMaterial("truth", "Linear", 3, [Lobe.create("Lambertian", [0.05] * 3),
                                                   Lobe.create("CookTorrance", [0.5] * 3, m=0.2, F0=0.3)])


def _ward() -> AnalyticMaterial:  # a fit that misses: broader than the data's highlight
    return AnalyticMaterial("ward", "Linear", 3, [Lobe.create("Lambertian", [0.06] * 3),
                                                  Lobe.create("Ward", [0.4] * 3, ax=0.2, ay=0.2)])


def _store_fits(window, fits, shown: int) -> None:
    """Stored fits, as a fit run leaves them, fit `shown` selected in the Fitting panel's list."""
    from brdflab.gui.main_window import ReplaceFittings
    from brdflab.io.xmlio import Fitting

    ws = window.workspace
    window.undo_stack.push(ReplaceFittings(window, (tuple(ws.document.fittings), ws.shown_fit),
                                           (tuple(Fitting(f, 0.1) for f in fits), shown), "fits"))
    assert window.fitting.fits.currentRow() == shown


def _lobe_rgb(window, qtbot) -> np.ndarray:
    """The lobe view's image once its surface is final (refined near the fit's peak)."""
    viewer = window.lobe_view.viewer
    qtbot.waitUntil(viewer.refined_in_use, timeout=60000)
    qtbot.wait(100)
    image = window.lobe_view.grabFramebuffer().convertToFormat(window.lobe_view.grabFramebuffer().Format.Format_RGB32)
    w, h = image.width(), image.height()
    return np.frombuffer(image.constBits(), np.uint8, image.sizeInBytes()).reshape(h, w, 4)[..., 2::-1].copy()


def _lobe_mask(rgb: np.ndarray) -> np.ndarray:
    """Pixels of the lobes: not the background, not the legend's corner, not an axis line."""
    mask = np.abs(rgb.astype(int) - np.array(BACKGROUND) * 255).max(axis=2) > 10
    for line in LINES:  # a line on the background, or seen through the translucent fit
        for alpha in (1.0, 0.45):
            seen = alpha * line + (1 - alpha) * np.array(BACKGROUND) * 255
            mask &= np.abs(rgb.astype(int) - seen).max(axis=2) > 30
    h, w = mask.shape
    mask[int(0.8 * h):, : int(0.5 * w)] = False  # where the legend is
    return mask


def speckle(rgb: np.ndarray) -> float:
    """Of the lobes' pixels (two pixels in from every edge), the fraction more than 12 levels
    (in some channel) from the median of their 3 × 3 neighbourhood: isolated flecks of another
    shade. Shading changes by a level or two from one pixel to the next."""
    from scipy.ndimage import binary_erosion, median_filter

    median = np.stack([median_filter(rgb[..., c].astype(int), size=3) for c in range(3)], axis=-1)
    off = np.abs(rgb.astype(int) - median).max(axis=2) > 12
    inner = binary_erosion(_lobe_mask(rgb), iterations=2)
    return float(off[inner].mean())


def rim_reversals(rgb: np.ndarray) -> int:
    """How often the lobes' lower outline (their rim, seen from above the horizon) turns from
    going down to going up or back, over the middle 80 % of its columns: a rim that is one
    smooth curve turns once (at its lowest point, a pixel staircase never turns), a saw-tooth
    at every tooth."""
    from scipy.ndimage import label

    parts, _ = label(_lobe_mask(rgb))
    lobe = parts == 1 + int(np.argmax(np.bincount(parts.ravel())[1:]))
    columns = np.flatnonzero(lobe.any(axis=0))
    columns = columns[int(0.1 * len(columns)): int(0.9 * len(columns))]
    steps = np.diff([np.flatnonzero(lobe[:, x])[-1] for x in columns])
    steps = steps[steps != 0]
    return int((np.diff(np.sign(steps)) != 0).sum())


def test_a_translucent_fit_is_drawn_without_speckle(window, qtbot, tmp_path):
    """Two causes: the fit blended in one pass over its own far side (one or two layers per
    pixel by triangle order: a patchwork of two blues), and a fit that matches its measured
    original z-fighting with it (a patchwork of orange and grey)."""
    open_and_wait(qtbot, window, window.open_path, _measured(tmp_path, "first", 0.2))
    assert window.lobe_view.viewer.settings.level == 5 and window.lobe_controls.translucent.isChecked()
    for shown, name in ((0, "matching"), (1, "missing")):
        _store_fits(window, [_truth(), _ward()], shown)
        rgb = _lobe_rgb(window, qtbot)
        shot(window.lobe_view, f"speckle_fit{shown}_{name}")
        assert speckle(rgb) < 0.002, name  # 0.018 (matching) and 0.0061 (missing) before, 0 and 0.0004 after


def test_the_rim_of_the_lobes_is_smooth(window, qtbot, tmp_path):
    open_and_wait(qtbot, window, window.open_path, _measured(tmp_path, "first", 0.2))
    assert window.lobe_view.viewer.settings.level == 5  # the default subdivision
    for shown in (0, 1):
        _store_fits(window, [_truth(), _ward()], shown)
        rgb = _lobe_rgb(window, qtbot)
        shot(window.lobe_view, f"rim_fit{shown}")
        assert rim_reversals(rgb) <= 4  # 31 and 29 turns before (a tooth per rim vertex), 1 and 3 after
