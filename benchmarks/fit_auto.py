"""Auto fitting against an exhaustive run over the same ladder, on the shared MERL slices.

    python benchmarks/fit_auto.py [--split N] [--tolerance T] [--slices a,b,...] [--jobs J] [--budget S] [--json OUT]
                                  [--resume]

Per slice, two independent runs of `brdflab.fitting.auto.auto_fit`: Auto (screens each
rung, stops when a rung no longer pays) and exhaustive (fully fits every candidate of every
rung). Auto's fully fitted candidates must equal the exhaustive run's (same split, same
starts): how many do is reported. Hit: Auto's pick has a held-back
error within T of the best candidate of the exhaustive run, with no more parameters than
that best candidate (the fewest parameters of any exhaustive candidate within T of the best
is reported too), and
Auto's total CPU time is below the exhaustive run's. CPU time (not wall time) is
compared: the machine is shared, and the runs are single-threaded (`--jobs J` runs J
slices at once, one process and one BLAS thread each). The JSON is rewritten after every
slice, so a run cut short by `--budget` (seconds) keeps what it finished, and `--resume`
runs only the slices the JSON does not have yet (same tolerance and split), keeping its rows.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from brdflab.fitting.auto import DEFAULT_TOLERANCE, auto_fit, improves
from brdflab.fitting.samples import samples_of
from brdflab.sources.measured import read_slice
from brdflab.study.workers import run_jobs

DATA = Path(os.environ.get("BRDFLAB_SHARED", Path(__file__).resolve().parents[2] / "shared")) / "data"
SLICES = DATA / "merl_slices"


def spread(names: list[str]) -> list[str]:
    """The slices in an order that spreads any prefix over the sorted list (halving strides)."""
    order, step = [], len(names)
    while step >= 1:
        order += [n for i, n in enumerate(names) if i % step == 0 and n not in order]
        step //= 2
    return order


def judge(auto: dict, exhaustive: dict, tolerance: float) -> dict:
    """The check of one slice, from the two ladders' dicts."""
    pick = auto["candidates"][auto["chosen"]]
    candidates = exhaustive["candidates"]
    best = min(candidates, key=lambda c: c["error_held_back"])
    near = [c for c in candidates if not improves(c["error_held_back"], best["error_held_back"], tolerance)]
    cheapest_near = min(c["parameters"] for c in near)
    within = not improves(pick["error_held_back"], best["error_held_back"], tolerance)
    params_ok = pick["parameters"] <= best["parameters"]
    faster = auto["cpu_seconds"] < exhaustive["cpu_seconds"]
    why = []
    if not within:
        why.append(f"error {pick['error_held_back']:.4g} is {pick['error_held_back'] / best['error_held_back'] - 1:.1%} "
                   f"above the best {best['error_held_back']:.4g} ({'+'.join(best['lobes'])})")
    if not params_ok:
        why.append(f"{pick['parameters']} parameters, more than the best's {best['parameters']}")
    if not faster:
        rungs = max(c["rung"] for c in auto["candidates"])
        why.append(f"Auto climbed {rungs} of {max(c['rung'] for c in candidates)} rungs"
                   + (" (every rung paid)" if rungs == max(c["rung"] for c in candidates) else ""))
    reference = {tuple(c["lobes"]): c["error_held_back"] for c in candidates}
    full = [c for c in auto["candidates"] if c["error_held_back"] is not None]
    same = sum(reference.get(tuple(c["lobes"])) == c["error_held_back"] for c in full)
    return {"auto_fully_fitted_as_in_exhaustive": f"{same}/{len(full)}", "pick": "+".join(["Lambertian", *pick["lobes"]]), "pick_parameters": pick["parameters"],
            "pick_error": pick["error_held_back"], "best": "+".join(["Lambertian", *best["lobes"]]),
            "best_parameters": best["parameters"], "best_error": best["error_held_back"],
            "cheapest_within_T_parameters": cheapest_near, "within_tolerance": within, "parameters_ok": params_ok,
            "auto_cpu_s": auto["cpu_seconds"], "exhaustive_cpu_s": exhaustive["cpu_seconds"],
            "auto_wall_s": auto["seconds"], "exhaustive_wall_s": exhaustive["seconds"],
            "auto_fits": len(auto["candidates"]), "auto_full_fits": len(full), "exhaustive_fits": len(candidates), "faster": faster,
            "hit": within and params_ok and faster, "why_missed": "; ".join(why)}


def run_slice(job: tuple[str, float, int]) -> dict:
    """Auto and the exhaustive run on one slice, judged (a worker process's job)."""
    name, tolerance, split = job
    samples = samples_of(read_slice(SLICES / f"{name}.slice"))
    auto = auto_fit(samples, tolerance, split=split).as_dict()
    exhaustive = auto_fit(samples, tolerance, split=split, exhaustive=True).as_dict()
    return {"slice": name, **judge(auto, exhaustive, tolerance), "auto": auto, "exhaustive": exhaustive}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--split", type=int, default=5_000, help="samples fitted (as many held back)")
    ap.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE)
    ap.add_argument("--slices", help="comma-separated slice names (default: every shared slice)")
    ap.add_argument("--jobs", type=int, default=1, help="slices run at once (processes)")
    ap.add_argument("--budget", type=float, default=float("inf"), help="stop starting slices after this many seconds")
    ap.add_argument("--json", default=str(Path(__file__).resolve().parents[1] / "docs" / "bench" / "fit_auto.json"))
    ap.add_argument("--resume", action="store_true", help="keep the JSON's rows and run the slices it lacks")
    args = ap.parse_args()
    names = sorted(p.stem for p in SLICES.glob("*.slice"))
    todo = args.slices.split(",") if args.slices else spread(names)
    started = time.time()
    rows: list[dict] = []
    if args.resume and Path(args.json).is_file():
        earlier = json.loads(Path(args.json).read_text())
        if (earlier["tolerance"], earlier["split"]) != (args.tolerance, args.split):
            raise SystemExit(f"{args.json}: made with another tolerance or split; not resumed")
        rows = earlier["rows"]
        todo = [n for n in todo if n not in {r["slice"] for r in rows}]
    total = len(rows) + len(todo)

    def finished(r: dict) -> None:
        rows.append(r)
        print(f"[{len(rows)}/{total}] {r['slice']}: {'hit' if r['hit'] else 'MISS'} pick {r['pick']} ({r['pick_parameters']} p, "
              f"{r['pick_error']:.4g}) best {r['best']} ({r['best_parameters']} p, {r['best_error']:.4g}); CPU "
              f"{r['auto_cpu_s']:.1f} s against {r['exhaustive_cpu_s']:.1f} s {r['why_missed']}", flush=True)
        write(rows)

    def write(rows: list[dict]) -> None:
        summary = {"tolerance": args.tolerance, "split": args.split, "metric": "Ngan", "jobs": args.jobs,
                   "slices_run": len(rows), "slices_available": len(names), "hits": sum(r["hit"] for r in rows),
                   "within_tolerance": sum(r["within_tolerance"] for r in rows),
                   "parameters_ok": sum(r["parameters_ok"] for r in rows), "faster": sum(r["faster"] for r in rows),
                   "auto_cpu_s_total": sum(r["auto_cpu_s"] for r in rows),
                   "exhaustive_cpu_s_total": sum(r["exhaustive_cpu_s"] for r in rows),
                   "load_average": os.getloadavg()[0], "wall_s": time.time() - started, "rows": rows}
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(args.json).with_suffix(".json.tmp")
        tmp.write_text(json.dumps(summary, indent=1))
        os.replace(tmp, args.json)

    run_jobs(run_slice, [(n, args.tolerance, args.split) for n in todo], args.jobs, lambda done, total: None,
             lambda: time.time() - started > args.budget, on_result=finished)


if __name__ == "__main__":
    main()
