"""GPU side of the generic tabulated sampler: each tabulated lobe's tables as one layer of a
texture array (shaders/tabulated.glsl reads it), uploaded when the material changes.

The tables are the ones the CPU side samples with (`brdflab.models.files.sampler`), so a
render's FIS and MIS draw from exactly the density the NumPy references use. Building them
costs 60 ms for an isotropic lobe and 0.6 s for an anisotropic one (288 views); in the window
(`background = True`) they are built in a thread, and until they are ready the lobe is drawn
from uniform tables (every half vector equally likely): unbiased, only noisier, so the
progressive image stays right while it sharpens.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import moderngl
import numpy as np

from brdflab.material.analytic import AnalyticMaterial
from brdflab.render.glsl import models_of, tabulated_slots

TAB_UNIT = 12  # clear of the other modes' texture units (0–7, 10, 11)


def _uniform_tables(rows: int) -> tuple[np.ndarray, np.ndarray]:
    """CDF and density rows that draw every half-vector cell with equal probability."""
    from brdflab.models.files.sampler import cells

    solid = cells()[2].ravel()
    cdf = np.arange(1, solid.size + 1) / solid.size
    return np.broadcast_to(cdf, (rows, solid.size)), np.broadcast_to(1.0 / (solid.size * solid), (rows, solid.size))


class TabulatedTextures:
    """The tables of one renderer's current material (its context must be current)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.background = False  # build tables in a thread (the window), else before drawing
        self._key = None  # what the uploaded texture holds: (material key, final or provisional)
        self._texture: moderngl.TextureArray | None = None
        self._aniso = np.zeros(1, np.float32)
        self._builder: ThreadPoolExecutor | None = None
        self._pending: tuple[tuple, Future] | None = None

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
        samplers = [material.lobes[k].model.tabulated_sampler(material.lobes[k].params) for k in slots]
        if self._key != (key, True):
            final = not self.background or self._built(key, samplers)
            if self._key != (key, final):
                self._upload(samplers, final)
                self._key = (key, final)
        self._texture.use(TAB_UNIT)
        program["u_tab"].value = TAB_UNIT
        set_uniforms(program, {"u_tab_aniso": self._aniso})

    @property
    def provisional(self) -> bool:
        """Whether the uploaded tables are the uniform stand-ins (the real ones are building)."""
        return self._key is not None and not self._key[1]

    def building_done(self) -> bool:
        """Whether the tables being built in the thread are ready to upload."""
        return self._pending is not None and self._pending[1].done()

    def _built(self, key: tuple, samplers: list) -> bool:
        """Whether the tables are built; if not, start building them in a thread."""
        if self._pending is None or self._pending[0] != key:
            if self._builder is None:
                self._builder = ThreadPoolExecutor(max_workers=1, thread_name_prefix="brdflab-tables")
            self._pending = (key, self._builder.submit(lambda: [s.cdf for s in samplers]))
        return self._pending[1].done()

    def _upload(self, samplers: list, final: bool) -> None:
        self.release()
        rows = max(len(s.view_theta) * len(s.view_phi) for s in samplers)
        cells = samplers[0].cdf.shape[1] if final else _uniform_tables(1)[0].shape[1]
        data = np.zeros((len(samplers), rows, cells, 2), np.float32)
        for layer, s in enumerate(samplers):
            cdf, density = (s.cdf, s.density) if final else _uniform_tables(rows)
            data[layer, : len(cdf), :, 0] = cdf
            data[layer, : len(cdf), :, 1] = density
        self._texture = self.ctx.texture_array((cells, rows, len(samplers)), 2, data.tobytes(), dtype="f4")
        self._texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._aniso = np.array([0.0 if s.isotropic else 1.0 for s in samplers], np.float32)

    def release(self) -> None:
        if self._texture is not None:
            self._texture.release()
        self._texture, self._key = None, None
