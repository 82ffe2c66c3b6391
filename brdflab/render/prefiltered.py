"""GPU side of the prefiltered lighting mode: the map's stack as a texture array and the
material's albedo table as a texture, uploaded when the map or the material changes.

The stack itself (its layers and lights) is built (and cached per map) by brdflab/lighting/prefilter.py; the per-lobe
split by brdflab/lighting/split_sum.py; the shading is shaders/prefiltered.glsl.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.lighting.envmap import EnvironmentMap
from brdflab.material.analytic import AnalyticMaterial

STACK_UNIT = 10  # texture units, clear of the other modes' (0–5)
ALBEDO_UNIT = 11
LIGHTS_UNIT = 13  # clear of tabulated.TAB_UNIT (12) too
MIXTURE_UNIT = 14
EXCESS_UNIT = 15  # MIS's control: the lights' excess texel by texel


class PrefilteredLighting:
    """The textures of one renderer's prefiltered mode (its context must be current)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._stack: tuple[EnvironmentMap, moderngl.TextureArray, moderngl.Texture, int, float] | None = None  # (map, layers, lights, count, blocks)
        self._albedo: tuple[tuple, moderngl.Texture, moderngl.Texture, dict] | None = None  # (key, albedo, mixtures, uniforms)
        self._splits: tuple[tuple, list] | None = None  # (material key, material_split) made elsewhere
        self._excess: tuple[EnvironmentMap, moderngl.Texture] | None = None  # MIS's control, per map

    def ready(self, env: EnvironmentMap) -> bool:
        """Whether `env`'s stack is uploaded or cached (drawing it builds nothing)."""
        from brdflab.lighting.prefilter import is_cached

        return (self._stack is not None and self._stack[0] is env) or is_cached(env)

    def _stack_texture(self, env: EnvironmentMap) -> tuple[moderngl.TextureArray, moderngl.Texture, int, float]:
        """The stack's layers, its lights as a texture (count × 2: directions, powers), their count
        and whether they are blocks of texels (1.0)."""
        from brdflab.lighting.prefilter import prefiltered_stack

        if self._stack is None or self._stack[0] is not env:
            self.release_stack()
            stack = prefiltered_stack(env)
            layers = np.ascontiguousarray(stack.layers, np.float32)
            tex = self.ctx.texture_array((stack.width, stack.height, layers.shape[0]), 3, layers.tobytes(), dtype="f4")
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x, tex.repeat_y = True, False
            count = len(stack.lights)
            rows = np.zeros((2, max(count, 1), 3), np.float32)
            rows[0, :count], rows[1, :count] = stack.lights[:, :3], stack.lights[:, 3:]
            lights = self.ctx.texture((rows.shape[1], 2), 3, rows.tobytes(), dtype="f4")
            lights.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._stack = (env, tex, lights, count, float(stack.blocks))
        return self._stack[1:]

    @staticmethod
    def material_key(material: AnalyticMaterial) -> tuple:
        return tuple((l.model.name, tuple(sorted(l.params.items()))) for l in material.lobes)

    def splits_ready(self, material: AnalyticMaterial) -> bool:
        """Whether drawing `material` needs no split computed first (80–120 ms of NumPy)."""
        key = self.material_key(material)
        return any(held is not None and held[0] == key for held in (self._albedo, self._splits))

    def remember_splits(self, key: tuple, splits: list) -> None:
        self._splits = (key, splits)

    def _albedo_texture(self, material: AnalyticMaterial) -> tuple[moderngl.Texture, moderngl.Texture, dict]:
        """The material's albedo table, its fitted lobes' lookups (`view_mixture`; zero rows for
        the others) and the per-lobe uniforms."""
        from brdflab.lighting.split_sum import TAPS
        from brdflab.lighting.view_mixture import COSINES, LOOKUPS

        key = self.material_key(material)
        if self._albedo is None or self._albedo[0] != key:
            self.release_albedo()
            splits = self._material_splits(material)
            table = np.ascontiguousarray(np.concatenate([s.albedo for s in splits]), np.float32)  # (lobes · φo, cos θo, 3)
            tex = self.ctx.texture((table.shape[1], table.shape[0]), 3, table.tobytes(), dtype="f4")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)  # interpolated in the shader
            rows = np.concatenate([s.mixture if s.mixture is not None else np.zeros((COSINES, LOOKUPS, 3))
                                   for s in splits]).astype(np.float32)  # (lobes · COSINES, LOOKUPS, 3)
            mixtures = self.ctx.texture((LOOKUPS, rows.shape[0]), 3, np.ascontiguousarray(rows).tobytes(), dtype="f4")
            mixtures.filter = (moderngl.NEAREST, moderngl.NEAREST)
            uniforms = {
                "u_pref_layers": np.array([[*s.layers, s.diffuse_share] for s in splits], np.float32),
                "u_pref_axis": np.array([[*s.axis, s.toward_axis] for s in splits], np.float32),
                "u_pref_taps": np.array([list(s.taps) + [(0.0, 0.0, 0.0)] * (TAPS - len(s.taps)) for s in splits],
                                        np.float32),
                "u_pref_fitted": np.array([float(s.mixture is not None) for s in splits], np.float32),
                "u_pref_albedo_size": float(table.shape[1]),
            }
            self._albedo = (key, tex, mixtures, uniforms)
        return self._albedo[1:]

    def _material_splits(self, material: AnalyticMaterial) -> list:
        """`material_split`, or the splits made elsewhere for this material (`remember_splits`)."""
        from brdflab.lighting.split_sum import material_split

        key = self.material_key(material)
        return self._splits[1] if self._splits is not None and self._splits[0] == key else material_split(material)

    def fitted_lobes(self, material: AnalyticMaterial) -> tuple[tuple[int, int], ...]:
        """(lobe index, kernel family in `control_variate.FAMILIES`) of each lobe of `material`
        drawn by fitted lookups (`view_mixture`)."""
        from brdflab.lighting.control_variate import layer_families

        families = layer_families()
        return tuple((k, families[int(split.mixture[..., 1].max())][0])
                     for k, split in enumerate(self._material_splits(material)) if split.mixture is not None)

    def bind(self, program: moderngl.Program, env: EnvironmentMap | None, material: AnalyticMaterial,
             rotation_degrees: float) -> None:
        """Bind the textures and set the mode's uniforms on `program`."""
        from brdflab.render.glsl import set_uniforms

        if env is None:
            raise BRDFLabError("no environment map for the prefiltered lighting mode")
        stack, lights, count, blocks = self._stack_texture(env)
        stack.use(STACK_UNIT)
        lights.use(LIGHTS_UNIT)
        albedo, mixtures, uniforms = self._albedo_texture(material)
        albedo.use(ALBEDO_UNIT)
        mixtures.use(MIXTURE_UNIT)
        values = {"u_pref_stack": STACK_UNIT, "u_pref_albedo": ALBEDO_UNIT, "u_pref_mixture": MIXTURE_UNIT,
                  "u_pref_rotation": math.radians(rotation_degrees), **uniforms,
                  "u_pref_lights": LIGHTS_UNIT, "u_pref_light_count": count, "u_pref_blocks": blocks}
        for name, value in values.items():
            if name not in program:
                continue
            if isinstance(value, np.ndarray):
                set_uniforms(program, {name: value})
            else:
                program[name].value = value

    def bind_control(self, program: moderngl.Program, env: EnvironmentMap) -> None:
        """MIS's control (shaders/mis_control.glsl), after `bind`: the lights' excess at the
        stack's texels and each layer's kernel."""
        from brdflab.lighting.control_variate import excess_radiance, layer_kernels
        from brdflab.lighting.prefilter import prefiltered_stack
        from brdflab.render.glsl import set_uniforms

        if self._excess is None or self._excess[0] is not env:
            self.release_excess()
            excess = np.ascontiguousarray(excess_radiance(prefiltered_stack(env)), np.float32)
            tex = self.ctx.texture((excess.shape[1], excess.shape[0]), 4, excess.tobytes(), dtype="f4")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._excess = (env, tex)
        self._excess[1].use(EXCESS_UNIT)
        if "u_cv_excess" in program:
            program["u_cv_excess"].value = EXCESS_UNIT
        if "u_cv_layer" in program:
            set_uniforms(program, {"u_cv_layer": layer_kernels().astype(np.float32)})

    def release_excess(self) -> None:
        if self._excess is not None:
            self._excess[1].release()
        self._excess = None

    def release_stack(self) -> None:
        if self._stack is not None:
            self._stack[1].release()
            self._stack[2].release()
        self._stack = None
        self.release_excess()

    def release_albedo(self) -> None:
        if self._albedo is not None:
            self._albedo[1].release()
            self._albedo[2].release()
        self._albedo = None
