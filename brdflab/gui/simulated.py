"""The Simulation dock: choose a simulated kind, edit its parameters, and watch its lobe
(BRDFLab §4, Figs. 9–10). The lobe comes from a (θo, φo) texture computed straight from
the simulation in a worker thread, coarse first then fine, with the time each took; any
change restarts it. "Save…" writes the simulated material file.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from PySide6.QtCore import QTimer, Signal
from PySide6.QtWidgets import (QComboBox, QDoubleSpinBox, QFileDialog, QFormLayout, QHBoxLayout, QLabel, QMessageBox,
                               QPushButton, QSpinBox, QVBoxLayout, QWidget)

from brdflab.errors import BRDFLabError
from brdflab.gui.gl_views import LobeView
from brdflab.io.xmlio import BRDFDocument, save
from brdflab.simulation.material import SimulationSpec, reference_of
from brdflab.simulation.registry import KINDS, get_kind
from brdflab.simulation.texture import lobe_texture

# texture rows per step: SCATMECH as BRDFLab (32 then 150); ray bouncing is costlier per texel
LEVELS = {"SCATMECH": (32, 150), "RayBounce": (12, 32)}


class SimulatedPanel(QWidget):
    """Kind, parameters, incidence and a lobe view of one simulated material."""

    texture_shown = Signal(int, float)  # level index, seconds
    use_requested = Signal(object)  # the spec to open as the window's material
    failed = Signal(str)
    _ready = Signal(int, int, object)  # generation, level, texture (from the worker)

    def __init__(self, spec: SimulationSpec | None = None, levels: dict | None = None, parent=None) -> None:
        super().__init__(parent)
        self.levels = levels or LEVELS
        self.spec = spec or SimulationSpec(next(k for k in KINDS.values() if k.available).name)
        self._generation = 0
        self._times: list[str] = []
        self._pool = ThreadPoolExecutor(max_workers=1)
        self.kind = QComboBox()
        for k in KINDS.values():
            self.kind.addItem(f"{k.name} ({k.library})", k.name)
            if not k.available:
                self.kind.model().item(self.kind.count() - 1).setEnabled(False)
                self.kind.setItemData(self.kind.count() - 1, "pySCATMECH is not installed", 3)  # tooltip role
        self.kind.setCurrentIndex(self.kind.findData(self.spec.kind))
        self.theta_i = QDoubleSpinBox(minimum=0.0, maximum=89.0, value=30.0, suffix="°", singleStep=5.0)
        self.form = QFormLayout()
        self.status = QLabel("")
        self.status.setWordWrap(True)
        self.view = LobeView()
        save_button = QPushButton("Save…")
        save_button.clicked.connect(self._save_dialog)
        self.use_button = QPushButton("Use")
        self.use_button.setToolTip("make this the window's material (its table is built in the background)")
        self.use_button.clicked.connect(lambda: self.use_requested.emit(self.spec))
        top = QHBoxLayout()
        top.addWidget(self.kind, 1)
        top.addWidget(self.use_button)
        top.addWidget(save_button)
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        layout.addLayout(self.form)
        incidence = QHBoxLayout()
        incidence.addWidget(QLabel("θi of the lobe"))
        incidence.addWidget(self.theta_i, 1)
        layout.addLayout(incidence)
        layout.addWidget(self.status)
        layout.addWidget(self.view, 1)
        self._editors: dict = {}
        self._build_editors()
        self._restart_timer = QTimer(self, singleShot=True, interval=150)
        self._restart_timer.timeout.connect(self.restart)
        self.kind.currentIndexChanged.connect(self._kind_changed)
        self.theta_i.valueChanged.connect(lambda _: self._restart_timer.start())
        self._ready.connect(self._show)
        self.restart()  # textures do not wait for OpenGL; the view takes the latest when ready

    # --- parameters ---------------------------------------------------------------------
    def _build_editors(self) -> None:
        while self.form.rowCount():
            self.form.removeRow(0)
        self._editors = {}
        for p in get_kind(self.spec.kind).parameters:
            value = self.spec.params[p.name]
            if p.choices:
                editor = QComboBox()
                editor.addItems(p.choices)
                editor.setCurrentText(str(value))
                editor.currentTextChanged.connect(lambda v, n=p.name: self.set_parameter(n, v))
            elif p.integer:
                editor = QSpinBox(minimum=int(p.lower), maximum=int(p.upper), value=int(value))
                editor.valueChanged.connect(lambda v, n=p.name: self.set_parameter(n, v))
            else:
                decimals = max(2, 3 - int(math.floor(math.log10(max(p.upper - p.lower, 1e-9)))))
                editor = QDoubleSpinBox(decimals=decimals, minimum=p.lower, maximum=p.upper, value=float(value))
                editor.setSingleStep((p.upper - p.lower) / 100)
                editor.valueChanged.connect(lambda v, n=p.name: self.set_parameter(n, v))
            editor.setToolTip(p.doc)
            self.form.addRow(f"{p.name}{f' [{p.unit}]' if p.unit else ''}", editor)
            self._editors[p.name] = editor

    def _kind_changed(self) -> None:
        self.spec = SimulationSpec(self.kind.currentData(), seed=self.spec.seed, samples=self.spec.samples,
                                   resolution=self.spec.resolution)
        self._build_editors()
        self.restart()

    def set_parameter(self, name: str, value) -> None:
        """A parameter change: a new spec, and the texture restarts (debounced)."""
        self.spec = SimulationSpec(self.spec.kind, {**self.spec.params, name: value}, self.spec.seed,
                                   self.spec.samples, self.spec.resolution)
        self._restart_timer.start()

    # --- progressive texture --------------------------------------------------------------
    def restart(self) -> None:
        self._generation += 1
        self._times = []
        self.status.setText("computing…")
        generation, spec, theta = self._generation, self.spec, math.radians(self.theta_i.value())
        self._pool.submit(self._compute, generation, spec, theta)

    def _compute(self, generation: int, spec: SimulationSpec, theta: float) -> None:
        for level, n in enumerate(self.levels[spec.library]):
            if generation != self._generation:
                return  # superseded by a newer change
            try:
                texture = lobe_texture(spec, theta, 0.0, n)
            except BRDFLabError as e:
                self.failed.emit(str(e))
                return
            self._ready.emit(generation, level, texture)

    def _show(self, generation: int, level: int, texture) -> None:
        if generation != self._generation:
            return
        rows, cols = texture.size
        self._times.append(f"{'coarse' if level == 0 else 'fine'} {rows}×{cols}: {texture.seconds:.2f} s")
        self.status.setText(" · ".join(self._times))
        self.shown = texture

        def apply() -> None:
            self.view.viewer.settings.theta_i = math.degrees(texture.theta_i)
            self.view.viewer.set_original(texture)

        self.view.when_ready(apply)
        self.texture_shown.emit(level, texture.seconds)

    # --- file ---------------------------------------------------------------------------
    def save_to(self, path: Path) -> None:
        save(BRDFDocument(reference_of(self.spec)), path)

    def _save_dialog(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Save simulated material", f"{self.spec.kind}.xml", "XML (*.xml)")
        if path:
            try:
                self.save_to(Path(path))
            except BRDFLabError as e:
                QMessageBox.warning(self, "BRDFLab", str(e))

    def shutdown(self) -> None:
        self._generation += 1
        self._pool.shutdown(wait=True, cancel_futures=True)


def show_simulation_dock(window) -> SimulatedPanel:
    """Create (once) and raise the Simulation dock of a main window; it starts on the
    window's simulated material when one is open."""
    from PySide6.QtCore import Qt
    from PySide6.QtWidgets import QDockWidget

    dock = getattr(window, "_simulation_dock", None)
    if dock is None:
        source = window.workspace.source
        spec = getattr(source, "spec", None) if isinstance(getattr(source, "spec", None), SimulationSpec) else None
        panel = SimulatedPanel(spec)
        panel.failed.connect(window.statusBar().showMessage)
        panel.use_requested.connect(lambda s: use_in_window(window, s))
        dock = QDockWidget("Simulation", window)
        dock.setObjectName("Simulation")
        dock.setWidget(panel)
        window.addDockWidget(Qt.RightDockWidgetArea, dock)
        window._simulation_dock = dock
    dock.show()
    dock.raise_()
    return dock.widget()


def use_in_window(window, spec: SimulationSpec) -> None:
    """Make `spec` the window's material: its table is built off the GUI thread (the window's
    loader, with its busy indicator), then every view shows it and Fitting can fit it."""
    from brdflab.workspace import Workspace

    if not window.maybe_save():
        return

    def apply(workspace: Workspace) -> None:
        window.set_workspace(workspace)
        window.statusBar().showMessage(f"simulated {spec.kind} ({workspace.source.seconds:.1f} s)", 5000)

    window._load("simulation", Path(spec.kind), lambda _: Workspace.simulated(spec), apply)
