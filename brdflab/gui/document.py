"""The document the window shows, evented: every view that shows part of it (the material
editor, the lobe viewer, the object view, the fits list, the plots, the XML) subscribes to its
signals, as napari's layers emit their changes, rather than being pushed into by the window;
a view following `switched` never goes on showing another document."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QObject, Signal

from brdflab.workspace import Workspace


class ShownDocument(QObject):
    """The Workspace shown, the run fitting it, and their changes as signals."""

    switched = Signal(object)  # the Workspace now shown, another document than before
    material_changed = Signal()  # its material was replaced
    guess_changed = Signal()  # (measured data) the next fit's initial guess, what the editor edits, was replaced
    fittings_changed = Signal()  # its stored fits, or which one is shown, were replaced
    drawn_changed = Signal()  # what is drawn over the original changed: a fit chosen, a running fit's newest parameters
    saved = Signal()  # written to its file (its title and the paths its XML names may change)

    def __init__(self, workspace: Workspace, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.workspace = workspace
        self.running = None  # the running fit's newest parameters (an AnalyticMaterial), drawn over the original
        self.history: list[tuple[int, float]] = []  # (iteration, error) of the running or last fit

    def show(self, workspace: Workspace) -> None:
        """Show `workspace`: `switched` when it is another document than the one shown (the
        last one's run is no longer drawn); the same one read again (a file located), every
        view refreshes."""
        if workspace is not self.workspace:
            self.workspace, self.running, self.history = workspace, None, []
            self.switched.emit(workspace)
        else:
            self.material_changed.emit()
            self.fittings_changed.emit()

    def replace_material(self, material) -> None:
        """Replace what the editor edits: the material, or for measured data the initial guess
        (which only the editor and the lobe viewer show: the object view, plots and XML do
        not redo their work for it)."""
        self.workspace.replace_material(material)
        (self.material_changed if self.workspace.analytic is not None else self.guess_changed).emit()

    def replace_guess(self, guess) -> None:
        """The next fit's initial guess (measured data): what the editor edits there."""
        self.workspace.guess = guess
        self.guess_changed.emit()

    def replace_fittings(self, fittings: list, shown: int | None) -> None:
        self.workspace.replace_fittings(fittings, shown)
        self.fittings_changed.emit()

    def select_fit(self, index: int | None) -> None:
        """Draw stored fit `index` over the original."""
        self.workspace.shown_fit = index
        self.drawn_changed.emit()

    def save(self, path: Path) -> None:
        self.workspace.save(path)
        self.saved.emit()

    # --- the run fitting this document -------------------------------------------------------------
    def start_run(self) -> None:
        self.running, self.history = None, []

    def show_progress(self, material, iteration: int, error: float) -> None:
        """A running fit's newest parameters, drawn over the original until it ends."""
        self.running = material
        self.history.append((iteration, error))
        self.drawn_changed.emit()

    def end_run(self) -> None:
        """The run ended (its history stays, for the convergence plot)."""
        if self.running is not None:
            self.running = None
            self.drawn_changed.emit()

    # --- what the views draw -----------------------------------------------------------------------
    def original(self):
        """The analytic material, or the measured or simulated data: 'original' in every view."""
        return self.workspace.original()

    def fit_or_run(self):
        """The material compared with the original: the running fit, else the stored fit shown."""
        return self.running if self.running is not None else self.workspace.fitted()

    def drawn_over(self):
        """What the lobe viewer draws over the original: the running fit, the stored fit shown,
        or (measured data, no fit shown) the next fit's initial guess."""
        ws = self.workspace
        if self.running is not None:
            return self.running
        if ws.analytic is None and ws.fitted() is None:
            return ws.guess
        return ws.fitted()

    def labels(self) -> list[str]:
        """What the legend calls the original and the material drawn over it: the stored fit by
        its number in the fits list, a running fit, or the next fit's initial guess."""
        ws, over = self.workspace, self.drawn_over()
        name = getattr(self.original(), "name", "")
        first = f"original: {name}" if name else "original"
        if over is None:
            return [first, ""]
        lobes = "+".join(over.lobe_models())  # as the list names a fit
        if over is self.running:
            return [first, f"fit running: {lobes}"]
        if over is ws.guess and ws.analytic is None:
            return [first, f"initial guess: {lobes}"]
        return [first, f"fit {ws.shown_fit}: {lobes}"]
