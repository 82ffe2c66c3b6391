"""How long the GUI thread blocks while the object view meets new shaders (issue 35 goal 6:
≤ 50 ms p99, ≤ 150 ms at most, with Mesa's shader cache off, as on a first use).

    xvfb-run -a python benchmarks/gui_blocking.py [--json docs/bench/gui_blocking.json] [SCENARIO ...]

Each scenario runs in a process of its own with `MESA_SHADER_CACHE_DISABLE=true` (Mesa reads
it once per process): the window opens on its default scene, draws it, and then a 10 ms timer
on the GUI thread records its ticks while the scenario does what a user does, until the
object view has drawn the result (and 1 s more). A gap between ticks is a time the event loop
did not turn. Scenarios: adding model files (a BRDF Explorer file and a BRDFLab one), a lobe
of every built-in model added to the default material in turn and undone (each a new
combination of models, so new programs for both views), a
measured table opened, a light probe opened, the subdivision changed and Auto subdivision
ticked.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

SCENARIOS = ("model-files", "every-model", "measured", "probe", "subdivision")


def _shared() -> Path:
    from brdflab.io.resources import shared_data_dir

    shared = shared_data_dir()
    if shared is None:
        raise SystemExit("needs ../shared/data (model files, slices, probes)")
    return shared


def _run(scenario: str) -> dict:
    """One scenario in this process (Mesa's shader cache already off): the GUI thread's gaps."""
    import numpy as np
    from PySide6.QtCore import QSettings, QTimer
    from PySide6.QtWidgets import QApplication

    from brdflab.gui.main_window import MainWindow
    from brdflab.models.registry import is_builtin, all_models

    app = QApplication.instance() or QApplication(sys.argv[:1])
    settings_dir = Path(os.environ.get("TMPDIR", "/tmp")) / f"brdflab-gui-blocking-{os.getpid()}"
    settings_dir.mkdir(parents=True, exist_ok=True)
    w = MainWindow(QSettings(str(settings_dir / "settings.ini"), QSettings.IniFormat))
    w.maybe_save = lambda: True
    w.resize(1400, 900)
    w.show()
    view = w.object_view

    def wait(condition, timeout: float = 120.0) -> None:
        end = time.perf_counter() + timeout
        while not condition():
            if time.perf_counter() > end:
                raise SystemExit(f"{scenario}: timed out")
            app.processEvents()
            time.sleep(0.002)

    def pause(seconds: float) -> None:
        end = time.perf_counter() + seconds
        wait(lambda: time.perf_counter() > end)

    def drawn_anew(before) -> bool:
        """The object view shows an image begun after `before` (its first samples landed)."""
        return not w.loading and view._progressive is not None and view._progressive is not before \
            and view.samples_done >= 1 and view._flight is None

    def act(action) -> None:
        """Do it, then wait until the object view has drawn what it changed."""
        before = view._progressive
        action()
        wait(lambda: drawn_anew(before))

    wait(lambda: view.ctx is not None and view.samples_done >= 16)
    pause(0.5)
    ticks: list[float] = []
    timer = QTimer(interval=10)
    timer.timeout.connect(lambda: ticks.append(time.perf_counter()))
    # GUI_BLOCKING_STACKS=FILE: every thread's stack whenever a gap passes GUI_BLOCKING_AFTER s (0.06)
    stacks = os.environ.get("GUI_BLOCKING_STACKS")
    if stacks:
        import faulthandler

        dump = open(stacks, "a")
        timer.timeout.connect(lambda: faulthandler.dump_traceback_later(float(os.environ.get("GUI_BLOCKING_AFTER", "0.06")), file=dump))
    shared = _shared()
    began = time.perf_counter()
    timer.start()
    ticks.append(began)
    if scenario == "model-files":
        for path in (shared / "models" / "brdf_explorer" / "disney.brdf", shared / "models" / "brdflab" / "Ward.xml"):
            act(lambda: w.add_model_file(path))
    elif scenario == "every-model":
        for model in all_models():  # each added to the default material, then undone
            if is_builtin(model):
                act(lambda: w.editor.lobe_added.emit(model.name))
                act(w.undo_stack.undo)
    elif scenario == "measured":
        act(lambda: w.open_path(shared / "merl_slices" / "nickel.slice"))
    elif scenario == "probe":
        act(lambda: w.open_environment(shared / "envmaps" / "probes" / "beach_probe.hdr"))
    elif scenario == "subdivision":
        w.lobe_controls.level.setValue(7)
        pause(2.0)
        w.lobe_controls.auto_level.setChecked(True)
        pause(3.0)
    else:
        raise SystemExit(f"unknown scenario {scenario!r} ({', '.join(SCENARIOS)})")
    pause(1.0)
    timer.stop()
    if stacks:
        faulthandler.cancel_dump_traceback_later()
    gaps = np.diff(np.array(ticks))
    w.close()
    return {"scenario": scenario, "seconds": round(ticks[-1] - began, 2), "ticks": int(len(gaps)),
            "median_ms": round(1e3 * float(np.median(gaps)), 1),
            "p99_ms": round(1e3 * float(np.sort(gaps)[int(0.99 * len(gaps))]), 1),
            "max_ms": round(1e3 * float(gaps.max()), 1)}


def measure(scenario: str) -> dict:
    """The scenario in a fresh process with Mesa's shader cache off."""
    env = {**os.environ, "MESA_SHADER_CACHE_DISABLE": "true"}
    out = subprocess.run([sys.executable, __file__, "--one", scenario], env=env, capture_output=True, text=True,
                         timeout=600)
    lines = [l for l in out.stdout.splitlines() if l.startswith("{")]
    if out.returncode != 0 or not lines:
        raise RuntimeError(f"{scenario}: exit {out.returncode}\n{out.stderr[-3000:]}")
    return json.loads(lines[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="*", default=list(SCENARIOS))
    ap.add_argument("--json")
    ap.add_argument("--one", help=argparse.SUPPRESS)  # run one scenario in this process
    args = ap.parse_args()
    if args.one:
        print(json.dumps(_run(args.one)), flush=True)
        return
    rows = []
    for scenario in args.scenarios:
        row = measure(scenario)
        rows.append(row)
        print(f"{scenario:12s} {row['seconds']:6.1f} s  {row['ticks']:5d} ticks  median {row['median_ms']:5.1f} ms  "
              f"p99 {row['p99_ms']:6.1f} ms  max {row['max_ms']:7.1f} ms", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({"python": sys.version.split()[0], "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
