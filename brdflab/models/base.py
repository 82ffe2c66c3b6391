"""What a lobe model is: parameters declared once, NumPy evaluation, sampling and pdf.

A model module subclasses `LobeModel`, fills in the class attributes and `_value`
(and, if the literature gives one, `_sample`/`_pdf`), and decorates the class with
`register`. Its GLSL twin is `shaders/<name>.glsl`. Everything else (the views,
the fitter, the renderers, the XML reader) finds it through `brdflab.models.registry`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Mapping

import numpy as np

from brdflab.geometry.vec import shared_term, upper_hemisphere

ParamValues = Mapping[str, "float | np.ndarray"]

SPLIT_SUM_KINDS = ("diffuse", "mirror", "axis")
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 weights of linear RGB: a colour lobe's one value


@dataclass(frozen=True)
class SplitSum:
    """How one lobe is drawn by prefiltered environment lighting (the split sum).

    `kind`: "diffuse" (lit by the irradiance), "mirror" (the prefiltered map looked up
    around the mirror direction of wo) or "axis" (around the lobe's own axis `axis` ∘ wo,
    e.g. Lafortune's C ∘ wo, which is a retro-reflection when Cx, Cy > 0).
    `roughness`: the α of the prefilter kernel `kernel` ("beckmann", "ggx", or "phong" for
    lobes around a direction in wi-space) whose width matches the lobe's (diffuse lobes:
    "cosine", the irradiance). `diffuse_share`: the part of the lobe's albedo that is lit by the
    irradiance instead (a lobe with a diffuse term of its own, Strauss). `tilt`: for an
    anisotropic lobe, the RMS slope (along t, along b) by which the normals of its lookups
    spread (`anisotropic_split`)."""

    kind: str
    roughness: float = 1.0
    kernel: str = "beckmann"
    axis: tuple[float, float, float] = (-1.0, -1.0, 1.0)
    diffuse_share: float = 0.0
    tilt: tuple[float, float] = (0.0, 0.0)


def anisotropic_split(ax: float, ay: float, **kwargs) -> SplitSum:
    """A mirror lobe of slope widths (ax, ay): a Gaussian (Beckmann) slope distribution of
    widths (ax, ay) is the isotropic one of the shorter width α convolved with a Gaussian spread
    of the normal along the longer axis, of RMS slope √((a² − α²)/2) per axis; so the lobe is
    looked up with the kernel of α around normals spread that way (exact for Beckmann slopes,
    close for GGX). An isotropic stand-in of the same solid angle, α = √(ax·ay), was 20–48 %
    off for Ward 0.1 × 0.4 on real maps."""
    ax, ay = min(1.0, float(ax)), min(1.0, float(ay))
    alpha = min(ax, ay)
    tilt = tuple(float(np.sqrt(max(0.0, a * a - alpha * alpha) / 2.0)) for a in (ax, ay))
    return SplitSum("mirror", alpha, tilt=tilt, **kwargs)


def phong_roughness(n) -> float:
    """Beckmann α of a cos^n lobe around a direction in wi-space (Phong, Lafortune): with
    n = v = r the half vector turns half as far as wi, so n ↔ the Blinn exponent 4n."""
    return blinn_roughness(4.0 * float(n))


def blinn_roughness(n) -> float:
    """Beckmann α of a Blinn–Phong cos^n θh lobe, α = √(2/(n+2)) (Walter et al. 2007)."""
    return float(min(1.0, np.sqrt(2.0 / (max(float(n), 0.0) + 2.0))))


@dataclass(frozen=True)
class Parameter:
    """One lobe parameter: its XML attribute name, default, bounds and unit."""

    name: str
    default: float
    lower: float
    upper: float
    unit: str = "1"
    doc: str = ""
    log: bool = False  # spans decades: the fitter searches it on a log scale
    # "float"; "bool" (0 or 1, a switch: held fixed by a fit); "colour" (one component of a
    # colour, as BRDF Explorer's `color` parameters are read: NAME_r, NAME_g, NAME_b)
    kind: str = "float"
    # where a fit's search stops short of `lower` (None: at `lower`): a value a file may hold
    # but a fit must not end on (Principled's specular = 0, where Mitsuba drops its main lobe)
    fit_lower: float | None = None

    @property
    def search_lower(self) -> float:
        """The lowest value a fit searches."""
        return self.lower if self.fit_lower is None else self.fit_lower

    @property
    def fitted(self) -> bool:
        """Whether a fit searches it (a switch is the user's choice, not a fitted value)."""
        return self.kind != "bool"

    def as_dict(self) -> dict:
        return {
            "name": self.name,
            "default": self.default,
            "lower": self.lower,
            "upper": self.upper,
            "unit": self.unit,
            "doc": self.doc,
            "log_scale": self.log,
            "kind": self.kind,
        }


class LobeModel:
    """Base class of every lobe. Subclasses are stateless; parameters are passed in.

    Directions are arrays of shape (..., 3) in the local frame; parameter values are
    floats or arrays broadcastable to the leading shape (so a fitter can evaluate a
    batch of parameter sets at once). Values are in 1/sr, without the cosine.
    """

    name: ClassVar[str]
    parameters: ClassVar[tuple[Parameter, ...]] = ()
    isotropic: ClassVar[bool] = True
    # an anisotropic model's two parameters that, when equal, make the lobe isotropic
    isotropic_when_equal: ClassVar[tuple[str, str] | None] = None
    reciprocal: ClassVar[bool] = True
    sampling: ClassVar[str | None] = None  # how wi is importance-sampled, or None
    summary: ClassVar[str] = ""
    reference: ClassVar[str] = ""
    # model-aware starting points for automatic restarts (partial parameter dicts)
    starts: ClassVar[tuple[dict, ...]] = ({},)
    # parameters whose common scale does not change the lobe (searched as a direction)
    scale_invariant: ClassVar[tuple[str, ...]] = ()
    # how `split_sum` maps the lobe to prefiltered lighting, in words (`brdflab models`)
    split_sum_rule: ClassVar[str] = ""
    # True for a lobe whose value is a colour (a BRDF Explorer file's vec3): `evaluate` gives
    # its luminance, `evaluate_rgb` the three values; see AnalyticMaterial for the channels
    colour: ClassVar[bool] = False
    # False for a lobe whose own parameters carry its magnitude and colour (Principled's base
    # colour): a fit holds its scaling factors at 1 instead of solving them
    scaled: ClassVar[bool] = True
    # True where the parameters are an artist's weights in [0, 1] (Principled): one that ends on
    # a bound (no clear coat, a pure metal) is a choice the fit made, not a symptom
    weights_on_bounds: ClassVar[bool] = False
    # where a model read from a file came from (None for a built-in)
    origin: ClassVar[object | None] = None

    @property
    def xml_name(self) -> str:
        """The name a material file gives the model (<Model>)."""
        return self.name

    @property
    def glsl_samplable(self) -> bool:
        """Whether the GLSL twin has sample_<id>/pdf_<id> (else renderers sample the cosine)."""
        return self.samplable

    @property
    def glsl_id(self) -> str:
        """The identifier of the model's GLSL functions (brdf_<id>, sample_<id>, pdf_<id>)."""
        return self.name

    def glsl_source(self) -> str:
        """The GLSL twin: `float brdf_<id>(vec3 wi, vec3 wo, float p[NP])` (a colour lobe:
        `vec3 brdf_<id>_rgb(...)`), and sample_/pdf_<id> if it is samplable."""
        from brdflab.io.resources import shader_path

        return shader_path(f"{self.name}.glsl").read_text()

    # --- declared-once metadata -------------------------------------------------
    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def samplable(self) -> bool:
        return self.sampling is not None

    def defaults(self) -> dict[str, float]:
        return {p.name: p.default for p in self.parameters}

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    def is_isotropic(self, params: Mapping[str, float]) -> bool:
        """Whether a lobe with these parameters is isotropic (what a file's <Type> says)."""
        if self.isotropic:
            return True
        pair = self.isotropic_when_equal
        return pair is not None and params[pair[0]] == params[pair[1]]

    def complete(self, given: Mapping[str, float]) -> dict[str, float]:
        """Parameters read from a file, with the model's historical aliases resolved.

        The default implementation accepts exactly the declared names; models with
        aliases (Ward's lone `ax`, Ashikhmin–Shirley's `Exponent`) override it.
        """
        return dict(given)

    def describe(self) -> dict:
        return {
            "id": self.name,
            "xml_name": self.xml_name,
            "summary": self.summary,
            "reference": self.reference,
            "isotropic": self.isotropic,
            "reciprocal": self.reciprocal,
            "samplable": self.samplable,
            "sampling": self.sampling,
            "parameters": [p.as_dict() for p in self.parameters],
            "prefiltered": {**self.split_sum(self.defaults()).__dict__, "rule": self.split_sum_rule},
        }

    def split_sum(self, params: Mapping[str, float]) -> SplitSum:
        """The lobe's kind and equivalent roughness for prefiltered lighting (its one
        definition: the renderer, `brdflab models` and the study all read it)."""
        raise NotImplementedError(f"{self.name} does not say how it maps to prefiltered lighting")

    # --- evaluation -------------------------------------------------------------
    def evaluate(self, wi: np.ndarray, wo: np.ndarray, params: ParamValues | None = None) -> np.ndarray:
        """f(wi, wo), zero unless both directions are above the surface."""
        wi = np.asarray(wi, dtype=float)
        wo = np.asarray(wo, dtype=float)
        p = self._with_defaults(params)
        mask = shared_term(wi, wo, ("upper hemisphere",), lambda: upper_hemisphere(wi, wo))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            v = self._value(wi, wo, p)
        out = np.array(np.broadcast_to(v, np.broadcast_shapes(np.shape(v), mask.shape)), dtype=float)
        out[~np.broadcast_to(mask, out.shape)] = 0.0
        if not np.isfinite(out.sum()):
            out[~np.isfinite(out)] = 0.0
        return out

    def evaluate_rgb(self, wi: np.ndarray, wo: np.ndarray, params: ParamValues | None = None) -> np.ndarray:
        """f(wi, wo) in red, green and blue, shape (..., 3): the value thrice but for a colour lobe."""
        v = self.evaluate(wi, wo, params)
        return np.repeat(v[..., None], 3, axis=-1)

    def sample(self, wo: np.ndarray, u: np.ndarray, params: ParamValues | None = None) -> np.ndarray:
        """Directions wi drawn from pdf(·, wo) using uniforms u of shape (..., 2)."""
        if not self.samplable:
            raise NotImplementedError(f"{self.name} has no importance sampling")
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            return self._sample(np.asarray(wo, float), np.asarray(u, float), self._with_defaults(params))

    def pdf(self, wi: np.ndarray, wo: np.ndarray, params: ParamValues | None = None) -> np.ndarray:
        """Solid-angle density of `sample` over the whole sphere."""
        if not self.samplable:
            raise NotImplementedError(f"{self.name} has no importance sampling")
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            d = self._pdf(np.asarray(wi, float), np.asarray(wo, float), self._with_defaults(params))
        return np.where(np.isfinite(d), d, 0.0)

    def _with_defaults(self, params: ParamValues | None) -> dict:
        p = self.defaults()
        if params:
            for k, v in params.items():
                if k not in p:
                    raise KeyError(f"{self.name} has no parameter {k!r}")
                p[k] = v
        return p

    # --- to implement -----------------------------------------------------------
    def _value(self, wi: np.ndarray, wo: np.ndarray, p: dict) -> np.ndarray:
        raise NotImplementedError

    def _sample(self, wo: np.ndarray, u: np.ndarray, p: dict) -> np.ndarray:
        raise NotImplementedError

    def _pdf(self, wi: np.ndarray, wo: np.ndarray, p: dict) -> np.ndarray:
        raise NotImplementedError


def normalised_phong_factor(n):
    """(n+2)/(2π): makes a cos^n lobe of the reflected direction energy-conserving."""
    return (np.asarray(n, float) + 2.0) / (2.0 * math.pi)


class CosineSampled(LobeModel):
    """Mixin for diffuse-like lobes: importance-sample the cosine factor alone; in
    prefiltered lighting they are lit by the irradiance."""

    sampling = "cosine-weighted hemisphere"
    split_sum_rule = "diffuse: irradiance × the lobe's directional albedo / π"

    def split_sum(self, params):
        return SplitSum("diffuse", kernel="cosine")

    def _sample(self, wo, u, p):
        from brdflab.geometry.sampling import cosine_hemisphere

        return cosine_hemisphere(np.broadcast_to(u, np.broadcast_shapes(u.shape, wo.shape[:-1] + (2,))))

    def _pdf(self, wi, wo, p):
        from brdflab.geometry.sampling import cosine_hemisphere_pdf

        return np.broadcast_to(cosine_hemisphere_pdf(wi), np.broadcast_shapes(wi.shape[:-1], wo.shape[:-1]))
