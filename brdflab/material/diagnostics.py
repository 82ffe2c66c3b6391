"""What is wrong with a material, in words a user can act on: parameters pinned at their
bounds (a fit that wanted to go further), and energy that is not conserved."""

from __future__ import annotations

from brdflab.material.analytic import AnalyticMaterial

BOUND_TOLERANCE = 1e-6  # relative to the parameter's range


def parameters_at_bounds(material: AnalyticMaterial) -> list[str]:
    """'lobe 2 Ward: ax = 0.001 (its lower bound)' for each parameter sitting on a bound."""
    found = []
    for k, lobe in enumerate(material.lobes):
        for p in lobe.model.parameters:
            value = lobe.params[p.name]
            span = (p.upper - p.lower) * BOUND_TOLERANCE
            for bound, name in ((p.lower, "lower"), (p.upper, "upper")):
                if abs(value - bound) <= span:
                    found.append(f"lobe {k} {lobe.model.name}: {p.name} = {value:.4g} (its {name} bound)")
    return found


def energy_words(conserves: bool, max_albedo: list[float]) -> str | None:
    """None when albedo ≤ 1 for every view; else what is violated and by how much."""
    if conserves:
        return None
    worst = max(max_albedo)
    return f"albedo up to {worst:.3g} > 1 (it reflects more light than it receives)"
