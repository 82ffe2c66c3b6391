"""GL fences: has the work issued so far finished? Asked without waiting.

A window that waits for the GPU (`ctx.finish()`) blocks its GUI thread for as long as the
draw takes: on a software GL (Mesa's llvmpipe, whose rasterizer runs in threads of its own)
a progressive step of a sampled lighting mode takes 25–60 ms. With a fence the GUI thread
issues the draws, returns to its event loop and asks later. moderngl has no fence objects:
on EGL (what `render.context.create_context` tries first) the core GL 3.2 entry points come
from `eglGetProcAddress`; elsewhere `Fence` waits (`finish`), as before.
"""

from __future__ import annotations

import moderngl

from brdflab.render import gil_free

GL_SYNC_GPU_COMMANDS_COMPLETE = 0x9117
GL_ALREADY_SIGNALED = 0x911A
GL_CONDITION_SATISFIED = 0x911C


def fences_available(ctx: moderngl.Context) -> bool:
    """Whether `Fence(ctx)` asks without waiting (an EGL context, made by render.context)."""
    return gil_free.available(ctx)


class Fence:
    """Marks the work issued so far in `ctx` (which must be current, here and in `done`)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self._ctx = ctx
        self._sync = None
        if fences_available(ctx):
            gl = gil_free.entry_points()
            self._sync = gl["FenceSync"](GL_SYNC_GPU_COMMANDS_COMPLETE, 0)
            gl["Flush"]()  # start the work now: a fence nobody flushed may never signal
        self._done = self._sync is None and self._wait()

    def _wait(self) -> bool:
        gil_free.finish(self._ctx)
        return True

    def done(self) -> bool:
        """True once everything issued before the fence has finished (never blocks on EGL)."""
        if self._done:
            return True
        gl = gil_free.entry_points()
        if gl["ClientWaitSync"](self._sync, 0, 0) in (GL_ALREADY_SIGNALED, GL_CONDITION_SATISFIED):
            gl["DeleteSync"](self._sync)
            self._sync, self._done = None, True
        return self._done

    def wait(self) -> None:
        """Block until done (what reading the result back would do anyway)."""
        if not self._done:
            if self._sync is not None:
                gil_free.entry_points()["DeleteSync"](self._sync)
                self._sync = None
            self._done = self._wait()
