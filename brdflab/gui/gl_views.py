"""OpenGL views inside Qt: the renderers of brdflab.render drawing offscreen, shown as images.

Why not QOpenGLWidget: a window that holds one is composed by GL on every repaint of any part
of it (25–60 ms per frame on software GL, measured with the 1600 × 1000 main window, the GUI
thread blocked meanwhile), and moving one to another window (floating a dock) destroys its
context and every object in it. Here each view owns a standalone context for its lifetime,
draws into a framebuffer of its own, and shows the image read back (1–3 ms); the window stays
a plain raster window.
"""

from __future__ import annotations

import time
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as wait_for
from contextlib import contextmanager
from functools import cache

import moderngl
import numpy as np
from PySide6.QtCore import QPointF, QRect, Qt, QTimer, Signal
from PySide6.QtGui import QColor, QImage, QPainter
from PySide6.QtWidgets import QWidget

from brdflab.errors import BRDFLabError
from brdflab.render import gil_free
from brdflab.render.context import create_context
from brdflab.render.lobe_view import LobeViewer
from brdflab.render.object_view import (
    DIFFERENCE_TICKS,
    Display,
    ObjectRenderer,
    RenderSettings,
    difference_colour,
    negative_pixels,
)

BACKGROUND = (0.12, 0.12, 0.14)


def clamped_fraction(rgba_bytes: bytes) -> float:
    """Of the pixels a surface covers, the fraction SH ringing made negative (clamped to black)."""
    clamped, covered = negative_pixels(np.frombuffer(rgba_bytes, np.float32))
    return clamped / covered if covered else 0.0


class _Queue:
    """Mesa's llvmpipe rasterizes the draws of every context in one queue, and reading
    anything back waits for all of it: a lobe-view frame read while an object-view step is
    queued waited for that step (40–50 ms, measured). So one view at a time has GL work in
    flight: it holds the turn from issuing its draws until it has read them back, and frames
    waiting to be drawn go before the object view's next refinement step."""

    def __init__(self) -> None:
        self.holder = None  # the _ContextOwner of the view whose work is in flight
        self.waiting: set = set()  # views with a frame to draw

    def take(self, owner) -> bool:
        if self.holder is None or self.holder is owner:
            self.holder = owner
            self.waiting.discard(owner)
            return True
        self.waiting.add(owner)
        return False

    def give_back(self, owner) -> None:
        if self.holder is owner:
            self.holder = None

    def others_waiting(self, owner) -> bool:
        return bool(self.waiting - {owner})


GL_QUEUE = _Queue()


@cache
def _step_thread() -> ThreadPoolExecutor:
    """The thread that draws the object views' steps (one at a time, as GL_QUEUE has them)."""
    return ThreadPoolExecutor(max_workers=1, thread_name_prefix="brdflab-gl-steps")


class _Draws:
    """A view's draws (a frame, a refinement step), run in the step thread with the view's
    context current there where GL can be called without the GIL: a program's first draw
    compiles it (seconds on a busy machine, with Mesa's shader cache off), and the GUI thread
    goes on meanwhile, showing the image it has (issue 35). Elsewhere they run at once, on the
    GUI thread (`ran_here`). `done` asks without waiting; `check` raises what the draws raised."""

    def __init__(self, work) -> None:
        self.work = work
        self.future: Future | None = None  # set once the GUI thread has let go of the context

    @classmethod
    def ran_here(cls, work, ctx: moderngl.Context) -> "_Draws":
        """The draws run now, in this thread, and waited for."""
        draws = cls(work)
        draws.future = Future()
        try:
            work()
            ctx.finish()
        except Exception as e:  # raised where the draws are checked, as the step thread's are
            draws.future.set_exception(e)
        else:
            draws.future.set_result(None)
        return draws

    def done(self) -> bool:
        return self.future is not None and self.future.done()

    def wait(self) -> None:
        if self.future is None:
            raise RuntimeError("waiting for draws not handed to the step thread yet (the GUI thread holds the context)")
        wait_for([self.future])

    def check(self) -> None:
        if self.future is not None:
            self.future.result()


class _ContextOwner:
    """Releases a view's context (its GL objects go with it) and its turn when Qt destroys it."""

    def __init__(self) -> None:
        self.ctx: moderngl.Context | None = None
        self.worker: _Draws | None = None  # the view's last work in the step thread

    def __call__(self, *_) -> None:
        if self.worker is not None:
            self.worker.wait()
        GL_QUEUE.give_back(self)
        GL_QUEUE.waiting.discard(self)
        if self.ctx is not None:
            self.ctx.release()
            self.ctx = None


class _GLView(QWidget):
    """Shared plumbing: a moderngl context of the view's own, an offscreen framebuffer of the
    view's size that `paintGL` draws into, the image shown, orbit by drag. The API follows
    QOpenGLWidget's (initialise on first show, `update`, `makeCurrent`, `grabFramebuffer`)."""

    failed = Signal(str)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.ctx: moderngl.Context | None = None
        self._current = 0  # makeCurrent nesting
        self._target: tuple | None = None  # (framebuffer, colour, depth, size) paintGL draws into
        self._frame: QImage | None = None  # the last image drawn: what the view shows
        self._dirty = True  # the frame is out of date
        self._frame_draws: _Draws | None = None  # a frame drawn, not read back yet
        self._poll = QTimer(self, interval=4)
        self._poll.timeout.connect(self._advance_frame)
        self._tried = False
        self._last: QPointF | None = None
        self._pending: list = []  # work for the context, waiting for it (not made yet, or in the step thread)
        self._handoff: _Draws | None = None  # work for the step thread once the GUI thread lets go
        self._worker: _Draws | None = None  # the step thread's work with this view's context
        self._set_up = False  # setup() has run: work waiting for the context may run
        self.gl_inits = 0  # contexts made: one per view (re-parenting keeps it)
        self._owner = _ContextOwner()
        self.destroyed.connect(self._owner)
        self.setMinimumSize(200, 160)
        self.setAttribute(Qt.WA_OpaquePaintEvent)

    def showEvent(self, event) -> None:
        super().showEvent(event)
        if not self._tried:
            self._initialize()

    def hideEvent(self, event) -> None:
        """A hidden view may not be polled: finish its work and give the turn back."""
        if self.ctx is not None and GL_QUEUE.holder is self._owner:
            with self.current():
                self.drop_flight()
        GL_QUEUE.give_back(self._owner)
        GL_QUEUE.waiting.discard(self._owner)
        super().hideEvent(event)

    def drop_flight(self) -> None:
        """Wait for the work in flight and forget it unseen (context current)."""
        if self._frame_draws is not None:
            self._frame_draws.wait()
        self._frame_draws, self._dirty = None, True

    def _initialize(self) -> None:
        self._tried = True
        try:
            self.ctx = self._owner.ctx = create_context()
            self.gl_inits += 1
            with self.current():
                self.setup()
        except Exception as e:  # no usable OpenGL: say so instead of crashing
            self.ctx = None
            self.failed.emit(f"OpenGL is not available for this view: {str(e).splitlines()[0] if str(e) else e}")
            return
        self._set_up = True
        self.catch_up()  # the work that waited for the context
        self.update()

    def busy_elsewhere(self) -> bool:
        """Whether the step thread holds the context (the GUI thread must not take it now)."""
        return self._worker is not None and not self._worker.done()

    def makeCurrent(self) -> None:
        """Take the context (waiting for the step thread if it holds it), then run the work
        that waited for it, in order."""
        if self._current == 0:
            if self._worker is not None:
                self._worker.wait()
            self.ctx.__enter__()
        self._current += 1
        if self._current == 1 and self._set_up:
            try:
                while self._pending:
                    self._pending.pop(0)()
            except BaseException:
                self.doneCurrent()
                raise

    def doneCurrent(self) -> None:
        """Let go of the context; draws handed to the step thread start now."""
        self._current -= 1
        if self._current == 0:
            self.ctx.__exit__(None, None, None)
            if self._handoff is not None:
                self._worker = self._owner.worker = self._handoff
                self._handoff = None
                self._worker.future = _step_thread().submit(self._in_step_thread, self._worker.work)

    def _in_step_thread(self, work) -> None:
        with self.ctx:
            work()
            gil_free.finish(self.ctx)

    def hand_off(self, work) -> _Draws:
        """Run `work` in the step thread, with the context current there, once the GUI thread
        lets go of it (context current here)."""
        if self._handoff is not None:
            raise RuntimeError("one hand-off at a time: the step thread draws a frame or a step, not both")
        self._handoff = _Draws(work)
        return self._handoff

    def draw(self, work) -> _Draws:
        """The draws `work` (context current here): handed to the step thread where GL can be
        called there without the GIL, else run here and waited for."""
        return self.hand_off(work) if gil_free.available(self.ctx) else _Draws.ran_here(work, self.ctx)

    @contextmanager
    def current(self):
        """`with view.current():` the view's context is current inside."""
        self.makeCurrent()
        try:
            yield
        finally:
            self.doneCurrent()

    def when_ready(self, fn) -> None:
        """Run fn with the context current: now if the view has one and holds it, else once it does."""
        if self.ctx is None or self.busy_elsewhere():
            self._pending.append(fn)
            if self.ctx is not None:
                self.update()
            return
        with self.current():
            fn()
        self.update()

    def catch_up(self) -> None:
        """Run the work queued for the context now, waiting for the step thread if it holds it:
        for a reader of the renderer's state that must see every change handed to it."""
        if self.ctx is not None:
            with self.current():
                pass

    def update(self, *args) -> None:
        """The image is out of date: draw it again. The draws run while the GUI thread goes
        on; the image shown changes once they are done (a poll reads it back)."""
        self._dirty = True
        if self.ctx is None:
            super().update(*args)
        elif not self._poll.isActive():
            self._poll.start()

    def setup(self) -> None:
        raise NotImplementedError

    def camera(self):
        raise NotImplementedError

    def framebuffer(self) -> moderngl.Framebuffer:
        """The view's offscreen framebuffer (8-bit RGBA, depth), at its pixel size (context current)."""
        size = self.pixel_size()
        if self._target is None or self._target[3] != size:
            if self._target is not None:
                for obj in self._target[:3]:
                    obj.release()
            colour, depth = self.ctx.texture(size, 4), self.ctx.depth_renderbuffer(size)
            self._target = (self.ctx.framebuffer([colour], depth), colour, depth, size)
        return self._target[0]

    def can_draw(self) -> bool:
        """Whether paintGL can be issued now (not before other work in flight has landed)."""
        return True

    def _advance_frame(self) -> None:
        """Read back a frame whose draws are done; issue the next if the image is out of date."""
        if self.ctx is None:
            self._poll.stop()
            return
        if self.busy_elsewhere():
            return  # asked again at the next poll
        with self.current():
            if self._frame_draws is not None:
                if not self._frame_draws.done():
                    return
                self._read_frame()
            if self._dirty and self.can_draw():
                if GL_QUEUE.take(self._owner):
                    self._issue_frame()
            else:  # done, or waiting for whoever makes it drawable (it calls update)
                self._poll.stop()

    def _issue_frame(self) -> None:
        """paintGL into the framebuffer (context current; `draw`). paintGL draws into `_target`,
        made here at the view's size: the step thread asks Qt nothing."""
        target = self.framebuffer()

        def frame() -> None:
            target.use()
            self.paintGL()

        self._frame_draws, self._dirty = self.draw(frame), False
        if not self._poll.isActive():
            self._poll.start()

    def _read_frame(self) -> None:
        """The issued frame, read back as the image shown (context current)."""
        _, colour, _, (w, h) = self._target
        landed, self._frame_draws = self._frame_draws, None
        GL_QUEUE.give_back(self._owner)
        try:
            landed.check()
        except BRDFLabError as e:
            self.failed.emit(str(e))
        rows = np.frombuffer(colour.read(alignment=1), np.uint8).reshape(h, w, 4)[::-1]
        frame = QImage(np.ascontiguousarray(rows).tobytes(), w, h, 4 * w, QImage.Format_RGBX8888).copy()
        frame.setDevicePixelRatio(self.devicePixelRatioF())
        self.decorate(frame)
        self._frame = frame
        super().update()  # repaint: only the image is drawn

    def decorate(self, frame: QImage) -> None:
        """Paint over a frame read back, before it is shown (and grabbed, and exported)."""

    def paintEvent(self, event) -> None:
        painter = QPainter(self)
        if self._frame is None:
            painter.fillRect(self.rect(), QColor.fromRgbF(*BACKGROUND))
        else:  # scaled while a resize waits for its first image
            painter.drawImage(self.rect(), self._frame)
        painter.end()

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        if self.ctx is not None:
            self.when_ready(lambda: self.resizeGL(*self.pixel_size()))
        self.update()

    def resizeGL(self, w: int, h: int) -> None:
        """The view's size changed (context current)."""

    def settle(self) -> None:
        """Wait for work in flight (context current)."""

    def grabFramebuffer(self) -> QImage:
        """The image the view shows, drawn now if it is out of date (this waits for the draws)."""
        if self.ctx is not None:
            with self.current():
                self.settle()
                if self._frame_draws is None and self._dirty and self.can_draw():
                    self._issue_frame()
            with self.current():  # a frame handed to the step thread went when the context was let go
                if self._frame_draws is not None:
                    self._frame_draws.wait()
                    self._read_frame()
        if self._frame is not None:
            return QImage(self._frame)
        w, h = self.pixel_size()
        blank = QImage(w, h, QImage.Format_RGBX8888)
        blank.fill(QColor.fromRgbF(*BACKGROUND))
        return blank

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
        self.viewer = LobeViewer(self.ctx)
        self._legend: list = []  # the viewer's legend for the frame issued
        self.legend_boxes: list[tuple[QRect, QRect]] = []  # (swatch, text) of each entry, as last painted

    def camera(self):
        return self.viewer.camera

    def paintGL(self) -> None:
        fbo, _, _, (w, h) = self._target
        self.ctx.viewport = (0, 0, w, h)
        fbo.clear(*BACKGROUND, 1.0, depth=1.0)
        self.viewer.draw(w, h)
        self._legend = self.viewer.legend()

    def decorate(self, frame: QImage) -> None:
        """An original and its fit drawn together: a legend in the bottom-left corner says
        which is which, each by a swatch of its colour as drawn (the translucent one over the
        background) and its name (BRDFLab and BRDF Explorer label them too). Under the
        warnings banner's opposite edge: the banner never covers it."""
        self.legend_boxes = []
        if not self._legend:
            return
        painter = QPainter(frame)
        try:
            painter.setRenderHint(QPainter.TextAntialiasing)
            painter.setFont(self.font())
            metrics = painter.fontMetrics()
            line, pad, margin = metrics.height() + 4, 6, 8
            swatch = metrics.height() - 2
            r = frame.devicePixelRatio()
            room = round(frame.width() / r) - 2 * (margin + pad) - swatch - 8
            # a narrow view shortens the names in their middle: which is which, and how drawn, stay
            texts = [metrics.elidedText(text, Qt.ElideMiddle, room) for text, _, _ in self._legend]
            width = 2 * pad + swatch + 8 + max(metrics.horizontalAdvance(text) for text in texts)
            height = 2 * pad + line * len(self._legend) - 4
            box = QRect(margin, round(frame.height() / r) - margin - height, width, height)
            painter.fillRect(box, QColor(0, 0, 0, 170))
            for k, (text, (_, color, alpha)) in enumerate(zip(texts, self._legend)):
                top = box.top() + pad + k * line
                square = QRect(box.left() + pad, top + (line - 4 - swatch) // 2, swatch, swatch)
                painter.fillRect(square, QColor.fromRgbF(*BACKGROUND))
                painter.fillRect(square, QColor.fromRgbF(*color, alpha))
                label = QRect(square.right() + 9, top, width - 2 * pad - swatch - 8, line - 4)
                painter.setPen(QColor(235, 235, 235))
                painter.drawText(label, Qt.AlignLeft | Qt.AlignVCenter, text)
                self.legend_boxes.append((square, label))
        finally:
            painter.end()

    def drag(self, dx, dy, buttons, modifiers) -> None:
        if buttons & Qt.RightButton or modifiers & Qt.ShiftModifier:
            s = self.viewer.settings
            theta = min(89.0, max(0.0, s.theta_i + 0.5 * dy))
            phi = (s.phi_i - 0.5 * dx) % 360.0
            self.incident_changed.emit(theta, phi)
        else:
            super().drag(dx, dy, buttons, modifiers)


class ObjectView(_GLView):
    """The object view; refines progressively while the view is still. A step's draws run
    while the GUI thread goes on (`_GLView.draw`; polled, never waited for); the image shown is the
    last one read back, kept on screen until a restarted image has its first samples."""

    STEP_S = 0.05  # a step's GL time: frequent enough images, a new edit waits at most this
    POLL_MS = 4  # how often the GUI thread asks whether a step is done
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
        self._step_samples = 1  # adapted so that a step takes about STEP_S
        self._flight: tuple | None = None  # (draws, image, samples, began) of the step being drawn
        self.blank = False  # nothing to show (a material without lobes): draw the background
        # comparing: a second renderer with the same scene and camera shows `compare_source`
        self.compare = "off"  # or "split" (original | fit) or "difference"
        self.compare_source = None
        self.split = 0.5
        self._renderer_b = None
        self._scene_b: tuple | None = None  # the scene _renderer_b was built for
        self._progressive_b = None
        self._table_note: str | None = None  # what table_shown last said
        self._drawing_difference = False  # the frame issued is the difference view: it gets a legend
        self._difference_pending: tuple[int, int] | None = None  # (samples, needed) while a difference is held back
        self._legend: tuple | None = None  # the legend on the frame shown (difference_legend)
        self._timer = QTimer(self)
        self._timer.setInterval(self.POLL_MS)
        self._timer.timeout.connect(self._refine)

    def setup(self) -> None:
        self.renderer = ObjectRenderer(self.ctx)
        self.renderer.tabulated.background = True  # a file lobe's tables never block the window
        self.display = Display(self.ctx)

    def shutdown(self) -> None:
        """The window is closing: no more refinement, and no SH table is built any further."""
        from brdflab.gui.background import stop_pool

        self._timer.stop()
        stop_pool(self._pool)
        self._pool, self._build_job = None, None

    def hideEvent(self, event) -> None:
        """A hidden (or closing) view refines nothing."""
        self._timer.stop()
        super().hideEvent(event)

    def drop_flight(self) -> None:
        super().drop_flight()
        if self._flight is not None:
            self._flight[0].wait()
        self._flight = None

    def showEvent(self, event) -> None:
        super().showEvent(event)
        self._timer.start()

    def camera(self):
        return self.renderer.camera

    def environment_map(self):
        """The map the renderer lights with, once the work handed to it has run (a map just
        opened waits in the view's queue while the step thread draws); None before OpenGL starts."""
        self.catch_up()
        renderer = getattr(self, "renderer", None)
        return None if renderer is None else renderer.environment

    def restart(self) -> None:
        """Something changed: throw the accumulated samples away. The image shown stays on
        screen until the new one has its first samples (no grey flash per edit)."""
        old = (self._progressive, self._progressive_b)
        self._progressive = self._progressive_b = None
        if self.ctx is not None:
            self.when_ready(lambda: self._release(*old))
        self._timer.start()
        self.update()

    @staticmethod
    def _release(*images) -> None:
        """Free the images' GL textures (the context must be current)."""
        for image in images:
            if image is not None:
                image.release()

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
            self._renderer_b.tabulated.background = True
        if scene != self._scene_b:
            self._renderer_b.adopt(r)
            self._scene_b = scene
        if self._renderer_b.source is not self.compare_source:
            self._renderer_b.set_source(self.compare_source)
        return self._renderer_b

    view_changed = restart

    @property
    def samples_done(self) -> int:
        """Samples drawn for the current image (a long FIS image's preview set included)."""
        return 0 if self._progressive is None else self._progressive.drawn

    @property
    def image_complete(self) -> bool:
        """Whether the image shown is the complete one (`render`'s of the same settings)."""
        return self._progressive is not None and self._progressive.complete

    def _prepared_elsewhere(self) -> bool:
        """SH tables and prefiltered stacks take seconds of NumPy: build what the current mode
        needs in the worker process (one job at a time); True while it is not ready."""
        from brdflab.gui.background import submit, worker_pool

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
            self._build_job = (submit(self._pool, build, *args), remember)
            self.busy.emit(message)
        self._timer.stop()  # ask again in 100 ms, not every poll
        QTimer.singleShot(100, self._timer, self._timer.start)
        return True

    def _still_needed(self):
        """What the current mode cannot draw without: (build, args, remember, message), or None."""
        from functools import partial

        from brdflab.lighting.env_sampling import environment_distribution
        from brdflab.lighting.prefilter import map_key, remember_stack, stored_or_built
        from brdflab.lighting.sh import project_environment
        from brdflab.lighting.split_sum import material_split
        from brdflab.lighting.sh_table_auto import AutoTable, build_table

        r = self.renderer
        if self.settings.mode == "sh" and not r.sh_table_ready():
            source = r.source if r.source is not None else r.material
            what = "choosing and building" if isinstance(r.sh_table, AutoTable) else "building"
            return (build_table, (source, r.sh_order, r.sh_table),
                    partial(self._remember_table, source, r.sh_order, r.sh_table), f"{what} the order-{r.sh_order} SH table…")
        if self.settings.mode == "sh" and r.environment is not None and not r.sh_light_ready():
            return (project_environment, (r.environment, r.sh_order, r.sh_window),
                    partial(r.remember_sh_light, r.environment, r.sh_order, r.sh_window), "projecting the map onto SH…")
        if self.settings.mode == "mis" and r.environment is not None and not r.env_distribution_ready():
            return (environment_distribution, (r.environment,), partial(r.remember_env_distribution, r.environment),
                    "preparing the map for MIS…")
        stacked = self.settings.mode == "prefiltered" or (self.settings.mode == "mis" and self.settings.mis_control)
        if stacked and r.environment is not None and not r.prefiltered_ready():
            return stored_or_built, (r.environment, map_key(r.environment)), remember_stack, "prefiltering the environment map…"
        pref = r.prefiltered
        if stacked and r.material is not None and not pref.splits_ready(r.material):
            return material_split, (r.material,), partial(pref.remember_splits, pref.material_key(r.material)), ""
        if self.settings.mode == "mis" and self.settings.mis_control and r.environment is not None \
                and r.material is not None and not r.control_weight_ready():
            function, args = r.control_weight_job()
            return (function, args, partial(r.remember_control_weight, pref.material_key(r.material), r.lit_source(),
                                            r.environment), "weighing MIS's control for this material and map…")
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
        """Poll the step in flight; once it is done, show it and issue the next. Outside
        paint events, and never waiting for the draws: the GUI thread only issues them."""
        if self.ctx is None or self.blank or not self.isVisible() or getattr(self.renderer, "material", None) is None:
            self._timer.stop()  # nothing to refine: the poll would spin the GUI thread
            return
        if self.busy_elsewhere():
            return  # the step thread draws: asked again at the next tick
        with self.current():
            try:
                if self._flight is not None and not self._landed():
                    return
                if self._frame_draws is not None:  # read it back first: GL would make that wait for the step
                    return
                if not self._prepared_elsewhere():
                    self._issue_step()
            except BRDFLabError as e:
                self._timer.stop()
                self.failed.emit(str(e))

    def _landed(self) -> bool:
        """Whether the step in flight is done; if so, show it (context current)."""
        draws, image, n, began = self._flight
        if not draws.done():
            return False
        self._flight = None
        GL_QUEUE.give_back(self._owner)
        draws.check()  # what the draws raised, raised here
        spent = time.perf_counter() - began
        self._step_samples = int(max(1, min(256, n * self.STEP_S / max(spent, 1e-4))))
        if image is self._progressive:  # not restarted meanwhile: show it
            self._dirty = True
            self._advance_frame()
            if self.settings.mode == "sh" and image.complete:
                self.ringing.emit(clamped_fraction(image.texture.read()))
        return True

    def _issue_step(self) -> None:
        """Issue the next step's draws, or stop when the image is complete (context current)."""
        if self.settings.mode == "sh":
            self._show_table()
        w, h = self.pixel_size()
        if self._progressive is None or (self._progressive.settings.width, self._progressive.settings.height) != (w, h):
            self._release(self._progressive, self._progressive_b)
            settings = RenderSettings(**{**self.settings.__dict__, "width": w, "height": h})
            self._progressive = self.renderer.start_progressive(settings)
            self._progressive_b = self._second_renderer().start_progressive(settings) if self.comparing else None
        p = self._progressive
        if p.complete:
            tables = self.renderer.tabulated
            if tables.provisional:  # drawn from a file lobe's stand-in tables: again once its own are built
                if tables.building_done():
                    self.restart()
                return
            self._timer.stop()
            return
        if GL_QUEUE.others_waiting(self._owner) or not GL_QUEUE.take(self._owner):
            return  # the timer asks again
        n = min(self._step_samples, max(1, p.needed - p.drawn)) if p.drawn else 1  # a first step also lays depth
        began = time.perf_counter()
        images = [image for image in (p, self._progressive_b) if image is not None]

        def step() -> None:
            for image in images:
                image.step(n)

        self._flight = (self.draw(step), p, n, began)

    def can_draw(self) -> bool:
        """Drawn images only: samples that have landed, or the background of a blank view."""
        p = self._progressive
        return self.blank or (self._flight is None and p is not None and p.samples > 0)

    def settle(self) -> None:
        if self._flight is not None:
            self._flight[0].wait()
            self._landed()

    def paintEvent(self, event) -> None:
        if not self.blank and self._progressive is None and not self._timer.isActive():
            self._timer.start()
        super().paintEvent(event)

    LEGEND_MARGIN = 8  # px from the view's bottom-left corner
    LEGEND_TITLES = ("|fit − original| ÷ the brighter (luminance)", "|fit − orig.| ÷ brighter")  # the first that fits

    def difference_legend(self) -> tuple[QRect, QRect, list[tuple[float, int, str]]] | None:
        """The difference view's legend on the image shown, None when it shows no difference:
        (its box, its colour bar, and per label its value, the bar's column x at that value and
        its text), in the view's coordinates. The bar's column i shows the relative difference
        i / (width − 1), coloured as the shader colours it."""
        return self._legend

    def _legend_geometry(self, fm, width: int, height: int) -> tuple[QRect, QRect, list[tuple[float, int, str]], str]:
        """Where the legend goes in an image `width` × `height` (logical px), by font metrics `fm`;
        with its title."""
        columns = 201 if width >= 260 else 101  # 0, 25, 50, 75, 100 % on whole columns
        pad, line = 6, fm.height()
        room = width - 2 * (self.LEGEND_MARGIN + pad)
        title = next((t for t in self.LEGEND_TITLES if fm.horizontalAdvance(t) <= room), self.LEGEND_TITLES[-1])
        title_w = fm.horizontalAdvance(title)
        box_w = max(columns, title_w) + 2 * pad + fm.horizontalAdvance("100 %") // 2
        box_h = pad + line + 4 + 12 + 3 + line + pad
        box = QRect(self.LEGEND_MARGIN, height - self.LEGEND_MARGIN - box_h, box_w, box_h)
        bar = QRect(box.left() + pad + fm.horizontalAdvance("0") // 2, box.top() + pad + line + 4, columns, 12)
        labels = [(v, bar.left() + round(v * (columns - 1)), f"{100 * v:.0f}" + (" %" if v == 1.0 else ""))
                  for v in DIFFERENCE_TICKS]
        return box, bar, labels, title

    def _paint_legend(self, frame: QImage) -> None:
        """Over a difference image: a dark box with what the colours measure, the colour bar and
        its values under ticks; painted into the image, so that grabbing and exporting it keep it."""
        painter = QPainter(frame)
        try:
            painter.setFont(self.font())
            fm = painter.fontMetrics()
            r = frame.devicePixelRatio()
            box, bar, labels, title = self._legend_geometry(fm, round(frame.width() / r), round(frame.height() / r))
            self._legend = box, bar, labels
            painter.fillRect(box, QColor(0, 0, 0, 170))
            painter.setPen(QColor(235, 235, 235))
            painter.drawText(box.left() + 6, box.top() + 6 + fm.ascent(), title)
            rgb = np.round(255.0 * difference_colour(np.arange(bar.width()) / (bar.width() - 1))).astype(np.uint8)
            strip = np.ascontiguousarray(np.broadcast_to(rgb[None], (bar.height(), bar.width(), 3)))
            painter.drawImage(bar.topLeft(), QImage(strip.tobytes(), bar.width(), bar.height(), 3 * bar.width(),
                                                    QImage.Format_RGB888))
            painter.setPen(QColor(120, 120, 120))  # a frame just outside the bar: its black end stays seen
            painter.drawRect(bar.adjusted(-1, -1, 0, 0))
            painter.setPen(QColor(235, 235, 235))
            baseline = bar.bottom() + 3 + fm.ascent()
            for _, x, text in labels:
                painter.drawLine(x, bar.bottom() + 1, x, bar.bottom() + 3)
                painter.drawText(x - fm.horizontalAdvance(text.split()[0]) // 2, baseline, text)
        finally:
            painter.end()

    def paintGL(self) -> None:
        fbo, _, _, (w, h) = self._target
        self.ctx.viewport = (0, 0, w, h)
        image = self._progressive
        self._drawing_difference = False
        if self.blank or image is None or image.samples == 0:
            fbo.clear(*BACKGROUND, 1.0)
            return
        lit_by_map = image.settings.mode in ("fis", "sh", "prefiltered", "mis")
        other = self._progressive_b if self.comparing and self._progressive_b is not None else None
        self._drawing_difference = other is not None and self.compare == "difference"
        self._difference_pending = None
        compare = self.compare
        if self._drawing_difference and not (image.complete and other.complete):
            # two images of a few samples each differ by their noise (a third of the pixels
            # 33 % or more for the first ~10 s): the original is shown until both are complete
            self._difference_pending = (min(image.drawn, other.drawn), max(image.needed, other.needed))
            other, compare = None, "off"
        self.display.draw(image, self.exposure, self.reinhard, gamma=self.gamma,
                          environment=self.renderer if lit_by_map else None, other=other,
                          compare=compare, split=self.split)

    def decorate(self, frame: QImage) -> None:
        """A difference image gets its legend."""
        self._legend = None
        if self._difference_pending is not None:
            self._paint_pending(frame, *self._difference_pending)
        elif self._drawing_difference:
            self._paint_legend(frame)

    def difference_pending(self) -> tuple[int, int] | None:
        """(samples so far, samples needed) while the difference view shows the original,
        waiting for both images to hold a full sample set; None otherwise."""
        return self._difference_pending

    def _paint_pending(self, frame: QImage, samples: int, needed: int) -> None:
        """Over the original shown meanwhile: what the difference view waits for."""
        painter = QPainter(frame)
        try:
            painter.setFont(self.font())
            fm = painter.fontMetrics()
            text = f"difference after {needed} samples: {samples} so far (the original meanwhile)"
            height = round(frame.height() / frame.devicePixelRatio())
            box = QRect(self.LEGEND_MARGIN, height - self.LEGEND_MARGIN - fm.height() - 12,
                        fm.horizontalAdvance(text) + 12, fm.height() + 12)
            painter.fillRect(box, QColor(0, 0, 0, 170))
            painter.setPen(QColor(235, 235, 235))
            painter.drawText(box.left() + 6, box.top() + 6 + fm.ascent(), text)
        finally:
            painter.end()

    def resizeGL(self, w: int, h: int) -> None:
        self._release(self._progressive, self._progressive_b)
        self._progressive = self._progressive_b = None
        self._timer.start()
