"""GL calls that let other Python threads run while they work.

moderngl keeps Python's GIL through every call into GL. On Mesa's llvmpipe the first draw of
a program in a new state compiles its shaders to machine code inside that draw: 0.05–0.5 s
on an idle machine, seconds on a busy one or for a large model file. A window that issues
its draws from a worker thread through moderngl still froze for that long (the GUI thread
waits for the GIL); the same draw issued through ctypes, which lets go of the GIL around a
foreign call, left the GUI thread's longest gap at 28 ms against 168 ms (measured, a
four-lobe material's first step with Mesa's shader cache off).

On EGL (what `render.context.create_context` tries first) the entry points come from
`eglGetProcAddress`; elsewhere `available` is False and callers use moderngl's own calls.
"""

from __future__ import annotations

import ctypes
import ctypes.util
from functools import cache

import moderngl
import numpy as np

_INDEX_TYPES = {1: 0x1401, 2: 0x1403, 4: 0x1405}  # GL_UNSIGNED_BYTE, _SHORT, _INT

_KINDS = {
    b"glFlush": (None,),
    b"glFinish": (None,),
    b"glUseProgram": (None, ctypes.c_uint),
    b"glBindVertexArray": (None, ctypes.c_uint),
    b"glDrawArraysInstanced": (None, ctypes.c_uint, ctypes.c_int, ctypes.c_int, ctypes.c_int),
    b"glDrawElementsInstanced": (None, ctypes.c_uint, ctypes.c_int, ctypes.c_uint, ctypes.c_void_p, ctypes.c_int),
    b"glTexImage2D": (None, ctypes.c_uint, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int,
                      ctypes.c_uint, ctypes.c_uint, ctypes.c_void_p),
    b"glBindBufferRange": (None, ctypes.c_uint, ctypes.c_uint, ctypes.c_uint, ctypes.c_ssize_t, ctypes.c_ssize_t),
    b"glEnable": (None, ctypes.c_uint),
    b"glDisable": (None, ctypes.c_uint),
    b"glBeginTransformFeedback": (None, ctypes.c_uint),
    b"glEndTransformFeedback": (None,),
}
GL_TEXTURE_2D, GL_RGB32F, GL_RGB, GL_FLOAT = 0x0DE1, 0x8815, 0x1907, 0x1406
GL_TRANSFORM_FEEDBACK_BUFFER, GL_RASTERIZER_DISCARD = 0x8C8E, 0x8C89


@cache
def entry_points() -> dict | None:
    """GL entry points by name (without the gl prefix) through EGL, or None."""
    try:
        egl = ctypes.CDLL(ctypes.util.find_library("EGL") or "libEGL.so.1")
    except OSError:
        return None
    get = egl.eglGetProcAddress
    get.restype, get.argtypes = ctypes.c_void_p, [ctypes.c_char_p]
    functions = {}
    for name, (result, *args) in _KINDS.items():
        address = get(name)
        if not address:
            return None
        functions[name[2:].decode()] = ctypes.CFUNCTYPE(result, *args)(address)
    return functions


def available(ctx: moderngl.Context) -> bool:
    """Whether `ctx` is an EGL context (made by render.context) and the entry points were found."""
    return (ctx.extra or {}).get("backend") == "egl" and entry_points() is not None


def draw(ctx: moderngl.Context, vao: moderngl.VertexArray, mode: int, vertices: int = -1) -> None:
    """`vao.render(mode, vertices)`, the GIL released while GL works (compiling included)."""
    if not available(ctx):
        vao.render(mode, vertices=vertices)
        return
    gl = entry_points()
    vertices = vao.vertices if vertices < 0 else vertices
    gl["UseProgram"](vao.program.glo)
    gl["BindVertexArray"](vao.glo)
    if vao.index_buffer is not None:
        gl["DrawElementsInstanced"](mode, vertices, _INDEX_TYPES[vao.index_element_size], None, 1)
    else:
        gl["DrawArraysInstanced"](mode, 0, vertices, 1)


def finish(ctx: moderngl.Context) -> None:
    """`ctx.finish()`, the GIL released while waiting."""
    if available(ctx):
        entry_points()["Finish"]()
    else:
        ctx.finish()


def transform_points(ctx: moderngl.Context, vao: moderngl.VertexArray, output: moderngl.Buffer, vertices: int) -> None:
    """`vao.transform(output, mode=POINTS, vertices=vertices)`, the GIL released while GL works:
    llvmpipe runs vertex shaders in the calling thread, and a file model's GLSL is compiled there."""
    if not available(ctx):
        vao.transform(output, mode=moderngl.POINTS, vertices=vertices)
        return
    gl = entry_points()
    gl["UseProgram"](vao.program.glo)
    gl["BindVertexArray"](vao.glo)
    gl["BindBufferRange"](GL_TRANSFORM_FEEDBACK_BUFFER, 0, output.glo, 0, output.size)
    gl["Enable"](GL_RASTERIZER_DISCARD)
    gl["BeginTransformFeedback"](moderngl.POINTS)
    gl["DrawArraysInstanced"](moderngl.POINTS, 0, vertices, 1)
    gl["EndTransformFeedback"]()
    gl["Disable"](GL_RASTERIZER_DISCARD)
    gl["Flush"]()


def mip_levels(ctx: moderngl.Context, texture: moderngl.Texture, levels: list) -> None:
    """Give an RGB float texture the mip levels 1, 2, … from `levels` ((h, w, 3) arrays).
    moderngl allocates levels only by computing them (`build_mipmaps`: 130 ms of a 1k map held
    the GUI thread, contents then overwritten); glTexImage2D defines each from its data."""
    if not available(ctx):
        texture.build_mipmaps()
        for level, texels in enumerate(levels, start=1):
            texture.write(np.ascontiguousarray(texels, np.float32).tobytes(), level=level)
        return
    texture.use(0)
    for level, texels in enumerate(levels, start=1):
        data = np.ascontiguousarray(texels, np.float32)
        entry_points()["TexImage2D"](GL_TEXTURE_2D, level, GL_RGB32F, data.shape[1], data.shape[0], 0, GL_RGB, GL_FLOAT,
                                     data.ctypes.data)
