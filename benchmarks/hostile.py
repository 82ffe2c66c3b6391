"""Time and peak memory of every hostile-input case, as a user meets it (the CLI in a subprocess).

    python benchmarks/hostile.py [--out docs/hostile_input.json]

Runs the corpus of tests/test_hostile.py one case at a time (no other load from this script),
under the same limits, and records each case's exit status, wall time and the child's peak
resident memory (from wait4's rusage, independent of the process's own view). Writes JSON
and a Markdown table next to it. CPU seconds (from the same rusage) do not depend on the
machine's load; wall seconds do.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from brdflab.errors import shown_path  # noqa: E402
from test_hostile import CASES, HANG_LIMIT_S, TIME_LIMIT_S, _limits, build_corpus  # noqa: E402


def measure(folder: Path, argv: list[str], hide_charset: bool) -> dict:
    """Exit status, wall and CPU seconds and peak RSS (MiB) of one CLI run (the test's limits)."""
    path = [str(folder / "no_charset"), str(ROOT)] if hide_charset else [str(ROOT)]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(path), "OPENBLAS_NUM_THREADS": "1"}
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "brdflab", *argv], cwd=folder, env=env, preexec_fn=_limits,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if time.perf_counter() - t0 > HANG_LIMIT_S:
            proc.kill()
            pid, status, usage = os.wait4(proc.pid, 0)
            break
        time.sleep(0.01)
    seconds = time.perf_counter() - t0
    stderr = proc.stderr.read().decode("utf-8", "replace")
    proc.stderr.close()
    proc.returncode = os.waitstatus_to_exitcode(status)  # reaped here: Popen must not wait again
    return {"status": proc.returncode, "seconds": round(seconds, 2),
            "cpu_seconds": round(usage.ru_utime + usage.ru_stime, 2), "peak_rss_mib": round(usage.ru_maxrss / 1024, 1),
            "stderr": stderr.strip().splitlines()[:2]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "hostile_input.json"))
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="brdflab-hostile-"))
    try:
        build_corpus(folder)
        rows = {}
        for name, case in CASES.items():
            # a file name that is not UTF-8 is written as the lab prints it (\xNN)
            rows[name] = {"command": "brdflab " + " ".join(map(shown_path, case.argv)), "expected_status": case.status,
                          **measure(folder, case.argv, case.hide_charset)}
            print(f"{name:32s} {rows[name]['status']:>3} {rows[name]['seconds']:6.2f} s "
                  f"{rows[name]['cpu_seconds']:6.2f} s CPU "
                  f"{rows[name]['peak_rss_mib']:7.1f} MiB", flush=True)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    out = Path(args.out)
    out.write_text(json.dumps({"cpu_limit_s": TIME_LIMIT_S, "load_average": os.getloadavg(), "cpu_count": os.cpu_count(), "cases": rows}, indent=2,
                              ensure_ascii=False) + "\n", encoding="utf-8")
    lines = ["| case | status (expected) | wall s | CPU s | peak RSS MiB | stderr |", "|---|---|---|---|---|---|"]
    for name, r in rows.items():
        said = (r["stderr"][0] if r["stderr"] else "").replace("|", "\\|")
        lines.append(f"| {name} | {r['status']} ({r['expected_status']}) | {r['seconds']:.2f} | {r['cpu_seconds']:.2f} | "
                     f"{r['peak_rss_mib']:.0f} | {said} |")
    out.with_suffix(".md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {out} and {out.with_suffix('.md')}")


if __name__ == "__main__":
    main()
