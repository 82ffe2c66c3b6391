"""A mesh's pixels as the object view draws it, for the image metric (fitting/image_metric.py):
the shading frame and the direction towards the camera at every pixel the mesh covers,
rasterised by the renderer's own vertex stage, mesh, camera and turn of the object, so that a
fit judged on a mesh is judged on the pixels a user sees."""

from __future__ import annotations

import math
from collections.abc import Callable

import moderngl
import numpy as np

from brdflab.fitting.image_metric import VIEW, PixelFrames, sphere_frames
from brdflab.io.mesh import Mesh
from brdflab.render.camera import OrbitCamera, gl_matrix
from brdflab.render.glsl import GLSL_VERSION, shader_source


def mesh_frames(ctx: moderngl.Context, mesh: Mesh, camera: OrbitCamera, width: int, height: int,
                rotation: np.ndarray | None = None) -> PixelFrames:
    """The frames of `mesh` turned by `rotation` (the object view's model rotation) and seen
    by `camera` at width × height pixels, row 0 at the top as `ObjectRenderer.render` returns
    its images (the object view's own draw: `tests/test_image_metric.py` compares them)."""
    return _with_mesh(ctx, mesh, lambda draw: draw(camera, width, height, rotation))


def frames_covering(ctx: moderngl.Context, mesh: Mesh, camera: OrbitCamera, rotation: np.ndarray | None = None,
                    pixels: int | None = None, largest: int = 128) -> PixelFrames:
    """The mesh's frames in a square view sized so that it covers about `pixels` pixels (by
    default the reference sphere's count at the metric's VIEW: a mesh that fills a fifth of the
    view is judged on as many pixels as the sphere), at most largest × largest."""
    pixels = int(sphere_frames(VIEW).inside.sum()) if pixels is None else pixels

    def sized(draw) -> PixelFrames:
        size = int(round(math.sqrt(pixels / (math.pi / 4))))
        frames = draw(camera, size, size, rotation)
        covered = int(frames.inside.sum())
        if 0 < covered < 0.9 * pixels:
            size = min(largest, int(math.ceil(size * math.sqrt(pixels / covered))))
            frames = draw(camera, size, size, rotation)
        return frames

    return _with_mesh(ctx, mesh, sized)


def _with_mesh(ctx: moderngl.Context, mesh: Mesh, use: Callable) -> PixelFrames:
    """`use(draw)` with the frames program compiled and the mesh uploaded once, released after."""
    program = ctx.program(vertex_shader=GLSL_VERSION + shader_source("object_vertex.glsl"),
                          fragment_shader=GLSL_VERSION + shader_source("gbuffer_fragment.glsl"))
    vbo, ibo = ctx.buffer(mesh.interleaved().tobytes()), ctx.buffer(mesh.faces.astype(np.uint32).tobytes())
    vao = ctx.vertex_array(program, [(vbo, "3f 3f 3f", "in_position", "in_normal", "in_tangent")],
                           index_buffer=ibo, index_element_size=4, skip_errors=True)
    try:
        return use(lambda camera, width, height, rotation: _draw(ctx, program, vao, mesh.name, camera, width, height,
                                                                 rotation))
    finally:
        for item in (vao, vbo, ibo, program):
            item.release()


def _draw(ctx: moderngl.Context, program: moderngl.Program, vao: moderngl.VertexArray, name: str,
          camera: OrbitCamera, width: int, height: int, rotation: np.ndarray | None) -> PixelFrames:
    targets = [ctx.texture((width, height), 4, dtype="f4") for _ in range(3)]
    depth = ctx.depth_renderbuffer((width, height))
    fbo = ctx.framebuffer(color_attachments=targets, depth_attachment=depth)
    try:
        fbo.use()
        ctx.viewport = (0, 0, width, height)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.BLEND)
        program["u_view_projection"].write(gl_matrix(camera.projection(width / height) @ camera.view()))
        model = np.eye(4)
        model[:3, :3] = np.eye(3) if rotation is None else rotation
        program["u_model"].write(gl_matrix(model))
        program["u_camera_position"].value = tuple(float(x) for x in camera.position)
        vao.render(moderngl.TRIANGLES)
        ctx.finish()
        n, t, v = (np.frombuffer(target.read(), np.float32).reshape(height, width, 4)[::-1].astype(float)
                   for target in targets)
    finally:
        for item in (fbo, depth, *targets):
            item.release()
    inside = n[..., 3] > 0.5
    unit = lambda a: a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)
    normal, tangent, view = unit(n[inside, :3]), unit(t[inside, :3]), unit(v[inside, :3])
    tangent = unit(tangent - (tangent * normal).sum(-1, keepdims=True) * normal)
    return PixelFrames(inside, normal, tangent, np.cross(normal, tangent), view, name)
