"""Scene-Auto on the sphere against scene-Auto on a mesh: a pick is for its scene (issue 34
goal 4, `fit --auto --env MAP --mesh FILE`).

    python benchmarks/scene_auto_mesh.py [--json docs/bench/scene_auto_mesh.json] [--materials a,b,...]

Per shared MERL slice, under the real forest probe (a map no default scene uses): scene-Auto
judged on the reference sphere and judged on Spot as `brdflab render --view orbit` shows it
(render/gbuffer.py, the view sized to ~812 pixels). Each pick is then scored in the other
scene, by the same operator: what the sphere's pick costs on the object a user looks at.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from brdflab.fitting.image_metric import VIEW, SceneImages
from brdflab.fitting.scene_auto import scene_auto
from brdflab.io.mesh import load_mesh
from brdflab.io.resources import data_dir
from brdflab.lighting.envmap import load_environment
from brdflab.render.camera import OrbitCamera
from brdflab.render.context import create_context
from brdflab.render.gbuffer import frames_covering
from brdflab.sources.files import load_source

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
MATERIALS = ("blue-fabric", "nickel", "pink-felt", "brass")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path)
    parser.add_argument("--materials", default=",".join(MATERIALS))
    args = parser.parse_args()
    env = load_environment(SHARED / "envmaps" / "forest.exr").downsampled(256, 128)
    mesh = load_mesh(data_dir("resources") / "meshes" / "spot.obj")
    views = {"sphere": VIEW, "spot": frames_covering(create_context(), mesh, OrbitCamera())}
    rows = []
    for name in args.materials.split(","):
        source = load_source(SHARED / "merl_slices" / f"{name}.slice")
        scenes = {k: SceneImages.of_source(source, [env], v) for k, v in views.items()}
        picks = {}
        for k, scene in scenes.items():
            t0 = time.perf_counter()
            ladder = scene_auto(scene, progress=lambda p, k=k: print(f"{name} on {k}: {p.describe()} "
                                                                   f"({time.perf_counter() - t0:.0f} s)",
                                                                   file=sys.stderr, flush=True))
            picks[k] = (ladder, time.perf_counter() - t0)
        for k, (ladder, seconds) in picks.items():
            other = "spot" if k == "sphere" else "sphere"
            chosen = ladder.chosen
            row = {"material": name, "judged_on": k, "pixels": scenes[k].size, "pick": "+".join(chosen.lobes) or "-",
                   "parameters": chosen.parameters, "seconds": seconds, "image_error": chosen.error_held_back,
                   f"image_error_on_{other}": scenes[other].errors([chosen.result.material])[0]}
            rows.append(row)
            print(json.dumps(row), flush=True)
    if args.json:
        args.json.write_text(json.dumps({"map": "forest (256 × 128)", "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
