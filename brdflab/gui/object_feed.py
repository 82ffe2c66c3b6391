"""The object view's feed: it follows the shown document (gui.document.ShownDocument) and the
Object view options, shades the material chosen there, and (auto lighting) asks a worker
process for the cheapest lighting predicted within the tolerance, or (prefiltered lighting)
for the split sum's predicted error, so the window says where the mode cannot be trusted."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import QObject, QTimer

from brdflab.errors import BRDFLabError
from brdflab.gui.auto_lighting import choose_job, chosen, prefiltered_job, prefiltered_note
from brdflab.gui.background import LatestOnly
from brdflab.gui.document import ShownDocument
from brdflab.gui.gl_views import ObjectView
from brdflab.gui.panels import PENDING_STYLE, SHOWN, WARNING_STYLE, ObjectControls, sh_table_request
from brdflab.material.analytic import AnalyticMaterial

RUN_REDRAW_MS = 500  # a running fit reaches the object view twice a second, not at every report
# (each restarted its image before it had more than a sample: 60–330 ms of GL per restart)


class ObjectViewFeed(QObject):
    """What the object view shades and how, from the document's events and the Object view options."""

    def __init__(self, document: ShownDocument, view: ObjectView, controls: ObjectControls,
                 warn: Callable[[str, str | None], None], show_error: Callable[[str], None],
                 parent: QObject | None = None) -> None:
        super().__init__(parent or view)  # it goes with its view
        self.document, self.view, self.controls = document, view, controls
        self._warn, self._show_error = warn, show_error
        self._auto_for: tuple | None = None  # (source, map, tolerance) the last choice was asked for
        self._auto_token = 0  # numbers the requests: an answer to an older one is dropped
        self.auto_choice = None  # the lighting.auto.LightingChoice the view draws with
        self._auto_job = LatestOnly(choose_job, self)
        self._auto_job.done.connect(self._auto_known)
        self._auto_job.failed.connect(
            lambda m: controls.show_auto_note(f"auto: the choice failed: {m}", style=WARNING_STYLE))
        self._check_for: tuple | None = None  # (source, map) the prefiltered check was asked for
        self._check_token = 0
        self._check_job = LatestOnly(prefiltered_job, self)
        self._check_job.done.connect(self._prefiltered_known)
        self._check_job.failed.connect(
            lambda m: controls.show_auto_note(f"prefiltered: the check failed: {m}", style=WARNING_STYLE))
        self._run_timer = QTimer(self, singleShot=True, interval=RUN_REDRAW_MS)
        self._run_timer.timeout.connect(self.draw)
        for signal in (document.material_changed, document.fittings_changed):
            signal.connect(self.draw)
        document.switched.connect(self.draw)
        document.drawn_changed.connect(self._drawn_changed)
        controls.changed.connect(self._settings_changed)
        self._apply_settings()

    def _drawn_changed(self) -> None:
        if self.document.running is None:
            self.draw()
        elif self.controls.shown.currentText() != "original" and not self._run_timer.isActive():
            self._run_timer.start()

    def draw(self, *_) -> None:
        """Shade the material the options choose (the original, or the fit), or a comparison."""
        shown = self.document.original()
        fit = self.document.fit_or_run()
        choice = self.controls.shown.currentText()
        if choice == "fitted":
            shown = fit or shown
        v = self.view
        v.compare = SHOWN[choice] if fit is not None and shown is not None else "off"
        v.compare_source = fit
        if v.ctx is None:
            return
        v.blank = shown is None or (isinstance(shown, AnalyticMaterial) and not shown.lobes)
        if v.blank:  # an empty material is valid: nothing to shade
            v.update()
            self.request_auto_lighting()
            return

        def apply():
            try:
                v.renderer.set_source(shown)
            except BRDFLabError as e:
                self._show_error(str(e))

        v.when_ready(apply)
        v.restart()
        self.request_auto_lighting()

    def _settings_changed(self) -> None:
        self._apply_settings()
        self.draw()

    def _apply_settings(self) -> None:
        """The controls into the view's settings; with auto, the mode is the choice's (until
        the first choice arrives, the view keeps the mode it had)."""
        c, v = self.controls, self.view
        s = v.settings
        if not c.auto:
            s.mode = c.mode.currentText()
        elif self.auto_choice is not None:
            s.mode = self.auto_choice.mode
        s.samples = c.samples.value()
        s.env_rotation = c.rotation.spin.value()
        s.light = c.light()
        v.exposure = c.exposure.spin.value()
        v.gamma = c.gamma.value()
        order, shadows, variant = c.sh_order.value(), c.sh_shadows.isChecked(), c.sh_variant.currentText()
        table = sh_table_request(c.sh_table.currentText())
        self._sh_order_applied = order  # the renderer's once its context is free (when_ready)

        def apply_sh():
            v.renderer.set_sh_order(order)
            v.renderer.set_sh_table(table)
            v.renderer.sh_shadows = shadows
            v.renderer.sh_variant = variant

        v.when_ready(apply_sh)
        v.reinhard = c.reinhard.isChecked()

    def request_auto_lighting(self) -> None:
        """Auto lighting: choose again when the drawn source, the map or the tolerance changed
        — not when the choice itself did (and the prefiltered mode's check, likewise). Asked
        once the renderer has taken what was handed to it before (work for the view's context
        runs in order; while the step thread holds it, it waits): it reads the renderer's source."""
        if self.view.ctx is None:
            self._request_now()
        else:
            self.view.when_ready(self._request_now)

    def _request_now(self) -> None:
        self._request_prefiltered_check()
        c, v = self.controls, self.view
        if not c.auto:
            self._auto_for = self.auto_choice = None
            self._auto_token += 1  # a choice still on its way is for what was drawn before
            self._warn("auto", None)
            return
        r = v.renderer
        unable = self._nothing_to_light("auto")
        if unable is not None:
            self._auto_for = None
            self._auto_token += 1
            self._warn("auto", None)
            c.show_auto_note(unable[0], style=unable[1])
            return
        key = (r.source, r.environment, c.tolerance.value())
        old = self._auto_for
        if old is not None and old[0] is key[0] and old[1] is key[1] and old[2] == key[2]:
            return
        self._auto_for = key
        self._auto_token += 1
        c.show_auto_note("auto: choosing the lighting for this material and map… (the view keeps its last "
                         "setting meanwhile)", style=PENDING_STYLE)
        # the renderer's own proxy lobes for a measured source, as the command line passes them
        self._auto_job.request((self._auto_token, r.source, r.environment, key[2] / 100, r.material))

    def _auto_known(self, result: tuple) -> None:
        token, choice = result
        c, v = self.controls, self.view
        if token != self._auto_token or not c.auto:
            return
        self.auto_choice = choice
        c.show_auto_choice(choice)
        self._warn("auto", None if choice.within else
                   f"Auto lighting: nothing is predicted within {100 * choice.tolerance:g} %; drawing the best "
                   f"predicted, {chosen(choice).label} ({100 * choice.predicted_error:.1f} %)")
        before = self._lighting_drawn()
        self._apply_settings()
        if self._lighting_drawn() != before:  # the same setting keeps its accumulated samples
            v.restart()

    def _nothing_to_light(self, mode: str) -> tuple[str, str] | None:
        """Why `mode`'s prediction cannot be made now (the note and its style), or None."""
        v = self.view
        r = getattr(v, "renderer", None)  # none before OpenGL starts: the default scene asks again
        if r is None or v.blank or r.source is None:
            return f"{mode}: nothing to light", PENDING_STYLE
        if r.environment is None:
            return f"{mode}: no environment map to light with", WARNING_STYLE
        return None

    def _request_prefiltered_check(self) -> None:
        """The prefiltered mode chosen by hand: its predicted error for the drawn source and map,
        asked again when either changed."""
        c, v = self.controls, self.view
        chosen_by_hand = c.mode.currentText() == "prefiltered"
        unable = self._nothing_to_light("prefiltered") if chosen_by_hand else None
        if not chosen_by_hand or unable is not None:
            self._check_for = None
            self._check_token += 1  # an answer still on its way is for what was drawn before
            self._warn("prefiltered", None)
            if unable is not None:
                c.show_auto_note(unable[0], style=unable[1])
            return
        r = v.renderer
        key = (r.source, r.environment)
        if self._check_for is not None and all(a is b for a, b in zip(self._check_for, key)):
            return
        self._check_for = key
        self._check_token += 1
        c.show_auto_note("prefiltered: predicting its error for this material and map…", style=PENDING_STYLE)
        self._check_job.request((self._check_token, r.source, r.environment, r.material))

    def _prefiltered_known(self, result: tuple) -> None:
        token, error = result
        if token != self._check_token or self.controls.mode.currentText() != "prefiltered":
            return
        text, warns = prefiltered_note(error)
        self.controls.show_auto_note(text, style=WARNING_STYLE if warns else "")
        self._warn("prefiltered", f"Prefiltered lighting: predicted {100 * error:.1f} % off pixel by pixel here; "
                                  "choose mis or auto" if warns else None)

    def _lighting_drawn(self) -> tuple:
        """The view's lighting: mode, samples and (SH) the order handed to its renderer."""
        s = self.view.settings
        return s.mode, s.samples, self._sh_order_applied if s.mode == "sh" else None

    def shutdown(self) -> None:
        self._auto_job.shutdown()
        self._check_job.shutdown()
