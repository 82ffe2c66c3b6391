"""What starting a command costs: wall time and import time of `brdflab --help`, `models`
and a slice fit, for this checkout and optionally another tree (e.g. an older revision
exported with `git archive REV | tar -x -C /tmp/before`).

    python benchmarks/startup.py [--before /tmp/before] [--runs 7] [--json docs/bench/startup.json]

Two routes per command: the wall time of the whole process (median of --runs) and the
sum of `python -X importtime`'s top-level import times (imports alone). Both are printed
with the heaviest modules imported, and written to docs/startup.md.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("BRDFLAB_SHARED", ROOT.parent / "shared")) / "data"
SLICE = DATA / "merl_slices" / "gold-metallic-paint3.slice"
COMMANDS = {
    "brdflab --help": ["--help"],
    "brdflab models": ["models"],
    "brdflab fit (slice, Lambertian+BlinnPhong)": ["fit", str(SLICE), "--lobes", "Lambertian,BlinnPhong"],
}
WATCHED = ("numpy", "scipy", "matplotlib", "lxml", "trimesh", "moderngl", "PySide6", "pandas", "PIL", "OpenEXR")


def _run(tree: Path, argv: list[str], importtime: bool = False) -> subprocess.CompletedProcess:
    flags = ["-X", "importtime"] if importtime else []
    return subprocess.run([sys.executable, *flags, "-m", "brdflab", *argv], cwd="/tmp", capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(tree)}, timeout=600)


def imports(stderr: str) -> tuple[float, dict[str, float]]:
    """Seconds of top-level imports, and each watched library's seconds: the cumulative time
    of its entries not nested in another entry of the same library (importtime prints a
    module's imports, indented, before the module itself)."""
    entries = []
    for line in stderr.splitlines():
        parts = line.split("|")
        if line.startswith("import time:") and len(parts) == 3 and parts[1].strip().isdigit():
            name = parts[2]
            entries.append(((len(name) - len(name.lstrip())) // 2, name.strip(), int(parts[1]) / 1e6))
    total, libraries, stack = 0.0, {}, []
    for depth, name, seconds in reversed(entries):  # parents first
        while stack and stack[-1][0] >= depth:
            stack.pop()
        root = name.split(".")[0]
        if depth == 0:
            total += seconds
        if root in WATCHED and not (stack and stack[-1][1] == root):
            libraries[root] = libraries.get(root, 0.0) + seconds
        stack.append((depth, root))
    return total, libraries


def measure(tree: Path, runs: int) -> dict:
    rows = {}
    for label, argv in COMMANDS.items():
        walls, cpus = [], []
        for _ in range(runs):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            t0 = time.perf_counter()
            done = _run(tree, argv)
            walls.append(time.perf_counter() - t0)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpus.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
            if done.returncode != 0:
                raise SystemExit(f"{label} failed: {done.stderr.strip()}")
        total, heavy = imports(_run(tree, argv, importtime=True).stderr)
        rows[label] = {"wall_s": statistics.median(walls), "cpu_s": statistics.median(cpus), "imports_s": total,
                       "heavy": heavy}
    return rows


def markdown(result: dict) -> str:
    trees = [t for t in ("before", "now") if t in result]
    head = ("| command | " + " | ".join(f"{t}: wall s | {t}: CPU s | {t}: imports s" for t in trees)
            + " | heavy imports now (s) |")
    lines = [head, "|" + "---|" * (1 + 3 * len(trees) + 1)]
    for label in COMMANDS:
        cells = [f"{result[t][label]['wall_s']:.3f} | {result[t][label]['cpu_s']:.3f} | {result[t][label]['imports_s']:.3f}"
                 for t in trees]
        heavy = ", ".join(f"{k} {v:.2f}" for k, v in sorted(result["now"][label]["heavy"].items(), key=lambda kv: -kv[1]))
        lines.append(f"| `{label}` | " + " | ".join(cells) + f" | {heavy or '—'} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, help="another source tree to compare with")
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--json", type=Path, help="write the numbers here")
    args = parser.parse_args()
    result = {"python": sys.version.split()[0], "runs": args.runs, "load_average": os.getloadavg()}
    if args.before:
        result["before"] = measure(args.before, args.runs)
    result["now"] = measure(ROOT, args.runs)
    table = markdown(result)
    print(table)
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))
        page = ROOT / "docs" / "startup.md"
        page.write_text("# Start-up cost of the commands\n\nWritten by `python benchmarks/startup.py"
                        f"{' --before TREE' if args.before else ''} --json {args.json}` (median wall time of "
                        f"{args.runs} runs, and its CPU time, user + system, which a busy machine disturbs less; "
                        "imports: the sum of `python -X importtime`'s top-level entries; heavy: cumulative "
                        "import seconds of the big libraries). Load average while measuring: "
                        f"{', '.join(f'{x:.1f}' for x in result['load_average'])} on "
                        f"{os.cpu_count()} cores.\n\n" + table + "\n")


if __name__ == "__main__":
    main()
