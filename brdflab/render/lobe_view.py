"""The lobe viewer (BRDFLab §5): f(wi, ·) as a 3-D lobe over a geodesic hemisphere.

Analytic materials are displaced in the vertex shader from their GLSL; any other source
(measured tables, raw samples) through a (θo, φo) texture recomputed when wi changes.
The original and a fitted material can be drawn together in distinct colours.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import moderngl
import numpy as np

from brdflab.geometry.geodesic import geodesic_hemisphere
from brdflab.render import gil_free
from brdflab.geometry.lobe_surface import CHANNELS, LobeShape, lobe_radii
from brdflab.material.analytic import AnalyticMaterial
from brdflab.geometry.vec import spherical_to_cartesian
from brdflab.render.camera import OrbitCamera, gl_matrix
from brdflab.render.glsl import GLSL_VERSION, lobe_uniforms, material_source, models_of, set_uniforms, shader_source

TRANSFERS = {"linear": 0, "cbrt": 1, "log": 2}
TEXTURE_GRID = (360, 90)  # φo × θo samples of non-analytic sources
# Where the fit and the original are this close (of the largest lobe's radius, 1 on screen)
# the fit is drawn in front: closer than the drawn surfaces' own accuracy (the auto
# subdivision's 1 % of the peak; a table is read through a bilinear texture, a model exactly),
# their order at a pixel meant nothing, and a good fit over its measured original was a
# speckle of the two colours (z-fighting).
AGREEMENT = 0.01


@dataclass
class LobeSettings:
    theta_i: float = 30.0  # degrees
    phi_i: float = 0.0
    transfer: str = "cbrt"
    cosine: bool = False
    channel: str = "luminance"
    level: int = 5
    translucent_fit: bool = True
    original_color: tuple = (0.85, 0.55, 0.25)
    fitted_color: tuple = (0.25, 0.55, 0.95)

    @property
    def wi(self) -> np.ndarray:
        return spherical_to_cartesian(math.radians(self.theta_i), math.radians(self.phi_i))

    @property
    def shape(self) -> LobeShape:
        return LobeShape(tuple(float(x) for x in self.wi), self.channel, self.cosine, self.transfer)


@dataclass
class _Layer:
    source: object
    program: moderngl.Program
    texture: moderngl.Texture | None = None
    texture_wi: tuple | None = None
    peak: tuple | None = None  # ((shape, level), largest radius): evaluating a table costs ~20 ms
    vaos: dict = field(default_factory=dict)


class LobeViewer:
    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.settings = LobeSettings()
        self.camera = OrbitCamera(yaw=35.0, pitch=25.0, distance=3.7)  # a radius-1 lobe fits whole
        self._programs: dict[tuple, moderngl.Program] = {}
        self._layers: list[_Layer | None] = [None, None]
        self.labels = ["original", "fit"]  # what the legend calls the two layers
        self._mesh_level = None  # what the buffers hold: a level, or a refined surface's key
        self._vbo = self._ibo = None
        self._refined: tuple | None = None  # (key, directions, faces, peak, tips) from refined_surface
        self._lines = self.ctx.program(vertex_shader=GLSL_VERSION + "#define VERTEX\n" + shader_source("lines.glsl"),
                                       fragment_shader=GLSL_VERSION + shader_source("lines.glsl"))
        self._line_vbo = self.ctx.buffer(reserve=12 * 6 * 4)
        self._line_vao = self.ctx.vertex_array(self._lines, [(self._line_vbo, "3f 3f", "in_position", "in_color")])

    # --- sources --------------------------------------------------------------------------
    def set_original(self, source) -> None:
        self._set_layer(0, source)

    def set_fitted(self, source) -> None:
        self._set_layer(1, source)

    def _set_layer(self, index: int, source) -> None:
        old = self._layers[index]
        if old is not None and source is old.source and not isinstance(source, AnalyticMaterial):
            return  # the same table: its texture (a 360 × 90 evaluation, 40–100 ms) still holds
        if old is not None:
            for vao in old.vaos.values():
                vao.release()
            if old.texture is not None:
                old.texture.release()
        if source is None:
            self._layers[index] = None
            return
        analytic = isinstance(source, AnalyticMaterial)
        if analytic and not source.lobes:  # an empty material is valid: nothing to draw
            self._layers[index] = None
            return
        models = models_of(source) if analytic else ("Lambertian",)
        channels = source.n_channels if analytic else 3
        self._layers[index] = _Layer(source, self._program(models, not analytic, channels))
        if analytic:
            set_uniforms(self._layers[index].program, lobe_uniforms(source))

    def update_material(self, index: int, material: AnalyticMaterial) -> None:
        """New parameters for a layer with the same lobe models: uniforms only, no rebuild."""
        layer = self._layers[index]
        if layer is None or not isinstance(layer.source, AnalyticMaterial) or models_of(layer.source) != models_of(material) \
                or layer.source.n_channels != material.n_channels:
            self._set_layer(index, material)
            return
        layer.source, layer.peak = material, None
        set_uniforms(layer.program, lobe_uniforms(material))

    def _program(self, models: tuple[str, ...], textured: bool, n_channels: int = 3) -> moderngl.Program:
        key = (models, textured, n_channels)
        if key not in self._programs:
            head = GLSL_VERSION + ("#define SOURCE_TEXTURE\n" if textured else "")
            self._programs[key] = self.ctx.program(
                vertex_shader=head + material_source(models, n_channels=n_channels) + shader_source("lobe_vertex.glsl"),
                geometry_shader=GLSL_VERSION + shader_source("lobe_geometry.glsl"),
                fragment_shader=GLSL_VERSION + shader_source("lobe_fragment.glsl"))
        return self._programs[key]

    def _refresh_texture(self, layer: _Layer) -> None:
        wi = tuple(np.round(self.settings.wi, 9))
        if layer.texture is not None and layer.texture_wi == wi:
            return
        n_phi, n_theta = TEXTURE_GRID
        theta = (np.arange(n_theta) + 0.5) / n_theta * 0.5 * np.pi
        phi = (np.arange(n_phi) + 0.5) / n_phi * 2.0 * np.pi
        wo = spherical_to_cartesian(theta[:, None], phi[None, :]).reshape(-1, 3)
        values = layer.source.evaluate(np.broadcast_to(np.asarray(wi, float), wo.shape), wo)[:, :3]
        if values.shape[1] == 1:
            values = np.repeat(values, 3, axis=1)
        data = np.ascontiguousarray(values.reshape(n_theta, n_phi, 3), np.float32)
        if layer.texture is None:
            layer.texture = self.ctx.texture((n_phi, n_theta), 3, dtype="f4")
            layer.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
            layer.texture.repeat_x, layer.texture.repeat_y = True, False
        layer.texture.write(data.tobytes())
        layer.texture_wi = wi

    # --- drawing --------------------------------------------------------------------------
    def surface_key(self) -> tuple:
        """What a refined surface is computed for: the analytic layers drawn, the shape, the level."""
        return tuple(id(s) for s in self.analytic_sources()), self.settings.shape, self.settings.level

    def analytic_sources(self) -> list[AnalyticMaterial]:
        return [l.source for l in self._layers if l is not None and isinstance(l.source, AnalyticMaterial)]

    def set_refined(self, key: tuple, directions: np.ndarray, faces: np.ndarray, peak: float,
                    tips: np.ndarray) -> None:
        """A surface refined near the lobes' peaks (geometry.lobe_surface.refined_surface), drawn
        while `key` is what is drawn; the uniform hemisphere otherwise. `tips`: each analytic
        layer's farthest point on it (geometry.lobe_surface.lobe_tips), its axis drawn as a line."""
        self._refined = (key, directions, faces, peak, np.asarray(tips, np.float32))

    def refined_in_use(self) -> bool:
        return self._refined is not None and self._refined[0] == self.surface_key()

    def _mesh(self) -> tuple[moderngl.Buffer, moderngl.Buffer]:
        refined = self.refined_in_use()
        wanted = self._refined[0] if refined else self.settings.level
        if self._mesh_level != wanted:
            for layer in self._layers:
                if layer is not None:
                    for vao in layer.vaos.values():
                        vao.release()
                    layer.vaos.clear()
            for b in (self._vbo, self._ibo):
                if b is not None:
                    b.release()
            v, f = self._refined[1:3] if refined else geodesic_hemisphere(self.settings.level)
            self._vbo, self._ibo = self.ctx.buffer(v.tobytes()), self.ctx.buffer(f.tobytes())
            self._mesh_level = wanted
        return self._vbo, self._ibo

    def triangle_count(self) -> int:
        return len(self._refined[2]) if self.refined_in_use() else len(geodesic_hemisphere(self.settings.level)[1])

    def draw(self, width: int, height: int) -> None:
        """Draw into the bound framebuffer (depth test on, caller clears)."""
        s = self.settings
        vp = self.view_projection(width, height)
        vbo, ibo = self._mesh()
        # set every state we rely on: a host toolkit may have changed it behind moderngl
        self.ctx.enable_only(moderngl.DEPTH_TEST)
        self.ctx.disable_direct(0x0BE2)  # GL_BLEND
        self.ctx.depth_func = "<"
        self.ctx.fbo.depth_mask = True
        self._draw_lines(vp, self._tip_lines())
        for index, layer in enumerate(self._layers):
            if layer is None:
                continue
            prog = layer.program
            if "u_values" in prog:
                self._refresh_texture(layer)
                layer.texture.use(0)
                prog["u_values"].value = 0
            values = {"u_wi": tuple(float(x) for x in s.wi), "u_transfer": TRANSFERS[s.transfer],
                      "u_cosine": bool(s.cosine), "u_channel": CHANNELS[s.channel], "u_gain": self.gain(),
                      "u_eye": tuple(float(x) for x in self._eye()), "u_depth_bias": AGREEMENT if index == 1 else 0.0}
            for name, value in values.items():
                if name in prog:
                    prog[name].value = value
            prog["u_view_projection"].write(gl_matrix(vp))
            color, alpha = self.layer_style(index)
            prog["u_color"].value = (*color, alpha)
            if index not in layer.vaos:
                layer.vaos[index] = self.ctx.vertex_array(prog, [(vbo, "3f", "in_direction")], index_buffer=ibo,
                                                          index_element_size=4)
            if alpha < 1.0:
                self._draw_translucent(layer.vaos[index])
            else:
                gil_free.draw(self.ctx, layer.vaos[index], moderngl.TRIANGLES)

    def _draw_translucent(self, vao: moderngl.VertexArray) -> None:
        """A translucent lobe blended once per pixel, its nearest surface only: a depth-only
        pass first, then the colour where the depth is that pass's. Blended in one pass, its
        own triangles overlap (the far side of the lobe behind the near side) and each pixel
        got one or two layers by which triangle came first in the mesh: a speckle of two
        shades over the whole lobe."""
        fbo = self.ctx.fbo  # the framebuffer bound by the caller
        self.ctx.enable_only(moderngl.DEPTH_TEST | moderngl.BLEND)
        # depth only: the colour is blended away (moderngl 5.13's color_mask setter reaches GL
        # only when the framebuffer is bound again: a masked pre-pass drew its colour, opaque)
        self.ctx.blend_func = moderngl.ZERO, moderngl.ONE
        try:
            gil_free.draw(self.ctx, vao, moderngl.TRIANGLES)
            fbo.depth_mask = False
            self.ctx.depth_func = "<="
            self.ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
            gil_free.draw(self.ctx, vao, moderngl.TRIANGLES)
        finally:
            self.ctx.enable_only(moderngl.DEPTH_TEST)
            fbo.depth_mask = True
            self.ctx.depth_func = "<"

    def layer_style(self, index: int) -> tuple[tuple, float]:
        """(colour, alpha) a layer is drawn in: the original solid, the fit translucent or solid."""
        s = self.settings
        if index == 0:
            return s.original_color, 1.0
        return s.fitted_color, 0.55 if s.translucent_fit else 1.0

    def legend(self) -> list[tuple[str, tuple, float]]:
        """(label with its style, colour, alpha) of each layer drawn, when two are drawn over
        each other: which is the original and which the fit."""
        drawn = [k for k, layer in enumerate(self._layers) if layer is not None]
        if len(drawn) < 2:
            return []
        entries = []
        for k in drawn:
            color, alpha = self.layer_style(k)
            entries.append((f"{self.labels[k]} — {'solid' if alpha >= 1.0 else 'translucent'}", color, alpha))
        return entries

    def gain(self) -> float:
        """Scale that makes the largest lobe reach radius 1 (same transfer as the shader)."""
        key = (self.settings.shape, min(self.settings.level, 5))
        peak = 0.0
        for layer in self._layers:
            if layer is not None:
                if layer.peak is None or layer.peak[0] != key:
                    r = lobe_radii(layer.source, self.settings.shape, geodesic_hemisphere(key[1])[0].astype(float))
                    layer.peak = (key, float(np.nanmax(r)) if r.size else 0.0)
                peak = max(peak, layer.peak[1])
        if self._refined_for_lobes() is not None:
            # a peak between the hemisphere's vertices: framed whole, at every level of the same
            # lobes (the uniform level 7 drawn while its refined surface was computed, framed by
            # level 5's vertices, ran off the top, then flipped back)
            peak = max(peak, self._refined[3])
        return 1.0 / peak if peak > 0 else 1.0

    def _eye(self) -> np.ndarray:
        """The camera position in the lobe's frame (z up on screen)."""
        return _Z_UP[:3, :3].T @ self.camera.position

    def _refined_for_lobes(self) -> tuple | None:
        """The refined surface of the lobes and shape drawn, at this level or another (its peak
        and tips hold at any level): None when it was computed for something else."""
        return self._refined if self._refined is not None and self._refined[0][:2] == self.surface_key()[:2] else None

    def _tip_lines(self) -> np.ndarray:
        """(2k, 6) segments from the origin to each analytic layer's tip on the refined surface,
        in its colour: a lobe narrower than a pixel is a solid line, not a dotted one."""
        if self._refined_for_lobes() is None:
            return np.zeros((0, 6), np.float32)
        analytic = [k for k, layer in enumerate(self._layers)
                    if layer is not None and isinstance(layer.source, AnalyticMaterial)]
        gain, rows = self.gain(), []
        for k, tip in zip(analytic, self._refined[4]):
            color = self.layer_style(k)[0]
            rows += [[0.0, 0.0, 0.0, *color], [*(gain * tip), *color]]
        return np.array(rows, np.float32).reshape(-1, 6)

    def _draw_lines(self, vp: np.ndarray, extra: np.ndarray) -> None:
        """The axes, the incident direction and `extra` segments ((2k, 6) position, colour)."""
        wi = self.settings.wi
        axis = 1.2
        lines = np.vstack([np.array([
            [0, 0, 0, 0.9, 0.2, 0.2], [axis, 0, 0, 0.9, 0.2, 0.2],
            [0, 0, 0, 0.2, 0.8, 0.2], [0, axis, 0, 0.2, 0.8, 0.2],
            [0, 0, 0, 0.3, 0.4, 1.0], [0, 0, axis, 0.3, 0.4, 1.0],
            [0, 0, 0, 1.0, 1.0, 0.2], [*(1.5 * wi), 1.0, 1.0, 0.2],
        ], np.float32), extra]).astype(np.float32)
        self._line_vbo.orphan(lines.nbytes)
        self._line_vbo.write(lines.tobytes())
        self._lines["u_view_projection"].write(gl_matrix(vp))
        gil_free.draw(self.ctx, self._line_vao, moderngl.LINES, len(lines))

    def view_projection(self, width: int, height: int) -> np.ndarray:
        return self.camera.projection(width / max(height, 1)) @ self.camera.view() @ _Z_UP

    def render(self, width: int, height: int, background=(0.12, 0.12, 0.14)) -> np.ndarray:
        """Offscreen: an (H, W, 3) uint8 image, row 0 at the top."""
        color = self.ctx.renderbuffer((width, height), 4, samples=0)
        depth = self.ctx.depth_renderbuffer((width, height))
        fbo = self.ctx.framebuffer([color], depth)
        try:
            fbo.use()
            self.ctx.viewport = (0, 0, width, height)
            fbo.clear(*background, 1.0, depth=1.0)
            self.draw(width, height)
            img = np.frombuffer(fbo.read(components=3), np.uint8).reshape(height, width, 3)[::-1]
        finally:
            fbo.release()
            color.release()
            depth.release()
        return np.ascontiguousarray(img)


# The lobe's frame has z = normal; on screen the normal points up (+Y): rotate z → y.
_Z_UP = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]], float)
