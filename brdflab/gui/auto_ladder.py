"""The Auto ladder dock: what the fitting panel's Auto run tried, what it chose and why
(the same ladder `brdflab fit SOURCE --auto` prints)."""

from __future__ import annotations

import math

from PySide6.QtCore import Qt
from PySide6.QtGui import QBrush, QColor, QFont
from PySide6.QtWidgets import QAbstractItemView, QHeaderView, QLabel, QTableWidget, QTableWidgetItem, QVBoxLayout, QWidget

from brdflab.fitting.auto import Candidate, Ladder

COLUMNS = ("rung", "lobes", "parameters", "fitted error", "held-back error", "screen (held back)", "seconds", "status")
SCENE_COLUMNS = ("rung", "lobes", "parameters", "fitted error", "image error", "screen (image)", "seconds", "status")
CHOSEN_COLOR = "#d8f0d0"
EMPTY_TEXT = "No Auto run for this document yet: press Auto in the Fitting panel."


def _number(x: float, digits: int = 5) -> str:
    return f"{x:.{digits}g}" if math.isfinite(x) else "—"


def candidate_cells(candidate: Candidate, chosen: bool) -> list[str]:
    """One table row: the candidate's rung, lobes, cost, errors, time and status."""
    lobes = "+".join(("Lambertian", *candidate.lobes))
    status = candidate.status + ("  ← chosen" if chosen else "")
    errors = (candidate.error_fitted, candidate.error_held_back) if candidate.fitted else (math.nan, math.nan)
    return [str(candidate.rung), ("★ " if chosen else "") + lobes, str(candidate.parameters), _number(errors[0]),
            _number(errors[1]), _number(candidate.screen_error, 4), f"{candidate.seconds:.2f}", status]


class AutoLadderPanel(QWidget):
    """The reason for the pick above a table of every candidate, the chosen row marked."""

    def __init__(self) -> None:
        super().__init__()
        self.summary = QLabel(EMPTY_TEXT)
        self.reason = QLabel("")
        for label in (self.summary, self.reason):
            label.setWordWrap(True)
            label.setTextInteractionFlags(Qt.TextSelectableByMouse)
        bold = QFont(self.reason.font())
        bold.setBold(True)
        self.reason.setFont(bold)
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        self.table.setEditTriggers(QAbstractItemView.NoEditTriggers)
        self.table.setSelectionBehavior(QAbstractItemView.SelectRows)
        self.table.verticalHeader().setVisible(False)
        self.table.verticalHeader().setDefaultSectionSize(self.fontMetrics().height() + 6)  # more rows in view
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeToContents)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.ladder: Ladder | None = None
        lay = QVBoxLayout(self)
        lay.addWidget(self.summary)
        lay.addWidget(self.reason)
        lay.addWidget(self.table, 1)

    def show_ladder(self, ladder: Ladder | None) -> None:
        """A finished (or stopped) Auto run; None: no run for the shown document."""
        self.ladder = ladder
        self.table.setRowCount(0)
        if ladder is None:
            self.summary.setText(EMPTY_TEXT)
            self.reason.setText("")
            return
        fitted = sum(c.fitted for c in ladder.candidates)
        scene = ladder.metric == "image"
        self.table.setHorizontalHeaderLabels(list(SCENE_COLUMNS if scene else COLUMNS))
        judged = (f"image error of {ladder.seen}'s {ladder.fitted_samples} pixels under the object "
                  f"view's map; an image "
                  f"error within" if scene else f"{ladder.metric} error on {ladder.fitted_samples} fitted and "
                  f"{ladder.held_back_samples} held-back samples; tolerance")
        self.summary.setText(
            f"{'Scene-' if scene else ''}Auto ladder: {len(ladder.candidates)} candidates, {fitted} fully fitted; "
            f"{judged} {ladder.tolerance:.1%}; {ladder.seconds:.1f} s. The chosen row is marked ★.")
        self.reason.setText("Chosen: " + ladder.reason)
        self.table.setRowCount(len(ladder.candidates))
        for row, candidate in enumerate(ladder.candidates):
            chosen = candidate is ladder.chosen
            for column, text in enumerate(candidate_cells(candidate, chosen)):
                item = QTableWidgetItem(text)
                if column != 1 and column != len(COLUMNS) - 1:
                    item.setTextAlignment(Qt.AlignRight | Qt.AlignVCenter)
                if chosen:
                    font = item.font()
                    font.setBold(True)
                    item.setFont(font)
                    item.setBackground(QBrush(QColor(CHOSEN_COLOR)))
                self.table.setItem(row, column, item)

    @property
    def chosen_row(self) -> int | None:
        if self.ladder is None:
            return None
        return next(k for k, c in enumerate(self.ladder.candidates) if c is self.ladder.chosen)
