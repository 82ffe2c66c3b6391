"""Auto lighting against an exhaustive sweep: does the choice meet the tolerance, and at what cost?

    python benchmarks/lighting_auto.py [--tolerance 0.02] [--json docs/bench/lighting_auto.json]
                                       [--quick]

For every (material, map) pair of eight of the lighting study's material classes (the
measured MERL slice, sharp Blinn–Phong and Cook–Torrance lobes, an anisotropic Ward, a
Lambertian) under its three real maps and the shared forest map, with the map area-averaged to 128 × 64 as the
study does: `choose_lighting` picks a setting from the pilot alone; then every candidate is
rendered (reference view, 48²) and scored against a quadrature of the map with the texels
near each pixel's mirror direction subdivided (`refined_environment_image`, through
`study.lighting.quadrature_reference`; texel centres alone are off by percents for a lobe
narrower than the texels, and their own floor estimate proved optimistic),
and timed (one 64² frame per material and setting, the study's `frame_ms`). Reported per
pair: the choice, its predicted and measured error, whether it met the tolerance, the
cheapest setting that actually met it (by measured frame time) and the cost ratio; overall:
the hit rate, the median and worst cost ratio, the misses and why, and the ratio of
measured to predicted error per mode.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from brdflab.io.atomic import atomic_write
from brdflab.io.resources import shared_data_dir
from brdflab.lighting.envmap import load_environment
from brdflab.lighting.auto import DEFAULT_TOLERANCE, choose_lighting, predict_all
from brdflab.lighting.auto_pilot import make_pilot
from brdflab.lighting.reference_view import relative_rmse, sphere_view
from brdflab.render.context import create_context
from brdflab.render.object_view import ObjectRenderer, RenderSettings
from brdflab.sources.proxy import proxy_lobes
from brdflab.study.lighting import (MEASURED_CLASS, build_sh_table, frame_ms, material_classes,
                                    quadrature_reference, reduced, study_maps)

EXTRA_MAP = "envmaps/forest.exr"  # a fourth map (shared data): 8 materials × 4 maps = 32 pairs
SIZE = 48  # error images
FRAME = 64  # timed frames (what matters is their ratio)


def measure_material(renderer, source, maps, candidates, references) -> tuple[dict, dict]:
    """Frame ms per candidate label, and measured error per (map, label)."""
    renderer.set_source(source)
    inside = sphere_view(SIZE, SIZE).inside
    ms, errors = {}, {}
    for c in candidates:
        if c.mode == "sh":
            build_sh_table(source, c.setting)
            renderer.set_sh_order(c.setting)
        samples = c.setting if c.mode in ("fis", "mis") else 1
        for k, (name, small) in enumerate(maps.items()):
            renderer.set_environment(small)
            if k == 0:
                ms[c.label] = frame_ms(renderer, RenderSettings(c.mode, FRAME, FRAME, samples=samples))
            image = renderer.render(RenderSettings(c.mode, SIZE, SIZE, samples=samples))
            errors[(name, c.label)] = relative_rmse(image, references[name][0], inside)
    return ms, errors


def run(tolerance: float, quick: bool, json_path: Path) -> dict:
    skipped: list[dict] = []
    classes = material_classes(False, skipped)
    # the most telling first, so that an interrupted run has covered every kind
    order = ["Lambertian", "Blinn-Phong n=1000", MEASURED_CLASS, "Cook-Torrance m=0.2",
             "Ward ax=0.05 ay=0.3 (anisotropic)", "Blinn-Phong n=100", "Cook-Torrance m=0.05", "Blinn-Phong n=10"]
    classes = {k: classes[k] for k in order if k in classes}
    if quick:
        classes = {k: classes[k] for k in ("Lambertian", "Blinn-Phong n=1000")}
    maps = {name: reduced(env) for name, _, env in study_maps(False, skipped)}
    if (extra := shared_data_dir()) is not None and (extra / EXTRA_MAP).is_file():
        maps[Path(EXTRA_MAP).stem] = reduced(load_environment(extra / EXTRA_MAP))
    renderer = ObjectRenderer(create_context())
    rows = []
    for material, make in classes.items():
        source = make()
        proxy = proxy_lobes(source)
        choices, every = {}, {}
        for name, small in maps.items():
            t0 = time.perf_counter()
            choices[name] = (choose_lighting(source, small, tolerance, proxy), time.perf_counter() - t0)
            every[name] = predict_all(source, proxy, small, make_pilot(source, small))  # the choice stops at its pick
        candidates = next(iter(every.values()))  # the same settings for every map
        references = {name: quadrature_reference(source, small, SIZE) for name, small in maps.items()}
        ms, errors = measure_material(renderer, source, maps, candidates, references)
        for name, small in maps.items():
            choice, seconds = choices[name]
            label = next(c.label for c in candidates if (c.mode, c.setting) == (choice.mode, choice.setting))
            meeting = sorted((ms[c.label], c.label) for c in candidates if errors[(name, c.label)] <= tolerance)
            row = {"material": material, "map": name, "choice": label, "predicted": choice.predicted_error,
                   "measured": errors[(name, label)], "hit": errors[(name, label)] <= tolerance,
                   "choice_ms": ms[label], "choose_seconds": seconds,
                   "cheapest_meeting": meeting[0][1] if meeting else None,
                   "cheapest_ms": meeting[0][0] if meeting else None,
                   "floor": references[name][1], "reference": references[name][2],
                   "sweep": [{"label": c.label, "ms": ms[c.label], "predicted": c.predicted_error,
                              "measured": errors[(name, c.label)]} for c in every[name]],
                   "reasons": choice.reasons}
            row["cost_ratio"] = row["choice_ms"] / row["cheapest_ms"] if meeting else None
            row["judged"] = row["floor"] <= tolerance / 2
            rows.append(row)
            print(f"{material:<40} {name:<22} {label:<14} predicted {100 * row['predicted']:6.2f} %  "
                  f"measured {100 * row['measured']:6.2f} %  cheapest {row['cheapest_meeting']}  "
                  f"ratio {row['cost_ratio']}  floor {100 * row['floor']:.2f} %", file=sys.stderr, flush=True)
        write(json_path, summarise(rows, tolerance, skipped))  # a partial result survives an interruption
    return summarise(rows, tolerance, skipped)


def write(path: Path, result: dict) -> None:
    atomic_write(path, (json.dumps(result, indent=1) + "\n").encode())


def summarise(rows: list[dict], tolerance: float, skipped: list[dict]) -> dict:
    """Hit rate, cost ratios, misses, and measured/predicted per mode, over the judged pairs:
    those whose quadrature reference resolves the tolerance (floor ≤ tolerance / 2)."""
    judged = [r for r in rows if r["judged"]]
    reachable = [r for r in judged if r["cheapest_meeting"] is not None]
    ratios = [r["cost_ratio"] for r in reachable if r["hit"]]
    by_mode: dict[str, list[float]] = {}
    for r in judged:
        for s in r["sweep"]:
            if s["predicted"] > 0:
                by_mode.setdefault(s["label"].split()[0], []).append(s["measured"] / s["predicted"])
    return {
        "tolerance": tolerance, "pairs": len(rows), "size": SIZE, "frame_size": FRAME, "map": [128, 64],
        "machine": platform.platform(), "skipped": skipped,
        "judged": len(judged),
        "not_judged": [{"material": r["material"], "map": r["map"], "floor": r["floor"], "choice": r["choice"],
                        "measured": r["measured"]} for r in rows if not r["judged"]],
        "hit_rate": sum(r["hit"] for r in judged) / max(len(judged), 1),
        "hit_rate_reachable": sum(r["hit"] for r in reachable) / max(len(reachable), 1),
        "unreachable": [f"{r['material']} on {r['map']}" for r in judged if r["cheapest_meeting"] is None],
        "cost_ratio_median": float(np.median(ratios)) if ratios else None,
        "cost_ratio_max": max(ratios) if ratios else None,
        "within_1_25": sum(x <= 1.25 for x in ratios) / max(len(ratios), 1),
        "measured_over_predicted": {m: {"median": float(np.median(v)), "p10": float(np.percentile(v, 10)),
                                        "p90": float(np.percentile(v, 90))} for m, v in by_mode.items()},
        "misses": [{"material": r["material"], "map": r["map"], "choice": r["choice"], "predicted": r["predicted"],
                    "measured": r["measured"], "floor": r["floor"], "cheapest_meeting": r["cheapest_meeting"]}
                   for r in judged if not r["hit"]],
        "rows": rows,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE)
    ap.add_argument("--json", default="docs/bench/lighting_auto.json")
    ap.add_argument("--quick", action="store_true", help="two materials only (a smoke run)")
    args = ap.parse_args()
    result = run(args.tolerance, args.quick, Path(args.json))
    write(Path(args.json), result)
    print(json.dumps({k: result[k] for k in ("pairs", "judged", "hit_rate", "hit_rate_reachable", "cost_ratio_median",
                                             "cost_ratio_max", "within_1_25", "unreachable")}))


if __name__ == "__main__":
    main()
