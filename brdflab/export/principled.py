"""Any source as Disney's principled parameters, for the renderers that speak that family.

A material that is one Principled lobe with unit scales goes out exactly. Anything else (other
lobes, a measured table, a stored fit of other lobes) is fitted to Principled on the way out
with the lab's fitter and the error that costs is said: the fit's Ngan error, and that error
relative to the source's own size (the error of a zero BRDF).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.models import get_model
from brdflab.models.principled import CHANNELS, MIN_SPECULAR, specular_eta, tint


@dataclass
class PrincipledExport:
    """The parameters an exporter writes, how they were reached, and what they cost."""

    params: dict[str, float]
    exact: bool
    error: float = 0.0  # Ngan RMSE of the principled material against the source
    relative_error: float = 0.0  # error / the source's own Ngan size
    warnings: list[str] = field(default_factory=list)

    @property
    def base_color(self) -> list[float]:
        return [self.params[f"base_color_{c}"] for c in CHANNELS]

    @property
    def eta(self) -> float:
        """The specular IOR the exports write, η(max(specular, MIN_SPECULAR))."""
        return float(specular_eta(max(self.params["specular"], MIN_SPECULAR)))

    def tinted(self, amount: str) -> np.ndarray:
        """White blended towards the base colour's hue by parameter `amount` (specular_tint, sheen_tint)."""
        return 1.0 + self.params[amount] * (tint(np.array(self.base_color)) - 1.0)

    def material(self, name: str = "principled") -> AnalyticMaterial:
        return AnalyticMaterial(name, "Linear", 3, [Lobe(get_model("Principled"), dict(self.params), [1.0, 1.0, 1.0])])


def exact_principled(source) -> dict[str, float] | None:
    """The parameters of a material that is one Principled lobe with unit scales, else None."""
    if not isinstance(source, AnalyticMaterial) or len(source.lobes) != 1:
        return None
    lobe = source.lobes[0]
    if lobe.model.name != "Principled" or not np.allclose(lobe.scale, 1.0, rtol=0, atol=1e-12):
        return None
    return dict(lobe.params)


def as_principled(source, fmt: str, cancel=None) -> PrincipledExport:
    """`source` as principled parameters for an export to `fmt` (a name for the warnings);
    `cancel` (an Event) stops the fit on the way out."""
    params = exact_principled(source)
    if params is not None:
        return PrincipledExport(params, exact=True)
    from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
    from brdflab.fitting.samples import samples_of

    samples = samples_of(source)
    result = fit(material_from_lobes(["Principled"], "Linear", samples.n_channels), samples, FitOptions(), cancel=cancel)
    relative = result.error / result.zero_error if result.zero_error > 0 else 0.0
    what = "measured data" if not isinstance(source, AnalyticMaterial) else (
        "+".join(l.model.name for l in source.lobes) + " lobes")
    warning = (f"{fmt}: the source ({what}) is not a principled material; it was fitted to Principled on the way "
               f"out: Ngan error {result.error:.4g}, {100 * relative:.1f} % of the source's own size (a black BRDF's error)")
    return PrincipledExport(dict(result.material.lobes[0].params), exact=False, error=result.error,
                            relative_error=relative, warnings=[warning])


def dropped_error(export: PrincipledExport, neutral: dict[str, float]) -> tuple[float, float]:
    """What a format loses by writing `neutral` values for parameters it cannot carry: the
    Ngan error (and its relative size) of the principled material with those values against
    the material with them, over the lab's analytic sample grid."""
    from brdflab.fitting.metrics import metric_errors
    from brdflab.fitting.samples import samples_of

    full = export.material()
    reduced = AnalyticMaterial("reduced", "Linear", 3, [Lobe(full.lobes[0].model, {**export.params, **neutral}, [1.0] * 3)])
    samples = samples_of(full)
    error, zero = metric_errors([reduced, None], samples, "Ngan")  # the grid's values are the full material's
    return error, (error / zero if zero > 0 else 0.0)
