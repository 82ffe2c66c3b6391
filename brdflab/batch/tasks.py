"""One batch task: fit one lobe set to one source. Runs in a worker process.

A task never raises for a bad source or a failed fit: it returns a row whose status is
"failed" and whose message is the one-line error, so the batch goes on.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import dataclasses
import functools
import hashlib
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

from brdflab.errors import BRDFLabError, is_text_name
from brdflab.sources.measured import READERS

FIT_EXTENSIONS = (*READERS, ".xml")  # every measured format the lab reads, and XML materials
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameters (malloc.h)


AUTO_LABEL = "auto"  # the lobes column of an Auto task (the pick is in its parameters and message)
KEY_PREFIX = "pair-"


def stored_key(value) -> str:
    """A pair key as a table or an XML file kept it: those written before keys had their
    prefix hold the same digest alone (an all-digit one read back as a number), so a rerun
    still finds their pairs done instead of fitting them again beside the old rows."""
    key = str(value)
    return key if key.startswith(KEY_PREFIX) else KEY_PREFIX + key


@dataclass(frozen=True)
class FitTask:
    """The inputs of one fit: a source file (and its sha256), a lobe set (or Auto's ladder,
    with its tolerance and split) and the fit options."""

    source: str  # absolute path
    sha256: str
    lobes: tuple[str, ...]  # empty for an Auto task
    combination: str  # Linear | Fixed
    options: dict  # every FitOptions field
    auto: tuple[tuple[str, object], ...] | None = None  # Auto's settings (models, split, tolerance)
    # (path, sha256, registry name) of each model read from a file that the task fits: a
    # worker process registers them before it builds the lobes
    model_files: tuple[tuple[str, str, str], ...] = ()

    @property
    def lobe_label(self) -> str:
        return AUTO_LABEL if self.auto is not None else ",".join(self.lobes)

    @property
    def options_json(self) -> str:
        auto = {"auto": dict(self.auto)} if self.auto is not None else {}
        return json.dumps({"combination": self.combination, **self.options, **auto}, sort_keys=True)

    @property
    def key(self) -> str:
        """The pair's identity (source, lobes, options), independent of the file's content.
        Never a number: a digest of digits alone would be read back from the XML's statistics or
        the table as one (and lose its leading zeros), so the fit would not be found again."""
        text = json.dumps([self.source, self.lobe_label, self.options_json])
        return KEY_PREFIX + hashlib.sha256(text.encode()).hexdigest()[:20]


@dataclass
class TaskOutcome:
    """A finished task: its table row and, when it succeeded, the fitted material."""

    row: dict
    fitting: object | None = None  # the <Fitting> of the fit (brdflab.io.xmlio.Fitting)
    source_type: str | None = None  # the measured type of a data file; None for XML sources


def file_sha256(path: Path) -> str:
    """The file's sha256, or '' when it cannot be read (the task then reports why)."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return ""
    return h.hexdigest()


def options_dict(metric: str, max_iterations: int) -> dict:
    """Every field of the fitter's options (so a change of its defaults counts as new inputs)."""
    from brdflab.fitting.lm import FitOptions

    options = FitOptions(metric=metric, max_iterations=max_iterations)
    options.validate()
    return {k: (str(v) if isinstance(v, float) and v == float("inf") else v)
            for k, v in dataclasses.asdict(options).items()}


def fit_options(options: dict):
    from brdflab.fitting.lm import FitOptions

    return FitOptions(**{k: (float(v) if v == "inf" else v) for k, v in options.items()})


def base_row(task: FitTask) -> dict:
    return {"key": task.key, "source": task.source, "material": Path(task.source).stem, "sha256": task.sha256,
            "lobes": task.lobe_label, "combination": task.combination, "metric": task.options["metric"],
            "options": task.options_json}


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return "local"


def one_line(e: BaseException) -> str:
    """A one-line message: BRDFLabError's own text, else the exception type and text."""
    text = str(e) if isinstance(e, BRDFLabError) else f"{type(e).__name__}: {e}"
    return " ".join(text.split())[:500]


@functools.cache
def restore_malloc_reuse() -> bool:
    """In a process started with MALLOC_TRIM_THRESHOLD_ set (a Dask nanny's default), glibc
    no longer adapts its mmap threshold, so each of a fit's temporary arrays over 128 KB is
    mapped, faulted in and unmapped again (30 % of a fit's time). Raise both thresholds so
    that freed arrays are reused. Once per process; True when it applied (glibc only)."""
    if "MALLOC_TRIM_THRESHOLD_" not in os.environ:
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    return bool(mallopt(M_MMAP_THRESHOLD, 32 << 20)) and bool(mallopt(M_TRIM_THRESHOLD, 64 << 20))


def _fit_lobes(task: FitTask, source):
    """The lobe set fitted on every sample: (its fit, its <Fitting>, its error on all samples,
    the message, seconds)."""
    from brdflab.fitting.lm import fit, material_from_lobes
    from brdflab.fitting.samples import samples_of
    from brdflab.fitting.stored import fitting_of

    start = material_from_lobes(list(task.lobes), task.combination, source.n_channels)
    result = fit(start, samples_of(source), fit_options(task.options))
    return result, fitting_of(result), result.error, result.message, result.seconds


def _fit_auto(task: FitTask, source):
    """Auto's ladder on its split of the samples (as `brdflab fit --auto`); the pick is then
    scored on every sample of the source, like every other row of the table."""
    from brdflab.fitting.auto import auto_fit, chosen_fit, chosen_fitting
    from brdflab.fitting.metrics import metric_error
    from brdflab.fitting.samples import samples_of

    settings = dict(task.auto)
    samples = samples_of(source)
    ladder = auto_fit(samples, settings["tolerance"], task.options["metric"], task.combination,
                      split=int(settings["split"]), models=settings["models"].split(",") if settings["models"] else None,
                      options=fit_options(task.options))
    result = chosen_fit(ladder)
    picked = "+".join(("Lambertian", *ladder.chosen.lobes))
    return (result, chosen_fitting(ladder), metric_error(result.material, samples, task.options["metric"]),
            f"Auto picked {picked}: {ladder.reason}", ladder.seconds)


def run_task(task: FitTask) -> TaskOutcome:
    """Load the source, fit the lobe set (or climb Auto's ladder), and return the row; its
    error is on all samples of the source."""
    restore_malloc_reuse()
    from brdflab.fitting.second_error import image_error
    from brdflab.sources.files import is_xml, load_source

    t0 = time.perf_counter()
    row = {**base_row(task), "worker": _worker_name(), "pid": os.getpid()}
    path = Path(task.source)
    try:
        if file_sha256(path) != task.sha256:
            raise BRDFLabError("the file changed or differs on this worker (sha256 mismatch)", path)
        from brdflab.models.files.library import rebuild

        for model_path, model_sha, name in task.model_files:
            rebuild(model_path, model_sha, name)
        source = load_source(path)
        result, fitting, error, message, seconds = (_fit_auto if task.auto is not None else _fit_lobes)(task, source)
    except Exception as e:  # a bad file or a failed fit is a row, not the end of the batch
        row.update(error=float("nan"), parameters="", seconds=time.perf_counter() - t0, iterations=0,
                   evaluations=0, status="failed", message=one_line(e))
        return TaskOutcome(row)
    try:  # every fit reports both numbers: the image error beside the sample metric's
        row["image_error"] = float(image_error(result.material, source))
    except BRDFLabError:  # a source the image metric cannot render (not 1 or 3 channels, black)
        row["image_error"] = float("nan")
    row.update(error=float(error), parameters=json.dumps(result.material.describe()["lobes"]),
               seconds=float(seconds), iterations=int(result.iterations),
               evaluations=int(result.evaluations), status=result.status, message=message)
    source_type = None if is_xml(path) else getattr(source, "source_type", None)
    return TaskOutcome(row, fitting, source_type)


def discover_sources(paths: list[Path]) -> list[Path]:
    """Files as given, and every fit-able file (by extension) directly inside a folder, sorted."""
    found: list[Path] = []
    for p in paths:
        if p.is_dir():
            found.extend(sorted(f for f in p.iterdir() if f.is_file() and f.suffix.lower() in FIT_EXTENSIONS
                                and not f.name.startswith(".")))
        elif p.exists():
            found.append(p)
        else:
            raise BRDFLabError("no such file or folder", p)
    unique = list(dict.fromkeys(f.resolve() for f in found))
    for f in unique:  # refused before any fit: its table row and XML file could not record it
        if not is_text_name(f):
            raise BRDFLabError("the file's name is not UTF-8 text, which the batch's table and XML files "
                               "cannot record (rename it)", f)
    if not unique:
        raise BRDFLabError("no measured, simulated or XML files found in " + ", ".join(map(str, paths)))
    return unique


def model_files_of(names) -> tuple[tuple[str, str, str], ...]:
    """What a worker needs to register the file models among `names` (built-ins need nothing)."""
    from brdflab.models import get_model

    out = {}
    for name in names:
        model = get_model(name)
        if model.origin is not None:
            out[name] = (str(model.origin.path), model.origin.sha256, model.name)
    return tuple(out.values())


def make_tasks(sources: list[Path], lobe_sets: list[tuple[str, ...]], combination: str, options: dict,
               auto: tuple[tuple[str, object], ...] | None = None) -> list[FitTask]:
    """One task per (source, lobe set), and per source one Auto task when `auto` is given."""
    tasks = []
    auto_models = [m for m in dict(auto or ()).get("models", "").split(",") if m]
    for s in sources:
        sha = file_sha256(s)
        tasks += [FitTask(str(s), sha, lobes, combination, options, model_files=model_files_of(lobes))
                  for lobes in lobe_sets]
        if auto is not None:
            tasks.append(FitTask(str(s), sha, (), combination, options, auto, model_files_of(auto_models)))
    return tasks
