"""Issue 30 §1, the lobe viewer: an original and a stored fit drawn over it say which is which,
and the translucent fit is drawn without speckle or a saw-toothed rim — in a real window."""

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
    from brdflab.gui.commands import ReplaceFittings
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


def _pixels(image, rect) -> np.ndarray:
    """(N, 3) RGB of `image` (H, W, 3) inside a QRect (a device pixel ratio of 1: Xvfb's)."""
    return image[rect.top(): rect.bottom() + 1, rect.left(): rect.right() + 1].reshape(-1, 3).astype(int)


def test_the_overlay_says_which_lobe_is_the_original_and_which_the_fit(window, qtbot, tmp_path):
    view, viewer = window.lobe_view, window.lobe_view.viewer
    _lobe_rgb(window, qtbot)
    assert viewer.legend() == [] and view.legend_boxes == []  # one material, no fit: nothing to tell apart
    open_and_wait(qtbot, window, window.open_path, _measured(tmp_path, "first", 0.2))
    _lobe_rgb(window, qtbot)
    assert [t for t, _, _ in viewer.legend()] == ["original: first — solid",
                                                  "initial guess: Lambertian+LafortuneIso — translucent"]
    _store_fits(window, [_truth(), _ward()], 1)
    rgb = _lobe_rgb(window, qtbot)
    shot(view, "legend_fit1_translucent")
    assert [t for t, _, _ in viewer.legend()] == ["original: first — solid", "fit 1: Lambertian+Ward — translucent"]
    background = np.array(BACKGROUND) * 255
    original, fitted = np.array(viewer.settings.original_color) * 255, np.array(viewer.settings.fitted_color) * 255
    (o_swatch, o_text), (f_swatch, f_text) = view.legend_boxes
    # each swatch in the colour its lobe is drawn in: the fit's as seen through, over the background
    assert np.abs(_pixels(rgb, o_swatch) - original).max() <= 2
    assert np.abs(_pixels(rgb, f_swatch) - (0.55 * fitted + 0.45 * background)).max() <= 2
    for text in (o_text, f_text):  # light text on the legend's dark box
        assert (_pixels(rgb, text).min(axis=1) > 150).sum() > 30
    # and so is the lobe: where the fit is seen over the background, its pixels are its colour
    # (shaded) at the swatch's opacity
    seen = (_lobe_mask(rgb)[..., None] * (rgb.astype(float) - 0.45 * background)).reshape(-1, 3)
    seen = seen[np.linalg.norm(seen, axis=1) > 20]
    along_fit = seen @ fitted / np.linalg.norm(seen, axis=1) / np.linalg.norm(fitted)
    assert (along_fit > 0.998).mean() > 0.1  # 0.16: the fit beside the original, over the background
    fit1_text = _pixels(rgb, f_text)

    window.fitting.fits.setCurrentRow(0)  # the other stored fit, picked in the list
    rgb = _lobe_rgb(window, qtbot)
    assert [t for t, _, _ in viewer.legend()][1] == "fit 0: Lambertian+CookTorrance — translucent"
    (_, o_text), (_, f_text) = view.legend_boxes
    assert _pixels(rgb, f_text).shape != fit1_text.shape or (_pixels(rgb, f_text) != fit1_text).any()

    window.lobe_controls.translucent.setChecked(False)
    rgb = _lobe_rgb(window, qtbot)
    shot(view, "legend_fit0_solid")
    assert [t for t, _, _ in viewer.legend()] == ["original: first — solid", "fit 0: Lambertian+CookTorrance — solid"]
    assert np.abs(_pixels(rgb, view.legend_boxes[1][0]) - fitted).max() <= 2

    total = sum(window.views.sizes())
    window.views.setSizes([220, total - 220])  # a narrow lobe view: the legend stays inside it
    qtbot.waitUntil(lambda: view.width() < 260, timeout=5000)
    qtbot.wait(100)
    image = view.grabFramebuffer()
    shot(view, "legend_narrow")
    assert image.width() == view.width() and all(text.right() < view.width() for _, text in view.legend_boxes)


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
