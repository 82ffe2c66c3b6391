"""Why a fit's result may be suspect, in words a user can act on: parameters that ended
on a bound of their range, Fixed values at the material cap, and energy violations (albedo
above 1)."""

from __future__ import annotations

from brdflab.material.albedo import energy_check
from brdflab.material.analytic import MAX_SCALE, AnalyticMaterial

BOUND_TOLERANCE = 1e-4  # of the parameter's range (of its logarithm for log-scale parameters)
AT_CAP = 0.9  # a Fixed value above this fraction of MAX_SCALE is near the cap (the fitter starts over-cap values at 0.99)


def at_bound(value: float, lower: float, upper: float, log: bool) -> str | None:
    """'lower' or 'upper' when `value` sits on that bound: within BOUND_TOLERANCE of the
    range on the scale the fitter searches (logarithmic for log-scale parameters)."""
    from brdflab.fitting.lm import Bounded  # the fitter's own parametrisation (lm imports this module)

    t = Bounded(lower, upper, log).position(value)
    if t <= BOUND_TOLERANCE:
        return "lower"
    if t >= 1.0 - BOUND_TOLERANCE:
        return "upper"
    return None


def bound_warnings(material: AnalyticMaterial, at_default: bool = True) -> list[str]:
    """One line per lobe parameter on a bound (scale-invariant directions excluded), and per
    Fixed value at the material cap. at_default=False leaves out a parameter that is at its
    model's default (a designed material: Disney's metallic = 0 is a choice, not a symptom)."""
    out = []
    for k, lobe in enumerate(material.lobes):
        for p in ([] if lobe.model.weights_on_bounds else lobe.model.parameters):
            if p.name in lobe.model.scale_invariant or not p.fitted or p.lower == p.upper:
                continue  # a switch (a file's bool) sits on a bound by design
            if not at_default and lobe.params[p.name] == p.default:
                continue
            side = at_bound(lobe.params[p.name], p.lower, p.upper, p.log)
            if side is not None:
                bound = p.lower if side == "lower" else p.upper
                out.append(f"lobe {k} ({lobe.model.name}) {p.name} = {lobe.params[p.name]:.6g} is on its {side} bound {bound:g}")
        if material.combination == "Fixed" and lobe.scale[0] >= AT_CAP * MAX_SCALE:
            out.append(f"lobe {k} ({lobe.model.name}) value = {lobe.scale[0]:.6g} is near the material cap {MAX_SCALE:g}, "
                       "the most a material may hold: typically a lobe switched off, or one whose shape vanishes")
    return out


def energy_words(conserves: bool, max_albedo) -> str | None:
    """None when albedo ≤ 1 for every view; else what is violated and by how much (also for
    energy checks run elsewhere, e.g. the window's worker process)."""
    if conserves:
        return None
    return f"albedo up to {above_one(max(float(a) for a in max_albedo))} > 1 (reflects more light than it receives)"


def above_one(albedo: float) -> str:
    """An albedo above 1 with the digits that show it is (1.003, not "1")."""
    for digits in range(3, 10):
        text = f"{albedo:.{digits}g}"
        if float(text) > 1.0:
            return text
    return f"{albedo:.10g}"


def energy_warnings(material: AnalyticMaterial) -> list[str]:
    """A line when some channel reflects more than it receives (albedo > 1)."""
    report = energy_check(material)
    words = energy_words(bool(report.conserves), report.max_albedo)
    return [words] if words else []


def suspicions(material: AnalyticMaterial) -> list[str]:
    """Everything that makes a fitted material suspect (empty: nothing found)."""
    return bound_warnings(material) + energy_warnings(material)
