"""The object view (BRDFLab §7): a material on a mesh or on the reference sphere, lit by a
point light or by an HDR environment through filtered importance sampling (of the BRDF,
or of the BRDF and the map's luminance combined by MIS) or spherical harmonics.

Renders into float targets in any moderngl context; `render()` returns linear radiance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from brdflab.lighting.envmap import EnvironmentMap
from brdflab.errors import BRDFLabError
from brdflab.material.analytic import AnalyticMaterial
from brdflab.sources.proxy import measured_sampler, proxy_lobes, render_table
from brdflab.io.mesh import Mesh
from brdflab.render import gil_free
from brdflab.render.camera import OrbitCamera, gl_matrix
from brdflab.render.prefiltered import PrefilteredLighting
from brdflab.lighting.split_sum import ALBEDO_PHIS, TAPS
from brdflab.lighting.view_mixture import COSINES as MIXTURE_COSINES, LOOKUPS, MIN_COS as MIXTURE_MIN_COS
from brdflab.lighting.control_variate import FITTED_LOBES, layer_kernels
from brdflab.render.glsl import GLSL_VERSION, MAX_LOBES, lobe_uniforms, material_source, models_of, set_uniforms, shader_source
from brdflab.render.tabulated import TabulatedTextures
from brdflab.lighting.env_sampling import environment_distribution
from brdflab.lighting.sampling_sets import lobe_shares, mis_sample_set, pieces_order, sample_set
from brdflab.lighting.sh_table_auto import AutoTable, known_choice, resolve
from brdflab.lighting.sh_tables import STANDARD, TableSetting

MODES = ("point", "fis", "sh", "prefiltered", "mis")
SAMPLED_MODES = ("fis", "mis")  # refined progressively, one sample set after another
BATCH = 32  # samples per draw: keeps each draw short on software rasterisers
VERTEX_ROW = 64  # vertices per row of the per-vertex SH lighting texture
SAMPLE_ROW = 4096  # samples per row of the sample texture: far below any GL_MAX_TEXTURE_SIZE (≥ 4096 in GL 3.3)


@dataclass
class RenderSettings:
    mode: str = "point"
    width: int = 512
    height: int = 512
    samples: int = 64
    light: tuple[float, float, float] = (0.0, 0.0, 1.0)
    light_color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    env_rotation: float = 0.0  # degrees about +Y
    reference_view: bool = True
    mis_control: bool = True  # MIS: the prefiltered image as a control variate (lighting/control_variate.py)


def _set(program: moderngl.Program, name: str, value) -> None:
    """Set a uniform if the compiled program kept it."""
    if name in program:
        program[name].value = value


class ObjectRenderer:
    """Holds the GPU state of one object view: programs, mesh, environment, material."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._programs: dict[tuple, moderngl.Program] = {}
        self._mesh_vao: dict[tuple, moderngl.VertexArray] = {}
        self.mesh: Mesh | None = None
        self._mesh_buffers: tuple | None = None
        self.material: AnalyticMaterial | None = None
        self.measured = False
        self.table_texture: moderngl.Texture3D | None = None
        self.table_size = (1, 1, 1)
        self._uniforms: dict = {}
        self._shares = np.ones(1)
        self.env_texture: moderngl.Texture | None = None
        self._env_tables: tuple[moderngl.Texture, moderngl.Texture] | None = None  # MIS: marginal, table
        self._env_distribution: tuple | None = None  # (map, its luminance distribution), made elsewhere
        self._env_fraction = 0.0
        self._control: tuple | None = None  # MIS's control weight: (material key, lit source, map, β)
        self.env_size = (1, 1)
        self.camera = OrbitCamera()
        self.model_rotation = np.eye(3)  # turns the object (meshes) in the world
        self.sh_shadows = False  # precomputed transfer (self-shadowing) in the SH mode
        self.sh_variant = "dynamic"  # or the paper's "fixed-light" / "fixed-view" (meshes)
        self._transfer: dict = {}
        self.sh_order = 5
        self.sh_window: str | None = None
        self.sh_table: TableSetting | AutoTable = STANDARD  # the BRDF table's size and samples, or Auto
        self.source = None
        self.environment: EnvironmentMap | None = None
        self._sh_state: tuple | None = None  # ((order, table setting), table texture, rx texture, half)
        self._sh_light: tuple | None = None  # (map, order, window, coefficients): per map, not per material
        self.clamped_pixels = 0
        self.prefiltered = PrefilteredLighting(ctx)  # the prefiltered mode's textures
        self.tabulated = TabulatedTextures(ctx)  # the tables file models are sampled from
        self._empty_vao = ctx.vertex_array(self._program(("Lambertian",), "point", True), [])

    def adopt(self, old: "ObjectRenderer") -> None:
        """Take over another renderer's scene (its GL context is gone), rebuilt on this one's."""
        self.camera, self.model_rotation = old.camera, old.model_rotation
        self.sh_shadows, self.sh_variant = old.sh_shadows, old.sh_variant
        self.sh_order, self.sh_window, self.sh_table = old.sh_order, old.sh_window, old.sh_table
        if old.mesh is not None:
            self.set_mesh(old.mesh)
        if old.environment is not None:
            self.set_environment(old.environment)
        self._env_distribution, self._sh_light = old._env_distribution, old._sh_light  # per map, kept by identity
        source = old.source if old.source is not None else old.material
        if source is not None:
            self.set_source(source)

    # --- state ----------------------------------------------------------------------------
    def set_material(self, material: AnalyticMaterial) -> None:
        if not material.lobes:
            raise BRDFLabError("the material has no lobes to render")
        if len(material.lobes) > MAX_LOBES:
            raise BRDFLabError(f"the material has {len(material.lobes):,} lobes; the renderer draws at most {MAX_LOBES}")
        material.validate()
        self.material = material
        self.measured = False
        self._shares = self._uniforms = None  # when first drawn: see _material_terms

    def _material_terms(self) -> dict:
        """The lobes' sampling shares and the uniforms that hold them, computed when first
        drawn: `lobe_shares` samples every lobe (a file model's GLSL too), which the window
        does in its step thread, not while the user adds the lobe."""
        if self._shares is None:
            self._shares = lobe_shares(self.material)
        if self._uniforms is None:
            self._uniforms = lobe_uniforms(self.material, self._shares)
        return self._uniforms

    def set_source(self, source) -> None:
        """Any source: analytic materials directly; measured ones as a table texture,
        importance-sampled through a fitted proxy (Lambertian + Cook–Torrance)."""
        if source is self.source and self.measured:
            return  # the same table: uploading it again took ~45 ms of the GUI thread
        self.source = source
        self._release_sh()
        if isinstance(source, AnalyticMaterial):
            self.set_material(source)
            return
        table = render_table(source)
        self.set_material(proxy_lobes(source))
        self._shares = np.ones(1)  # FIS and MIS draw from the table's own sampler alone
        self.measured = True
        if self.table_texture is not None:
            self.table_texture.release()
        values = np.ascontiguousarray(np.moveaxis(table.values[:3], 0, -1), np.float32)  # (θh, θd, φd, 3)
        tex = self.ctx.texture3d((values.shape[2], values.shape[1], values.shape[0]), 3, values, dtype="f4")  # no copy: its buffer
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        tex.repeat_x, tex.repeat_y, tex.repeat_z = True, False, False
        self.table_texture = tex
        self.table_size = (values.shape[2], values.shape[1], values.shape[0])

    def set_mesh(self, mesh: Mesh | None) -> None:
        """A mesh to draw, or None for the reference view's sphere."""
        for entry in self._transfer.values():
            if entry.get("texture") is not None:
                entry["texture"].release()
        self._transfer.clear()
        for vao in self._mesh_vao.values():
            vao.release()
        self._mesh_vao.clear()
        if self._mesh_buffers:
            for b in self._mesh_buffers:
                b.release()
        self.mesh = mesh
        self._mesh_buffers = None
        if mesh is not None:
            self._mesh_buffers = (self.ctx.buffer(mesh.interleaved().tobytes()), self.ctx.buffer(mesh.faces.tobytes()),
                                  self.ctx.buffer(np.arange(mesh.n_vertices, dtype="i4").tobytes()))

    def set_environment(self, env: EnvironmentMap) -> None:
        if self.env_texture is not None:
            self.env_texture.release()
        tex = self.ctx.texture((env.width, env.height), 3, np.ascontiguousarray(env.data, np.float32).tobytes(), dtype="f4")
        gil_free.mip_levels(self.ctx, tex, env.mips[1:])  # averaged by solid angle
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        tex.repeat_x, tex.repeat_y = True, False
        self.env_texture = tex
        self.env_size = (env.width, env.height)
        self.environment = env
        self._release_sh()
        self.prefiltered.release_stack()
        self._release_env_tables()

    # --- environment importance sampling (MIS) -------------------------------------------------
    def _release_env_tables(self) -> None:
        if self._env_tables is not None:
            for tex in self._env_tables:
                tex.release()
        self._env_tables = None

    def env_distribution_ready(self) -> bool:
        """Whether the MIS mode can draw without building the map's distribution (0.25 s for a
        2k map: the window has a worker build it)."""
        held = self._env_distribution
        return self._env_tables is not None or (held is not None and held[0] is self.environment)

    def remember_env_distribution(self, env: EnvironmentMap, dist) -> None:
        self._env_distribution = (env, dist)

    def _map_distribution(self):
        """The map's luminance distribution: the one remembered for it, else built here."""
        held = self._env_distribution
        if held is None or held[0] is not self.environment:
            self.remember_env_distribution(self.environment, environment_distribution(self.environment))
        return self._env_distribution[1]

    def _env_sampling_tables(self) -> tuple[moderngl.Texture, moderngl.Texture]:
        """The map's luminance CDFs and density as textures, built once per map."""
        if self._env_tables is None:
            dist = self._map_distribution()
            marginal = self.ctx.texture((dist.height, 1), 1, dist.marginal.astype(np.float32).tobytes(), dtype="f4")
            table = np.ascontiguousarray(np.stack([dist.conditional, dist.density], axis=-1), np.float32)
            table_tex = self.ctx.texture((dist.width, dist.height), 2, table.tobytes(), dtype="f4")
            for tex in (marginal, table_tex):
                tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._env_tables = (marginal, table_tex)
        return self._env_tables

    # --- MIS's control variate ----------------------------------------------------------------
    def lit_source(self):
        """What the material is evaluated with at the map's lights: a measured table, or the material."""
        return self.source if self.measured else self.material

    def control_weight_ready(self) -> bool:
        """Whether MIS knows its control's weight for this material and map (a pilot of
        0.1–0.5 s: the window has a worker compute it, `control_weight_job`)."""
        held = self._control
        return (held is not None and held[1] is self.lit_source() and held[2] is self.environment
                and held[0] == self.prefiltered.material_key(self.material))

    def control_weight_job(self) -> tuple:
        """(function, arguments) that compute the control's weight, e.g. in a worker process."""
        from brdflab.lighting.auto_twins import weight_for

        return weight_for, (self.lit_source(), self.material, self.environment)

    def remember_control_weight(self, material_key: tuple, lit, env: EnvironmentMap, weight: float) -> None:
        self._control = (material_key, lit, env, float(weight))

    def control_weight(self) -> float:
        """The control's weight β for this material and map: the remembered one, else computed
        here from the map's whole stack, which the draw binds (a map met for the first time has
        its stack built once, not its control's layers first)."""
        if not self.control_weight_ready():
            from brdflab.lighting.auto_twins import weight_for
            from brdflab.lighting.control_variate import MapControl, excess_radiance
            from brdflab.lighting.prefilter import prefiltered_stack

            stack = prefiltered_stack(self.environment)
            weight = weight_for(self.lit_source(), self.material, self.environment,
                                MapControl(stack, excess_radiance(stack)))
            self.remember_control_weight(self.prefiltered.material_key(self.material), self.lit_source(),
                                         self.environment, weight)
        return self._control[3]

    def _control_lobes(self) -> tuple[int, ...] | None:
        """The lobes whose fitted lookups MIS's control draws (those among the first FITTED_LOBES
        drawn by fitted lookups), or None where its weight is 0: plain MIS, at plain MIS's cost."""
        if self.control_weight() <= 0.0:
            return None
        return tuple(lobe for lobe in self.prefiltered.fitted_lobes(self.material) if lobe[0] < FITTED_LOBES)

    # --- spherical harmonics ------------------------------------------------------------------
    def _release_sh(self) -> None:
        if self._sh_state is not None:
            for tex in self._sh_state[1:3]:
                tex.release()
        self._sh_state = None

    def set_sh_order(self, order: int, window: str | None = None) -> None:
        from brdflab.lighting import sh

        sh.check_order(order)
        if (order, window) != (self.sh_order, self.sh_window):
            self.sh_order, self.sh_window = order, window
            self._release_sh()

    def set_sh_table(self, table: TableSetting | AutoTable) -> None:
        """How the BRDF table is built: a fixed setting, or Auto's pick within a tolerance."""
        if table != self.sh_table:
            self.sh_table = table
            self._release_sh()

    def _sh_source(self):
        return self.source if self.source is not None else self.material

    def sh_table_setting(self) -> TableSetting | None:
        """The table setting the SH mode draws with; None while Auto has not chosen yet."""
        if isinstance(self.sh_table, AutoTable):
            choice = known_choice(self._sh_source(), self.sh_order, self.sh_table)
            return None if choice is None else choice.setting
        return self.sh_table

    def _sh_resources(self, settings: RenderSettings):
        """BRDF table, rotation matrices and lighting for the current order (built lazily)."""
        from brdflab.lighting import sh
        from brdflab.lighting.sh_tables import cached_table

        if self.environment is None:
            raise BRDFLabError("no environment map for the spherical-harmonics mode")
        order = self.sh_order
        source = self._sh_source()
        setting = resolve(source, order, self.sh_table)  # Auto chooses here unless a worker already did
        if self._sh_state is None or self._sh_state[0] != (order, setting):
            self._release_sh()
            table = cached_table(source, order, setting)
            size = table.shape[0]
            flat = table[..., :3].reshape(size, size, -1) if table.shape[-1] >= 3 else np.repeat(table, 3, -1).reshape(size, size, -1)
            layers = (flat.shape[-1] + 3) // 4
            packed = np.zeros((size, size, layers * 4), np.float32)
            packed[..., : flat.shape[-1]] = flat
            data = np.ascontiguousarray(packed.reshape(size, size, layers, 4).transpose(2, 0, 1, 3))
            tex = self.ctx.texture_array((size, size, layers), 4, data.tobytes(), dtype="f4")
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = False
            blocks = []
            for angle in (math.pi / 2, -math.pi / 2):
                M = sh.rotation_matrix(sh.axis_rotation("x", angle), order)
                blocks.append(np.concatenate([np.zeros(0)] + [M[l * l:(l + 1) ** 2, l * l:(l + 1) ** 2].ravel()
                                                              for l in range(1, order)]))
            # order 1 (band 0 alone) turns nothing: a one-texel texture keeps the sampler valid
            rx_data = np.concatenate(blocks + [np.zeros(1)]).astype(np.float32)
            rx = self.ctx.texture((len(rx_data), 1), 1, rx_data.tobytes(), dtype="f4")
            rx.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._sh_state = ((order, setting), tex, rx, len(blocks[0]))
        return self._sh_state

    def sh_light_ready(self) -> bool:
        """Whether the map's projection at the current order and window is at hand."""
        state = self._sh_light
        return state is not None and state[0] is self.environment and state[1:3] == (self.sh_order, self.sh_window)

    def remember_sh_light(self, env: EnvironmentMap, order: int, window: str | None, light: np.ndarray) -> None:
        self._sh_light = (env, order, window, light)

    def _sh_light_coefficients(self) -> np.ndarray:
        """The map projected onto SH (projecting a 2k map takes about a second: the window has
        a worker do it, see gui/gl_views.py; kept until the map, order or window changes)."""
        from brdflab.lighting import sh

        if not self.sh_light_ready():
            self.remember_sh_light(self.environment, self.sh_order, self.sh_window,
                                   sh.project_environment(self.environment, self.sh_order, self.sh_window))
        return self._sh_light[3]

    def sh_table_ready(self) -> bool:
        """Whether the SH mode can draw without building a table first."""
        from brdflab.lighting.sh_tables import is_cached

        setting = self.sh_table_setting()
        return setting is not None and (self._sh_state is not None and self._sh_state[0] == (self.sh_order, setting)
                                         or is_cached(self._sh_source(), self.sh_order, setting))

    def prefiltered_ready(self) -> bool:
        """Whether the prefiltered mode can draw without building the map's stack first."""
        return self.environment is None or self.prefiltered.ready(self.environment)

    def _vertex_frames(self) -> tuple[np.ndarray, np.ndarray]:
        """World → local rotation of every vertex (rows t, b, n, as the fragment shader
        builds them) and every vertex's view direction (world)."""
        from brdflab.geometry.vec import normalize

        R_model = self.model_rotation
        p = self.mesh.positions.astype(float) @ R_model.T
        n = normalize(self.mesh.normals.astype(float) @ R_model.T)
        wo = normalize(self.camera.position[None, :] - p)
        n = np.where(((n * wo).sum(axis=1) < 0)[:, None], -n, n)  # two-sided, as the shader
        along = self.mesh.tangents.astype(float) @ R_model.T if not self.material.isotropic else np.array([1.0, 0.0, 0.0])
        t = along - (along * n).sum(axis=-1, keepdims=True) * n
        short = np.linalg.norm(t, axis=1) < 1e-6
        t[short] = np.array([0.0, 0.0, 1.0]) - n[short, 2:3] * n[short]
        t = normalize(t)
        return np.stack([t, np.cross(n, t), n], axis=1), wo

    def _vertex_light_texture(self, settings: RenderSettings) -> moderngl.Texture:
        """Per-vertex SH data as a texture: the (shadowed) world lighting; for the fixed-light
        variant that lighting in each vertex's frame; for the fixed-view variant each vertex's
        colour (its BRDF vector turned to world, dotted with the lighting). Visibility is
        computed once per mesh and order, the rest when the lighting or the view changes."""
        from brdflab.lighting import sh
        from brdflab.lighting.sh_tables import cached_table, lookup
        from brdflab.render.transfer import quadrature, transferred_lighting, vertex_visibility

        light = self.sh_lighting(settings)[:, :3]
        key = (id(self.mesh), self.sh_order)
        entry = self._transfer.setdefault(key, {})
        if self.sh_variant not in ("dynamic", "fixed-light", "fixed-view"):
            raise BRDFLabError(f"unknown SH variant {self.sh_variant!r} (dynamic, fixed-light or fixed-view)")
        if self.sh_shadows and "visibility" not in entry:
            dirs, weights = quadrature(self.sh_order)
            entry.update(dirs=dirs, weights=weights, visibility=vertex_visibility(self.ctx, self.mesh, dirs))
        state = (self.sh_variant, self.sh_shadows, light.tobytes(), self.model_rotation.tobytes(),
                 self.camera.position.tobytes() if self.sh_variant == "fixed-view" else b"")
        if entry.get("state") != state:
            if self.sh_shadows:
                world = transferred_lighting(light, entry["visibility"], entry["dirs"], entry["weights"])
            else:
                world = np.broadcast_to(light, (self.mesh.n_vertices,) + light.shape)
            if self.sh_variant == "dynamic":
                data = np.asarray(world)
            else:
                R, wo = self._vertex_frames()
                if self.sh_variant == "fixed-light":
                    data = sh.rotate_many(np.asarray(world), R)
                else:  # the view's BRDF vectors turned to world, kept while the view stays
                    setting = resolve(self._sh_source(), self.sh_order, self.sh_table)
                    view = (self.camera.position.tobytes(), self.model_rotation.tobytes(), setting)
                    if entry.get("view") != view:
                        table = cached_table(self._sh_source(), self.sh_order, setting)
                        c_local = lookup(table, np.einsum("vij,vj->vi", R, wo))[..., :3]
                        entry["c_world"], entry["view"] = sh.rotate_many(c_local, np.transpose(R, (0, 2, 1))), view
                    data = np.einsum("vic,vic->vc", entry["c_world"], world)[:, None, :]
            n_vertices, stride = data.shape[0], data.shape[1]
            rows = -(-n_vertices // VERTEX_ROW)
            padded = np.zeros((rows * VERTEX_ROW, stride, 3), np.float32)
            padded[:n_vertices] = data
            if entry.get("texture") is not None:
                entry["texture"].release()
            tex = self.ctx.texture((stride * VERTEX_ROW, rows), 3,
                                   np.ascontiguousarray(padded.reshape(rows, VERTEX_ROW * stride, 3)).tobytes(), dtype="f4")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            entry["texture"], entry["state"] = tex, state
        return entry["texture"]

    def sh_lighting(self, settings: RenderSettings) -> np.ndarray:
        """World-frame lighting coefficients, with the environment's rotation applied."""
        from brdflab.lighting import sh

        self._sh_resources(settings)  # says what is missing first (no map)
        light = self._sh_light_coefficients()
        if settings.env_rotation:
            # the environment turned as in the FIS mode: L'(d) = L(Ry(θ) d)
            light = sh.rotate(light, sh.axis_rotation("y", math.radians(settings.env_rotation)).T)
        return light

    # --- programs -------------------------------------------------------------------------
    def _shadowed(self, mode: str, reference: bool) -> bool:
        """Whether the SH shading reads per-vertex data (shadows or a fixed variant)."""
        return mode == "sh" and not reference and self.mesh is not None and (
            self.sh_shadows or self.sh_variant != "dynamic")

    def _program(self, models: tuple[str, ...], mode: str, reference: bool, measured: bool = False,
                 n_channels: int = 3, control: tuple[int, ...] | None = None) -> moderngl.Program:
        """`control`: MIS's control is drawn, with the fitted lookups of these lobes ((index, kernel family) each)."""
        shadowed = self._shadowed(mode, reference)
        control = control if mode == "mis" else None
        key = (models, n_channels, mode, reference, measured, self.sh_order if mode == "sh" else 0, shadowed,
               self.sh_variant if shadowed else "", control)
        if key not in self._programs:
            defines = f"#define MODE_{mode.upper()}\n" + ("#define GEOMETRY_REFERENCE\n" if reference else "")
            material = material_source(models, measured, n_channels)
            if mode == "mis":
                material += shader_source("env_sampling.glsl")
            if mode == "sh":
                defines += f"#define SH_ORDER {self.sh_order}\n"
                if shadowed:
                    stride = 1 if self.sh_variant == "fixed-view" else self.sh_order ** 2
                    defines += (f"#define SH_VERTEX_LIGHT\n#define SH_VERTEX_ROW {VERTEX_ROW}\n"
                                f"#define SH_VERTEX_STRIDE {stride}\n")
                    if self.sh_variant == "fixed-light":
                        defines += "#define SH_FIXED_LIGHT\n"
                    elif self.sh_variant == "fixed-view":
                        defines += "#define SH_FIXED_VIEW\n"
                material += shader_source("sh.glsl")
            if mode == "prefiltered" or control is not None:
                defines += (f"#define PREF_TAPS {TAPS}\n#define PREF_PHIS {ALBEDO_PHIS}\n"
                            f"#define PREF_COSINES {MIXTURE_COSINES}\n#define PREF_LOOKUPS {LOOKUPS}\n"
                            f"#define PREF_MIN_COS {MIXTURE_MIN_COS!r}\n")
                material += shader_source("prefiltered.glsl")
            if control is not None:
                lobes = [k for k, _ in control]
                slots = [lobes.index(k) if k in lobes else -1 for k in range(len(models))]
                families = [family for _, family in control] or [0]
                defines += (f"#define MIS_CONTROL\n#define PREF_LAYERS {len(layer_kernels())}\n"
                            f"#define CV_FITTED {len(control)}\n#define CV_LOOKUPS {LOOKUPS * max(len(control), 1)}\n"
                            f"#define CV_SLOTS int[{len(models)}]({', '.join(map(str, slots))})\n"
                            f"#define CV_FAMILIES int[{len(families)}]({', '.join(map(str, families))})\n")
                material += shader_source("mis_control.glsl")
            self._programs[key] = self.ctx.program(
                vertex_shader=GLSL_VERSION + defines + shader_source("object_vertex.glsl"),
                fragment_shader=GLSL_VERSION + defines + material + shader_source("object_fragment.glsl"),
            )
        return self._programs[key]

    def _vao(self, program: moderngl.Program, key: tuple) -> moderngl.VertexArray:
        if key not in self._mesh_vao:
            vbo, ibo, ids = self._mesh_buffers
            content = [(vbo, "3f 3f 3f", "in_position", "in_normal", "in_tangent")]
            if "in_vertex" in program:
                content.append((ids, "i", "in_vertex"))
            self._mesh_vao[key] = self.ctx.vertex_array(
                program, content, index_buffer=ibo,
                index_element_size=4, skip_errors=True)  # attributes a program does not use are fine
        return self._mesh_vao[key]

    # --- drawing --------------------------------------------------------------------------
    def draw(self, settings: RenderSettings, sample_range: tuple[int, int] = (0, 0),
             samples_texture: moderngl.Texture | None = None, set_size: int = 1) -> None:
        """Draw once into the bound framebuffer (additively for sample batches)."""
        if self.material is None:
            raise BRDFLabError("no material to render")
        if settings.mode not in MODES:
            raise BRDFLabError(f"unknown lighting mode {settings.mode!r} ({', '.join(MODES)})")
        reference = settings.reference_view or self.mesh is None
        models = models_of(self.material)
        if settings.mode in SAMPLED_MODES and self.env_texture is None:
            raise BRDFLabError("no environment map for the environment lighting mode")
        control = self._control_lobes() if settings.mode == "mis" and settings.mis_control else None
        prog = self._program(models, settings.mode, reference, self.measured, self.material.n_channels, control)
        set_uniforms(prog, self._material_terms())
        if self.measured:
            self.table_texture.use(2)
            _set(prog, "u_table", 2)
            _set(prog, "u_table_size", tuple(float(x) for x in self.table_size))
        _set(prog, "u_light_direction", tuple(float(x) for x in settings.light))
        _set(prog, "u_light_color", tuple(float(x) for x in settings.light_color))
        if settings.mode in SAMPLED_MODES:
            self.env_texture.use(0)
            samples_texture.use(1)
            _set(prog, "u_env", 0)
            _set(prog, "u_samples", 1)
            _set(prog, "u_sample_row", SAMPLE_ROW)
            _set(prog, "u_env_size", tuple(float(x) for x in self.env_size))
            _set(prog, "u_env_max_lod", float(math.floor(math.log2(max(self.env_size)))))
            _set(prog, "u_env_rotation", math.radians(settings.env_rotation))
            _set(prog, "u_sample_begin", sample_range[0])
            _set(prog, "u_sample_end", sample_range[1])
            _set(prog, "u_set_size", float(set_size))
            if self.measured:
                self.tabulated.bind_samplers(prog, ("measured", id(self.source)), [measured_sampler(self.source)])
            else:
                self.tabulated.bind(prog, self.material)
        if settings.mode == "mis":
            marginal, table = self._env_sampling_tables()
            marginal.use(6)
            table.use(7)
            _set(prog, "u_env_marginal", 6)
            _set(prog, "u_env_table", 7)
            _set(prog, "u_env_fraction", float(self._env_fraction))
            if control is not None:
                self.prefiltered.bind(prog, self.environment, self.material, settings.env_rotation)
                self.prefiltered.bind_control(prog, self.environment)
                _set(prog, "u_cv_weight", self.control_weight())
        if settings.mode == "sh":
            order, table, rx, half = self._sh_resources(settings)
            table.use(3)
            rx.use(4)
            _set(prog, "u_sh_table", 3)
            _set(prog, "u_sh_rx", 4)
            _set(prog, "u_sh_rx_half", half)
            if "u_sh_light" in prog:
                prog["u_sh_light"].write(np.ascontiguousarray(self.sh_lighting(settings)[:, :3], np.float32).tobytes())
            if self._shadowed(settings.mode, reference):
                self._vertex_light_texture(settings).use(5)
                _set(prog, "u_sh_vertex_light", 5)
        if settings.mode == "prefiltered":
            self.prefiltered.bind(prog, self.environment, self.material, settings.env_rotation)
        if reference:
            gil_free.draw(self.ctx, self._empty_vao_for(prog), moderngl.TRIANGLES, 3)
        else:
            aspect = settings.width / settings.height
            prog["u_view_projection"].write(gl_matrix(self.camera.projection(aspect) @ self.camera.view()))
            model = np.eye(4)
            model[:3, :3] = self.model_rotation
            prog["u_model"].write(gl_matrix(model))
            _set(prog, "u_camera_position", tuple(float(x) for x in self.camera.position))
            _set(prog, "u_mesh_tangents", not self.material.isotropic)
            gil_free.draw(self.ctx, self._vao(prog, ("mesh", id(prog))), moderngl.TRIANGLES)  # one vertex array per program

    def _empty_vao_for(self, prog: moderngl.Program) -> moderngl.VertexArray:
        key = ("empty", id(prog))
        if key not in self._mesh_vao:
            self._mesh_vao[key] = self.ctx.vertex_array(prog, [])
        return self._mesh_vao[key]

    def samples_texture(self, n: int, rotation: np.ndarray | None = None, mode: str = "fis",
                        pieces: np.random.Generator | None = None) -> tuple[moderngl.Texture, int]:
        """The sample set as an RGBA32F texture, SAMPLE_ROW samples per row, so that any
        count fits under GL's texture size limit (and with the exact lobe shares applied);
        for MIS half of it drawn from the map (mis_sample_set). With its size: at least one
        sample per lobe, so a set may hold more than `n`. `pieces`: the set will be drawn in
        pieces, its rows in `pieces_order` so that every run from the first is a spread part of it."""
        self._material_terms()
        if mode == "mis":
            data, fractions, self._env_fraction = mis_sample_set(self._shares, n, rotation)
        else:
            data, fractions = sample_set(self._shares, n, rotation)
        if pieces is not None:
            data = data[pieces_order(data, pieces)]
        self._uniforms = {**self._uniforms, "u_lobe_share": fractions.astype(np.float32)}
        rows = -(-len(data) // SAMPLE_ROW)
        limit = int(self.ctx.info.get("GL_MAX_TEXTURE_SIZE", 4096))
        if rows > limit:
            raise BRDFLabError(f"{len(data)} samples exceed this OpenGL's texture limit ({SAMPLE_ROW * limit})")
        width = SAMPLE_ROW if rows > 1 else len(data)
        padded = np.zeros((rows * width, 4), np.float32)
        padded[: len(data)] = data
        tex = self.ctx.texture((width, rows), 4, padded.tobytes(), dtype="f4")
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return tex, len(data)

    # --- progressive refinement (the GUI) ----------------------------------------------------------
    def start_progressive(self, settings: RenderSettings) -> "Progressive":
        return Progressive(self, settings)

    def render(self, settings: RenderSettings) -> np.ndarray:
        """Linear radiance (H, W, 3), row 0 at the top; 0 where nothing is drawn: one step
        of a progressive image with all the samples."""
        image = Progressive(self, settings)
        try:
            image.step(max(1, int(settings.samples)))
            self.ctx.finish()
            raw = np.frombuffer(image.texture.read(), np.float32).reshape(settings.height, settings.width, 4)[::-1]
        finally:
            image.release()
        out = np.ascontiguousarray(raw[:, :, :3] / image.samples)
        if settings.mode == "sh":
            # ringing can make the truncated integral negative: clamp it, and say how often
            self.clamped_pixels, _ = negative_pixels(raw)
            out = np.maximum(out, 0.0)
        return out


GL_BLEND = 0x0BE2

DIFFERENCE_TICKS = (0.0, 0.25, 0.5, 0.75, 1.0)  # the values the difference view's legend labels


def difference_colour(t) -> np.ndarray:
    """The difference view's false colour of relative luminance differences `t` (1 = 100 %),
    as display.glsl's heat() draws it: black at 0, pure red at 1/3, yellow at 2/3, white at 1
    (the largest: |a − b| / max(a, b) ≤ 1). RGB in [0, 1], shape t.shape + (3,)."""
    t = np.asarray(t, float)[..., None]
    return np.clip(3.0 * t - np.array([0.0, 1.0, 2.0]), 0.0, 1.0)


def negative_pixels(rgba: np.ndarray) -> tuple[int, int]:
    """(pixels with a negative channel, pixels a surface covers) of an accumulated RGBA image:
    SH ringing, which renders and displays clamp to black."""
    rgba = np.asarray(rgba).reshape(-1, 4)
    covered = rgba[:, 3] > 0
    return int((covered & (rgba[:, :3] < 0).any(axis=1)).sum()), int(covered.sum())


def _set_state(ctx: moderngl.Context, depth: bool, blend: bool) -> None:
    """Set every capability these draws depend on, for real: a host toolkit (Qt) can
    change GL state behind moderngl's cached flags (seen: GL_BLEND left enabled)."""
    flags = (moderngl.DEPTH_TEST if depth else 0) | (moderngl.BLEND if blend else 0)
    ctx.enable_only(flags)
    if not blend:
        ctx.disable_direct(GL_BLEND)


class _Accumulation:
    """A float target samples are summed into (RGB and coverage), on the image's depth."""

    def __init__(self, ctx: moderngl.Context, size: tuple[int, int], depth) -> None:
        self.texture = ctx.texture(size, 4, dtype="f4")
        # read texel by texel: bilinear reads (the default) at a display's pixel centres gave a
        # background pixel beside the object a sliver of its coverage (alpha > 0), so it was
        # drawn as the object with ~0 radiance, a black one-pixel ring round the silhouette
        self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.fbo = ctx.framebuffer([self.texture], depth)
        self.samples = 0

    def release(self) -> None:
        self.fbo.release()
        self.texture.release()


PREVIEW = 64  # samples of the finished set a long FIS image is shown as first (docs/mis.md)


class Progressive:
    """An image that keeps improving while the view stays still, in a float accumulation
    target. The sampled modes draw stratified sets of `settings.samples` (the first as is, the
    next Cranley–Patterson rotated); a step draws the next rows of the current set, so that
    however small the steps (the window's are a few samples on a slow machine), a finished set
    is the image `render` makes of it — its stratification, its filter footprint — and the
    lighting's predicted error (lighting/auto.py) holds for what the window shows.

    FIS's filter footprint is its set's size: 64 of a set of 256 drawn were 2.1 % off per pixel
    on the default scene, a finished set of 64 1.0–1.5 %. So an FIS image of 256 samples or
    more drawn in pieces first draws a set of PREVIEW in its own target and shows it until the
    image's own set holds 4 × PREVIEW samples: the user sees a finished set of
    64 after 64 samples, the image complete after 25 % more drawing, and that image is still
    `render`'s."""

    def __init__(self, renderer: ObjectRenderer, settings: RenderSettings, seed: int | None = None) -> None:
        """`seed`: rotate the first set too (from this seed), so that images with different
        seeds are independent estimates (what measuring a method's bias needs)."""
        self.renderer = renderer
        self.settings = settings
        ctx = renderer.ctx
        self.depth = ctx.depth_texture((settings.width, settings.height))
        self._image = _Accumulation(ctx, (settings.width, settings.height), self.depth)
        self._preview: _Accumulation | None = None
        self._previewing = False  # the preview's set is being drawn
        self.drawn = 0  # samples drawn in all (the preview's too)
        self.steps = 0
        self._rng = np.random.default_rng(1 if seed is None else seed)
        self._preview_rng = np.random.default_rng([PREVIEW, 1 if seed is None else seed])
        self._rotate_first = seed is not None
        self._set: tuple | None = None  # (texture, size asked, rows, footprint, target) of the set being drawn
        self._set_drawn = 0  # rows of it drawn so far

    @property
    def _shown(self) -> _Accumulation:
        """The preview until the image's own set holds 4 × PREVIEW samples (a preview is drawn
        only for sets of at least that many)."""
        return self._image if self._preview is None or self._image.samples >= 4 * PREVIEW else self._preview

    @property
    def texture(self) -> moderngl.Texture:
        """The sum of the samples of the image shown (`samples` of them)."""
        return self._shown.texture

    @property
    def samples(self) -> int:
        return self._shown.samples

    def _own(self) -> int:
        return int(self.settings.samples) if self.settings.mode in SAMPLED_MODES else 1

    @property
    def needed(self) -> int:
        """Samples drawn in all when the image is complete (its set's and the preview's)."""
        preview = 0 if self._preview is None else max(PREVIEW, self._preview.samples)
        return self._own() + preview

    @property
    def complete(self) -> bool:
        """Whether the image holds its set of `settings.samples` (one draw in other modes)."""
        return self._image.samples >= self._own()

    def step(self, samples: int) -> None:
        r, s = self.renderer, self.settings
        ctx = r.ctx
        if self.steps == 0:
            if s.mode == "fis" and samples < s.samples and s.samples >= 4 * PREVIEW:
                self._preview = _Accumulation(ctx, (s.width, s.height), self.depth)
                self._previewing = True
            for accumulation in (self._image, self._preview):
                if accumulation is not None:
                    # a host toolkit (Qt) may have changed GL state behind moderngl: set what we need
                    accumulation.fbo.depth_mask = True
                    accumulation.fbo.color_mask = (True, True, True, True)
                    accumulation.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        target = self._preview if self._previewing else self._image
        fbo = target.fbo
        fbo.use()  # callers bind their own framebuffer afterwards
        ctx.viewport = (0, 0, s.width, s.height)
        reference = s.reference_view or r.mesh is None
        if s.mode not in SAMPLED_MODES:  # deterministic: one depth-tested draw
            if self.steps == 0:
                _set_state(ctx, depth=not reference, blend=False)
                ctx.depth_func = "<"
                r.draw(s)
                target.samples = self.drawn = 1
        else:
            if self._set is None:
                self._start_set(samples, target)
            tex, size, rows, footprint, _ = self._set
            begin = self._set_drawn
            end = rows if begin == 0 and samples >= size else min(rows, begin + max(1, int(samples)))
            if reference:
                _set_state(ctx, depth=False, blend=False)
            elif self.steps == 0:
                self._depth_prepass(s, fbo, tex, footprint)
            else:
                fbo.depth_mask = False
                ctx.depth_func = "=="
            _set_state(ctx, depth=not reference, blend=True)
            ctx.blend_func = moderngl.ONE, moderngl.ONE
            try:
                for first in range(begin, end, BATCH):
                    r.draw(s, (first, min(end, first + BATCH)), tex, footprint)
            finally:
                ctx.disable(moderngl.BLEND)
                fbo.depth_mask = True
                ctx.depth_func = "<"
            target.samples += end - begin
            self.drawn += end - begin
            self._set_drawn = end
            if end == rows:
                self._end_set()
        self.steps += 1

    def _start_set(self, samples: int, target: _Accumulation) -> None:
        """The next stratified set of `target`: `settings.samples` (PREVIEW for the preview;
        more if one step asks for more), every row drawn and counted (a set holds at least one
        sample per lobe, so it may have more rows); its filter footprint is every sample of its
        target so far and its own. Ordered for drawing in pieces when it will be."""
        r, s = self.renderer, self.settings
        preview = target is self._preview
        rng = self._preview_rng if preview else self._rng  # the image's sets are the ones it has without a preview
        size = PREVIEW if preview else max(int(s.samples), int(samples), 1)
        rotation = rng.random(2) if target.samples or self._rotate_first else None
        tex, rows = r.samples_texture(size, rotation, s.mode, pieces=rng if samples < size else None)
        self._set, self._set_drawn = (tex, size, rows, target.samples + rows, target), 0

    def _end_set(self) -> None:
        if self._set is not None:
            self._set[0].release()
            if self._set[4] is self._preview:
                self._previewing = False
        self._set, self._set_drawn = None, 0

    def _depth_prepass(self, s: RenderSettings, fbo, tex, footprint: int) -> None:
        """Lay down the visible surface's depth (shared by the preview's target), then leave
        the test at '==' with depth writes off, so that the shading draws touch only the
        front-most fragments."""
        ctx = self.renderer.ctx
        _set_state(ctx, depth=True, blend=False)
        ctx.depth_func = "<"
        fbo.color_mask = (False, False, False, False)
        self.renderer.draw(s, (0, 0), tex, footprint)
        fbo.color_mask = (True, True, True, True)
        fbo.depth_mask = False
        ctx.depth_func = "=="

    def release(self) -> None:
        self._end_set()
        for target in (self._image, self._preview):
            if target is not None:
                target.release()
        self.depth.release()


def independent_image(renderer: ObjectRenderer, settings: RenderSettings, seed: int) -> np.ndarray:
    """One finished image (height, width, 3), rows top first, whose sample set is rotated by
    `seed`: images of different seeds are independent estimates (a method's bias is their
    mean's error, its noise their spread)."""
    image = Progressive(renderer, settings, seed=seed)
    try:
        image.step(settings.samples)
        raw = np.frombuffer(image.texture.read(), np.float32).reshape(settings.height, settings.width, 4)[::-1]
    finally:
        image.release()
    return raw[:, :, :3] / settings.samples


class Display:
    """Draws an accumulated image into the bound framebuffer, tone-mapped."""

    def __init__(self, ctx: moderngl.Context) -> None:
        src = shader_source("display.glsl")
        self.ctx = ctx
        self.program = ctx.program(vertex_shader=GLSL_VERSION + "#define VERTEX\n" + src,
                                   fragment_shader=GLSL_VERSION + shader_source("common.glsl") + src)
        self.vao = ctx.vertex_array(self.program, [])

    def draw(self, image: Progressive, exposure: float = 0.0, reinhard: bool = False,
             background=(0.12, 0.12, 0.14), gamma: float = 0.0, environment: "ObjectRenderer | None" = None,
             other: "Progressive | None" = None, compare: str = "split", split: float = 0.5) -> None:
        """`environment`: show that renderer's map behind the object, seen through its camera
        and turned as its lighting is (image.settings). `other`: a second image of the same
        scene (a fit beside its original), shown right of `split` ("split") or as the relative
        luminance difference in false colour ("difference": difference_colour, black 0, white 100 %)."""
        _set_state(self.ctx, depth=False, blend=False)
        image.texture.use(0)
        _set(self.program, "u_image", 0)
        _set(self.program, "u_compare", 0 if other is None else {"split": 1, "difference": 2}[compare])
        if other is not None:
            other.texture.use(2)
            _set(self.program, "u_image_b", 2)
            _set(self.program, "u_scale_b", float(2.0**exposure / max(other.samples, 1)))
            _set(self.program, "u_split", float(split))
        show_env = environment is not None and environment.env_texture is not None
        _set(self.program, "u_show_env", show_env)
        if show_env:
            s = image.settings
            environment.env_texture.use(1)
            _set(self.program, "u_env", 1)
            _set(self.program, "u_env_rotation", math.radians(s.env_rotation))
            _set(self.program, "u_env_scale", float(2.0**exposure))
            camera = environment.camera
            view_projection = camera.projection(s.width / s.height) @ camera.view()
            self.program["u_inverse_view_projection"].write(gl_matrix(np.linalg.inv(view_projection)))
            _set(self.program, "u_camera_position", tuple(float(x) for x in camera.position))
        _set(self.program, "u_scale", float(2.0**exposure / max(image.samples, 1)))
        _set(self.program, "u_reinhard", bool(reinhard))
        _set(self.program, "u_gamma", float(gamma))
        _set(self.program, "u_background", tuple(background))
        gil_free.draw(self.ctx, self.vao, moderngl.TRIANGLES, 3)
