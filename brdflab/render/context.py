"""OpenGL contexts for offscreen rendering."""

from __future__ import annotations

import moderngl

from brdflab.errors import BRDFLabError


def create_context() -> moderngl.Context:
    """A standalone OpenGL ≥ 3.3 context (EGL first: it needs no display)."""
    errors = []
    for kwargs in ({"backend": "egl"}, {}):
        try:
            ctx = moderngl.create_standalone_context(require=330, **kwargs)
            # a standalone context has no default framebuffer, and Mesa runs nothing
            # (transform feedback included) until one is bound
            ctx.extra = {"default_fbo": ctx.simple_framebuffer((1, 1)), "backend": kwargs.get("backend", "default")}
            ctx.extra["default_fbo"].use()
            return ctx
        except Exception as e:  # moderngl raises plain Exceptions for missing drivers
            errors.append(str(e).splitlines()[0] if str(e) else type(e).__name__)
    raise BRDFLabError("no OpenGL 3.3 context available (" + "; ".join(errors) + ")")
