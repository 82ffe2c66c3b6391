"""Analytic materials: lobes in a Linear or a Fixed combination over any number of channels.

Linear (BRDFLab, Ngan et al.): every channel shares the lobes; lobe k contributes
scale[k][c] · lobe_k to channel c. Fixed (McAllister et al.): each lobe belongs to one
channel and carries its own magnitude `value` (BRDFLab's Lambertian `value`; for the
other models the same attribute, 1 by default).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.models import LobeModel, get_model

Combination = Literal["Linear", "Fixed"]

# What a material may declare: far above any real one, low enough that a hostile file
# cannot make the lab allocate or compute without bound.
MAX_CHANNELS = 64
MAX_LOBES = 100_000
MAX_SCALE = 1e6  # a scaling factor (or Fixed value) above this is not a reflectance


class SourceLinked:
    """A value read from XML: it may link to the element it was read from (`source`) and
    carry unknown elements (`extra`, a document's `info`). lxml elements do not pickle, so
    a value sent to another process leaves the link behind and carries those elements as
    text, parsed back on arrival."""

    _CARRIED = ("extra", "info")

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["source"] = None
        for key in self._CARRIED:
            if key in state:
                state[key] = _as_text(state[key])
        return state

    def __setstate__(self, state: dict) -> None:
        for key in self._CARRIED:
            if key in state:
                state[key] = _from_text(state[key])
        self.__dict__.update(state)


class _ElementText(bytes):
    """An XML element serialised for pickling."""


def _as_text(value):
    if isinstance(value, (list, tuple)):
        return type(value)(_as_text(v) for v in value)
    if hasattr(value, "getroottree"):  # an lxml element
        from lxml import etree

        return _ElementText(etree.tostring(value))
    return value


def _from_text(value):
    if isinstance(value, (list, tuple)):
        return type(value)(_from_text(v) for v in value)
    if isinstance(value, _ElementText):
        from lxml import etree

        parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False)
        return etree.fromstring(bytes(value), parser)
    return value


@dataclass
class Lobe(SourceLinked):
    """One lobe of a material: a model, its parameters and its weight(s)."""

    model: LobeModel
    params: dict[str, float]
    scale: list[float]  # Linear: one factor per channel; Fixed: [value]
    channel: int | None = None  # Fixed only
    extra: list = field(default_factory=list)  # unknown XML children, kept verbatim
    # the XML elements it was read from, (<ScalingFactors> or None, <Lobe>): a save writes
    # its values into them, so that what was not edited keeps its exact text
    source: object | None = field(default=None, compare=False, repr=False)

    @classmethod
    def create(cls, model_name: str, scale: list[float], channel: int | None = None, **params: float) -> "Lobe":
        model = get_model(model_name)
        values = model.defaults()
        values.update(params)
        lobe = cls(model, values, [float(s) for s in scale], channel)
        lobe.validate()
        return lobe

    def validate(self, where: str = "") -> None:
        """Raise BRDFLabError for unknown, missing, non-finite or out-of-bounds values."""
        prefix = f"{where}: " if where else ""
        names = set(self.model.parameter_names)
        extra = sorted(set(self.params) - names)
        if extra:
            raise BRDFLabError(f"{prefix}{self.model.name} has no parameter(s) {', '.join(extra)}")
        missing = sorted(names - set(self.params))
        if missing:
            raise BRDFLabError(f"{prefix}{self.model.name} lobe is missing parameter(s) {', '.join(missing)}")
        for p in self.model.parameters:
            v = self.params[p.name]
            if not math.isfinite(v):
                raise BRDFLabError(f"{prefix}{self.model.name} parameter {p.name} is {v}")
            if not (p.lower <= v <= p.upper):
                raise BRDFLabError(
                    f"{prefix}{self.model.name} parameter {p.name}={v:g} is outside [{p.lower:g}, {p.upper:g}]"
                )
        for s in self.scale:
            if not math.isfinite(s):
                raise BRDFLabError(f"{prefix}{self.model.name} scaling factor is {s}")
            if s < 0.0:
                raise BRDFLabError(f"{prefix}{self.model.name} scaling factor {s:g} is negative (a BRDF is never negative)")
            if s > MAX_SCALE:
                raise BRDFLabError(f"{prefix}{self.model.name} scaling factor {s:g} is above {MAX_SCALE:g} "
                                   "(no real material reflects that much)")

    def channel_values(self, wi: np.ndarray, wo: np.ndarray, n_channels: int) -> np.ndarray:
        """The lobe's value per channel, shape (..., 1) (the same in every channel) or
        (..., 3): see `lobe_channels`."""
        return lobe_channels(self.model, wi, wo, self.params, n_channels)


def lobe_channels(model: LobeModel, wi, wo, params, n_channels: int) -> np.ndarray:
    """A lobe's value per channel of an `n_channels` material: (..., 1) for a lobe with one
    value; a colour lobe gives its red, green and blue to a 3-channel material, (..., 3), and
    its luminance to every channel of any other (there is no colour to map)."""
    if model.colour and n_channels == 3:
        return model.evaluate_rgb(wi, wo, params)
    return model.evaluate(wi, wo, params)[..., None]


@dataclass
class AnalyticMaterial(SourceLinked):
    """A material made of analytic lobes; evaluates to (N, n_channels) BRDF values."""

    name: str = "material"
    combination: Combination = "Linear"
    n_channels: int = 3
    lobes: list[Lobe] = field(default_factory=list)
    extra: list = field(default_factory=list)  # unknown XML children of <Material>
    source: object | None = field(default=None, compare=False, repr=False)  # its <Material> element

    kind = "Analytic"

    def lobe_models(self) -> list[str]:
        """The model of each lobe of the design, once: a Fixed material holds every lobe once
        per channel, and its channel-0 copies stand for them (what fits and lists name)."""
        return [lobe.model.name for lobe in self.lobes if lobe.channel in (None, 0)]

    def validate(self, where: str = "") -> None:
        prefix = f"{where}: " if where else ""
        if self.combination not in ("Linear", "Fixed"):
            raise BRDFLabError(f"{prefix}LobeCombination must be Linear or Fixed, not {self.combination!r}")
        if not 1 <= self.n_channels <= MAX_CHANNELS:
            raise BRDFLabError(f"{prefix}nChannels must be 1..{MAX_CHANNELS}, not {self.n_channels}")
        if len(self.lobes) > MAX_LOBES:
            raise BRDFLabError(f"{prefix}{len(self.lobes)} lobes is more than the {MAX_LOBES} supported")
        for k, lobe in enumerate(self.lobes):
            lobe.validate(f"{prefix}lobe {k}" if not where else f"{where}, lobe {k}")
            if self.combination == "Linear" and len(lobe.scale) != self.n_channels:
                raise BRDFLabError(
                    f"{prefix}lobe {k} has {len(lobe.scale)} scaling factors for {self.n_channels} channels"
                )
            if self.combination == "Fixed":
                if lobe.channel is None or not (0 <= lobe.channel < self.n_channels):
                    raise BRDFLabError(f"{prefix}lobe {k} has channel {lobe.channel}, not in 0..{self.n_channels - 1}")
                if len(lobe.scale) != 1:
                    raise BRDFLabError(f"{prefix}lobe {k} of a Fixed material needs exactly one value")

    def channels_without_lobes(self) -> list[int]:
        """Channels of a Fixed material that no lobe belongs to (they would render black)."""
        if self.combination != "Fixed":
            return []
        return sorted(set(range(self.n_channels)) - {lobe.channel for lobe in self.lobes})

    @property
    def isotropic(self) -> bool:
        return all(l.model.isotropic for l in self.lobes)

    def rgb_scales(self) -> np.ndarray:
        """(lobes, 3): what each lobe adds to red, green and blue (Fixed lobes scale their
        own channel; one-channel materials are grey): the renderers' colours of the lobes."""
        scales = np.zeros((len(self.lobes), 3))
        for k, lobe in enumerate(self.lobes):
            if self.combination == "Linear":
                s = np.asarray(lobe.scale, float)
                scales[k] = s[:3] if s.size >= 3 else np.repeat(s[0], 3)
            elif self.n_channels == 1:
                scales[k] = lobe.scale[0]
            elif lobe.channel < 3:
                scales[k, lobe.channel] = lobe.scale[0]
        return scales

    def evaluate(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """BRDF values of every channel, shape (N, n_channels), in 1/sr."""
        wi = np.asarray(wi, float)
        wo = np.asarray(wo, float)
        shape = np.broadcast_shapes(wi.shape[:-1], wo.shape[:-1])
        out = np.zeros(shape + (self.n_channels,))
        for lobe in self.lobes:
            v = lobe.channel_values(wi, wo, self.n_channels)
            if self.combination == "Linear":
                out += v * np.asarray(lobe.scale)
            else:
                out[..., lobe.channel] += lobe.scale[0] * v[..., min(lobe.channel, v.shape[-1] - 1)]
        return out

    def copy(self) -> "AnalyticMaterial":
        return AnalyticMaterial(
            self.name,
            self.combination,
            self.n_channels,
            [Lobe(l.model, dict(l.params), list(l.scale), l.channel, list(l.extra), l.source) for l in self.lobes],
            list(self.extra),
            self.source,
        )

    def describe(self) -> dict:
        return {
            "type": self.kind,
            "name": self.name,
            "combination": self.combination,
            "channels": self.n_channels,
            "isotropic": self.isotropic,
            "domain": "every pair of directions above the surface",
            "lobes": [
                {"model": l.model.name, "parameters": dict(l.params), "scale": list(l.scale), "channel": l.channel}
                for l in self.lobes
            ],
        }
