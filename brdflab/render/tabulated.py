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

TAB_UNIT = 12  # clear of the other modes' texture units (0–7, 10, 11, 13, 14)


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
        self._final: tuple[tuple, moderngl.TextureArray] | None = None  # (material key, its tables)
        self._stand_in: tuple[tuple, moderngl.TextureArray] | None = None  # ((layers, rows), uniform tables)
        self.provisional = False  # whether the last bind drew from the uniform stand-ins
        self._builder: ThreadPoolExecutor | None = None
        self._pending: tuple[tuple, Future] | None = None  # (material key, its build)
        self._wanted = None  # the key of the material drawn last

    @staticmethod
    def key(material: AnalyticMaterial) -> tuple:
        return tuple((l.model.name, tuple(sorted(l.params.items()))) for l in material.lobes)

    def bind(self, program: moderngl.Program, material: AnalyticMaterial) -> None:
        """Upload the material's tables if they changed, and point `program` at them."""
        slots = tabulated_slots(models_of(material))
        if slots:
            self.bind_samplers(program, self.key(material),
                               [material.lobes[k].model.tabulated_sampler(material.lobes[k].params) for k in slots])

    def bind_samplers(self, program: moderngl.Program, key: tuple, samplers: list) -> None:
        """Upload these samplers' tables (layer k: samplers[k]) if `key` changed, and point
        `program` at them."""
        from brdflab.render.glsl import set_uniforms

        if "u_tab" not in program:
            return
        self._wanted = key
        self.provisional = self.background and (self._final is None or self._final[0] != key) \
            and not self._built(key, samplers)
        texture = self._stand_in_texture(samplers) if self.provisional else self._final_texture(key, samplers)
        texture.use(TAB_UNIT)
        program["u_tab"].value = TAB_UNIT
        set_uniforms(program, {"u_tab_aniso": np.array([0.0 if s.isotropic else 1.0 for s in samplers], np.float32)})

    def building_done(self) -> bool:
        """Whether the tables being built in the thread are ready to upload."""
        return self._pending is not None and self._pending[1].done() and self._pending[1].result()

    def _built(self, key: tuple, samplers: list) -> bool:
        """Whether the tables are built; if not, start building them in a thread. A build for
        a material no longer drawn (a slider moved on) stops at its next pass."""
        pending = self._pending
        if pending is None or pending[0] != key or (pending[1].done() and not pending[1].result()):
            if self._builder is None:
                self._builder = ThreadPoolExecutor(max_workers=1, thread_name_prefix="brdflab-tables")
            stop = lambda: self._wanted != key
            self._pending = (key, self._builder.submit(lambda: all([s.ensure_all(stop) for s in samplers])))
        return self.building_done()

    def _final_texture(self, key: tuple, samplers: list) -> moderngl.TextureArray:
        if self._final is None or self._final[0] != key:
            if self._final is not None:
                self._final[1].release()
            self._final = (key, self._texture(samplers, [(s.cdf, s.density) for s in samplers]))
        return self._final[1]

    def _stand_in_texture(self, samplers: list) -> moderngl.TextureArray:
        """Uniform tables, uploaded once for as many layers and rows (they hold no values)."""
        shape = (len(samplers), max(len(s.view_theta) * len(s.view_phi) for s in samplers))
        if self._stand_in is None or self._stand_in[0] != shape:
            if self._stand_in is not None:
                self._stand_in[1].release()
            self._stand_in = (shape, self._texture(samplers, [_uniform_tables(shape[1])] * shape[0]))
        return self._stand_in[1]

    def _texture(self, samplers: list, tables: list) -> moderngl.TextureArray:
        rows = max(len(s.view_theta) * len(s.view_phi) for s in samplers)
        cells = tables[0][0].shape[1]
        data = np.zeros((len(tables), rows, cells, 2), np.float32)
        for layer, (cdf, density) in enumerate(tables):
            data[layer, : len(cdf), :, 0] = cdf
            data[layer, : len(cdf), :, 1] = density
        texture = self.ctx.texture_array((cells, rows, len(tables)), 2, data.tobytes(), dtype="f4")
        texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return texture

    def release(self) -> None:
        for held in (self._final, self._stand_in):
            if held is not None:
                held[1].release()
        self._final = self._stand_in = None
