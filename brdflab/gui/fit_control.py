"""The main window's fit control: a fit or an Auto run in a worker process, its progress, and
its result stored in the document it started on."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import Qt

from brdflab.errors import BRDFLabError
from brdflab.fitting.auto import AutoProgress, Ladder, chosen_fitting
from brdflab.fitting.lm import FitOptions, FitProgress, FitResult, material_from_lobes
from brdflab.fitting.second_error import describe
from brdflab.fitting.stored import fitting_of
from brdflab.gui.background import AutoFitProcess, FitProcess
from brdflab.gui.commands import ReplaceFittings
from brdflab.models import get_model
from brdflab.workspace import Workspace

LADDER_HEIGHT = 400  # pixels: the Auto ladder dock's reason and a dozen candidates


class FitControl:
    """Fit / Auto / Stop for MainWindow (a mixin: it uses the window's panels, views and undo stack)."""

    def _source_to_fit(self):
        """The source a new fit or Auto run would fit; None (and said) when one is running
        or the measured data is missing."""
        if self._thread is not None:
            return None
        source = self.workspace.original()
        if source is None:
            self.show_error("nothing to fit: the measured data of this material is missing")
        return source

    def start_fit(self, lobes: list, combination: str, metric: str, kind: str, size: int, start=None) -> None:
        source = self._source_to_fit()
        if source is None:
            return
        try:
            guess = self.workspace.guess
            if start is None and self.workspace.analytic is None and guess is not None and \
                    guess.lobe_models() == lobes and guess.combination == combination:
                start = guess.copy()  # the guess the user edited
            if start is None:
                start = material_from_lobes(lobes, combination, source.n_channels)
        except BRDFLabError as e:
            self.show_error(str(e))
            return
        options = FitOptions(metric=metric)
        sampling = {"kind": kind, "size": size, "density": 45}
        if metric == "image":  # judged on the object view's mesh, camera and map, as the user sees the material
            view, seen = self._object_view_frames()
            sampling = {"maps": self._object_view_maps(), "view": view}
        # the samples are drawn and the fit runs in a worker process: the window stays live
        self._start_worker(FitProcess(start, source, sampling, options, self),
                           lambda n: f"fitting {n} pixels of {seen} under the object view's map…" if metric == "image" else
                           f"fitting {n} samples…", self._fit_progress, self._fit_finished,
                           "starting the fit…")

    def _object_view_maps(self) -> list | None:
        """The object view's environment map, which the image metric renders under in the
        window (None before OpenGL starts: the metric's default maps)."""
        environment = self.object_view.environment_map()
        return None if environment is None else [environment]

    def _object_view_frames(self) -> tuple:
        """The image metric's view in the window: the object view's mesh as its camera and turn
        show it (render/gbuffer.py: its own rasterisation, sized to cover as many pixels as the
        reference sphere at the metric's size), and what it is called; the reference sphere
        where the view shows it or has no OpenGL."""
        from brdflab.fitting.image_metric import SPHERE, VIEW
        from brdflab.render.gbuffer import frames_covering

        view = self.object_view
        renderer = getattr(view, "renderer", None)
        if view.ctx is None or renderer is None or renderer.mesh is None or view.settings.reference_view:
            return VIEW, SPHERE
        with view.current():
            frames = frames_covering(view.ctx, renderer.mesh, renderer.camera, renderer.model_rotation)
        if not frames.inside.any():
            return VIEW, SPHERE
        return frames, f"the object view's {renderer.mesh.name}"

    def _start_worker(self, thread, started: Callable[[int], str], progress: Callable, finished: Callable,
                      starting: str) -> None:
        """Run a fit or an Auto run's worker for the document open now, the panel showing it."""
        self._fit_owner = self.workspace
        self.document.start_run()
        self._thread = thread
        thread.started.connect(lambda n: self.fitting.status.setText(started(n)))
        thread.progress.connect(progress)
        thread.finished.connect(finished)
        thread.failed.connect(self._fit_failed)
        thread.start()
        self.fitting.set_running(True)
        self.fitting.status.setText(starting)

    def stop_fit(self) -> None:
        if self._thread is not None:
            self._thread.cancel.set()
            self.fitting.status.setText("stopping Auto: keeping the pick among the candidates fully fitted…"
                                        if isinstance(self._thread, AutoFitProcess) else
                                        "stopping: scoring the best parameters so far on every sample…")

    def _fit_progress(self, p: FitProgress) -> None:
        if self._fit_owner is not self.workspace:
            return  # a report of a fit of a closed document: no view draws it
        self.fitting.status.setText(f"{p.stage}: iteration {p.iteration}, {self._thread.options.metric} error {p.error:.6g}")
        self.document.show_progress(p.material, p.iteration, p.error)  # the views draw it, coalesced

    def _end_fit(self) -> None:
        self.fitting.set_running(False)
        self._thread = None
        self.document.end_run()

    def _store_in_owner(self, fitting, what: str) -> Workspace | None:
        """End the running fit or Auto run and store its fitting, undoably, in the document it
        started on; None (nothing stored) when that document was closed meanwhile."""
        owner, self._fit_owner = self._fit_owner, None
        self._end_fit()
        if owner is not self.workspace:  # its document was closed: never store it in another
            self.statusBar().showMessage(f"the {what.lower()} of {owner.title.rstrip(' *')} was stopped: its document "
                                         "was closed", 10000)
            self.fitting.status.setText("")  # the panel tells of the shown document's runs only
            return None
        old = (tuple(self.workspace.document.fittings), self.workspace.shown_fit)
        new_list = list(old[0]) + [fitting]
        self.undo_stack.push(ReplaceFittings(self, old, (tuple(new_list), len(new_list) - 1), what))
        return owner

    def _fit_finished(self, result: FitResult) -> None:
        if self._store_in_owner(fitting_of(result), "Fit") is None:
            return
        second = describe(result.second)
        self.fitting.status.setText(f"{result.metric} error {result.error:.6g} after {result.iterations} iterations, "
                                    f"{result.seconds:.2f} s ({result.status})" + (f"; {second}" if second else ""))

    def _fit_failed(self, message: str) -> None:
        self._fit_owner = None
        self._end_fit()
        self.fitting.status.setText(message)
        self.show_error(message)

    def start_auto(self, settings: dict) -> None:
        """Auto (fitting/auto.py) on the source's samples, in a worker process like a fit; the
        pick is stored as a new fitting of the document it started on, the ladder shown."""
        source = self._source_to_fit()
        if source is None:
            return
        try:
            for name in settings["models"] or []:
                get_model(name)  # an unknown name is said before any fit
        except BRDFLabError as e:
            self.show_error(f"Auto models: {e}")
            return
        if settings["metric"] == "image":  # scene-Auto: the object view's mesh, camera and map, as the user sees it
            view, seen = self._object_view_frames()
            settings = {**settings, "maps": self._object_view_maps(), "view": view}
            started = lambda n: f"scene-Auto on {n} pixels of {seen} under the object view's map…"
        else:
            started = lambda n: f"Auto on {n} samples: fitting up to {settings['split']}, holding as many back…"
        self._start_worker(AutoFitProcess(source, settings, self), started, self._auto_progress,
                           self._auto_finished, "starting Auto…")

    def _auto_progress(self, p: AutoProgress) -> None:
        if self._fit_owner is not self.workspace:
            return  # a report of a run of a closed document
        bar = self.fitting.progress
        bar.setRange(0, p.expected)
        bar.setValue(p.step)
        bar.setFormat("candidate %v of about %m")
        self.fitting.status.setText(f"Auto: {p.stage} {p.candidate}, {p.measure} {p.error:.4g} "
                                    f"(best so far {p.best_error:.4g})")

    def _auto_finished(self, ladder: Ladder) -> None:
        owner = self._store_in_owner(chosen_fitting(ladder), "Auto fit")
        if owner is None:
            return
        self._auto_ladder = (owner, ladder)
        self._show_own_ladder()
        self.show_ladder()
        chosen = ladder.chosen
        stopped = " (cancelled)" if ladder.reason.startswith("cancelled") else ""
        measure = "image error in the scene" if ladder.metric == "image" else f"held-back {ladder.metric} error"
        self.fitting.status.setText(f"Auto chose {'+'.join(('Lambertian', *chosen.lobes))}: {measure} "
                                    f"{chosen.error_held_back:.5g}, {ladder.seconds:.1f} s{stopped}; see the Auto ladder")

    def _show_own_ladder(self) -> None:
        """The ladder dock shows the last Auto run of the shown document only."""
        own = self._auto_ladder is not None and self._auto_ladder[0] is self.workspace
        self.ladder.show_ladder(self._auto_ladder[1] if own else None)
        self.fitting.ladder_button.setEnabled(own)

    def show_ladder(self) -> None:
        """The Auto ladder dock in front, tall enough for a ladder (the views keep the rest)."""
        dock = self._docks["Auto ladder"]
        dock.show()
        dock.raise_()
        if not dock.isFloating() and dock.height() < LADDER_HEIGHT:
            self.resizeDocks([dock], [min(LADDER_HEIGHT, self.height() // 2)], Qt.Vertical)

    def _refit(self, index: int) -> None:
        start = self.workspace.document.fittings[index].material.copy()
        f = self.fitting
        self.start_fit([], start.combination, f.metric_box.currentText(), f.sample_kind.currentText(), f.sample_size.value(), start)

    def _promote(self, index: int) -> None:
        material = self.workspace.document.fittings[index].material.copy()
        if self.workspace.analytic is None:
            # measured data stay with their fits: the fit becomes a new analytic document
            if self.maybe_save():
                workspace = Workspace.new()
                workspace.document.material = material
                workspace.dirty = True
                self.set_workspace(workspace)
            return
        self._edit(material, "Make fit the main material")
