"""The dock panels. Each shows part of the Workspace and reports edits as signals; the
main window turns edits into undoable commands."""

from __future__ import annotations

import math

import numpy as np
from collections.abc import Callable

from PySide6.QtCore import QSignalBlocker, Qt, QTimer, Signal
from PySide6.QtGui import QColor, QFont, QSyntaxHighlighter, QTextCharFormat
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QPlainTextEdit,
    QProgressBar,
    QPushButton,
    QScrollArea,
    QSizePolicy,
    QSlider,
    QSpinBox,
    QTreeWidget,
    QTreeWidgetItem,
    QVBoxLayout,
    QWidget,
)

from brdflab.gui.auto_lighting import details, summary
from brdflab.gui.background import LatestOnly
from brdflab.gui.fields import typing
from brdflab.gui.probe_open import LAYOUT_TIP
from brdflab.io.xmlio import to_text
from brdflab.lighting.probes import LAYOUTS
from brdflab.lighting.auto import DEFAULT_TOLERANCE as LIGHTING_TOLERANCE
from brdflab.material.albedo import energy_check
from brdflab.fitting.auto import DEFAULT_SPLIT
from brdflab.fitting.auto import DEFAULT_TOLERANCE as FIT_TOLERANCE
from brdflab.fitting.scene_auto import DEFAULT_SCENE_TOLERANCE
from brdflab.fitting.defaults import DEFAULT_METRIC, DEFAULTS_WHY
from brdflab.fitting.diagnosis import above_one
from brdflab.fitting.lm import METRICS
from brdflab.material.analytic import AnalyticMaterial
from brdflab.models import model_names

CHANNEL_COLORS = ("#d04040", "#40a040", "#4060d0")
SLIDER_STEPS = 1000


def scrolling(widget: QWidget) -> QScrollArea:
    """A panel in a scroll area: a dock may then be shorter than its contents (small screens),
    never narrower (a window shrunk and grown again left the Fitting panel 100 px wide,
    scrolling sideways, until Reset layout)."""
    area = QScrollArea()
    area.setWidgetResizable(True)
    area.setFrameShape(QScrollArea.NoFrame)
    area.setWidget(widget)
    area.setMinimumWidth(widget.minimumSizeHint().width() + area.verticalScrollBar().sizeHint().width())
    return area


class ParameterRow(QWidget):
    """A spin box and a slider for one bounded value (log-scaled when it spans decades)."""

    edited = Signal(float)

    def __init__(self, lower: float, upper: float, value: float, log: bool = False) -> None:
        super().__init__()
        self.lower, self.upper, self.log = lower, upper, log
        self.spin = QDoubleSpinBox(decimals=6, minimum=lower, maximum=upper)
        self.spin.setKeyboardTracking(False)
        self.spin.setSingleStep((upper - lower) / 100.0)
        self.slider = QSlider(Qt.Horizontal, minimum=0, maximum=SLIDER_STEPS)
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.spin, 1)
        lay.addWidget(self.slider, 2)
        self.set_value(value)
        self.spin.valueChanged.connect(self._typed)
        self.slider.valueChanged.connect(self._slid)

    def _typed(self, v: float) -> None:
        """A value typed (Enter or leaving the box): the slider follows at once."""
        with QSignalBlocker(self.slider):
            self.slider.setValue(self._to_slider(v))
        self.edited.emit(v)

    def _slid(self, t: int) -> None:
        """The slider moved: the box shows its value at once, during a drag too."""
        v = self._from_slider(t)
        with QSignalBlocker(self.spin):
            self.spin.setValue(v)
        self.edited.emit(v)

    def _span(self):
        c = max(1e-5 * (self.upper - self.lower), 1e-12)
        return c, math.log(c), math.log(self.upper - self.lower + c)

    def _to_slider(self, v: float) -> int:
        if self.log:
            c, a, b = self._span()
            t = (math.log(v - self.lower + c) - a) / (b - a)
        else:
            t = (v - self.lower) / (self.upper - self.lower)
        return int(round(max(0.0, min(1.0, t)) * SLIDER_STEPS))

    def _from_slider(self, t: int) -> float:
        t = t / SLIDER_STEPS
        if self.log:
            c, a, b = self._span()
            return min(self.upper, max(self.lower, self.lower + math.exp(a + t * (b - a)) - c))
        return self.lower + t * (self.upper - self.lower)

    def held(self) -> bool:
        """Whether the user is working this row now (dragging, or typing in it): a focused box
        whose value was entered follows an undo."""
        return self.slider.isSliderDown() or (self.spin.hasFocus() and typing(self.spin))

    def set_value(self, v: float) -> None:
        with QSignalBlocker(self.spin), QSignalBlocker(self.slider):
            self.spin.setValue(v)
            self.slider.setValue(self._to_slider(v))


class MaterialEditor(QWidget):
    """Lobes as a tree, their parameters and scales, the combination, the energy check."""

    parameter_edited = Signal(int, str, float)  # lobe, parameter, value
    scale_edited = Signal(int, int, float)  # lobe, channel, value
    lobe_added = Signal(str)
    model_file_requested = Signal()  # "From file…": add a lobe of a model read from a file
    lobe_removed = Signal(int)
    lobe_moved = Signal(int, int)
    combination_changed = Signal(str)
    channels_changed = Signal(int)
    energy_known = Signal(object)  # (conserves, max albedo per channel) of the shown material

    def __init__(self) -> None:
        super().__init__()
        self.material: AnalyticMaterial | None = None
        self.tree = QTreeWidget()
        self.tree.setHeaderLabels(["Lobe", "Scale / value"])
        self.tree.currentItemChanged.connect(lambda *_: self._show_lobe())
        self.model_box = QComboBox()
        self.refresh_models()
        add = QPushButton("Add")
        add.clicked.connect(lambda: self.lobe_added.emit(self.model_box.currentData()))
        from_file = QPushButton("From file…")
        from_file.setToolTip("Add a lobe of a model from a BRDF Explorer .brdf or a BRDFLab model descriptor")
        from_file.clicked.connect(self.model_file_requested.emit)
        remove = QPushButton("Remove")
        remove.clicked.connect(lambda: self.current() is not None and self.lobe_removed.emit(self.current()))
        up, down = QPushButton("Up"), QPushButton("Down")
        up.clicked.connect(lambda: self.current() is not None and self.lobe_moved.emit(self.current(), -1))
        down.clicked.connect(lambda: self.current() is not None and self.lobe_moved.emit(self.current(), 1))
        self.combination = QComboBox()
        self.combination.addItems(["Linear", "Fixed"])
        self.combination.activated.connect(lambda _: self.combination_changed.emit(self.combination.currentText()))
        self.channels = QSpinBox(minimum=1, maximum=16)
        self.channels.setKeyboardTracking(False)
        self.channels.valueChanged.connect(self.channels_changed.emit)
        self.energy = QLabel()
        self.energy.setWordWrap(True)
        self._energy_job = LatestOnly(energy_summary, self)
        self._energy_job.done.connect(self._show_energy)
        self._energy_job.failed.connect(lambda m: self.energy.setText(f"Energy check failed: {m}"))
        self._rows: dict = {}  # ("param", name) or ("scale", channel) → ParameterRow of the shown lobe
        self.params = QFormLayout()
        params_box = QWidget()
        params_box.setLayout(self.params)

        top = QHBoxLayout()
        top.addWidget(QLabel("Combination"))
        top.addWidget(self.combination)
        top.addWidget(QLabel("Channels"))
        top.addWidget(self.channels)
        buttons = QGridLayout()  # two short rows: the dock stays narrow
        buttons.addWidget(self.model_box, 0, 0, 1, 2)
        buttons.addWidget(add, 0, 2)
        for column, w in enumerate((remove, up, down)):
            buttons.addWidget(w, 1, column)
        buttons.addWidget(from_file, 2, 0, 1, 3)
        # the buttons above the lobes, the lobes a few rows high: nothing above the parameters
        # changes height with the selected lobe, and a laptop's short dock shows its parameters
        self.tree.setMaximumHeight(self.tree.sizeHintForRow(0) * 5 + self.tree.header().sizeHint().height() + 8
                                   if self.tree.sizeHintForRow(0) > 0 else 6 * self.fontMetrics().height() + 8)
        lay = QVBoxLayout(self)
        lay.addLayout(top)
        lay.addLayout(buttons)
        lay.addWidget(self.tree)
        lay.addWidget(params_box, 1)
        lay.addWidget(self.energy)

    def refresh_models(self, select: str | None = None) -> None:
        """The models one can add: the built-ins, then every model read from a file, named
        with its file (its full path in the tooltip)."""
        from brdflab.models import all_models

        keep = select or self.model_box.currentData()
        with QSignalBlocker(self.model_box):
            self.model_box.clear()
            for model in all_models():
                if model.origin is None:
                    self.model_box.addItem(model.name, model.name)
            for model in all_models():
                if model.origin is not None:
                    self.model_box.addItem(f"{model.xml_name} — {model.origin.path.name}", model.name)
                    self.model_box.setItemData(self.model_box.count() - 1,
                                               f"{model.origin.format}: {model.origin.path}", Qt.ToolTipRole)
            index = self.model_box.findData(keep) if keep else -1
            self.model_box.setCurrentIndex(max(index, 0))

    def current(self) -> int | None:
        item = self.tree.currentItem()
        return None if item is None else item.data(0, Qt.UserRole)

    def follow(self, document) -> None:
        """Subscribe to the shown document (gui.document.ShownDocument): the material, or for
        measured data the next fit's initial guess, is what this panel edits."""
        self._followed = document
        for signal in (document.material_changed, document.guess_changed, document.switched):
            signal.connect(self._show_followed)

    def _show_followed(self, *_) -> None:  # a method: Qt disconnects it when this panel goes
        ws = self._followed.workspace
        self.show_material(ws.editable())
        self.setToolTip("" if ws.analytic is not None else
                        "Measured material: you are editing the initial guess of the next fit")

    def show_material(self, material: AnalyticMaterial | None) -> None:
        """Show `material`. When only values changed (same lobes, channels, combination), the
        rows are updated in place, so a dragged slider or a focused spin box keeps working."""
        if material is not None and self.material is not None and _shape(material) == _shape(self.material):
            self.material = material
            self._update_values()
            self._request_energy()
            return
        keep = self.current()
        self.material = material
        self.setEnabled(material is not None)
        with QSignalBlocker(self.tree):
            self.tree.clear()
            if material is None:
                self._clear_params()
                self._energy_job.request(None)
                self.energy.setText("A measured material without its data: its fits are listed in Fitting.")
                self.energy.setStyleSheet("")
                return
            for k, lobe in enumerate(material.lobes):
                label = lobe.model.name + (f"  (channel {lobe.channel})" if lobe.channel is not None else "")
                item = QTreeWidgetItem([label, _scale_text(lobe)])
                if lobe.model.origin is not None:
                    item.setToolTip(0, f"{lobe.model.origin.format}: {lobe.model.origin.path}")
                item.setData(0, Qt.UserRole, k)
                self.tree.addTopLevelItem(item)
            if material.lobes:
                k = keep if keep is not None and keep < len(material.lobes) else 0
                self.tree.setCurrentItem(self.tree.topLevelItem(k))
        with QSignalBlocker(self.combination), QSignalBlocker(self.channels):
            self.combination.setCurrentText(material.combination)
            self.channels.setValue(material.n_channels)
        self._show_lobe()
        self._request_energy()

    def shutdown(self) -> None:
        """Stop the editor's worker process (the window is closing)."""
        self._energy_job.shutdown()

    def _update_values(self) -> None:
        for k, lobe in enumerate(self.material.lobes):
            self.tree.topLevelItem(k).setText(1, _scale_text(lobe))
        k = self.current()
        if k is None or k >= len(self.material.lobes):
            return
        lobe = self.material.lobes[k]
        values = {("param", n): v for n, v in lobe.params.items()}
        values.update({("scale", c): s for c, s in enumerate(lobe.scale)})
        for key, row in self._rows.items():
            if key in values and not row.held():
                row.set_value(values[key])

    def _request_energy(self) -> None:
        if not self.material.lobes:
            self._energy_job.request(None)
            self.energy.setText("No lobes: the material reflects nothing.")
            self.energy.setStyleSheet("")
            self.energy_known.emit((True, [0.0]))
            return
        if not self._energy_job.busy:
            self.energy.setStyleSheet("color: #707070")
        self._energy_job.request(self.material)

    def _show_energy(self, summary) -> None:
        if summary is None:
            return
        self.energy_known.emit(summary)
        conserves, max_albedo = summary
        if conserves:
            self.energy.setText("Energy: albedo ≤ 1 for every view (max " + ", ".join(f"{a:.3f}" for a in max_albedo) + ")")
            self.energy.setStyleSheet("color: #2a7a2a")
        else:
            self.energy.setText(f"⚠ Energy: albedo up to {above_one(max(max_albedo))} > 1")
            self.energy.setStyleSheet("color: #b03030; font-weight: bold")

    def _clear_params(self) -> None:
        while self.params.rowCount():
            self.params.removeRow(0)

    def _show_lobe(self) -> None:
        self._clear_params()
        self._rows = {}
        k = self.current()
        if self.material is None or k is None or k >= len(self.material.lobes):
            return
        lobe = self.material.lobes[k]
        for p in lobe.model.parameters:
            row = ParameterRow(p.lower, p.upper, lobe.params[p.name], p.log)
            row.setToolTip(p.doc)
            row.edited.connect(lambda v, name=p.name, k=k: self.parameter_edited.emit(k, name, v))
            self.params.addRow(p.name, row)
            self._rows[("param", p.name)] = row
        for c, s in enumerate(lobe.scale):
            row = ParameterRow(0.0, max(10.0, 2 * s), s, False)
            channel = c if lobe.channel is None else lobe.channel
            swatch = QLabel("■")
            swatch.setStyleSheet(f"color: {CHANNEL_COLORS[channel % 3]}; font-size: 16px")
            box = QWidget()
            bl = QHBoxLayout(box)
            bl.setContentsMargins(0, 0, 0, 0)
            bl.addWidget(swatch)
            bl.addWidget(row, 1)
            row.edited.connect(lambda v, c=c, k=k: self.scale_edited.emit(k, c, v))
            self._rows[("scale", c)] = row
            self.params.addRow("value" if lobe.channel is not None else f"scale {c}", box)


def _shape(material: AnalyticMaterial) -> tuple:
    """What decides the editor's rows: values may change under it without a rebuild."""
    return material.combination, material.n_channels, tuple((l.model.name, l.channel) for l in material.lobes)


def _scale_text(lobe) -> str:
    return ", ".join(f"{s:.4g}" for s in lobe.scale)


def energy_summary(material: AnalyticMaterial | None):
    """(conserves, max albedo per channel) — run in a worker process by the editor."""
    if material is None:
        return None
    report = energy_check(material)
    return bool(report.conserves), [float(a) for a in report.max_albedo]


def energy_summaries(materials: list[AnalyticMaterial]) -> list:
    """energy_summary of each (the stored fits) — run in a worker process by the window."""
    return [energy_summary(m) for m in materials]


AUTO_LEVEL_TOLERANCE = 0.01  # of the lobe's peak radius


def auto_level_job(job: tuple) -> tuple[int, float]:
    """(sources, shape, tolerance) → geometry.lobe_surface.auto_level — run in a worker process."""
    from brdflab.geometry.lobe_surface import auto_level

    sources, shape, tolerance = job
    return auto_level(sources, shape, tolerance)


def refine_job(job: tuple) -> tuple:
    """(key, sources, shape, level) → (key, *geometry.lobe_surface.refined_surface, the
    sources' tips on it) — run in a worker process."""
    from brdflab.geometry.lobe_surface import lobe_tips, refined_surface

    key, sources, shape, level = job
    dirs, faces, peak = refined_surface(sources, shape, level, AUTO_LEVEL_TOLERANCE)
    return key, dirs, faces, peak, lobe_tips(sources, shape, dirs)


SAMPLE_AUTO_TIP = "Auto: a rung of lobes must improve the held-back error by more than this (relative) to be climbed"
SCENE_AUTO_TIP = ("scene-Auto (the image metric): the fewest lobes whose render of what the object view shows "
                  "(its mesh, camera and map) is within this image error of the measurement's (2 %: about one "
                  "just-noticeable difference)")


def _second_error(statistics: dict) -> str:
    """The number a stored fit was not fitted by, for the fits list ('' when it has none)."""
    if isinstance(statistics.get("imageError"), float):
        return f" · image {statistics['imageError']:.4g}"
    if isinstance(statistics.get("sampleError"), float):
        return f" · {statistics.get('sampleMetric', '')} {statistics['sampleError']:.5g}"
    return ""


def _side_by_side(*widgets: QWidget) -> QHBoxLayout:
    row = QHBoxLayout()
    for w in widgets:
        row.addWidget(w)
    row.addStretch(1)
    return row


class LobeControls(QWidget):
    """θ/φ of the incident direction and how the lobe is drawn."""

    changed = Signal()

    def __init__(self) -> None:
        super().__init__()
        self.theta = ParameterRow(0.0, 89.0, 30.0)
        self.phi = ParameterRow(0.0, 359.0, 0.0)
        self.transfer = QComboBox()
        self.transfer.addItems(["cbrt", "linear", "log"])
        self.channel = QComboBox()
        self.channel.addItems(["luminance", "red", "green", "blue"])
        self.cosine = QCheckBox("× cos θo")
        self.level = QSpinBox(minimum=2, maximum=7, value=5)
        self.auto_level = QCheckBox("auto")
        self.auto_level.setToolTip(f"the lowest subdivision that draws every lobe within {AUTO_LEVEL_TOLERANCE:.0%} "
                                   "of its peak radius (checked inside every triangle, in the background)")
        self.auto_level_note = QLabel("")
        self.auto_level_note.setStyleSheet("color: #707070")
        self.auto_level_note.setWordWrap(True)
        self.translucent = QCheckBox("translucent fit")
        self.translucent.setChecked(True)
        form = QFormLayout(self)  # one control or two per row: the dock is narrow on a laptop
        form.addRow("θi (°)", self.theta)
        form.addRow("φi (°)", self.phi)
        form.addRow("transfer", self.transfer)
        form.addRow("channel", self.channel)
        form.addRow(_side_by_side(self.cosine, self.translucent))
        form.addRow("subdivision", _side_by_side(self.level, self.auto_level, self.auto_level_note))
        self.auto_level.toggled.connect(self.level.setDisabled)
        self.auto_level.toggled.connect(lambda on: self.auto_level_note.setText("") if not on else None)
        self.auto_level.toggled.connect(lambda _: self.changed.emit())
        for sig in (self.theta.edited, self.phi.edited):
            sig.connect(lambda _: self.changed.emit())
        for box in (self.transfer, self.channel):
            box.currentIndexChanged.connect(lambda _: self.changed.emit())
        self.cosine.toggled.connect(lambda _: self.changed.emit())
        self.translucent.toggled.connect(lambda _: self.changed.emit())
        self.level.valueChanged.connect(lambda _: self.changed.emit())

    def apply(self, settings) -> None:
        settings.theta_i = self.theta.spin.value()
        settings.phi_i = self.phi.spin.value()
        settings.transfer = self.transfer.currentText()
        settings.channel = self.channel.currentText()
        settings.cosine = self.cosine.isChecked()
        settings.level = self.level.value()
        settings.translucent_fit = self.translucent.isChecked()


SH_TABLES = {"auto": "auto", "128² standard": "standard"}


def sh_table_choice() -> tuple[QComboBox, QLabel]:
    """The SH table's setting (Auto by default) and the label that shows what it built."""
    from brdflab.lighting.sh_table_auto import DEFAULT_TOLERANCE

    box = QComboBox()
    box.addItems(list(SH_TABLES))
    box.setToolTip(f"auto: the smallest table and fewest samples whose estimated error stays within "
                   f"{DEFAULT_TOLERANCE:.0%} (relative RMS over views), chosen in the background; "
                   "standard: 128² texels, 2^12 samples per elevation (2^8 per texel when anisotropic)")
    note = QLabel("")
    note.setStyleSheet("color: #707070")
    note.setWordWrap(True)
    return box, note


def sh_table_request(text: str):
    """The renderer's table request for the combo box's entry: AutoTable or the standard setting."""
    from brdflab.lighting.sh_table_auto import AutoTable
    from brdflab.lighting.sh_tables import STANDARD

    return AutoTable() if SH_TABLES[text] == "auto" else STANDARD


SHOWN = {"original": "off", "fitted": "off", "original | fit": "split", "difference": "difference"}


WARNING_STYLE = "color: #b03030; font-weight: bold"
PENDING_STYLE = "color: #707070"
CAVEAT_STYLE = "color: #a06000"


class WrappedLabel(QLabel):
    """A word-wrapped label that keeps the height its lines need at its width: a form inside
    a scroll area (the docks) sizes rows by minimum sizes and squeezed wrapped lines together."""

    def __init__(self) -> None:
        super().__init__(wordWrap=True)

    def setText(self, text: str) -> None:
        super().setText(text)
        self._fit_height()

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        self._fit_height()

    def _fit_height(self) -> None:
        self.setMinimumHeight(self.heightForWidth(max(self.width(), 1)) if self.text() else 0)


class StatusLines(QLabel):
    """A word-wrapped status of a fixed number of lines: a status that grows by a line must not
    move the buttons above it (a click at Fit's place would miss). Text past the last line is
    cut and the whole text is the tooltip."""

    def __init__(self, lines: int = 3) -> None:
        super().__init__(wordWrap=True, alignment=Qt.AlignLeft | Qt.AlignTop)
        self.setFixedHeight(lines * self.fontMetrics().lineSpacing() + 4)

    def setText(self, text: str) -> None:
        super().setText(text)
        self.setToolTip(text)


class ObjectControls(QWidget):
    """Lighting mode (or auto: the cheapest predicted within a tolerance), samples, exposure,
    environment rotation, which material is shown."""

    changed = Signal()
    open_mesh = Signal()
    open_environment = Signal()

    def __init__(self) -> None:
        super().__init__()
        self.mode = QComboBox()
        self.mode.addItems(["fis", "point", "sh", "prefiltered", "mis", "auto"])
        self.mode.setItemData(self.mode.findText("auto"), "the cheapest of prefiltered, SH and FIS / MIS predicted to "
                              "stay within the tolerance for this material and map (chosen in the background)",
                              Qt.ToolTipRole)
        self.tolerance = QDoubleSpinBox(minimum=0.01, maximum=50.0, value=100 * LIGHTING_TOLERANCE, decimals=2,
                                        singleStep=0.5, suffix=" %", enabled=False)
        self.tolerance.setKeyboardTracking(False)
        self.tolerance.setToolTip("auto: the relative error (reference view, over the view and per pixel) the chosen lighting is predicted to stay within")
        self.auto_note = WrappedLabel()
        self.auto_note.setVisible(False)
        self.auto_caveat = WrappedLabel()  # where the view departs from what the choice predicts for
        self.auto_caveat.setStyleSheet(CAVEAT_STYLE)
        self.auto_caveat.setVisible(False)
        self._auto_mode: str | None = None  # the mode of the choice shown
        self.sh_order = QSpinBox(minimum=1, maximum=10, value=5)
        self.sh_shadows = QCheckBox("SH self-shadowing")
        self.sh_variant = QComboBox()
        self.sh_variant.addItems(["dynamic", "fixed-light", "fixed-view"])
        self.sh_table, self.sh_table_note = sh_table_choice()
        self.samples = QSpinBox(minimum=1, maximum=4096, value=256)
        self.exposure = ParameterRow(-8.0, 8.0, 0.0)
        self.gamma = QDoubleSpinBox(minimum=0.0, maximum=4.0, value=0.0, singleStep=0.1, specialValueText="sRGB")
        self.rotation = ParameterRow(0.0, 359.0, 0.0)
        self.env_layout = QComboBox()  # not `layout`: that is QWidget's
        self.env_layout.addItems(list(LAYOUTS))
        self.env_layout.setToolTip(LAYOUT_TIP)
        self.light_theta = ParameterRow(0.0, 89.0, 35.0)
        self.light_phi = ParameterRow(0.0, 359.0, 40.0)
        self.shown = QComboBox()
        self.shown.addItems(list(SHOWN))
        self.shown.setToolTip("What the object shows: the original, the shown fit, both split down the middle "
                              "(original left, fit right), or their relative difference (black 0, white 100 %; "
                              "fis, mis and point modes)")
        self.reinhard = QCheckBox("Reinhard")
        mesh, env = QPushButton("Open mesh…"), QPushButton("Open environment…")
        mesh.clicked.connect(self.open_mesh.emit)
        env.clicked.connect(self.open_environment.emit)
        form = QFormLayout(self)
        form.addRow("lighting", self.mode)
        form.addRow("tolerance", self.tolerance)
        form.addRow(self.auto_note)
        form.addRow(self.auto_caveat)
        form.addRow("samples", self.samples)
        form.addRow("SH order", self.sh_order)
        form.addRow("SH variant", self.sh_variant)
        form.addRow("SH table", self.sh_table)
        form.addRow(self.sh_table_note)
        form.addRow("exposure (EV)", self.exposure)
        form.addRow("gamma", self.gamma)
        form.addRow("environment rotation (°)", self.rotation)
        form.addRow("map layout", self.env_layout)
        form.addRow("light θ (°)", self.light_theta)
        form.addRow("light φ (°)", self.light_phi)
        form.addRow("show", self.shown)
        for pair in ((mesh, env), (self.reinhard, self.sh_shadows)):  # two short rows: the dock stays narrow
            row = QHBoxLayout()
            for w in pair:
                row.addWidget(w)
            form.addRow(row)
        self.mode.currentIndexChanged.connect(lambda _: self._auto_toggled())
        self.sh_shadows.toggled.connect(lambda _: self._show_auto_caveat())
        self.sh_variant.currentIndexChanged.connect(lambda _: self._show_auto_caveat())
        self.mode.currentIndexChanged.connect(lambda _: self.changed.emit())
        self.tolerance.valueChanged.connect(lambda _: self.changed.emit())
        self.samples.valueChanged.connect(lambda _: self.changed.emit())
        self.sh_order.valueChanged.connect(lambda _: self.changed.emit())
        self.shown.currentIndexChanged.connect(lambda _: self.changed.emit())
        self.reinhard.toggled.connect(lambda _: self.changed.emit())
        self.gamma.valueChanged.connect(lambda _: self.changed.emit())
        self.sh_shadows.toggled.connect(lambda _: self.changed.emit())
        self.sh_variant.currentIndexChanged.connect(lambda _: self.changed.emit())
        self.sh_table.currentIndexChanged.connect(lambda _: self.changed.emit())
        for row_ in (self.exposure, self.rotation, self.light_theta, self.light_phi):
            row_.edited.connect(lambda _: self.changed.emit())

    @property
    def auto(self) -> bool:
        return self.mode.currentText() == "auto"

    def _auto_toggled(self) -> None:
        """Auto sets the samples and the SH order (shown, not editable); the tolerance is its own."""
        for w in (self.samples, self.sh_order):
            w.setEnabled(not self.auto)
        self.tolerance.setEnabled(self.auto)
        self.auto_note.setVisible(self.auto or self.mode.currentText() == "prefiltered")  # what either predicts
        if not self.auto:
            self._auto_mode = None
        self._show_auto_caveat()

    def _show_auto_caveat(self) -> None:
        """Auto predicts plain SH lighting (the command line refuses the rest): say so when the
        chosen SH mode is drawn self-shadowed or as a fixed variant."""
        departs = []
        if self._auto_mode == "sh" and self.sh_shadows.isChecked():
            departs.append("SH self-shadowing is on")
        if self._auto_mode == "sh" and self.sh_variant.currentText() != "dynamic":
            departs.append(f"the SH variant is {self.sh_variant.currentText()}")
        text = ("the prediction is for unshadowed, dynamic SH; here " + ", ".join(departs)
                if self.auto and departs else "")
        self.auto_caveat.setText(text)
        self.auto_caveat.setVisible(bool(text))

    def show_auto_note(self, text: str, tooltip: str = "", style: str = "") -> None:
        """The line under the lighting choice: what auto chose (or is doing) and why, or how far off the prefiltered mode is predicted."""
        self.auto_note.setText(text)
        self.auto_note.setToolTip(tooltip)
        self.auto_note.setStyleSheet(style)

    def show_auto_choice(self, choice) -> None:
        """The choice (lighting.auto.LightingChoice): its settings in the disabled spin boxes
        (without signalling an edit), its summary, every reason and candidate in the tooltip."""
        settings = choice.render_settings()
        with QSignalBlocker(self.samples), QSignalBlocker(self.sh_order):
            self.samples.setValue(settings["samples"])
            if settings["sh_order"] is not None:
                self.sh_order.setValue(settings["sh_order"])
        self.show_auto_note(f"{summary(choice)}\n{choice.reasons[0]}", details(choice), "" if choice.within else WARNING_STYLE)
        self._auto_mode = choice.mode
        self._show_auto_caveat()

    def light(self) -> tuple[float, float, float]:
        t, p = math.radians(self.light_theta.spin.value()), math.radians(self.light_phi.spin.value())
        # world: +Y up, the camera starts on +Z
        return (math.sin(t) * math.sin(p), math.cos(t), math.sin(t) * math.cos(p))


class FittingPanel(QWidget):
    """Stored fits, and a new fit: lobes, strategy, metric, samples; Fit / Stop. Auto climbs
    the ladder of lobe sets instead (fitting/auto.py) within a tolerance, on a split of the
    source's samples, over the named models."""

    fit_requested = Signal(list, str, str, str, int)  # lobes, combination, metric, sample kind, size
    auto_requested = Signal(dict)  # auto_fit's settings: tolerance, metric, combination, split, models
    ladder_requested = Signal()
    stop_requested = Signal()
    fit_selected = Signal(int)
    refit_requested = Signal(int)
    promote_requested = Signal(int)
    fits_energy_known = Signal(list)  # one energy summary per stored fit, checked

    def __init__(self) -> None:
        super().__init__()
        self.fits = QListWidget()
        self.fits.currentRowChanged.connect(lambda r: r >= 0 and self.fit_selected.emit(r))
        # the list takes the height left over (at least three rows): the controls below stay in view
        self.fits.setSizePolicy(QSizePolicy.Expanding, QSizePolicy.Ignored)
        self.fits.setMinimumHeight(3 * self.fits.fontMetrics().height() + 12)
        self.lobes = QComboBox()
        self.lobes.setEditable(True)
        self.lobes.addItems(["Lambertian,LafortuneIso", "Lambertian,CookTorrance", "Lambertian,Ward",
                             "Lambertian,Kurt", "Lambertian,CookTorrance,CookTorrance", "Lambertian,BlinnPhong"])
        self.strategy = QComboBox()
        self.strategy.addItems(["Linear", "Fixed"])
        self.metric_box = QComboBox()
        self.metric_box.addItems(list(METRICS))
        self.metric_box.setCurrentText(DEFAULT_METRIC)  # the core's default, the same as the command line's
        self.metric_box.setToolTip(DEFAULTS_WHY)
        self.sample_kind = QComboBox()
        self.sample_kind.addItems(["all", "subset", "grid"])
        self.sample_size = QSpinBox(minimum=1000, maximum=2_000_000, value=50_000, singleStep=10_000)
        self.fit_button, self.stop_button = QPushButton("Fit"), QPushButton("Stop")
        self.stop_button.setEnabled(False)
        self.auto_button = QPushButton("Auto")
        self.auto_button.setToolTip("Climb from the Lambertian to three lobes, fitting half of a split of the "
                                    "samples and scoring the other half; stop when more lobes no longer pay")
        self.tolerance = QDoubleSpinBox(decimals=1, minimum=0.0, maximum=99.9, value=100 * FIT_TOLERANCE,
                                        singleStep=0.5, suffix=" %")
        self.tolerance.setToolTip(SAMPLE_AUTO_TIP)
        self.metric_box.currentTextChanged.connect(self._metric_changed)
        self.auto_models = QLineEdit()
        self.auto_models.setPlaceholderText("all models")
        self.auto_models.setToolTip("Auto: the lobe models to try, comma-separated (empty: all of "
                                    + ", ".join(m for m in model_names() if m != "Lambertian") + ")")
        self.auto_split = QSpinBox(minimum=100, maximum=2_000_000, value=DEFAULT_SPLIT, singleStep=5_000)
        self.auto_split.setToolTip("Auto: samples fitted, and as many held back")
        self.ladder_button = QPushButton("Ladder")
        self.ladder_button.setToolTip("The last Auto run's candidates, errors and choice")
        self.ladder_button.setEnabled(False)
        self.refit_button, self.promote_button = QPushButton("Fit again from this"), QPushButton("Make main material")
        self.progress = QProgressBar()
        self.progress.setRange(0, 0)
        keep = self.progress.sizePolicy()
        keep.setRetainSizeWhenHidden(True)  # showing it moves nothing
        self.progress.setSizePolicy(keep)
        self.progress.setVisible(False)
        self.status = StatusLines()  # a long status neither widens the dock nor moves a button
        self.fit_button.clicked.connect(self._request)
        self.auto_button.clicked.connect(self._request_auto)
        self.ladder_button.clicked.connect(self.ladder_requested.emit)
        self.stop_button.clicked.connect(self.stop_requested.emit)
        self.refit_button.clicked.connect(lambda: self.fits.currentRow() >= 0 and self.refit_requested.emit(self.fits.currentRow()))
        self.promote_button.clicked.connect(lambda: self.fits.currentRow() >= 0 and self.promote_requested.emit(self.fits.currentRow()))
        controls = QWidget()
        grid = QGridLayout(controls)
        grid.addWidget(QLabel("Stored fits"), 0, 0, 1, 2)
        grid.addWidget(self.fits, 1, 0, 1, 4)
        grid.addWidget(self.refit_button, 2, 0, 1, 2)
        grid.addWidget(self.promote_button, 2, 2, 1, 2)
        grid.addWidget(QLabel("lobes"), 3, 0)
        grid.addWidget(self.lobes, 3, 1, 1, 3)
        grid.addWidget(QLabel("strategy"), 4, 0)
        grid.addWidget(self.strategy, 4, 1)
        grid.addWidget(QLabel("metric"), 4, 2)
        grid.addWidget(self.metric_box, 4, 3)
        grid.addWidget(QLabel("samples"), 5, 0)
        grid.addWidget(self.sample_kind, 5, 1)
        grid.addWidget(self.sample_size, 5, 2, 1, 2)
        grid.addWidget(self.fit_button, 6, 0, 1, 2)
        grid.addWidget(self.auto_button, 6, 2)
        grid.addWidget(self.stop_button, 6, 3)
        grid.addWidget(QLabel("tolerance"), 7, 0)
        grid.addWidget(self.tolerance, 7, 1)
        grid.addWidget(QLabel("split"), 7, 2)
        grid.addWidget(self.auto_split, 7, 3)
        grid.addWidget(QLabel("models"), 8, 0)
        grid.addWidget(self.auto_models, 8, 1, 1, 2)
        grid.addWidget(self.ladder_button, 8, 3)
        grid.setRowStretch(1, 1)  # spare height goes to the stored fits
        # the controls scroll; a run's progress and result stay in view below them (in the
        # grid's last rows they were below the fold at every window size)
        column = QVBoxLayout(self)
        column.setContentsMargins(0, 0, 0, 0)
        column.addWidget(scrolling(controls), 1)
        footer = QVBoxLayout()
        margins = grid.contentsMargins()
        footer.setContentsMargins(margins.left(), 0, margins.right(), margins.bottom())
        footer.addWidget(self.progress)
        footer.addWidget(self.status)
        column.addLayout(footer)

    def _request(self) -> None:
        lobes = [s.strip() for s in self.lobes.currentText().split(",") if s.strip()]
        self.fit_requested.emit(lobes, self.strategy.currentText(), self.metric_box.currentText(),
                                self.sample_kind.currentText(), self.sample_size.value())

    def _metric_changed(self, metric: str) -> None:
        """Auto's tolerance means a relative gain on held-back samples, or (the image metric:
        scene-Auto) an image error in the object view's scene: each has its own default,
        and an untouched value follows the metric."""
        scene = metric == "image"
        if self.tolerance.value() == 100 * (FIT_TOLERANCE if scene else DEFAULT_SCENE_TOLERANCE):
            self.tolerance.setValue(100 * (DEFAULT_SCENE_TOLERANCE if scene else FIT_TOLERANCE))
        self.tolerance.setToolTip(SCENE_AUTO_TIP if scene else SAMPLE_AUTO_TIP)

    def auto_settings(self) -> dict:
        """auto_fit's settings from the panel (models: None for all)."""
        models = [m.strip() for m in self.auto_models.text().split(",") if m.strip()]
        return {"tolerance": self.tolerance.value() / 100.0, "metric": self.metric_box.currentText(),
                "combination": self.strategy.currentText(), "split": self.auto_split.value(), "models": models or None}

    def _request_auto(self) -> None:
        self.auto_requested.emit(self.auto_settings())

    def follow(self, document) -> None:
        """Subscribe to the shown document (gui.document.ShownDocument): its stored fits, marked
        (once a worker process has checked them) where they do not conserve energy; a fit
        chosen in the list is the one the document draws."""
        self._followed = document
        self._energy_job = LatestOnly(energy_summaries, self)
        self._energy_job.done.connect(self._energy_known)
        document.fittings_changed.connect(self._show_followed)
        document.switched.connect(self._show_followed)
        self.fit_selected.connect(document.select_fit)

    def _show_followed(self, *_) -> None:
        fittings = self._followed.workspace.document.fittings
        self.show_fits(fittings, self._followed.workspace.shown_fit)
        self._energy_for = fittings
        self._energy_job.request([f.material for f in fittings])

    def _energy_known(self, summaries: list) -> None:
        ws = self._followed.workspace
        if self._energy_for is not ws.document.fittings or len(summaries) != len(self._energy_for):
            return  # about fits that have changed since: a newer request is on its way
        self.show_fits(self._energy_for, ws.shown_fit, summaries)
        self.fits_energy_known.emit(summaries)

    def shutdown(self) -> None:
        self._energy_job.shutdown()

    def show_fits(self, fittings, shown: int | None, energy: list | None = None) -> None:
        """The stored fits; `energy` (one summary per fit, when known) marks those that do not
        conserve energy."""
        with QSignalBlocker(self.fits):
            self.fits.clear()
            for k, f in enumerate(fittings):
                # one name per lobe (Auto picks repeat a model), not per channel of a Fixed fit
                lobes = "+".join(f.material.lobe_models())
                err = "—" if f.error is None else f"{f.error:.5g}"
                metric = f.statistics.get("metric", "")
                second = _second_error(f.statistics)
                summary = energy[k] if energy is not None and k < len(energy) else None
                mark = f"  ⚠ albedo {max(summary[1]):.3g}" if summary is not None and not summary[0] else ""
                self.fits.addItem(f"{k}: {lobes}  {metric} {err}{second}{mark}")
            if shown is not None and shown < len(fittings):
                self.fits.setCurrentRow(shown)

    def set_running(self, running: bool) -> None:
        """Fit and Auto, or Stop. The focus goes from the button clicked to the one enabled
        (disabling a focused button handed it down the panel, which scrolled to it)."""
        starts, stop = (self.fit_button, self.auto_button), self.stop_button
        enabled, disabled = ((stop,), starts) if running else (starts, (stop,))
        for button in enabled:
            button.setEnabled(True)
        if any(b.hasFocus() for b in disabled):
            enabled[0].setFocus(Qt.OtherFocusReason)
        for button in disabled:
            button.setEnabled(False)
        self.progress.setVisible(running)
        self.progress.setRange(0, 0)  # busy until a run reports how far it is
        self.progress.setFormat("%p%")


PLOT_ROW_HEIGHT = 210  # figure pixels (at 100 dpi) a row of plots needs to stay readable
PLOT_COLUMN_WIDTH = 200  # and a column: narrower, neighbours' labels overlap (and below ~70, the layout gives up)


def plot_grid(compare: bool, width: int) -> tuple[int, int]:
    """(columns, rows) of the plots in a figure `width` pixels wide: three columns where
    they fit, else two or one, the plots reflowed into more rows (the panel scrolls)."""
    plots = 6 if compare else 3
    columns = max(1, min(3, width // PLOT_COLUMN_WIDTH))
    return columns, -(-plots // columns)


class PlotsPanel(QWidget):
    """BRDF Explorer's plots: the plane of incidence (polar), a θh × θd slice, albedo(θ).

    The figure is computed and drawn (matplotlib, Agg) in a worker process and shown as an
    image, so neither the evaluation nor matplotlib's layout ever blocks the window."""

    def __init__(self) -> None:
        super().__init__()
        self.image = QLabel(alignment=Qt.AlignCenter)
        self.scroll = QScrollArea()  # two rows of plots (a fit to compare) scroll rather than shrink
        self.scroll.setWidget(self.image)
        self.scroll.setMinimumSize(200, 120)
        self.scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarAlwaysOff)
        self.status = QLabel("")
        self.status.setStyleSheet("color: #707070")
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.scroll, 1)
        lay.addWidget(self.status)
        self._job = LatestOnly(draw_plots_of, self)
        self._job.done.connect(self._show)
        self._job.failed.connect(lambda m: self.status.setText(f"plots failed: {m}"))
        self._last: tuple | None = None
        self._document = 0  # numbers the documents shown: plots of an earlier one are dropped

    def follow(self, document, theta_i: Callable[[], float]) -> None:
        """Subscribe to the shown document (gui.document.ShownDocument): another one shown, these
        plots go; any change, they are drawn again (coalesced) at the lobe viewer's θi."""
        self._followed, self._theta_i = document, theta_i
        self._redraw = QTimer(self, singleShot=True, interval=250)
        self._redraw.timeout.connect(self._draw_followed)
        document.switched.connect(self._switched)
        for signal in (document.material_changed, document.fittings_changed, document.drawn_changed):
            signal.connect(self.refresh_soon)

    def _switched(self, workspace) -> None:
        self.new_document(workspace.title.rstrip(" *"))
        self.refresh_soon()

    def _draw_followed(self) -> None:
        d = self._followed
        self.show_sources(d.original(), d.fit_or_run(), self._theta_i(), d.history)

    def refresh_soon(self, *_) -> None:
        """Draw again in a moment, with what is shown then (a running fit's reports coalesce)."""
        if not self._redraw.isActive():
            self._redraw.start()

    def new_document(self, title: str) -> None:
        """Another document is shown: nothing of the last one stays drawn while its plots are
        computed (a measured table's take 14–45 s; the old plots stayed up meanwhile, marked
        only by a small grey "updating…")."""
        self._document += 1
        self.image.clear()
        self.image.setText(f"plotting {title}…")
        self.image.resize(self.scroll.viewport().size())

    def show_sources(self, original, fitted, theta_i_deg: float, history: list | None = None) -> None:
        """`history`: (iteration, error) of the running or last fit, for its convergence plot."""
        self._last = (original, fitted, theta_i_deg, list(history or []))
        self._request()

    def _request(self) -> None:
        if self._last is None:
            return
        ratio = self.devicePixelRatioF()
        room = self.scroll.maximumViewportSize()  # the viewport without scroll bars
        compare = self._last[0] is not None and self._last[1] is not None
        width = max(200, room.width())
        _, rows = plot_grid(compare, int(width * ratio))
        if PLOT_ROW_HEIGHT * rows > room.height():  # taller than the dock: the scroll bar takes its width
            width = max(200, room.width() - self.scroll.verticalScrollBar().sizeHint().width())
            _, rows = plot_grid(compare, int(width * ratio))
        height = max(120, room.height(), PLOT_ROW_HEIGHT * rows)
        size = (int(width * ratio), int(height * ratio))
        self.status.setText("updating…")
        self._job.request((self._document, (*self._last, size)))

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        self._request()

    def _show(self, result: tuple[int, np.ndarray]) -> None:
        from PySide6.QtGui import QImage, QPixmap

        document, rgba = result
        if document != self._document:
            return  # the plots of a document no longer shown
        h, w = rgba.shape[:2]
        # copy into an image Qt owns (QImage over a Python bytes object broke None's refcount)
        img = QImage(w, h, QImage.Format_RGBA8888)
        np.frombuffer(img.bits(), np.uint8).reshape(h, img.bytesPerLine())[:, : 4 * w] = rgba.reshape(h, 4 * w)
        img.setDevicePixelRatio(self.devicePixelRatioF())
        self.image.setPixmap(QPixmap.fromImage(img))
        self.image.resize(round(w / self.devicePixelRatioF()), round(h / self.devicePixelRatioF()))
        self.status.setText("")

    def shutdown(self) -> None:
        self._job.shutdown()


def _luminance(f: np.ndarray) -> np.ndarray:
    f = np.asarray(f)[:, :3]
    weights = np.array([0.2126, 0.7152, 0.0722])[: f.shape[1]]
    return f @ weights / weights.sum() if f.shape[1] > 1 else f[:, 0]


def _slice(source) -> np.ndarray:
    """Luminance on the θh × θd plane at φd = 90° (MERL's θh spacing), 90 × 90."""
    from brdflab.geometry.halfdiff import from_half_diff

    th = ((np.arange(90) + 0.5) / 90.0) ** 2 * np.pi / 2
    td = (np.arange(90) + 0.5) / 90.0 * np.pi / 2
    TH, TD = np.meshgrid(th, td, indexing="ij")
    a, b = from_half_diff(TH.ravel(), 0.0, TD.ravel(), np.full(TH.size, np.pi / 2))
    return _luminance(source.evaluate(a, b)).reshape(90, 90)


def _slice_axes(ax, title: str) -> None:
    ax.set_xlabel("θh bin (MERL spacing)", fontsize=7)
    ax.set_ylabel("θd (°)", fontsize=7)
    ax.set_title(title, fontsize=8)
    ax.tick_params(labelsize=6)


def draw_plots(request) -> np.ndarray:
    """The plots as an RGBA image of the requested pixel size (runs in a worker)."""
    figure = plot_figure(request)
    figure.canvas.draw()
    return np.asarray(figure.canvas.buffer_rgba()).copy()


def draw_plots_of(job: tuple) -> tuple:
    """(document number, image) of draw_plots(request) for job = (document number, request)."""
    document, request = job
    return document, draw_plots(request)


def plot_figure(request):
    """The plots' matplotlib figure (Agg canvas) at the requested pixel size, laid out in
    plot_grid's columns and rows: what draw_plots draws.

    Always: the plane of incidence (polar), directional albedo and the θh × θd slice. With a
    fit: the fit's slice and the error slice (log10 fit / original) beside the original's,
    and the running fit's convergence (error per iteration)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    from brdflab.geometry.vec import spherical_to_cartesian

    original, fitted, theta_i_deg, history, (width, height) = request
    compare = original is not None and fitted is not None
    dpi = 100
    figure = Figure(figsize=(width / dpi, height / dpi), dpi=dpi, layout="constrained")
    FigureCanvasAgg(figure)
    columns, rows = plot_grid(compare, width)
    grid = figure.add_gridspec(rows, columns)
    split = "\n" if width / columns < 240 else " "  # the longest titles on two lines in narrow columns

    def cell(k: int, **kw):
        """The k-th plot's axes, row by row."""
        return figure.add_subplot(grid[k // columns, k % columns], **kw)

    ax_polar = cell(0, projection="polar")
    ax_albedo = cell(1)
    ax_third = cell(2)
    pairs = [(s, label, style) for s, label, style in ((original, "original", "-"), (fitted, "fit", "--"))
             if s is not None]

    t = np.radians(np.linspace(-89.5, 89.5, 361))
    wo = spherical_to_cartesian(np.abs(t), np.where(t < 0, np.pi, 0.0))
    wi = np.broadcast_to(spherical_to_cartesian(np.radians(theta_i_deg), np.pi), wo.shape)
    for source, label, style in pairs:
        ax_polar.plot(t, np.cbrt(np.maximum(_luminance(source.evaluate(wi, wo)), 0)), style, label=label)
    ax_polar.set_thetamin(-90)
    ax_polar.set_thetamax(90)
    ax_polar.set_theta_zero_location("N")
    ax_polar.yaxis.set_major_locator(MaxNLocator(3))  # few radial labels: they never overlap
    ax_polar.set_rlabel_position(-80)
    ax_polar.tick_params(labelsize=6)
    ax_polar.set_title(f"plane of incidence,{split}θi = {theta_i_deg:.0f}° (∛f)", fontsize=8)

    theta = np.radians(np.linspace(0, 85, 18))
    for src, label, style in pairs:
        if not isinstance(src, AnalyticMaterial) or src.lobes:
            ax_albedo.plot(np.degrees(theta), albedo_curve(src, theta), style, label=label)
    ax_albedo.axhline(1.0, color="grey", lw=0.8, ls=":")
    ax_albedo.set_xlabel("θo (°)", fontsize=7)
    ax_albedo.set_ylabel("albedo (luminance)", fontsize=7)
    ax_albedo.set_title(f"directional albedo{split}(1: dotted)", fontsize=8)
    ax_albedo.tick_params(labelsize=6)
    if ax_albedo.get_legend_handles_labels()[0]:  # which curve is which, here and in the polar plot
        ax_albedo.legend(fontsize=6, loc="best", framealpha=0.8)

    if compare:
        _convergence(ax_third, history, split)
        a, b = _slice(original), _slice(fitted)
        logs = [np.log10(np.maximum(x, 1e-4)) for x in (a, b)]
        lo, hi = min(l.min() for l in logs), max(l.max() for l in logs)
        together = 3 // columns == 4 // columns  # the two slices in one row share a colour bar
        for k, (img, title) in enumerate(zip(logs, ("log10 f, original", "log10 f, fit"))):
            ax = cell(3 + k)
            shown = ax.imshow(img.T, origin="lower", aspect="auto", extent=(0, 90, 0, 90), vmin=lo, vmax=hi)
            _slice_axes(ax, title + ", φd = 90°")
            if not together:
                _colorbar(figure, shown, ax, "log10 f (1/sr)")
        if together:
            _colorbar(figure, shown, figure.axes[-2:], "log10 f (1/sr)")
        ax = cell(5)
        ratio = np.log10(np.maximum(b, 1e-4) / np.maximum(a, 1e-4))
        shown = ax.imshow(ratio.T, origin="lower", aspect="auto", extent=(0, 90, 0, 90), cmap="RdBu_r", vmin=-1, vmax=1)
        _slice_axes(ax, "error: log10 (fit / original)")
        _colorbar(figure, shown, ax, "decades (red: fit too bright)")
    else:
        source = original if original is not None else fitted
        if source is not None:
            shown = ax_third.imshow(np.log10(np.maximum(_slice(source), 1e-4)).T, origin="lower", aspect="auto",
                                    extent=(0, 90, 0, 90))
            _colorbar(figure, shown, ax_third, "log10 f (1/sr)")
            _slice_axes(ax_third, "log10 f, φd = 90°")
    return figure


def albedo_curve(source, theta: np.ndarray) -> np.ndarray:
    """The plotted directional albedo (luminance) at view angles θo (radians, φo = 0):
    importance-sampled for analytic materials, a half-vector quadrature for measured data."""
    from brdflab.geometry.vec import spherical_to_cartesian
    from brdflab.material.albedo import directional_albedo, half_vector_albedo

    views = spherical_to_cartesian(theta, 0.0)
    albedo = directional_albedo(source, views, samples_log2=9) if isinstance(source, AnalyticMaterial) \
        else half_vector_albedo(source, views)
    return _luminance(albedo)


def _colorbar(figure, shown, ax, label: str) -> None:
    bar = figure.colorbar(shown, ax=ax)
    bar.set_label(label, fontsize=7)
    bar.ax.tick_params(labelsize=6)


def _convergence(ax, history: list, split: str = " ") -> None:
    """Error per iteration of the running (or last) fit, log scale; `split`: a narrow
    column's line break in the axis label."""
    if history:
        it, err = np.array([h[0] for h in history]), np.array([h[1] for h in history])
        ax.semilogy(np.arange(len(err)), np.maximum(err, 1e-300), ".-", ms=3)
        ax.set_xlabel(f"progress reports{split}(starting points,\nthen LM; iteration {it[-1]})", fontsize=7)
    else:
        ax.text(0.5, 0.5, "fit to see\nits convergence", ha="center", va="center", fontsize=7, color="grey",
                transform=ax.transAxes)
        ax.set_xticks([])  # nothing plotted: no scale (its labels were under the note)
        ax.set_yticks([])
    ax.set_ylabel("error", fontsize=7)
    ax.set_title("fit convergence", fontsize=8)
    ax.tick_params(which="both", labelsize=6)  # a log axis's minor labels (2×10⁻¹) too


class XmlHighlighter(QSyntaxHighlighter):
    def highlightBlock(self, text: str) -> None:
        import re

        tag, attr, value = QTextCharFormat(), QTextCharFormat(), QTextCharFormat()
        tag.setForeground(QColor("#2050a0"))
        attr.setForeground(QColor("#a05020"))
        value.setForeground(QColor("#208040"))
        for m in re.finditer(r"</?[\w:]+|/?>", text):
            self.setFormat(m.start(), m.end() - m.start(), tag)
        for m in re.finditer(r'(\w+)=("[^"]*"|\'[^\']*\')', text):
            self.setFormat(m.start(1), len(m.group(1)), attr)
            self.setFormat(m.start(2), len(m.group(2)), value)


class XmlView(QPlainTextEdit):
    """The shown document as its file would hold it, written again (coalesced) on every change
    while it can be seen: a serialisation costs."""

    def __init__(self) -> None:
        super().__init__(readOnly=True)
        self.setFont(QFont("monospace"))
        self.highlighter = XmlHighlighter(self.document())
        self._shown = None
        self._stale = False
        self._rewrite = QTimer(self, singleShot=True, interval=150)
        self._rewrite.timeout.connect(self._write)

    def follow(self, document) -> None:
        """Subscribe to the shown document (gui.document.ShownDocument)."""
        self._shown = document
        for signal in (document.switched, document.material_changed, document.fittings_changed, document.saved):
            signal.connect(self._rewrite_soon)

    def _rewrite_soon(self, *_) -> None:
        self._rewrite.start()

    def _write(self) -> None:
        self._stale = not (self.isVisible() or self.toPlainText() == "")
        if not self._stale:
            self.setPlainText(to_text(self._shown.workspace.document))

    def showEvent(self, event) -> None:
        super().showEvent(event)
        if self._stale:
            self._write()
