"""OpenGL views inside Qt: the renderers of brdflab.render drawing into QOpenGLWidgets."""

from __future__ import annotations

import time

import moderngl
import numpy as np
from PySide6.QtCore import QPointF, Qt, QTimer, Signal
from PySide6.QtGui import QOpenGLContext, QSurfaceFormat
from PySide6.QtOpenGLWidgets import QOpenGLWidget

from brdflab.errors import BRDFLabError
from brdflab.render.lobe_view import LobeViewer
from brdflab.render.object_view import SAMPLED_MODES, Display, ObjectRenderer, RenderSettings, negative_pixels


def set_default_surface_format() -> None:
    """OpenGL 3.3 core with depth, for every QOpenGLWidget (call before QApplication)."""
    fmt = QSurfaceFormat()
    fmt.setVersion(3, 3)
    fmt.setProfile(QSurfaceFormat.CoreProfile)
    fmt.setDepthBufferSize(24)
    QSurfaceFormat.setDefaultFormat(fmt)


def clamped_fraction(rgba_bytes: bytes) -> float:
    """Of the pixels a surface covers, the fraction SH ringing made negative (clamped to black)."""
    clamped, covered = negative_pixels(np.frombuffer(rgba_bytes, np.float32))
    return clamped / covered if covered else 0.0


class _GLView(QOpenGLWidget):
    """Shared plumbing: a moderngl context on the widget's own GL context, orbit by drag."""

    failed = Signal(str)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.ctx: moderngl.Context | None = None
        self._last: QPointF | None = None
        self._pending: list = []
        self.gl_inits = 0  # Qt re-runs initializeGL with a new context when the widget moves window
        self.setMinimumSize(200, 160)

    def initializeGL(self) -> None:
        self.gl_inits += 1
        self.context().aboutToBeDestroyed.connect(self._context_lost, Qt.DirectConnection)
        try:
            self.ctx = moderngl.create_context()
            self.setup()
        except Exception as e:  # no usable OpenGL: say so instead of crashing
            self.ctx = None
            self.failed.emit(f"OpenGL is not available for this view: {str(e).splitlines()[0] if str(e) else e}")
            return
        pending, self._pending = self._pending, []
        for fn in pending:
            fn()

    def _context_lost(self) -> None:
        """Qt is about to destroy the GL context (re-parenting, floating a dock): every GL
        object dies with it. The next initializeGL rebuilds them from the views' state."""
        self.ctx = None
        self.context_lost()

    def context_lost(self) -> None:
        """Drop references to GL objects of the dying context (never release them)."""

    def when_ready(self, fn) -> None:
        """Run fn now if GL is initialised, else right after initialisation. Inside
        initializeGL/paintGL the context is already current and must stay so."""
        if self.ctx is None:
            self._pending.append(fn)
            return
        if QOpenGLContext.currentContext() is self.context():
            fn()
        else:
            self.makeCurrent()
            try:
                fn()
            finally:
                self.doneCurrent()
        self.update()

    def setup(self) -> None:
        raise NotImplementedError

    def camera(self):
        raise NotImplementedError

    def framebuffer(self) -> moderngl.Framebuffer:
        return self.ctx.detect_framebuffer(self.defaultFramebufferObject())

    def pixel_size(self) -> tuple[int, int]:
        r = self.devicePixelRatioF()
        return max(1, int(self.width() * r)), max(1, int(self.height() * r))

    def mousePressEvent(self, e) -> None:
        self._last = e.position()

    def mouseReleaseEvent(self, e) -> None:
        self._last = None

    def mouseMoveEvent(self, e) -> None:
        if self._last is None or self.ctx is None:
            return
        d = e.position() - self._last
        self._last = e.position()
        self.drag(d.x(), d.y(), e.buttons(), e.modifiers())

    def drag(self, dx: float, dy: float, buttons, modifiers) -> None:
        self.camera().orbit(-0.5 * dx, 0.5 * dy)
        self.view_changed()

    def wheelEvent(self, e) -> None:
        if self.ctx is None:
            return
        self.camera().zoom(0.9 if e.angleDelta().y() > 0 else 1.1)
        self.view_changed()

    def view_changed(self) -> None:
        self.update()


class LobeView(_GLView):
    """The lobe viewer; right-drag (or Shift+drag) moves the incident direction."""

    incident_changed = Signal(float, float)

    def setup(self) -> None:
        old = getattr(self, "viewer", None)
        self.viewer = LobeViewer(self.ctx)
        if old is not None:  # a new context: the same lobes, settings and camera
            self.viewer.adopt(old)

    def camera(self):
        return self.viewer.camera

    def paintGL(self) -> None:
        if self.ctx is None:
            return
        w, h = self.pixel_size()
        fbo = self.framebuffer()
        fbo.use()
        self.ctx.viewport = (0, 0, w, h)
        fbo.clear(0.12, 0.12, 0.14, 1.0, depth=1.0)
        try:
            self.viewer.draw(w, h)
        except BRDFLabError as e:
            self.failed.emit(str(e))

    def drag(self, dx, dy, buttons, modifiers) -> None:
        if buttons & Qt.RightButton or modifiers & Qt.ShiftModifier:
            s = self.viewer.settings
            theta = min(89.0, max(0.0, s.theta_i + 0.5 * dy))
            phi = (s.phi_i - 0.5 * dx) % 360.0
            self.incident_changed.emit(theta, phi)
        else:
            super().drag(dx, dy, buttons, modifiers)


class ObjectView(_GLView):
    """The object view; refines progressively while the view is still."""

    STEP_BUDGET_S = 0.025  # one refinement step may hold the GUI thread this long
    busy = Signal(str)  # a long preparation started ("" when it is over)
    ringing = Signal(float)  # SH mode, image complete: the fraction of object pixels clamped at 0
    table_shown = Signal(str)  # SH mode: the table drawn with (Auto: its pick and estimated error)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self._pool = None  # a worker process for SH tables (NumPy in a thread held the GIL for seconds)
        self._build_job = None  # (future, remember) of an SH table or prefiltered stack being built
        self.settings = RenderSettings(reference_view=False, samples=256)
        self.exposure = 0.0
        self.gamma = 0.0  # 0: sRGB
        self.reinhard = False
        self._progressive = None
        self._step_samples = 1  # adapted so that a step costs about STEP_BUDGET_S
        self.blank = False  # nothing to show (a material without lobes): draw the background
        # comparing: a second renderer with the same scene and camera shows `compare_source`
        self.compare = "off"  # or "split" (original | fit) or "difference"
        self.compare_source = None
        self.split = 0.5
        self._renderer_b = None
        self._scene_b: tuple | None = None  # the scene _renderer_b was built for
        self._progressive_b = None
        self._stale = None  # the last complete-enough image, shown while a new one starts
        self._table_note: str | None = None  # what table_shown last said
        self._timer = QTimer(self)
        self._timer.setInterval(0)
        self._timer.timeout.connect(self._refine)

    def setup(self) -> None:
        old = getattr(self, "renderer", None)
        self.renderer = ObjectRenderer(self.ctx)
        self.display = Display(self.ctx)
        if old is not None:  # a new context: the same scene, rebuilt on it
            self.renderer.adopt(old)
            self._timer.start()

    def context_lost(self) -> None:
        self._progressive = self._progressive_b = self._renderer_b = self._stale = None
        self._scene_b = None
        self._timer.stop()

    def shutdown(self) -> None:
        """The window is closing: no more refinement, and no SH table is built any further."""
        from brdflab.gui.background import stop_pool

        self._timer.stop()
        stop_pool(self._pool)
        self._pool, self._build_job = None, None

    def hideEvent(self, event) -> None:
        """A hidden (or closing) view refines nothing: its context may be on its way out."""
        self._timer.stop()
        super().hideEvent(event)

    def showEvent(self, event) -> None:
        super().showEvent(event)
        self._timer.start()

    def camera(self):
        return self.renderer.camera

    def restart(self) -> None:
        """Something changed: throw the accumulated samples away. The last image that had
        samples stays on screen until the new one has its first (no grey flash per edit)."""
        old = [self._progressive_b]
        if self._progressive is not None and self._progressive.samples > 0 and not self.blank:
            old.append(self._stale)
            self._stale = self._progressive
        else:
            old.append(self._progressive)
        if self.ctx is not None:
            self.when_ready(lambda: self._release(*old))
        self._progressive = self._progressive_b = None
        self._timer.start()
        self.update()

    @staticmethod
    def _release(*images) -> None:
        """Free the images' GL textures (the context must be current)."""
        for image in images:
            if image is not None:
                image.release()

    def _drop_stale(self) -> None:  # context current
        self._release(self._stale)
        self._stale = None

    @property
    def comparing(self) -> bool:
        """Two images at once: in the fis, mis and point modes (an SH table per source would stall)."""
        return self.compare != "off" and self.compare_source is not None and self.settings.mode != "sh"

    def _second_renderer(self) -> ObjectRenderer:
        """The compared source's renderer: the main renderer's scene (mesh, map, SH settings),
        its very camera, rebuilt when that scene changes (context current)."""
        r = self.renderer
        scene = (id(r.mesh), id(r.environment), r.sh_order, r.sh_window, r.sh_shadows, r.sh_variant)
        if self._renderer_b is None:
            self._renderer_b = ObjectRenderer(self.ctx)
        if scene != self._scene_b:
            self._renderer_b.adopt(r)
            self._scene_b = scene
        if self._renderer_b.source is not self.compare_source:
            self._renderer_b.set_source(self.compare_source)
        return self._renderer_b

    view_changed = restart

    @property
    def samples_done(self) -> int:
        return 0 if self._progressive is None else self._progressive.samples

    def _prepared_elsewhere(self) -> bool:
        """SH tables and prefiltered stacks take seconds of NumPy: build what the current mode
        needs in the worker process (one job at a time); True while it is not ready."""
        from brdflab.gui.background import worker_pool

        if self._build_job is not None and self._build_job[0].done():
            (job, remember), self._build_job = self._build_job, None
            self.busy.emit("")
            remember(job.result())  # a failed build raises here, where it is reported
        need = self._still_needed()
        if need is None:
            return False
        if self._build_job is None:
            build, args, remember, message = need
            if self._pool is None:
                self._pool = worker_pool()
            self._build_job = (self._pool.submit(build, *args), remember)
            self.busy.emit(message)
        QTimer.singleShot(100, self._refine)
        return True

    def _still_needed(self):
        """What the current mode cannot draw without: (build, args, remember, message), or None."""
        from functools import partial

        from brdflab.lighting.prefilter import build_stack, map_key, remember_stack
        from brdflab.lighting.sh_table_auto import AutoTable, build_table

        r = self.renderer
        if self.settings.mode == "sh" and not r.sh_table_ready():
            source = r.source if r.source is not None else r.material
            what = "choosing and building" if isinstance(r.sh_table, AutoTable) else "building"
            return (build_table, (source, r.sh_order, r.sh_table),
                    partial(self._remember_table, source, r.sh_order, r.sh_table), f"{what} the order-{r.sh_order} SH table…")
        if self.settings.mode == "prefiltered" and r.environment is not None and not r.prefiltered_ready():
            return build_stack, (r.environment, map_key(r.environment)), remember_stack, "prefiltering the environment map…"
        return None

    @staticmethod
    def _remember_table(source, order: int, table, built) -> None:
        """Keep what the worker's build_table returned: Auto's choice, and the table under its setting."""
        from brdflab.lighting.sh_table_auto import remember_choice
        from brdflab.lighting.sh_tables import remember_table

        choice, setting, values = built
        if choice is not None:
            remember_choice(source, order, table, choice)
        remember_table(source, order, values, setting)

    def _show_table(self) -> None:
        """Say which table the SH mode draws with, once per change."""
        from brdflab.lighting.sh_table_auto import AutoTable, known_choice

        r = self.renderer
        source = r.source if r.source is not None else r.material
        if isinstance(r.sh_table, AutoTable):
            choice = known_choice(source, r.sh_order, r.sh_table)
            note = "" if choice is None else choice.label
        else:
            note = r.sh_table.of(source).text
        if note != self._table_note:
            self._table_note = note
            self.table_shown.emit(note)

    def _refine(self) -> None:
        """Render more samples, outside paint events (Qt's paint-time GL state is not
        moderngl's), then ask for a repaint that only displays the image."""
        if self.ctx is None or self.blank or not self.isVisible() or getattr(self.renderer, "material", None) is None:
            self._timer.stop()  # nothing to refine: a 0 ms timer would spin the GUI thread
            return
        w, h = self.pixel_size()
        self.makeCurrent()
        try:
            if self._prepared_elsewhere():
                return
            if self.settings.mode == "sh":
                self._show_table()
            if self._progressive is None or (self._progressive.settings.width, self._progressive.settings.height) != (w, h):
                self._release(self._progressive, self._progressive_b)
                settings = RenderSettings(**{**self.settings.__dict__, "width": w, "height": h})
                self._progressive = self.renderer.start_progressive(settings)
                self._progressive_b = self._second_renderer().start_progressive(settings) if self.comparing else None
            p = self._progressive
            target = self.settings.samples if self.settings.mode in SAMPLED_MODES else 1
            if p.samples < target:
                n = min(self._step_samples, target - p.samples)
                began = time.perf_counter()
                for image in (p, self._progressive_b):
                    if image is not None:
                        image.step(n)
                self.ctx.finish()  # llvmpipe renders lazily: time the real work
                spent = time.perf_counter() - began
                self._step_samples = int(max(1, min(256, n * self.STEP_BUDGET_S / max(spent, 1e-4))))
                self._timer.start()
                if self.settings.mode == "sh" and p.samples >= target:
                    self.ringing.emit(clamped_fraction(p.texture.read()))
            else:
                self._timer.stop()
        except BRDFLabError as e:
            self._timer.stop()
            self.failed.emit(str(e))
        finally:
            self.doneCurrent()
        self.update()

    def paintGL(self) -> None:
        if self.ctx is None:
            return
        fbo = self.framebuffer()
        fbo.use()
        w, h = self.pixel_size()
        self.ctx.viewport = (0, 0, w, h)
        image = self._progressive
        if image is None or image.samples == 0:
            image = self._stale if self._stale is not None and (self._stale.settings.width, self._stale.settings.height) == (w, h) else None
        else:
            self._drop_stale()
        if self.blank or image is None:
            fbo.clear(0.12, 0.12, 0.14, 1.0)
            if not self.blank and not self._timer.isActive():
                self._timer.start()
            return
        lit_by_map = image.settings.mode in ("fis", "sh", "prefiltered", "mis")
        other = self._progressive_b if self.comparing and image is self._progressive and self._progressive_b is not None else None
        self.display.draw(image, self.exposure, self.reinhard, gamma=self.gamma,
                          environment=self.renderer if lit_by_map else None, other=other,
                          compare=self.compare, split=self.split)

    def resizeGL(self, w: int, h: int) -> None:
        self._release(self._progressive, self._progressive_b, self._stale)  # current during resizeGL
        self._progressive = self._progressive_b = self._stale = None
        self._timer.start()
