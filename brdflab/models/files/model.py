"""A lobe model read from a file: a peer of the built-ins in the one registry.

What a file gives (parameters with defaults and bounds, a CPU formula and/or GLSL) is held
here in the shape every built-in has, so the viewer, the fitter, the renderers, the energy
check and the file format use it without knowing where it came from:

- **evaluation**: BRDFLab's `<Equation>` compiled to NumPy (`expression`); a model with
  GLSL alone (every BRDF Explorer file) is evaluated by its own GLSL through the headless
  OpenGL context (`brdflab.render.model_eval`, plugged in by `backend`);
- **GLSL twin**: the file's code with its names prefixed (`glsl_text`) and a wrapper with
  the lab's signature `brdf_<id>(wi, wo, float p[NP])` (a colour lobe: `brdf_<id>_rgb`);
- **sampling**: a table built from the lobe's own values (`sampler.TabulatedSampler`);
- **prefiltered lighting**: an equivalent roughness measured on the lobe's own shape.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np

from brdflab.geometry.vec import rotate_about_z
from brdflab.models.base import LUMINANCE, LobeModel, Parameter, SplitSum
from brdflab.models.files.expression import Formula, direction_values
from brdflab.models.files.glsl_text import OVER, STEP, STEPS
from brdflab.models.files.limits import MAX_LOOP_STEPS

NUDGE = 0.01  # radians: wi and wo turned this far apart where a file's value is NaN (its limit)



@dataclass(frozen=True)
class Origin:
    """Where a file model came from: its file, that file's sha256 and its format."""

    path: Path
    sha256: str
    format: str  # "BRDFLab descriptor" or "BRDF Explorer"

    @classmethod
    def of(cls, path: Path, data: bytes, fmt: str) -> "Origin":
        return cls(Path(path).resolve(), hashlib.sha256(data).hexdigest(), fmt)


@dataclass
class GlslParts:
    """The file's GLSL, ready to link: `library` (prefixed declarations and helpers) and the
    body of the wrapper that sets the parameters and returns the value (vec3 or float)."""

    library: str
    call: str  # an expression of wi, wo and p[] giving the lobe's value
    returns_colour: bool
    line_offset: int = 0  # the file's line of the library's first line (compiler messages)


class FileModel(LobeModel):
    """A lobe model defined by a model file. What it computes depends on the parameters
    passed in alone; it keeps caches of work done for them (sampling tables, isotropy)."""

    def __init__(self, name: str, model_name: str, parameters: tuple[Parameter, ...], isotropic: bool,
                 origin: Origin, glsl: GlslParts, formula: Formula | None = None, summary: str = "",
                 warnings: tuple[str, ...] = ()) -> None:
        self.name = name
        self.model_name = model_name
        self.parameters = parameters
        self.isotropic = isotropic
        self.origin = origin
        self.glsl = glsl
        self.formula = formula
        self.colour = glsl.returns_colour  # a BRDF Explorer file's vec3 (descriptors have one value)
        self.summary = summary or f"{origin.format} model from {origin.path.name}"
        self.reference = str(origin.path)
        self.warnings = list(warnings)
        self.undefined: str | None = None  # where its values are NaN at its defaults (library.check_model)
        self.sampling = "tabulated from the lobe's own values (the lab's generic sampler)"
        self.split_sum_rule = ("measured on the lobe's own values at normal view: mirror, Beckmann α = "
                               "√(albedo / (4π f(n, n))) (exact for a microfacet lobe's core); diffuse "
                               "when that is ≥ 0.5, a Lambertian's")
        self.starts = ({},)
        self._id = model_glsl_id(model_name, origin.sha256)
        self._samplers: dict = {}
        self._isotropic_at: dict = {}  # parameters → whether the lobe is isotropic there

    def __reduce__(self):
        """Sent to another process (a fit's worker) as its file: read there again."""
        from brdflab.models.files.library import rebuild

        return rebuild, (str(self.origin.path), self.origin.sha256, self.name)

    def note_undefined(self, where: str | None) -> None:
        """Record where the model is undefined (one warning, said when the file is opened)."""
        if where and self.undefined is None:
            self.undefined = f"{self.origin.path.name}: {where}"
            self.warnings.append(self.undefined)

    # --- identity
    @property
    def glsl_id(self) -> str:
        return self._id

    @property
    def xml_name(self) -> str:
        return self.model_name

    def describe(self) -> dict:
        out = super().describe()
        out.update(xml_name=self.model_name, colour=self.colour, file=str(self.origin.path),
                   sha256=self.origin.sha256, format=self.origin.format,
                   evaluation="formula (NumPy)" if self.formula is not None else "GLSL (OpenGL)")
        return out

    def is_isotropic(self, params: Mapping[str, float]) -> bool:
        """Declared isotropic, or found so at these parameters: the lobe's values do not change
        when both directions turn about the normal (Disney's at anisotropic = 0). A lobe
        found isotropic is tabulated for 24 views instead of 288."""
        if self.isotropic:
            return True
        key = self._key(self._with_defaults(params))
        if key not in self._isotropic_at:
            if len(self._isotropic_at) > 64:
                self._isotropic_at.clear()
            self._isotropic_at[key] = self._turns_alike(params)
        return self._isotropic_at[key]

    def _turns_alike(self, params: Mapping[str, float]) -> bool:
        from brdflab.models.files.library import probe_pairs

        wi, wo = probe_pairs(64, seed=13)
        angle = np.random.default_rng(17).uniform(0.3, 6.0, 64)
        p = self._with_defaults(params)
        a = self.evaluate_rgb(wi, wo, p)
        b = self.evaluate_rgb(rotate_about_z(wi, angle), rotate_about_z(wo, angle), p)
        return bool(np.allclose(a, b, rtol=1e-4, atol=1e-7 * max(float(np.abs(a).max()), 1e-30)))

    def complete(self, given: Mapping[str, float]) -> dict[str, float]:
        """A file's lobe as BRDFLab read it: a parameter it does not give takes its default."""
        out = self.defaults()
        out.update(given)
        return out

    # --- evaluation
    def _value(self, wi, wo, p):
        if self.formula is not None:
            return self.formula_values(wi, wo, p)
        return self._gl_values(wi, wo, p) @ LUMINANCE if self.colour else self._gl_values(wi, wo, p)[..., 0]

    def formula_values(self, wi: np.ndarray, wo: np.ndarray, p: Mapping) -> np.ndarray:
        """The <Equation>'s values; where NaN or infinite, its limit as the GLSL twin takes it
        (glsl_source): the mean of its finite values at wi and wo turned ±NUDGE apart about x
        and about y (NaN where none is finite: the file is undefined there)."""
        def raw(a, b, q):
            values = direction_values(a, b)
            values.update({k: np.asarray(v, float) for k, v in q.items()})
            return self.formula.evaluate(values)

        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            v = raw(wi, wo, p)
            shape = np.broadcast_shapes(np.shape(v), wi.shape[:-1], wo.shape[:-1], *(np.shape(x) for x in p.values()))
            v = np.array(np.broadcast_to(v, shape), float)
            bad = ~np.isfinite(v)
            if not bad.any():
                return v
            a, b = (np.broadcast_to(w, shape + (3,))[bad] for w in (wi, wo))
            q = {k: np.broadcast_to(np.asarray(x, float), shape)[bad] for k, x in p.items()}
            around = np.stack([np.broadcast_to(raw(nudged(a, k, NUDGE), nudged(b, k, -NUDGE), q), a.shape[:1])
                               for k in range(1, 5)])
        finite = np.isfinite(around)
        count = finite.sum(axis=0)
        v[bad] = np.where(count > 0, np.where(finite, around, 0.0).sum(axis=0) / np.maximum(count, 1), np.nan)
        return v

    def evaluate_rgb(self, wi, wo, params=None):
        if not self.colour:
            return super().evaluate_rgb(wi, wo, params)
        wi = np.asarray(wi, float)
        wo = np.asarray(wo, float)
        out = self._gl_values(wi, wo, self._with_defaults(params))
        above = np.broadcast_to((wi[..., 2] > 0) & (wo[..., 2] > 0), out.shape[:-1])
        out[~above] = 0.0
        out[~np.isfinite(out)] = 0.0
        return out

    def _gl_values(self, wi, wo, p) -> np.ndarray:
        from brdflab.models.files.backend import glsl_evaluator

        return glsl_evaluator().evaluate(self, wi, wo, self.parameter_vector(p))

    def parameter_vector(self, p: Mapping[str, "float | np.ndarray"]) -> list:
        return [p[q.name] for q in self.parameters]

    # --- sampling (generic: the file's own samplers are not trusted, see sampler.py)
    def _key(self, p: Mapping) -> tuple:
        """The parameter values as a cache key (a lobe's caches hold work per parameter set)."""
        return tuple(float(np.asarray(p[q.name]).ravel()[0]) for q in self.parameters)

    def _sampler(self, p):
        from brdflab.models.files.sampler import TabulatedSampler

        key = self._key(p)
        s = self._samplers.get(key)
        if s is None:
            if len(self._samplers) > 8:
                self._samplers.clear()
            s = self._samplers[key] = TabulatedSampler(self, dict(zip(self.parameter_names, key)))
        return s

    def _sample(self, wo, u, p):
        return self._sampler(p).sample(wo, u)

    def _pdf(self, wi, wo, p):
        return self._sampler(p).pdf(wi, wo)

    # --- prefiltered lighting
    def split_sum(self, params):
        from brdflab.models.files.sampler import equivalent_roughness

        alpha = equivalent_roughness(self, self._with_defaults(params))
        if alpha is None:
            return SplitSum("diffuse", kernel="cosine")
        return SplitSum("mirror", alpha)

    # --- GLSL twin
    def glsl_source(self) -> str:
        """The file's GLSL and the lab's wrapper `brdf_<id>(wi, wo, p)` (a colour lobe also
        `brdf_<id>_rgb`). The file's loops count their steps (glsl_text.guarded_loops): past
        MAX_LOOP_STEPS in one call of the wrapper (its limit included) the loops end, the flag
        `<id>_0over` is set and the value is NaN. Where the file's value is NaN or infinite, the wrapper takes its limit:
        the mean of its finite values at wi, wo turned ±NUDGE apart about x and about y
        (`nudged`, shaders/common.glsl), so a removable singularity (Schlick's pow(1 − wi·h, 5)
        at wi = wo, where rounding puts wi·h above 1) has its value, and what stays NaN is
        where the file is undefined."""
        i = self._id
        kind = "vec3" if self.colour else "float"
        head = (f"int {i}_{STEPS}; bool {i}_{OVER}; bool {i}_{STEP}() {{ {i}_{STEPS}++; "
                f"if ({i}_{STEPS} > {MAX_LOOP_STEPS}) {{ {i}_{OVER} = true; return false; }} return true; }} ")
        finite = "!(any(isnan(f)) || any(isinf(f)))" if self.colour else "!(isnan(f) || isinf(f))"
        name = f"brdf_{i}_rgb" if self.colour else f"brdf_{i}"
        out = (f"{head}{self.glsl.library}\n{kind} {i}_0file(vec3 wi, vec3 wo, float p[NP]) {{ {self.glsl.call} }}\n"
               f"{kind} {name}(vec3 wi, vec3 wo, float p[NP]) {{\n"
               f"    {i}_{OVER} = false; {i}_{STEPS} = 0; {kind} sum = {kind}(0.0); float n = 0.0;\n"
               f"    for (int k = 0; k < 5; k++) {{\n"
               f"        {kind} f = {i}_0file(nudged(wi, k, {NUDGE}), nudged(wo, k, -{NUDGE}), p);\n"
               f"        if ({i}_{OVER}) return {kind}(nan_value());\n"
               f"        if ({finite}) {{ if (k == 0) return f; sum += f; n += 1.0; }}\n"
               f"    }}\n    return n > 0.0 ? sum / n : {kind}(nan_value());\n}}\n")
        if self.colour:
            out += (f"float brdf_{i}(vec3 wi, vec3 wo, float p[NP]) "
                    f"{{ return dot(brdf_{i}_rgb(wi, wo, p), vec3({', '.join(map(str, LUMINANCE))})); }}\n")
        return out

    # sampled by the generic tabulated sampler, in NumPy (_sample, _pdf) and in the renderers
    # (shaders/tabulated.glsl, textures from render/tabulated.py)
    tabulated = True

    def tabulated_sampler(self, params):
        """The tables this lobe is sampled from at these parameters (cached per parameters)."""
        return self._sampler(self._with_defaults(params))

    @property
    def glsl_samplable(self) -> bool:
        return False  # no sample_<id>/pdf_<id>: the renderers use the tables (tabulated = True)


def nudged(w: np.ndarray, k: int, angle: float) -> np.ndarray:
    """Directions (n, 3) turned by `angle` about x (k = 1: +, 2: −) or y (k = 3: +, 4: −): the
    NumPy twin of shaders/common.glsl's nudged."""
    s = math.sin(angle) if k in (1, 3) else -math.sin(angle)
    c = math.cos(angle)
    x, y, z = w[:, 0], w[:, 1], w[:, 2]
    if k <= 2:
        return np.stack([x, c * y - s * z, s * y + c * z], axis=-1)
    return np.stack([c * x + s * z, y, -s * x + c * z], axis=-1)


def model_glsl_id(model_name: str, sha256: str) -> str:
    """The GLSL identifier of a file model: its name, made an identifier, and the file's
    checksum (two files with one model name never share GLSL names)."""
    from brdflab.models.files.glsl_text import identifier

    return f"{identifier(model_name)[:40]}_{sha256[:6]}"
