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


@dataclass
class Lobe:
    """One lobe of a material: a model, its parameters and its weight(s)."""

    model: LobeModel
    params: dict[str, float]
    scale: list[float]  # Linear: one factor per channel; Fixed: [value]
    channel: int | None = None  # Fixed only
    extra: list = field(default_factory=list)  # unknown XML children, kept verbatim

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

    def values(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        return self.model.evaluate(wi, wo, self.params)


@dataclass
class AnalyticMaterial:
    """A material made of analytic lobes; evaluates to (N, n_channels) BRDF values."""

    name: str = "material"
    combination: Combination = "Linear"
    n_channels: int = 3
    lobes: list[Lobe] = field(default_factory=list)
    extra: list = field(default_factory=list)  # unknown XML children of <Material>

    kind = "Analytic"

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

    def evaluate(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """BRDF values of every channel, shape (N, n_channels), in 1/sr."""
        wi = np.asarray(wi, float)
        wo = np.asarray(wo, float)
        shape = np.broadcast_shapes(wi.shape[:-1], wo.shape[:-1])
        out = np.zeros(shape + (self.n_channels,))
        for lobe in self.lobes:
            v = lobe.values(wi, wo)
            if self.combination == "Linear":
                out += v[..., None] * np.asarray(lobe.scale)
            else:
                out[..., lobe.channel] += lobe.scale[0] * v
        return out

    def copy(self) -> "AnalyticMaterial":
        return AnalyticMaterial(
            self.name,
            self.combination,
            self.n_channels,
            [Lobe(l.model, dict(l.params), list(l.scale), l.channel, list(l.extra)) for l in self.lobes],
            list(self.extra),
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
