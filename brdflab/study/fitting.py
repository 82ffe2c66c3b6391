"""Study part `fitting`: the fit's error against its time, for every registry model
with one and two lobes (after a Lambertian), Linear and Fixed, fitted on all samples and
on stratified subsets, on the shared MERL slices.

The error is always the Ngan metric of the result on ALL samples of the source, whatever
the fit saw; the time is the fit's CPU time in a one-thread worker (wall time in a scoped
run, `fit_jobs.run_job`), with the fitter's defaults: restarts on a 60,000-sample coarse
subset, then a polish on the fitted set.

The full matrix (`FULL`: 62 families — the Lambertian alone, every other model with one and
two lobes, Linear and Fixed — at 5 k, 20 k, 50 k, 200 k and all samples on each of the 31
slices: 9,610 fits of up to three CPU minutes each, 12.8 CPU-hours measured, docs/study.md) takes
longer than one sitting on a small machine, so the part resumes: every finished fit is
appended to a journal in the output folder, and a later run into the same folder
(`earlier_rows`) fits only what is missing; `brdflab study --stop-after MINUTES` stops
starting fits and draws the charts from what is done. Fits run slice by slice, so a
stopped run leaves whole materials.

Smaller matrices fit two tiers (`design`):
- core: on every slice, on a `core_size` subset, every family (`every_family_core`) or every
  model with one lobe and the Lambertian alone, Linear (the quick and scoped runs);
- sampled: every family at every size of `sizes` (Linear) or `fixed_sizes` (Fixed), all
  samples included, on `per_model` slices (None: all); all families of a model share their
  slices (a material's chart shows that model's whole story: lobes, combination, subset
  curve), and the models' slices spread evenly over the sorted list.
A scoped run (the GUI's current source) fits a small matrix on that source alone.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

from brdflab.errors import BRDFLabError
from brdflab.models import model_names
from brdflab.study.fit_jobs import FitJob, register_source, run_job
from brdflab.study.fitting_charts import LESSON, draw, summarise
from brdflab.study.framework import Part, StudyContext, earlier_rows, journal_writer, register
from brdflab.study.workers import core_count, run_jobs

QUICK_SLICES = ("blue-fabric", "nickel")


@dataclass(frozen=True)
class Matrix:
    """What one run fits (sizes: samples fitted, None for all)."""

    models: tuple[str, ...]
    core_size: int | None
    sizes: tuple[int | None, ...]  # the sampled tier's Linear families
    fixed_sizes: tuple[int | None, ...]  # its Fixed families
    per_model: int | None = 1  # None: every slice
    two_fixed: bool = True  # Fixed with two lobes (3 × 2 per-channel lobes)
    every_family_core: bool = False  # every family on every slice (else one lobe, Linear)

    def is_core(self, family: "Family") -> bool:
        """Whether the family is fitted on every slice at `core_size`."""
        return self.every_family_core or family.basic


# the full run: every family at every size on every slice (9,610 fits, docs/study.md)
FULL = Matrix(tuple(model_names()), 20_000, (5_000, 20_000, 50_000, 200_000, None),
              (5_000, 20_000, 50_000, 200_000, None), per_model=None, every_family_core=True)
QUICK = Matrix(("Lambertian", "BlinnPhong", "Ward"), 10_000, (2_000, 10_000, None), (2_000, 10_000))
SCOPED = Matrix(("Lambertian", "BlinnPhong", "CookTorrance", "Ward", "LafortuneIso"), None,
                (5_000, 50_000, None), (50_000,), two_fixed=False)
SCOPED_QUICK = Matrix(("Lambertian", "BlinnPhong", "CookTorrance"), None, (5_000, None), (20_000,), two_fixed=False)


@dataclass(frozen=True)
class Family:
    """A lobe configuration: `model` after a Lambertian `lobes` times (0: Lambertian alone)."""

    model: str
    lobes: int
    combination: str

    @property
    def lobe_names(self) -> tuple[str, ...]:
        return (self.model,) * self.lobes

    @property
    def basic(self) -> bool:
        """One lobe (or the Lambertian alone), Linear: the families every run fits everywhere."""
        return self.lobes <= 1 and self.combination == "Linear"

    @property
    def label(self) -> str:
        name = "Lambertian" if self.lobes == 0 else f"{self.lobes}×{self.model}"
        return f"{name} {self.combination}"


def families(models: list[str]) -> list[Family]:
    """The Lambertian alone, then every model with one and two lobes, Linear and Fixed (a
    model that carries its own magnitude and colour, Principled, Linear only: a fit refuses it
    in a Fixed material)."""
    from brdflab.models import get_model

    out = [Family("Lambertian", 0, c) for c in ("Linear", "Fixed")]
    return out + [Family(m, n, c) for m in models if m != "Lambertian" for n in (1, 2)
                  for c in (("Linear", "Fixed") if get_model(m).scaled else ("Linear",))]


def design(slices: list[str], matrix: Matrix) -> list[tuple[str, Family, int | None]]:
    """(slice, family, size or None for all samples) of every fit, without repeats: the
    matrix's core families on every slice at `core_size`; every family at each of its sizes on
    `per_model` slices, the same for all families of a model (the models' first slices
    spread evenly over the list, the others len/per_model apart)."""
    plan: dict[tuple, None] = {}
    fams = [f for f in families(list(matrix.models)) if matrix.two_fixed or (f.lobes, f.combination) != (2, "Fixed")]
    for family in fams:
        if matrix.is_core(family):
            for s in slices:
                plan[(s, family, matrix.core_size)] = None
    per_model = len(slices) if matrix.per_model is None else min(matrix.per_model, len(slices))
    stride = max(1, len(slices) // max(1, per_model))
    model_order = list(dict.fromkeys(f.model for f in fams))
    for family in fams:  # a model's families share slices: its whole story on one material
        first = model_order.index(family.model) * len(slices) // len(model_order)
        chosen = {slices[(first + j * stride) % len(slices)] for j in range(per_model)}
        for s in sorted(chosen):
            for size in matrix.sizes if family.combination == "Linear" else matrix.fixed_sizes:
                plan[(s, family, size)] = None
    return list(plan)


def shared_slices(context: StudyContext) -> dict[str, str]:
    """Material name → slice path of the shared MERL slices (quick: a few)."""
    from brdflab.io.resources import shared_data_dir

    data = shared_data_dir()
    folder = data / "merl_slices" if data is not None else None
    if folder is None or not folder.is_dir():
        raise BRDFLabError("the fitting study needs the shared MERL slices: set BRDFLAB_SHARED, "
                           "or put shared/data next to the checkout (or scope it to a source)")
    paths = {p.stem: str(p) for p in sorted(folder.glob("*.slice"))}
    if context.quick:
        paths = {k: paths[k] for k in QUICK_SLICES if k in paths}
    if not paths:
        raise BRDFLabError(f"no MERL slices in {folder}")
    return paths


def _expected_cost(job: FitJob) -> float:
    """A rough relative cost, to start a slice's longest fits first (the pool then balances)."""
    samples = 1_100_000 if job.size is None else job.size
    fixed = 3 if job.combination == "Fixed" else 1
    return (len(job.lobes) + 1) * fixed * (60_000 + samples)


def _load_average() -> float | None:
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:
        return None


def measure(context: StudyContext) -> dict:
    source = context.source
    if source is not None:
        key = register_source("current source", source)
        slices = {getattr(source, "name", None) or "current source": key}
        matrix = SCOPED_QUICK if context.quick else SCOPED
        workers = 1  # in memory: this process only
    else:
        slices = shared_slices(context)
        matrix = QUICK if context.quick else FULL
        workers = core_count()
    plan = design(list(slices), matrix)
    clock = "wall" if workers == 1 else "cpu"
    jobs = [FitJob(slices[s], f.lobe_names, f.combination, size, clock=clock,
                   tag={"material": s, "model": f.model, "lobes_count": f.lobes, "family": f.label,
                        "size": size, "core": matrix.is_core(f) and size == matrix.core_size})
            for s, f, size in plan]
    # a scoped run's source lives in this process only: nothing of it to resume
    earlier = {_key(r): r for r in earlier_rows(context, "fitting")} if source is None else {}
    kept = [{**earlier[_key(j.tag)], **j.tag} for j in jobs if _key(j.tag) in earlier]
    order = {s: k for k, s in enumerate(slices)}  # slice by slice, a slice's longest fits first
    todo = sorted((j for j in jobs if _key(j.tag) not in earlier),
                  key=lambda j: (order[j.tag["material"]], -_expected_cost(j)))
    started = time.time()
    load_before = _load_average()
    if kept:
        context.progress(f"fitting: {len(kept)} of {len(jobs)} fits measured by an earlier run here, "
                         f"{len(todo)} to go (--fresh measures all again)")

    def progress(done: int, total: int) -> None:
        if done % max(1, total // 20) == 0 or done == total:
            context.progress(f"fitting: {done}/{total} fits, {time.time() - started:.0f} s")

    new = run_jobs(run_job, todo, workers, progress, context.cancelled,
                   on_result=journal_writer(context, "fitting") if source is None else None)
    done = kept + new
    if len(done) < len(jobs):
        context.progress(f"fitting: stopped with {len(done)} of {len(jobs)} fits; run again into the same "
                         "folder to go on")
    rows = [r for r in done if r["error"] is not None]
    return {**summarise(rows, matrix.core_size), "failed": [r for r in done if r["error"] is None], "metric": "Ngan", "workers": workers, "clock": clock,
            "materials": list(slices), "models": list(matrix.models), "core_size": matrix.core_size,
            "sizes": list(matrix.sizes), "fixed_sizes": list(matrix.fixed_sizes), "per_model": matrix.per_model,
            "every_family_core": matrix.every_family_core,
            "fits_planned": len(jobs), "fits_done": len(done), "fits_this_run": len(new),
            "wall_s": time.time() - started, "load_average": {"before": load_before, "after": _load_average()},
            "rows": rows}


def _key(row: dict) -> tuple:
    """What identifies one fit of the matrix: material, family and sample set."""
    return row["material"], row["family"], row["size"]


register(Part("fitting", "fitting: error on all samples against fit time, per model, lobes, combination and subset",
              measure, draw, lesson=LESSON, rows_apart=True))
