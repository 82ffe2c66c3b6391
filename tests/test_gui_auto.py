"""Auto in the window (issue 13): the lobe viewer's subdivision follows the drawn material."""

import os

import pytest

from test_gui import window  # noqa: F401  (the fixture)

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)


def test_auto_subdivision_follows_the_material(window, qtbot, tmp_path):
    from brdflab.geometry.lobe_surface import auto_level

    controls = window.lobe_controls
    controls.auto_level.setChecked(True)
    assert not controls.level.isEnabled()
    settings = window.lobe_view.viewer.settings
    expected, _ = auto_level([window.workspace.original()], settings.shape, 0.01)
    qtbot.waitUntil(lambda: controls.auto_level_note.text().startswith("level"), timeout=60000)
    assert controls.level.value() == expected == settings.level
    assert f"level {expected}:" in controls.auto_level_note.text()
    # a sharper lobe needs a finer hemisphere
    lobe = next(k for k, l in enumerate(window.workspace.analytic.lobes) if l.model.name == "LafortuneIso")
    top = next(p for p in window.workspace.analytic.lobes[lobe].model.parameters if p.name == "Exponent").upper
    # |Cz| = |Cxy|: the lobe's peak keeps its height as it sharpens (the default's Cz < |Cxy| fades)
    window.editor.parameter_edited.emit(lobe, "Cz", abs(window.workspace.analytic.lobes[lobe].params["Cxy"]))
    window.editor.parameter_edited.emit(lobe, "Exponent", min(top, 2000.0))
    sharper, _ = auto_level([window.workspace.original()], settings.shape, 0.01)
    assert sharper > expected
    qtbot.waitUntil(lambda: controls.level.value() == sharper, timeout=60000)
    window.grab().save(str(tmp_path / "auto.png"))
    controls.auto_level.setChecked(False)
    assert controls.level.isEnabled() and controls.auto_level_note.text() == ""
