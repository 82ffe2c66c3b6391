"""GPU side of the generic tabulated sampler: each tabulated lobe's tables as one layer of a
texture array (shaders/tabulated.glsl reads it), uploaded when the material changes.

The tables are the ones the CPU side samples with (`brdflab.models.files.sampler`), so a
render's FIS and MIS draw from exactly the density the NumPy references use.
"""

from __future__ import annotations

import moderngl
import numpy as np

from brdflab.material.analytic import AnalyticMaterial
from brdflab.render.glsl import models_of, tabulated_slots

TAB_UNIT = 12  # clear of the other modes' texture units (0–7, 10, 11)


class TabulatedTextures:
    """The tables of one renderer's current material (its context must be current)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._key = None
        self._texture: moderngl.TextureArray | None = None
        self._aniso = np.zeros(1, np.float32)

    @staticmethod
    def key(material: AnalyticMaterial) -> tuple:
        return tuple((l.model.name, tuple(sorted(l.params.items()))) for l in material.lobes)

    def bind(self, program: moderngl.Program, material: AnalyticMaterial) -> None:
        """Upload the material's tables if they changed, and point `program` at them."""
        from brdflab.render.glsl import set_uniforms

        slots = tabulated_slots(models_of(material))
        if not slots or "u_tab" not in program:
            return
        key = self.key(material)
        if key != self._key:
            self.release()
            samplers = [material.lobes[k].model.tabulated_sampler(material.lobes[k].params) for k in slots]
            rows = max(len(s.cdf) for s in samplers)
            data = np.zeros((len(samplers), rows, samplers[0].cdf.shape[1], 2), np.float32)
            for layer, s in enumerate(samplers):
                data[layer, : len(s.cdf), :, 0] = s.cdf
                data[layer, : len(s.cdf), :, 1] = s.density
            self._texture = self.ctx.texture_array((data.shape[2], rows, len(samplers)), 2, data.tobytes(), dtype="f4")
            self._texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._aniso = np.array([0.0 if s.isotropic else 1.0 for s in samplers], np.float32)
            self._key = key
        self._texture.use(TAB_UNIT)
        program["u_tab"].value = TAB_UNIT
        set_uniforms(program, {"u_tab_aniso": self._aniso})

    def release(self) -> None:
        if self._texture is not None:
            self._texture.release()
        self._texture, self._key = None, None
