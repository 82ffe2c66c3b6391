"""Real light probes in the window (issue 30 §2): an angular probe opens as one, both halves
of a dual-paraboloid pair open together from the Open dialog, and the object view's map
layout reads the shown map again (asking for a missing back half)."""

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from test_gui import open_and_wait, window  # noqa: F401  (the fixture)

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)
PROBES = Path(os.environ.get("BRDFLAB_SHARED", Path(__file__).resolve().parents[2] / "shared")) / "data" / "envmaps" / "probes"
SHOTS = os.environ.get("BRDFLAB_SCREENSHOTS")  # a folder: keep the screenshots to look at


def banner(w) -> str:
    return w.warnings.text() if w.warnings.isVisible() else ""


def shown_map(qtbot, w, expected):
    """The map the object view draws once it has taken `expected` (a loaded EnvironmentMap)."""
    qtbot.waitUntil(lambda: not w.loading, timeout=30000)
    renderer = w.object_view.renderer
    qtbot.waitUntil(lambda: renderer.environment is not None and renderer.environment.data.shape == expected.data.shape
                    and np.array_equal(renderer.environment.data, expected.data), timeout=30000)
    return renderer.environment


def screenshot(qtbot, w, name: str) -> np.ndarray:
    from PySide6.QtGui import QImage

    view = w.object_view
    qtbot.waitUntil(lambda: view.samples_done >= 1, timeout=120000)
    qtbot.wait(300)
    img = view.grabFramebuffer().convertToFormat(QImage.Format_RGB32)
    if SHOTS:
        img.save(str(Path(SHOTS) / f"{name}.png"))
        w.grab().save(str(Path(SHOTS) / f"{name}_window.png"))
    return np.frombuffer(img.constBits(), np.uint8, img.sizeInBytes()).reshape(img.height(), img.width(), 4)[..., :3].copy()


@pytest.mark.skipif(not (PROBES / "beach_probe.hdr").exists(), reason="shared probes not found")
def test_real_probes_open_in_the_window(window, qtbot, tmp_path, monkeypatch):
    from PySide6.QtCore import Qt
    from PySide6.QtWidgets import QFileDialog, QScrollArea

    from brdflab.lighting.envmap import load_environment

    e, c = window.editor, window.object_controls
    e.lobe_removed.emit(1)  # a near-mirror shows the map the way up it is
    e.lobe_added.emit("BlinnPhong")
    e.parameter_edited.emit(1, "Exponent", 3000.0)
    for channel in range(3):
        e.scale_edited.emit(0, channel, 0.02)
        e.scale_edited.emit(1, channel, 0.22)  # albedo below 1
    c.mode.setCurrentText("prefiltered")

    # an angular probe with its copyright line, layout auto: read as a disk, not stretched
    open_and_wait(qtbot, window, window.open_environment, PROBES / "beach_probe.hdr")
    env = shown_map(qtbot, window, load_environment(PROBES / "beach_probe.hdr", "angular"))
    assert env.layout == "angular" and "2:1" not in banner(window)
    angular_shot = screenshot(qtbot, window, "beach_angular")
    window._docks["Object view options"].raise_()  # the map layout in sight
    area = c.parentWidget()
    while not isinstance(area, QScrollArea):
        area = area.parentWidget()
    area.ensureWidgetVisible(c.env_layout)

    # the Open dialog takes both halves of a pair, in any order, under any names
    front, back = tmp_path / "left.hdr", tmp_path / "right.hdr"
    shutil.copy(PROBES / "beach-front.hdr", front)
    shutil.copy(PROBES / "beach-back.hdr", back)
    pair = load_environment(front, "dual-paraboloid", back)
    monkeypatch.setattr(QFileDialog, "getOpenFileNames", lambda *a, **k: ([str(front), str(back)], ""))
    window.open_environment_dialog()
    assert shown_map(qtbot, window, pair).layout == "dual-paraboloid"
    assert c.env_layout.currentText() == "dual-paraboloid" and "2:1" not in banner(window)
    pair_shot = screenshot(qtbot, window, "beach_pair")
    difference = np.abs(pair_shot.astype(float) - angular_shot).mean()
    assert difference < 8, f"the pair shows the scene the probe shows ({difference:.1f} of 255)"

    # map layout, chosen with the keyboard: lat-long shows the front half stretched, and the
    # banner says so; dual-paraboloid asks for the back half this file's name does not give
    monkeypatch.setattr(QFileDialog, "getOpenFileName", lambda *a, **k: (str(back), ""))
    c.env_layout.setFocus()
    qtbot.keyClick(c.env_layout, Qt.Key_Home)
    qtbot.keyClick(c.env_layout, Qt.Key_Down)
    assert c.env_layout.currentText() == "latlong"
    shown_map(qtbot, window, load_environment(front, "latlong"))
    assert "not the 2:1 shape" in banner(window)
    qtbot.keyClick(c.env_layout, Qt.Key_End)
    assert c.env_layout.currentText() == "dual-paraboloid"
    shown_map(qtbot, window, pair)
    assert "2:1" not in banner(window)

    # the real halves by their own names: layout auto finds the other half; the dialog puts
    # the halves chosen in either order as their names say
    campus = load_environment(PROBES / "campus-front.hdr", "dual-paraboloid")
    c.env_layout.setCurrentIndex(0)
    open_and_wait(qtbot, window, window.open_environment, PROBES / "campus-back.hdr")
    assert shown_map(qtbot, window, campus).layout == "dual-paraboloid"
    open_and_wait(qtbot, window, window.open_environment, PROBES / "beach_probe.hdr")
    monkeypatch.setattr(QFileDialog, "getOpenFileNames",
                        lambda *a, **k: ([str(PROBES / "campus-back.hdr"), str(PROBES / "campus-front.hdr")], ""))
    window.open_environment_dialog()
    assert shown_map(qtbot, window, campus).layout == "dual-paraboloid"
    screenshot(qtbot, window, "campus_pair")
