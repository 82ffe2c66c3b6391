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
from brdflab.models.principled import CHANNELS, MIN_SPECULAR, alphas, specular_eta, tint

DISNEY_ANISOTROPY = 0.9  # Disney's (and Mitsuba's) roughness aspect is √(1 − 0.9 a)
LOSS_SAID = 5e-4  # a loss below 0.05 % of the material is not said (it would read "0.0 %")


@dataclass
class PrincipledExport:
    """The parameters an exporter writes, how they were reached, and what they cost."""

    params: dict[str, float]
    exact: bool
    error: float = 0.0  # Ngan RMSE of the principled material against the source
    relative_error: float = 0.0  # error / the source's own Ngan size
    warnings: list[str] = field(default_factory=list)
    fitted_now: bool = False  # fitted on the way out by this export (not exact, not read from the cache)
    _grid: object = field(default=None, init=False, repr=False, compare=False)

    @property
    def base_color(self) -> list[float]:
        return [self.params[f"base_color_{c}"] for c in CHANNELS]

    def ior(self, f0_scale: float = 1.0) -> float:
        """The specular IOR the exports write: η(max(specular, MIN_SPECULAR)), or with
        `f0_scale` the IOR of that normal-incidence reflectance times f0_scale."""
        return float(specular_eta(max(self.params["specular"], MIN_SPECULAR) * f0_scale))

    def tinted(self, amount: str) -> np.ndarray:
        """White blended towards the base colour's hue by parameter `amount` (specular_tint, sheen_tint)."""
        return 1.0 + self.params[amount] * (tint(np.array(self.base_color)) - 1.0)

    def sheen_in_range(self) -> float:
        """The sheen the formats write: at most 1 / the sheen tint's largest channel, so that the
        sheen's colour, sheen × its tint (up to 4.7 for a saturated red), stays within [0, 1]."""
        return min(self.params["sheen"], 1.0 / float(self.tinted("sheen_tint").max()))

    def aspect(self) -> float:
        """αy / αx of the main lobe: √(1 − 0.9 a)² = 1 − 0.9 a (Disney's and Mitsuba's aspect)."""
        return 1.0 - DISNEY_ANISOTROPY * self.params["anisotropic"]

    def material(self, name: str = "principled") -> AnalyticMaterial:
        return AnalyticMaterial(name, "Linear", 3, [Lobe(get_model("Principled"), dict(self.params), [1.0, 1.0, 1.0])])

    def grid(self):
        """The lab's analytic sample grid of this material, built once for all the losses an
        export weighs (a grid of Principled is seconds; an export weighed four losses, each on its own)."""
        if self._grid is None:
            from brdflab.fitting.samples import samples_of

            self._grid = samples_of(self.material())
        return self._grid


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
    from brdflab.fitting.fit_cache import fit_once
    from brdflab.fitting.lm import material_from_lobes
    from brdflab.fitting.samples import samples_of
    from brdflab.fitting.second_error import describe, second_error

    samples = samples_of(source)
    result, cached = fit_once(material_from_lobes(["Principled"], "Linear", samples.n_channels), samples, cancel=cancel,
                              second=lambda r: second_error(r.material, source, samples))
    relative = result.error / result.zero_error if result.zero_error > 0 else 0.0
    what = "measured data" if not isinstance(source, AnalyticMaterial) else (
        "+".join(l.model.name for l in source.lobes) + " lobes")
    when = "fitted to Principled by an earlier export (read from the cache)" if cached else \
        "fitted to Principled on the way out"
    warning = (f"{fmt}: the source ({what}) is not a principled material; it was {when}: "
               f"Ngan error {result.error:.4g}, {100 * relative:.1f} % of the source's own size (a black BRDF's error)"
               + (f"; {describe(result.second)}" if result.second else ""))
    return PrincipledExport(dict(result.material.lobes[0].params), exact=False, error=result.error,
                            relative_error=relative, warnings=[warning], fitted_now=not cached)


LOSSES = "export_losses"  # the user cache's folder of weighed losses


def dropped_error(export: PrincipledExport, neutral: dict[str, float]) -> tuple[float, float]:
    """What a format loses by writing `neutral` values for parameters it cannot carry: the
    Ngan error (and its relative size) of the principled material with those values against
    the material with them, over the lab's analytic sample grid. Weighed once per parameters
    and kept in the user's cache: a second export of a source (any format) weighed its losses
    again, 4–9 s of a 10 s export whose fit came from the cache (issue 35, goal 4)."""
    from brdflab.fitting.fit_cache import CODE
    from brdflab.io.user_cache import code_digest, entry_key, read_entry, write_entry

    # what decides a loss: the code a fit runs (the metric, the model) and this module
    key = entry_key({"params": sorted(export.params.items()), "neutral": sorted(neutral.items()),
                     "code": code_digest(*CODE, "export/principled.py")})
    kept = read_entry(LOSSES, key)
    if kept is not None and _finite_pair(kept.get("loss")):
        return tuple(kept["loss"])
    from brdflab.fitting.metrics import metric_errors

    reduced = AnalyticMaterial("reduced", "Linear", 3, [Lobe(get_model("Principled"), {**export.params, **neutral}, [1.0] * 3)])
    error, zero = metric_errors([reduced, None], export.grid(), "Ngan")  # the grid's values are the full material's
    loss = (error, error / zero if zero > 0 else 0.0)
    write_entry(LOSSES, key, {"loss": list(loss)})
    return loss


def _finite_pair(value) -> bool:
    return (isinstance(value, list) and len(value) == 2 and all(isinstance(v, float) for v in value)
            and all(np.isfinite(value)))


def loss_warnings(export: PrincipledExport, neutral: dict[str, float], what: str) -> list[str]:
    """`what: Ngan E (R % of the material)`, the cost of writing `neutral` values in place of
    the material's own (see `dropped_error`), or nothing where that is below LOSS_SAID."""
    error, relative = dropped_error(export, neutral)
    return [f"{what}: Ngan {error:.4g} ({100 * relative:.1f} % of the material)"] if relative >= LOSS_SAID else []


def approximation_warnings(export: PrincipledExport, fmt: str, subsurface: str, coat: str, sheen: str) -> list[str]:
    """What a format loses of the lobes it cannot carry exactly, each said in the format's own
    words (`subsurface`, `coat`, `sheen`) with its cost, only where the material has that lobe;
    and what keeping the sheen's colour in range costs."""
    p = export.params
    warnings = []
    if p["subsurface"] > 0.0:
        warnings += loss_warnings(export, {"subsurface": 0.0}, f"{fmt}: {subsurface}")
    if p["clearcoat"] > 0.0:
        warnings += loss_warnings(export, {"clearcoat": 0.0}, f"{fmt}: {coat}; the whole coat")
    if p["sheen"] > 0.0:
        warnings += loss_warnings(export, {"sheen": 0.0}, f"{fmt}: {sheen}; the whole sheen")
        warnings += sheen_range_warnings(export, fmt)
    return warnings


def sheen_range_warnings(export: PrincipledExport, fmt: str) -> list[str]:
    """What keeping the sheen's colour within [0, 1] costs (`sheen_in_range`), if anything."""
    sheen, written = export.params["sheen"], export.sheen_in_range()
    if written >= sheen:
        return []
    return loss_warnings(export, {"sheen": written}, f"{fmt}: the sheen's colour (sheen × its tint) reaches "
                         f"{sheen / written:.3g}, above the format's 0–1: written at sheen {written:.3g} "
                         f"instead of {sheen:.3g}, hue kept")


def stretch_warnings(export: PrincipledExport, what: str) -> list[str]:
    """What holding αx at 1 costs (glTF's and Standard Surface's most; Disney's has none),
    if anything: the lobe written is Disney's (αx, αy) = (1, αy), roughness αy^¼ and
    anisotropic (1 − αy) / 0.9 (within 0–1: αx / αy ≤ 10, so αy > 0.1 wherever αx > 1)."""
    ax, ay = (float(v) for v in alphas(export.params["roughness"], export.params["anisotropic"]))
    if ax <= 1.0:
        return []
    return loss_warnings(export, {"roughness": ay ** 0.25, "anisotropic": (1.0 - ay) / DISNEY_ANISOTROPY},
                         f"{what}: αx = {ax:.3g} along the tangent is held at the format's 1 (a rough, strongly "
                         "anisotropic lobe)")
