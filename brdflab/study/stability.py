"""Study part `stability`: where Levenberg–Marquardt fails, over material × model × start.

For each (material, model) — a Lambertian plus one lobe of the model, Linear — the fit is
run from the model's default start, from each of its model-aware restarts
(`lm.restart_guesses`) and from `RANDOM_STARTS` random starts in the parameter bounds, each
start alone (no restarts, no coarse stage) on the same stratified subset of the slice.
Per cell: the fraction of starts that end within 1 % of the best error any start found,
the spread (median/best and worst/best), whether the fitter's own strategy (default start
plus restarts, what `brdflab fit` does) reaches the best, and how many of the starts that
miss end with a parameter on a bound of its range.
"""

from __future__ import annotations

import textwrap
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

from brdflab.fitting.lm import material_from_lobes, restart_guesses
from brdflab.models import get_model, model_names
from brdflab.study.fit_jobs import FitJob, random_start, register_source, run_job
from brdflab.study.fitting import shared_slices
from brdflab.study.framework import Part, StudyContext, pyplot, register, save_figure
from brdflab.study.workers import core_count, run_jobs

RANDOM_STARTS = 20
QUICK_RANDOM_STARTS = 6
SUBSET = 10_000
QUICK_SUBSET = 5_000
WITHIN = 0.01  # "reached the best": error ≤ (1 + WITHIN) · best
# diffuse, paint, plastics, metallic paint, metals (the two where Cook–Torrance ends on F0 = 1)
MATERIALS = ("blue-fabric", "dark-red-paint", "red-specular-plastic", "specular-black-phenolic",
             "gold-metallic-paint3", "nickel", "tungsten-carbide", "grease-covered-steel")
QUICK_MODELS = ("BlinnPhong", "CookTorrance", "Ward")
SEED = 17


def starts_of(model_name: str, random_starts: int, rng: np.random.Generator) -> list[tuple[str, tuple]]:
    """(kind, parameter values) of every start: the default, the model-aware restarts,
    then random starts in bounds."""
    base = material_from_lobes(["Lambertian", model_name], "Linear", 3)
    lobe = lambda m: m.lobes[-1].params  # noqa: E731  (the model's lobe, after the Lambertian)
    starts = [("default", tuple(lobe(base).items()))]
    starts += [("restart", tuple(lobe(g).items())) for g in restart_guesses(base)]
    model = get_model(model_name)
    return starts + [("random", random_start(model, rng)) for _ in range(random_starts)]


def cell_summary(errors: list, kinds: list[str], on_bound: list[bool]) -> dict:
    """The numbers of one (material, model) cell from the errors its starts reached (None:
    the fit could not run from that start; it counts as a miss)."""
    errors = np.array([np.inf if e is None else e for e in errors], float)
    finite = errors[np.isfinite(errors)]
    best = float(finite.min()) if finite.size else np.inf
    reached = errors <= (1.0 + WITHIN) * best
    own = np.array([k in ("default", "restart") for k in kinds])
    missed = ~reached
    median = float(np.median(errors))
    ratio = lambda x: float(x / best) if np.isfinite(x) and 0 < best < np.inf else None  # noqa: E731
    return {"starts": int(errors.size), "failed": int(errors.size - finite.size),
            "best": best if finite.size else None, "fraction_within": float(reached.mean()),
            "random_fraction_within": float(reached[~own].mean()) if (~own).any() else None,
            "median_over_best": ratio(median), "worst_over_best": ratio(finite.max()) if finite.size else None,
            "default_reaches": bool(reached[0]), "fitter_reaches": bool(reached[own].any()),
            "missed": int(missed.sum()), "missed_on_bound": int((missed & np.asarray(on_bound, bool)).sum())}


def measure(context: StudyContext) -> dict:
    rng = np.random.default_rng(SEED)
    random_starts = QUICK_RANDOM_STARTS if context.quick else RANDOM_STARTS
    subset = QUICK_SUBSET if context.quick else SUBSET
    if context.source is not None:
        name = getattr(context.source, "name", None) or "current source"
        sources = {name: register_source("current source", context.source)}
        workers = 1
    else:
        paths = shared_slices(context)
        sources = {m: paths[m] for m in MATERIALS if m in paths} if not context.quick else paths
        workers = core_count()
    models = list(QUICK_MODELS) if context.quick or context.source is not None else \
        [m for m in model_names() if m != "Lambertian"]
    clock = "wall" if workers == 1 else "cpu"
    jobs = [FitJob(path, (model,), "Linear", subset, seed=SEED, start=start, restarts=False, coarse=False,
                   score_all=False, clock=clock,
                   tag={"material": material, "model": model, "kind": kind, "start": dict(start)})
            for material, path in sources.items() for model in models
            for kind, start in starts_of(model, random_starts, rng)]
    started = time.time()

    def progress(done: int, total: int) -> None:
        if done % max(1, total // 20) == 0 or done == total:
            context.progress(f"stability: {done}/{total} fits, {time.time() - started:.0f} s")

    rows = run_jobs(run_job, jobs, workers, progress, context.cancelled)
    cells = defaultdict(list)
    for r in rows:
        cells[(r["material"], r["model"])].append(r)
    summary = [{"material": m, "model": mo, **cell_summary([r["error_fitted"] for r in rs], [r["kind"] for r in rs],
                                                           [bool(r["on_bound"]) for r in rs])}
               for (m, mo), rs in cells.items()]
    slim = [{k: r[k] for k in ("material", "model", "kind", "start", "error_fitted", "seconds", "iterations",
                               "status", "on_bound")} for r in rows]
    return {"subset": subset, "random_starts": random_starts, "within": WITHIN, "clock": clock,
            "materials": list(sources), "models": models, "wall_s": time.time() - started,
            "cells": summary, "caption": caption(summary, slim), "rows": slim}


def _reached(rows: list[dict]) -> list[bool]:
    """Whether each row's start reached within WITHIN of its cell's best."""
    best: dict[tuple, float] = {}
    for r in rows:
        if r["error_fitted"] is not None:
            key = (r["material"], r["model"])
            best[key] = min(best.get(key, np.inf), r["error_fitted"])
    return [r["error_fitted"] is not None and r["error_fitted"] <= (1 + WITHIN) * best[(r["material"], r["model"])]
            for r in rows]


def why(model: str, rows: list[dict], reached: list[bool]) -> str:
    """Why the starts of one model miss: the bounds they end on, or (a scale-invariant
    direction, Lafortune's C) the sign of the start's first direction component."""
    mine = [(r, hit) for r, hit in zip(rows, reached) if r["model"] == model]
    misses = [r for r, hit in mine if not hit]
    if not misses:
        return f"{model}: no start missed"
    bounds = Counter(b for r in misses for b in r["on_bound"])
    on_bound = sum(bool(r["on_bound"]) for r in misses)
    text = f"{model}: {on_bound} of {len(misses)} misses end on a bound"
    if bounds:
        text += " (" + ", ".join(f"{b} ×{n}" for b, n in bounds.most_common(3)) + ")"
    group = get_model(model).scale_invariant
    if group and on_bound < len(misses) / 2:
        axis = group[0]
        split = {sign: [hit for r, hit in mine if (r["start"][axis] >= 0) == sign] for sign in (True, False)}
        text += (f"; starts with {axis} ≥ 0 (a retro-reflective or vanishing lobe) reach the best in "
                 f"{sum(split[True])} of {len(split[True])}, with {axis} < 0 in {sum(split[False])} of "
                 f"{len(split[False])}: LM keeps the sign it starts with (the lobe is 0 between the two)")
    defaults = [hit for r, hit in mine if r["kind"] == "default"]
    return text + f"; the default start reaches it on {sum(defaults)} of {len(defaults)} materials"


def caption(cells: list[dict], rows: list[dict]) -> str:
    """Where LM breaks and why, in words, from the cells and their fits."""
    if not cells:
        return "no fits finished"
    by_model, by_material = defaultdict(list), defaultdict(list)
    for c in cells:
        by_model[c["model"]].append(c["fraction_within"])
        by_material[c["material"]].append(c["fraction_within"])
    worst_models = sorted(by_model, key=lambda m: np.mean(by_model[m]))[:4]
    worst_materials = sorted(by_material, key=lambda m: np.mean(by_material[m]))[:3]
    reached = _reached(rows)
    fitter_misses = [f"{c['model']} on {c['material']}" for c in cells if not c["fitter_reaches"]]
    text = (f"LM breaks most for {', '.join(f'{m} ({np.mean(by_model[m]):.0%})' for m in worst_models)} "
            f"and on {', '.join(f'{m} ({np.mean(by_material[m]):.0%})' for m in worst_materials)} "
            f"(mean fraction of starts within {WITHIN:.0%} of the best). Why — "
            + ". ".join(why(m, rows, reached) for m in worst_models)
            + ". Bounds: see docs/fitting.md ('Exponent on a bound', F0 = 1 in 'Cook–Torrance against Lafortune'). ")
    if fitter_misses:
        text += (f"The fitter's own default + restarts miss the best in {len(fitter_misses)} of {len(cells)} "
                 f"cells: {', '.join(fitter_misses[:6])}{' …' if len(fitter_misses) > 6 else ''}.")
    else:
        text += f"The fitter's own default + restarts reach the best in all {len(cells)} cells."
    return text


def _grid(cells: list[dict], key: str, materials: list[str], models: list[str]) -> np.ndarray:
    grid = np.full((len(models), len(materials)), np.nan)
    for c in cells:
        if c[key] is not None:
            grid[models.index(c["model"]), materials.index(c["material"])] = c[key]
    return grid


def draw(numbers: dict, out_dir: Path) -> list[str]:
    cells = numbers["cells"]
    if not cells:
        return []
    plt = pyplot()
    materials = [m for m in numbers["materials"] if any(c["material"] == m for c in cells)]
    models = [m for m in numbers["models"] if any(c["model"] == m for c in cells)]
    width = max(10.0, 1.1 * len(materials) * 2 + 4)
    fig, axes = plt.subplots(1, 2, figsize=(width, 0.42 * len(models) + 4.2), dpi=100)
    panels = ((axes[0], _grid(cells, "fraction_within", materials, models), "viridis", (0, 1),
               f"fraction of starts within {numbers['within']:.0%} of the best", "{:.0%}"),
              (axes[1], np.log10(_grid(cells, "worst_over_best", materials, models)), "magma_r", None,
               "spread: log10(worst / best); label: median / best", None))
    medians = _grid(cells, "median_over_best", materials, models)
    misses = _grid(cells, "fitter_reaches", materials, models)
    for ax, grid, cmap, limits, title, fmt in panels:
        image = ax.imshow(grid, cmap=cmap, aspect="auto", vmin=None if limits is None else limits[0],
                          vmax=None if limits is None else limits[1])
        fig.colorbar(image, ax=ax, fraction=0.04, pad=0.02)
        for i in range(len(models)):
            for j in range(len(materials)):
                if np.isnan(grid[i, j]):
                    continue
                text = fmt.format(grid[i, j]) if fmt else f"{medians[i, j]:.2f}"
                dark = grid[i, j] < 0.5 if limits else grid[i, j] > 0.6 * max(np.nanmax(grid), 1e-9)
                ax.text(j, i, text, ha="center", va="center", fontsize=6.5, color="white" if dark else "black")
                if fmt and misses[i, j] == 0:
                    ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, ec="red", lw=1.6))
        ax.set_xticks(range(len(materials)), materials, rotation=40, ha="right", fontsize=7)
        ax.set_yticks(range(len(models)), models, fontsize=7)
        ax.set_title(title, fontsize=9)
    axes[0].set_xlabel("red frame: the fitter's default + restarts miss the best", fontsize=7, color="red")
    fig.suptitle(f"LM stability: Lambertian + one lobe (Linear, Ngan) from the default, the restarts and "
                 f"{numbers['random_starts']} random starts, {numbers['subset']:,} samples", fontsize=10)
    lines = textwrap.wrap(numbers["caption"], int(width * 14))
    fig.text(0.01, 0.01, "\n".join(lines), fontsize=7.5, va="bottom")
    fig.tight_layout(rect=(0, (0.16 * len(lines) + 0.2) / fig.get_figheight(), 1, 0.96))
    return [save_figure(fig, out_dir / "stability_lm.png")]


register(Part("stability", "stability: LM over material × model × start (default, restarts, random)", measure, draw,
              lesson="Ward, Phong, Oren–Nayar and the diffuse lobes reach their best from every start; "
                     "Lafortune from about half (a start whose lobe points back, Cxy ≥ 0, stays there and the lobe "
                     "dies), Schwenk and Strauss from 40–60 % (parameters run onto their bounds). The model-aware "
                     "restarts are what make the default fit reach the best (docs/study.md)."))
