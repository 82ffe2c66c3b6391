"""Precomputed radiance transfer for self-shadowing (Sloan et al. 2002, generalised to any
BRDF by Kautz et al. 2002 §5): each vertex gets the lighting that reaches it,
L_p = Σ_k w_k V_p(s_k) y(s_k) (y(s_k)·L), over a quadrature of directions s_k.

Visibility V_p(s) comes from the GPU: one orthographic depth map of the mesh per direction,
against which every vertex is tested (a ray cast from the vertex towards s, in effect).
Directions below a vertex's tangent plane count as visible: the BRDF's cosine removes them.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np

from brdflab.lighting import sh
from brdflab.io.mesh import Mesh

DEPTH_SIZE = 512
_VERTEX = """
in vec3 in_position;
uniform mat3 u_basis;  // rows: u, v, d (d points from the mesh towards the light)
void main() {
    vec3 q = u_basis * in_position;
    gl_Position = vec4(q.x / 1.05, q.y / 1.05, -q.z / 1.05, 1.0);
}
"""
_FRAGMENT = "void main() {}\n"


def quadrature(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Directions and weights integrating products of two order-L SH functions exactly
    (Gauss–Legendre in cos θ × uniform φ)."""
    n_theta, n_phi = order + 3, 2 * order + 6
    x, w = np.polynomial.legendre.leggauss(n_theta)
    phi = (np.arange(n_phi) + 0.5) * 2.0 * math.pi / n_phi
    z, p = np.meshgrid(x, phi, indexing="ij")
    s = np.sqrt(1.0 - z * z)
    dirs = np.stack([s * np.cos(p), s * np.sin(p), z], axis=-1).reshape(-1, 3)
    return dirs, np.repeat(w, n_phi) * (2.0 * math.pi / n_phi)


def _basis(d: np.ndarray) -> np.ndarray:
    a = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(a, d)
    u /= np.linalg.norm(u)
    return np.stack([u, np.cross(d, u), d])


def vertex_visibility(ctx: moderngl.Context, mesh: Mesh, dirs: np.ndarray, bias: float = 4e-3) -> np.ndarray:
    """(V, K) visibility of each vertex towards each direction (1 visible, 0 occluded)."""
    prog = ctx.program(vertex_shader="#version 330 core\n" + _VERTEX, fragment_shader="#version 330 core\n" + _FRAGMENT)
    vbo = ctx.buffer(mesh.positions.astype("f4").tobytes())
    ibo = ctx.buffer(mesh.faces.tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "3f", "in_position")], index_buffer=ibo, index_element_size=4)
    depth = ctx.depth_texture((DEPTH_SIZE, DEPTH_SIZE))
    fbo = ctx.framebuffer(depth_attachment=depth)
    pos = mesh.positions.astype(float) + bias * mesh.normals
    vis = np.ones((len(pos), len(dirs)))
    previous, viewport = ctx.fbo, ctx.viewport  # called from inside a draw: give it back
    try:
        fbo.use()
        ctx.viewport = (0, 0, DEPTH_SIZE, DEPTH_SIZE)
        ctx.enable_only(moderngl.DEPTH_TEST)
        ctx.depth_func = "<"
        for k, d in enumerate(dirs):
            B = _basis(d)
            prog["u_basis"].write(np.ascontiguousarray(B.T, np.float32).tobytes())  # column-major
            fbo.clear(depth=1.0)
            vao.render(moderngl.TRIANGLES)
            dmap = np.frombuffer(depth.read(), np.float32).reshape(DEPTH_SIZE, DEPTH_SIZE)
            q = pos @ B.T / 1.05
            col = np.clip(((q[:, 0] + 1) * 0.5 * DEPTH_SIZE).astype(int), 0, DEPTH_SIZE - 1)
            row = np.clip(((q[:, 1] + 1) * 0.5 * DEPTH_SIZE).astype(int), 0, DEPTH_SIZE - 1)
            z = (-q[:, 2] + 1.0) * 0.5  # window depth of the vertex
            occluded = z > dmap[row, col] + 1.5 / DEPTH_SIZE
            facing = mesh.normals @ d > 0.0
            vis[:, k] = np.where(facing & occluded, 0.0, 1.0)
    finally:
        try:
            previous.use()
            ctx.viewport = viewport
        except AttributeError:  # the framebuffer bound before was already released
            pass
        for obj in (fbo, depth, vao, ibo, vbo, prog):
            obj.release()
    return vis


def transferred_lighting(light: np.ndarray, visibility: np.ndarray, dirs: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Per-vertex world-frame lighting after occlusion: (V, order², C)."""
    order = int(round(math.sqrt(light.shape[0])))
    Y = sh.basis(order, dirs)  # (K, n)
    radiance = Y @ light  # (K, C): the lighting along each direction
    out = np.empty((visibility.shape[0], Y.shape[1], light.shape[1]))
    vw = visibility * weights[None, :]
    for c in range(light.shape[1]):
        out[:, :, c] = vw @ (Y * radiance[:, c:c + 1])
    return out
