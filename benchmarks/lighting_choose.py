"""How long Render Auto takes to choose, against the frame it chooses (issue 35 goal 7: ≤ 1 s or
≤ 5× the chosen frame's cost, whichever is larger).

    python benchmarks/lighting_choose.py [--json docs/bench/lighting_choose.json]

Per (example material, map): `choose_lighting` as `brdflab render --mode auto` calls it:
first (the map never seen: no prefiltered stack in memory or in the user's cache), in a new
process that has seen the map before (the memory emptied), and again (in memory); then the
chosen setting's frame at 128² timed on this machine's renderer (llvmpipe; a tiny frame first
compiles the program, as `study.lighting.frame_ms` does), and per map the time to build its
prefiltered stack (what the first prefiltered frame of a map adds; since Auto predicts from a
material's own layers, choosing no longer builds it). Maps: the default map as the CLI reads
it, and two synthetic maps (a tuning interior and a held-out sunrise with a tiny sun). Run it
against another tree (`PYTHONPATH=…`) in the same session to compare before and after;
`--repeat N` keeps the best of N timings of each (the machine is shared and noisy).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

from brdflab.io.resources import default_environment_path
from brdflab.io.xmlio import load
from brdflab.lighting import prefilter
from brdflab.lighting.auto import choose_lighting
from brdflab.lighting.envmap import load_environment
from brdflab.lighting.synthetic_maps import spec
from brdflab.render.context import create_context
from brdflab.render.object_view import ObjectRenderer, RenderSettings
from brdflab.study.lighting import frame_ms

ROOT = Path(__file__).resolve().parents[1]
MATERIALS = ("lambertian", "fig2_lambertian_lafortune", "blinn_phong", "ward", "principled_car_paint")
SYNTHETIC = ("room-one-window", "sunrise-tiny")
FRAME = 128


def timed(run) -> float:
    t0 = time.perf_counter()
    run()
    return time.perf_counter() - t0


def maps() -> dict:
    out = {"default map": load_environment(default_environment_path())}
    out.update({name: spec(name).build() for name in SYNTHETIC})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json")
    ap.add_argument("--repeat", type=int, default=1, help="time each choice this many times and keep the best")
    args = ap.parse_args()
    cache = Path(tempfile.mkdtemp(prefix="brdflab-choose-"))
    os.environ["BRDFLAB_CACHE"] = str(cache)  # the user's own cache is not touched, and starts empty
    renderer = ObjectRenderer(create_context())
    rows = []
    for map_name, env in maps().items():
        renderer.set_environment(env)
        build = timed(lambda: prefilter.build_stack(env))  # what a map's first prefiltered frame adds
        print(f"{map_name}: its prefiltered stack builds in {build:.2f} s", flush=True)
        for name in MATERIALS:
            material = load(ROOT / "materials" / f"{name}.xml").material
            firsts, seens, warms = [], [], []
            for _ in range(args.repeat):  # the best of each: this machine is shared and noisy
                prefilter._CACHE.clear()
                shutil.rmtree(cache, ignore_errors=True)
                firsts.append(timed(lambda: choose_lighting(material, env)))
                prefilter._CACHE.clear()  # a new process: the stack, if kept, is on disk only
                seens.append(timed(lambda: choose_lighting(material, env)))
                t0 = time.perf_counter()
                choice = choose_lighting(material, env)
                warms.append(time.perf_counter() - t0)
            first, seen, warm = min(firsts), min(seens), min(warms)
            renderer.set_source(material)
            if choice.mode == "sh":
                renderer.set_sh_order(choice.setting)
            setting = choice.render_settings()
            ms = frame_ms(renderer, RenderSettings(choice.mode, FRAME, FRAME, samples=setting["samples"]))
            bound = max(1.0, 5e-3 * ms)
            rows.append({"map": map_name, "material": name, "choice": f"{choice.mode} {choice.setting or ''}".strip(),
                         "first_s": first, "seen_s": seen, "warm_s": warm, "frame_ms": ms, "bound_s": bound,
                         "weighed": len(choice.candidates), "stack_build_s": build})
            print(f"{map_name:<16} {name:<28} {rows[-1]['choice']:<12} first {first:5.2f} s  map seen {seen:5.2f} s  "
                  f"again {warm:5.2f} s  "
                  f"frame {ms:7.1f} ms  bound {bound:4.2f} s  weighed {len(choice.candidates)}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({"tree": str(Path(prefilter.__file__).parents[2]), "rows": rows}, indent=1))
    shutil.rmtree(cache, ignore_errors=True)


if __name__ == "__main__":
    main()
