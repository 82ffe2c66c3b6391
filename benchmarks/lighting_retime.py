"""Re-time some of the lighting study's frames in a fresh process, by a harness of its own
(not `study.lighting.frame_ms`): one warm-up frame at full size, then the median of three,
each ended by reading the image back.

    python benchmarks/lighting_retime.py docs/study/lighting.json
"""

import json
import statistics
import sys
import time

from brdflab.io.resources import shared_data_dir
from brdflab.lighting.envmap import load_environment
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.render.context import create_context
from brdflab.render.object_view import ObjectRenderer, RenderSettings

CASES = (("Blinn-Phong n=100", "BlinnPhong", {"Exponent": 100.0}, "fis", 64),
         ("Blinn-Phong n=100", "BlinnPhong", {"Exponent": 100.0}, "mis", 256),
         ("Cook-Torrance m=0.2", "CookTorrance", {"m": 0.2}, "mis", 256),
         ("Blinn-Phong n=10000", "BlinnPhong", {"Exponent": 10000.0}, "fis", 256),
         ("Lambertian", "Lambertian", {}, "prefiltered", None))
MAP = "quarry_01_1k"  # the map the study times frames with


def main(study_json: str) -> None:
    rows = json.load(open(study_json))["parts"]["lighting"]["rows"]
    study = {(r["material"], r["mode"], r["value"]): r["ms"] for r in rows if r["map"] == MAP}
    env = load_environment(shared_data_dir() / "envmaps" / f"{MAP}.hdr")
    ctx = create_context()
    for label, model, params, mode, samples in CASES:
        renderer = ObjectRenderer(ctx)
        renderer.set_environment(env)
        renderer.set_source(AnalyticMaterial(model, "Linear", 3, [Lobe.create(model, [0.5] * 3, **params)]))
        settings = RenderSettings(mode, 256, 256, samples=samples or 1)
        renderer.render(settings)
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            renderer.render(settings)
            times.append(1e3 * (time.perf_counter() - t0))
        print(f"{label:22s} {mode:12s} {samples or '':>5}: median {statistics.median(times):8.1f} ms "
              f"(min {min(times):.1f}); study {study[(label, mode, samples)]:8.1f} ms")


if __name__ == "__main__":
    main(sys.argv[1])
