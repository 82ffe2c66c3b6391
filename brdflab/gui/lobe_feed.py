"""The lobe viewer's feed: it follows the shown document (gui.document.ShownDocument) and the
Lobe options, draws the original and what is compared with it, and keeps the surface refined
and the automatic subdivision in worker processes (the newest request wins)."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import QObject, Signal

from brdflab.gui.background import LatestOnly
from brdflab.gui.document import ShownDocument
from brdflab.gui.gl_views import LobeView
from brdflab.gui.panels import AUTO_LEVEL_TOLERANCE, LobeControls, auto_level_job, refine_job
from brdflab.material.analytic import AnalyticMaterial


class LobeViewFeed(QObject):
    """What the lobe viewer draws, from the document's events and the Lobe options."""

    settings_changed = Signal()  # the incident direction or how lobes are drawn (the plots follow θi)

    def __init__(self, document: ShownDocument, view: LobeView, controls: LobeControls,
                 show_error: Callable[[str], None], parent: QObject | None = None) -> None:
        super().__init__(parent or view)  # it goes with its view
        self.document, self.view, self.controls = document, view, controls
        self._auto_level_for = None  # what the auto subdivision was last computed for
        self._auto_level_job = LatestOnly(auto_level_job, self)
        self._auto_level_job.done.connect(self._auto_level_known)
        self._auto_level_job.failed.connect(lambda m: controls.auto_level_note.setText(f"failed: {m}"))
        self._refine_for: tuple | None = None  # (key, sources) the refined surface was last asked for
        self._refine_job = LatestOnly(refine_job, self)
        self._refine_job.done.connect(self._refined_known)
        self._refine_job.failed.connect(show_error)
        for signal in (document.material_changed, document.guess_changed, document.fittings_changed,
                       document.drawn_changed):
            signal.connect(self.draw)
        document.switched.connect(self.draw)
        controls.changed.connect(self._settings_changed)
        view.incident_changed.connect(self._drag_incident)

    def draw(self, *_) -> None:
        """The original and the material drawn over it (a fit, a running fit or the initial guess)."""
        original, over = self.document.original(), self.document.drawn_over()
        labels = self.document.labels()

        def apply():
            v = self.view.viewer
            v.labels = labels
            if original is not None and isinstance(original, AnalyticMaterial):
                v.update_material(0, original)
            else:
                v.set_original(original)
            if over is not None:
                v.update_material(1, over)
            else:
                v.set_fitted(None)

        self.view.when_ready(apply)
        self._request_auto_level()
        self._request_refined_surface()

    def _settings_changed(self) -> None:
        self.controls.apply(self.view.viewer.settings)
        self.view.update()
        self.settings_changed.emit()
        self._request_auto_level()
        self._request_refined_surface()

    def _drag_incident(self, theta: float, phi: float) -> None:
        self.controls.theta.set_value(theta)
        self.controls.phi.set_value(phi)
        self._settings_changed()

    def _request_refined_surface(self) -> None:
        """The surface refined near the analytic lobes' peaks; the uniform hemisphere is drawn meanwhile."""
        def ask() -> None:
            viewer = self.view.viewer
            key, sources = viewer.surface_key(), viewer.analytic_sources()
            if sources and (self._refine_for is None or key != self._refine_for[0]):
                self._refine_for = (key, sources)  # held: the ids in the key stay theirs
                self._refine_job.request((key, sources, viewer.settings.shape, viewer.settings.level))

        self.view.when_ready(ask)

    def _refined_known(self, result: tuple) -> None:
        self.view.when_ready(lambda: self.view.viewer.set_refined(*result))

    def _request_auto_level(self) -> None:
        """Auto subdivision: the level again when what is drawn changes (not when the level itself does)."""
        if not self.controls.auto_level.isChecked():
            self._auto_level_for = None
            return
        sources = (self.document.original(), self.document.drawn_over())
        shape = self.view.viewer.settings.shape
        key = (tuple(id(s) for s in sources), shape)
        if key != self._auto_level_for:
            self._auto_level_for = key
            self.controls.auto_level_note.setText("checking…")
            self._auto_level_job.request((sources, shape, AUTO_LEVEL_TOLERANCE))

    def _auto_level_known(self, result: tuple[int, float]) -> None:
        level, error = result
        if self.controls.auto_level.isChecked():
            self.controls.auto_level_note.setText(f"level {level}: {error:.1%} of the peak")
            self.controls.level.setValue(level)

    def shutdown(self) -> None:
        self._auto_level_job.shutdown()
        self._refine_job.shutdown()
