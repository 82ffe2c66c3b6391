"""The window fits by the image metric, and its fits list shows both numbers of every fit
(issue 34, goals 1 and 2): driven as a user would, in a real window under Xvfb."""

import os

import pytest

from test_gui import open_and_wait, window  # noqa: F401  (the fixture)

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)


def open_table(window, qtbot, path, diffuse: list[float], specular: float, roughness: float) -> None:
    """Open in the window a MERL table of Lambertian + isotropic Ward, tabulated to `path`."""
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.sources.measured import tabulate, write_merl_binary

    truth = AnalyticMaterial("t", "Linear", 3, [Lobe.create("Lambertian", diffuse),
                                                Lobe.create("Ward", [specular] * 3, ax=roughness, ay=roughness)])
    write_merl_binary(tabulate(truth), path)
    open_and_wait(qtbot, window, window.open_path, path)


def test_the_window_fits_by_the_image_metric_and_lists_both_numbers(window, qtbot, tmp_path):
    open_table(window, qtbot, tmp_path / "truth.binary", [0.05, 0.04, 0.03], 0.3, 0.15)
    panel = window.fitting
    panel.lobes.setCurrentText("Lambertian")  # one lobe: quick, and the two metrics disagree on it
    for metric in ("image", "Ngan"):
        panel.metric_box.setCurrentText(metric)
        panel.fit_button.click()
        if metric == "image":
            qtbot.waitUntil(lambda: "under the object view's map" in panel.status.text() or window._thread is None,
                            timeout=60000)
        qtbot.waitUntil(lambda: window._thread is None, timeout=180000)
    items = [panel.fits.item(k).text() for k in range(panel.fits.count())]
    window.grab().save(str(tmp_path / "image_metric_fits.png"))
    assert len(items) == 2, items
    assert "image" in items[0] and "· Ngan" in items[0], items  # fitted by the image metric, its Ngan error beside
    assert "Ngan" in items[1] and "· image" in items[1], items
    image_fit, ngan_fit = (window.workspace.document.fittings[k] for k in range(2))
    assert image_fit.statistics["metric"] == "image" and ngan_fit.statistics["metric"] == "Ngan"
    # judged on what the object view shows: its mesh (Spot), camera and map
    assert image_fit.statistics["scoredOn"].startswith("renders of spot.obj under 1 map ("), image_fit.statistics
    # each fit is the better one by its own number, and the list says both
    assert image_fit.error <= ngan_fit.statistics["imageError"]
    assert ngan_fit.error <= image_fit.statistics["sampleError"]
    assert "; image error" in panel.status.text(), panel.status.text()  # the last fit's line says it too


def test_scene_auto_in_the_window_judges_by_the_object_views_map(window, qtbot, tmp_path):
    """Auto with the image metric: the tolerance becomes an image error (2 %), the ladder is
    climbed on the object view's mesh under its map, and the dock and status say what was judged."""
    open_table(window, qtbot, tmp_path / "glossy.binary", [0.1, 0.08, 0.05], 0.4, 0.2)
    panel = window.fitting
    assert panel.tolerance.value() == 5.0
    panel.metric_box.setCurrentText("image")
    assert panel.tolerance.value() == 2.0 and "image error" in panel.tolerance.toolTip()
    panel.auto_models.setText("BlinnPhong,Ward")
    panel.auto_button.click()
    qtbot.waitUntil(lambda: "image" in panel.status.text() and window._thread is not None, timeout=120000)
    qtbot.waitUntil(lambda: window._thread is None, timeout=300000)
    window.grab().save(str(tmp_path / "scene_auto.png"))
    ladder = window.ladder.ladder
    assert ladder.metric == "image" and ladder.chosen.lobes == ("Ward",), ladder.reason
    assert ladder.chosen.error_held_back <= 0.02
    assert window.ladder.summary.text().startswith("Scene-Auto ladder")
    assert "image error of spot.obj's" in window.ladder.summary.text(), window.ladder.summary.text()
    assert "image error in the scene" in panel.status.text(), panel.status.text()
    stored = window.workspace.document.fittings[-1]
    assert stored.statistics["metric"] == "image" and stored.statistics["autoTolerance"] == 0.02
    assert stored.statistics["scoredOn"].startswith("renders of spot.obj under 1 map ("), stored.statistics
    assert "· Ngan" in panel.fits.item(panel.fits.count() - 1).text()  # the pick reports both numbers too
    panel.metric_box.setCurrentText("Ngan")
    assert panel.tolerance.value() == 5.0  # an untouched tolerance follows the metric back
