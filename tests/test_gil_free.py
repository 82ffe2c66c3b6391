"""GL calls made through ctypes so that other threads run meanwhile (render/gil_free.py): they
do what moderngl's own calls do."""

import numpy as np
import pytest

from brdflab.errors import BRDFLabError


@pytest.fixture(scope="module")
def ctx():
    from brdflab.render.context import create_context

    try:
        context = create_context()
    except BRDFLabError as e:
        pytest.skip(str(e))
    yield context
    context.release()


def _triangle_image(ctx, render) -> np.ndarray:
    import moderngl

    prog = ctx.program(vertex_shader="#version 330\nin vec2 p; void main() { gl_Position = vec4(p, 0.0, 1.0); }",
                       fragment_shader="#version 330\nout vec4 c; void main() { c = vec4(0.25, 0.5, 1.0, 1.0); }")
    vbo = ctx.buffer(np.array([-1, -1, 1, -1, 0, 1, 0.5, 0.5], np.float32).tobytes())
    ibo = ctx.buffer(np.array([0, 1, 2], np.uint32).tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "2f", "p")], index_buffer=ibo, index_element_size=4)
    fbo = ctx.simple_framebuffer((32, 32))
    fbo.use()
    fbo.clear(0.0, 0.0, 0.0, 1.0)
    render(vao, moderngl.TRIANGLES)
    return np.frombuffer(fbo.read(), np.uint8).reshape(32, 32, 3).copy()


def test_a_draw_through_ctypes_draws_what_moderngl_draws(ctx):
    from brdflab.render import gil_free

    with ctx:
        ours = _triangle_image(ctx, lambda vao, mode: gil_free.draw(ctx, vao, mode))
        theirs = _triangle_image(ctx, lambda vao, mode: vao.render(mode))
    assert gil_free.available(ctx) == (ctx.extra["backend"] == "egl")
    assert (ours[..., 2] == 255).sum() > 200  # the triangle is there
    np.testing.assert_array_equal(ours, theirs)


def test_mip_levels_hold_the_given_texels(ctx):
    """Read back as a shader sees them (texelFetch of each level): moderngl's `read` knows only
    the levels it made itself."""
    from brdflab.lighting.synthetic_maps import spec
    from brdflab.render import gil_free

    env = spec("room-one-window").build()
    with ctx:
        tex = ctx.texture((env.width, env.height), 3, np.ascontiguousarray(env.data, np.float32).tobytes(), dtype="f4")
        gil_free.mip_levels(ctx, tex, env.mips[1:])
        prog = ctx.program(vertex_shader="#version 330\nvoid main() { vec2 p = vec2(gl_VertexID & 1, gl_VertexID >> 1);"
                                         " gl_Position = vec4(4.0 * p - 1.0, 0.0, 1.0); }",
                           fragment_shader="#version 330\nuniform sampler2D t; uniform int level; out vec4 c;"
                                           " void main() { c = vec4(texelFetch(t, ivec2(gl_FragCoord.xy), level).rgb, 1.0); }")
        vao = ctx.vertex_array(prog, [])
        tex.use(0)
        prog["t"].value = 0
        for level in (1, 3, len(env.mips) - 1):
            h, w = env.mips[level].shape[:2]
            target = ctx.texture((w, h), 4, dtype="f4")
            fbo = ctx.framebuffer([target])
            fbo.use()
            ctx.viewport = (0, 0, w, h)
            prog["level"].value = level
            gil_free.draw(ctx, vao, 4, 3)  # GL_TRIANGLES
            back = np.frombuffer(target.read(), np.float32).reshape(h, w, 4)[..., :3]
            np.testing.assert_array_equal(back, env.mips[level])
            fbo.release()
            target.release()
        tex.release()
