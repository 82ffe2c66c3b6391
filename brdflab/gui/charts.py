"""The Charts dock: `brdflab study` parts measured on the window's own scene.

A part (speed against accuracy of the lighting modes, the lobe viewer's subdivision, the
fitter …) runs in a worker process with the current material and map, at quick sizes, with
progress and Stop; its charts appear here when it is done, with what they teach.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QPixmap
from PySide6.QtWidgets import (QComboBox, QHBoxLayout, QLabel, QProgressBar, QPushButton, QScrollArea, QVBoxLayout,
                               QWidget)

from brdflab.gui.background import StudyProcess
from brdflab.study.framework import load_parts


class ChartsPanel(QWidget):
    """Pick a study part, Measure (on the scene `scene()` returns), look at its charts."""

    measured = Signal(dict)  # the part's result, once its charts are shown

    def __init__(self, scene=lambda: {}) -> None:
        super().__init__()
        self._scene = scene
        self._folder = tempfile.TemporaryDirectory(prefix="brdflab-charts-")
        self._job: StudyProcess | None = None
        self.part = QComboBox()
        for name, part in load_parts().items():
            self.part.addItem(f"{name}: {part.title}", name)
        self.part.setToolTip("What to measure, on the current material and environment map")
        # as wide as the dock allows, not as its longest title (772 px pushed the bottom row off a laptop)
        self.part.setSizeAdjustPolicy(QComboBox.AdjustToMinimumContentsLengthWithIcon)
        self.part.setMinimumContentsLength(8)  # the dock beside Fitting fits a 1024-px window
        self.run_button = QPushButton("Measure")
        self.run_button.setToolTip("Measure this part now on the current scene (quick sizes, in the background)")
        self.run_button.clicked.connect(self.measure)
        self.stop_button = QPushButton("Stop")
        self.stop_button.setEnabled(False)
        self.stop_button.clicked.connect(self.stop)
        self.progress = QProgressBar(maximumWidth=120)
        self.progress.setRange(0, 0)
        self.progress.setVisible(False)
        self.status = QLabel("Measure a part to see its charts for this material and map.")
        self.status.setStyleSheet("color: #707070")
        self.status.setWordWrap(True)
        self.lesson = QLabel("")
        self.lesson.setWordWrap(True)
        self.pages = QWidget()
        self.pages_layout = QVBoxLayout(self.pages)
        self.pages_layout.setAlignment(Qt.AlignTop)
        self.scroll = QScrollArea()
        self.scroll.setWidgetResizable(True)
        self.scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarAlwaysOff)  # charts follow the width
        self.scroll.setWidget(self.pages)
        self.scroll.setMinimumSize(200, 120)
        row = QHBoxLayout()
        row.addWidget(self.part, 1)
        row.addWidget(self.run_button)
        row.addWidget(self.stop_button)
        row.addWidget(self.progress)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        lay.addLayout(row)
        lay.addWidget(self.status)
        lay.addWidget(self.lesson)
        lay.addWidget(self.scroll, 1)
        self._pixmaps: list[tuple[QLabel, QPixmap]] = []

    @property
    def busy(self) -> bool:
        return self._job is not None and self._job.running

    def measure(self) -> None:
        if self.busy:
            return
        name = self.part.currentData()
        out = Path(self._folder.name) / name
        out.mkdir(exist_ok=True)
        self._job = StudyProcess(str(out), name, self._scene(), self)
        self._job.progress.connect(lambda text: self.status.setText(str(text)))
        self._job.finished.connect(lambda result, o=out: self._show(result, o))
        self._job.failed.connect(self._failed)
        self._job.start()
        self._running(True)
        self.status.setText(f"measuring {name} on the current scene…")

    def stop(self) -> None:
        if self.busy:
            self._job.cancel.set()
            self.status.setText("stopping after the current step…")

    def shutdown(self) -> None:
        """The window is closing: stop the worker, drop the charts folder."""
        if self._job is not None:
            self._job.kill()
        self._folder.cleanup()

    def _running(self, running: bool) -> None:
        self.run_button.setEnabled(not running)
        self.part.setEnabled(not running)
        self.stop_button.setEnabled(running)
        self.progress.setVisible(running)

    def _failed(self, message: str) -> None:
        self._running(False)
        self.status.setText(f"the study failed: {message}")

    def _show(self, result: dict, folder: Path) -> None:
        self._running(False)
        part = load_parts()[self.part.currentData()]
        stopped = " (stopped early: partial numbers)" if result.get("stopped") else ""
        self.status.setText(f"{part.title}: measured in {result['seconds']:.1f} s{stopped}")
        self.lesson.setText(part.lesson)
        while self.pages_layout.count():
            self.pages_layout.takeAt(0).widget().deleteLater()
        self._pixmaps = []
        for name in result["charts"]:
            label = QLabel(alignment=Qt.AlignCenter)
            pixmap = QPixmap(str(folder / name))
            label.setToolTip(name)
            self.pages_layout.addWidget(label)
            self._pixmaps.append((label, pixmap))
        self._fit_width()
        self.measured.emit(result)

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        self._fit_width()

    def _fit_width(self) -> None:
        """Charts scaled to the dock's width (never enlarged past their pixels)."""
        width = max(100, self.scroll.viewport().width() - 12)
        for label, pixmap in self._pixmaps:
            if not pixmap.isNull():
                label.setPixmap(pixmap.scaledToWidth(min(width, pixmap.width()), Qt.SmoothTransformation))
