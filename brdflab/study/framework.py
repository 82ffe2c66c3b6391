"""`brdflab study`: the lab measuring itself, part by part.

A study part measures one trade-off (numbers, JSON-able) and draws its charts (PNG) from
those numbers. Parts register here; the command, the CI check and the GUI's Charts dock
all run them through `run_study`, so a chart always comes from a measurement of that run.
A part may be scoped to one material and one map (the GUI's current scene) through
`StudyContext`; without a scope it uses its own test matrix.
"""

from __future__ import annotations

import gzip
import importlib
import io
import json
import math
import platform
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from brdflab.errors import BRDFLabError
from brdflab.io.resources import shared_data_dir

Progress = Callable[[str], None]

# the modules that define parts, in the order a study runs them
PART_MODULES = ("brdflab.study.viewer", "brdflab.study.lighting", "brdflab.study.lighting_classes",
                "brdflab.study.prefiltered", "brdflab.study.fitting", "brdflab.study.stability")
DATA_SLICE = ("merl_slices", "gold-metallic-paint3.slice")  # under the developers' shared data


def quiet(message: str) -> None:
    """No progress output."""


def stderr_progress(message: str) -> None:
    """One line per step on stderr, so a long run shows it is alive."""
    print(f"brdflab study: {message}", file=sys.stderr, flush=True)


@dataclass
class StudyContext:
    """What a part measures on. `quick`: small sizes (CI, the GUI). `material`, `source`,
    `environment`: restrict the part to this scene (None: the part's own test matrix).
    `cancelled`: polled between steps; a part returns what it has when it turns true.
    `out_dir` (set by `run_study`): where a resumable part finds what an earlier run
    measured there, and keeps its journal; `fresh`: measure everything again."""

    quick: bool = False
    progress: Progress = quiet
    material: object | None = None
    source: object | None = None
    environment: object | None = None
    cancelled: Callable[[], bool] = lambda: False
    out_dir: Path | None = None
    fresh: bool = False


@dataclass(frozen=True)
class Part:
    name: str
    title: str
    measure: Callable[[StudyContext], dict]
    draw: Callable[[dict, Path], list[str]]
    lesson: str = ""  # what the charts teach, for the README and the GUI
    rows_apart: bool = False  # its "rows" go to ROWS_FILE (gzip JSON lines), not study.json


PARTS: dict[str, Part] = {}


def register(part: Part) -> Part:
    PARTS[part.name] = part
    return part


def load_parts() -> dict[str, Part]:
    for module in PART_MODULES:
        importlib.import_module(module)
    return PARTS


@dataclass
class StudyResult:
    numbers: dict = field(default_factory=dict)
    charts: dict[str, list[str]] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)


def run_study(out_dir: Path, context: StudyContext, only: list[str] | None = None) -> StudyResult:
    """Measure the chosen parts (all by default), draw their charts into `out_dir` and
    write `study.json` there; every number must be finite (BRDFLabError otherwise)."""
    from brdflab.io.atomic import atomic_write

    parts = load_parts()
    names = list(parts) if not only else only
    unknown = [n for n in names if n not in parts]
    if unknown:
        raise BRDFLabError(f"unknown study part {', '.join(unknown)} (parts: {', '.join(parts)})")
    result = StudyResult()
    context.out_dir = out_dir
    for name in names:
        part = parts[name]
        context.progress(f"{part.title}")
        t0 = time.perf_counter()
        numbers = part.measure(context)
        check_finite(numbers, name)
        result.numbers[name] = numbers
        result.charts[name] = part.draw(numbers, out_dir)
        result.seconds[name] = time.perf_counter() - t0
    stored = dict(result.numbers)
    for name in names:
        if parts[name].rows_apart:
            lines = "".join(json.dumps(row) + "\n" for row in stored[name]["rows"])
            atomic_write(out_dir / ROWS_FILE.format(part=name), gzip.compress(lines.encode(), mtime=0))
            stored[name] = {k: v for k, v in stored[name].items() if k != "rows"} | \
                {"rows_file": ROWS_FILE.format(part=name)}
    payload = {"machine": {"platform": platform.platform(), "processor": platform.processor() or platform.machine()},
               "quick": context.quick, "seconds": result.seconds, "charts": result.charts, "parts": stored}
    atomic_write(out_dir / "study.json", json.dumps(payload, indent=1).encode())
    for name in names:  # its rows are in study.json or ROWS_FILE now
        journal_path(out_dir, name).unlink(missing_ok=True)
    return result


ROWS_FILE = "{part}_rows.jsonl.gz"


def read_study(out_dir: Path) -> dict:
    """study.json of `out_dir` with every part's rows in place (read back from ROWS_FILE
    where the part keeps them apart); {} when there is none."""
    path = out_dir / "study.json"
    if not path.is_file():
        return {}
    try:
        study = json.loads(path.read_text())
        for numbers in study.get("parts", {}).values():
            if "rows_file" in numbers:
                text = gzip.decompress((out_dir / numbers.pop("rows_file")).read_bytes()).decode()
                numbers["rows"] = [json.loads(line) for line in text.splitlines()]
    except (OSError, ValueError, EOFError) as e:
        raise BRDFLabError(f"{path}: cannot read an earlier study's results ({e}); pass --fresh to measure again")
    return study


def journal_path(out_dir: Path, part: str) -> Path:
    """A resumable part's journal: one JSON line per finished measurement, while it runs."""
    return out_dir / f"{part}.journal.jsonl"


def earlier_rows(context: StudyContext, part: str) -> list[dict]:
    """The rows a resumable part measured in earlier runs into `context.out_dir`: those in
    its study.json (a finished or stopped run), then those in its journal (a run that was
    killed; a torn last line is skipped). [] when `context.fresh`."""
    if context.fresh or context.out_dir is None:
        return []
    numbers = read_study(context.out_dir).get("parts", {}).get(part, {})
    rows = list(numbers.get("rows", [])) + list(numbers.get("failed", []))
    journal = journal_path(context.out_dir, part)
    if journal.is_file():
        for line in journal.read_text().splitlines():
            try:
                rows.append(json.loads(line))
            except ValueError:
                continue
    return rows


def journal_writer(context: StudyContext, part: str) -> Callable[[dict], None]:
    """A function that appends one finished row to the part's journal (flushed at once, so
    that a killed run loses only the measurements under way)."""
    from brdflab.io.atomic import append_line

    if context.out_dir is None:
        return lambda row: None
    path = journal_path(context.out_dir, part)
    if context.fresh:
        path.unlink(missing_ok=True)
    elif path.is_file() and not path.read_bytes().endswith(b"\n"):
        append_line(path, "")  # end a killed run's torn line, so that the next row is a line of its own
    return lambda row: append_line(path, json.dumps(row))


def measured_slice() -> tuple[Path | None, str]:
    """The measured MERL slice that studies and the bench use, or None and why it is missing."""
    shared = shared_data_dir()
    if shared is None:
        return None, "no shared data: set BRDFLAB_SHARED, or put shared/data next to the checkout"
    path = shared.joinpath(*DATA_SLICE)
    return (path, "") if path.is_file() else (None, f"not found: {path}")


def check_finite(numbers, where: str) -> None:
    """Raise if any number in a part's result is NaN or infinite (None marks a missing value)."""
    stack = [(numbers, where)]
    while stack:
        value, path = stack.pop()
        if isinstance(value, dict):
            stack.extend((v, f"{path}.{k}") for k, v in value.items())
        elif isinstance(value, (list, tuple)):
            stack.extend((v, f"{path}[{i}]") for i, v in enumerate(value))
        elif isinstance(value, float) and not math.isfinite(value):
            raise BRDFLabError(f"study part produced a non-finite number at {path}: {value}")


def save_figure(fig, path: Path) -> str:
    """Save a chart atomically and close it; its file name."""
    import matplotlib.pyplot as plt

    from brdflab.io.atomic import atomic_write

    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    atomic_write(path, buf.getvalue())
    return path.name


def pyplot():
    """matplotlib's pyplot on the file-only Agg backend (no display, no Qt)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def timed(fn, repeat: int) -> float:
    """Best of `repeat` wall times in seconds, after one warm-up call (compilation, caches)."""
    fn()
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best
