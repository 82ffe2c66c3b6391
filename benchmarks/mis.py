"""FIS against MIS (BRDF + environment importance sampling): error against samples, and the
expected sphere mean at 16 samples (bias), for three materials on three real maps.

    PYTHONPATH=$PWD python3 benchmarks/mis.py [--json docs/bench/mis.json] [--chart docs/bench/mis.png]
    # the same numbers for an older revision's FIS (overlaid dashed on the chart):
    git archive REV | tar -x -C /tmp/before
    PYTHONPATH=/tmp/before python3 benchmarks/mis.py --modes fis --json /tmp/before.json
    PYTHONPATH=$PWD python3 benchmarks/mis.py --before /tmp/before.json

Ground truth: the reference view's texel quadrature (environment_image) over the same
reduced map the renderer reads. Error: relative RMSE over the sphere of one render (the
unrotated set, what `brdflab render` gives); bias: the sphere mean of 8 independent
16-sample renders against the quadrature's.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from brdflab.lighting.envmap import load_environment
from brdflab.lighting.reference_view import environment_image, relative_rmse, sphere_view
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.render.context import create_context
from brdflab.render.object_view import ObjectRenderer, Progressive, RenderSettings

ROOT = Path(__file__).resolve().parents[1]
ENVMAPS = Path(os.environ.get("BRDFLAB_SHARED", ROOT.parent / "shared")) / "data" / "envmaps"
MAPS = {"quarry (sun)": "quarry_01_1k.hdr", "royal esplanade (lamps)": "royal_esplanade_1k.hdr",
        "venice sunset (smooth)": "venice_sunset_1k.hdr"}
MATERIALS = {
    "Lambertian": AnalyticMaterial("Lambertian", "Linear", 3, [Lobe.create("Lambertian", [0.5] * 3)]),
    "Blinn-Phong n=100": AnalyticMaterial("BlinnPhong", "Linear", 3, [Lobe.create("BlinnPhong", [0.5] * 3, Exponent=100.0)]),
    "Ward 0.08 x 0.3": AnalyticMaterial("Ward", "Linear", 3, [Lobe.create("Ward", [0.5] * 3, ax=0.08, ay=0.3)]),
}
COUNTS = (4, 16, 64, 256, 1024)
SIZE = 64
MAP_SIZE = (256, 128)
SEEDS = 8


def _independent(renderer: ObjectRenderer, settings: RenderSettings, seed: int) -> np.ndarray:
    """One render whose sample set is rotated by `seed` (older trees: through the steps)."""
    try:
        from brdflab.render.object_view import independent_image
    except ImportError:  # a revision before independent_image
        pass
    else:
        return independent_image(renderer, settings, seed)
    try:
        image = Progressive(renderer, settings, seed=seed)
    except TypeError:  # a revision before Progressive(seed=): its later steps are rotated
        image = Progressive(renderer, settings)
        image.steps, image._rng = 1, np.random.default_rng(seed)
    try:
        image.step(settings.samples)
        raw = np.frombuffer(image.texture.read(), np.float32).reshape(settings.height, settings.width, 4)[::-1]
    finally:
        image.release()
    return raw[:, :, :3] / settings.samples


def measure(modes: list[str]) -> list[dict]:
    renderer = ObjectRenderer(create_context())
    inside = sphere_view(SIZE, SIZE).inside
    rows = []
    for map_label, file in MAPS.items():
        env = load_environment(ENVMAPS / file).downsampled(*MAP_SIZE)
        renderer.set_environment(env)
        for material_label, material in MATERIALS.items():
            renderer.set_material(material)
            ref = environment_image(material, env, SIZE, SIZE)
            ref_mean = float(ref[inside].mean())
            for mode in modes:
                errors, ms = [], []
                for n in COUNTS:
                    settings = RenderSettings(mode=mode, width=SIZE, height=SIZE, samples=n)
                    renderer.render(settings)  # compiles; the second render is timed
                    t0 = time.perf_counter()
                    image = renderer.render(settings)
                    ms.append((time.perf_counter() - t0) * 1e3)
                    errors.append(relative_rmse(image, ref, inside))
                settings = RenderSettings(mode=mode, width=SIZE, height=SIZE, samples=16)
                expected = np.mean([_independent(renderer, settings, seed) for seed in range(SEEDS)], axis=0)
                rows.append({"map": map_label, "file": file, "material": material_label, "mode": mode,
                             "samples": list(COUNTS), "relative_rmse": errors, "ms": ms,
                             "mean_bias_at_16": float(expected[inside].mean()) / ref_mean - 1.0})
                print(f"{map_label:<24} {material_label:<18} {mode}  " +
                      "  ".join(f"{n}:{100 * e:6.2f}%" for n, e in zip(COUNTS, errors)) +
                      f"  bias@16 {100 * rows[-1]['mean_bias_at_16']:+.1f}%", flush=True)
    return rows


def chart(rows: list[dict], before: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(MAPS), len(MATERIALS), figsize=(12, 10), sharex=True)
    style = {"fis": ("tab:blue", "-", "FIS"), "mis": ("tab:red", "-", "MIS"), "fis-before": ("tab:blue", ":", "FIS before")}
    for i, map_label in enumerate(MAPS):
        for j, material_label in enumerate(MATERIALS):
            ax = axes[i, j]
            for key, source, mode in (("fis", rows, "fis"), ("mis", rows, "mis"), ("fis-before", before, "fis")):
                for r in source:
                    if (r["map"], r["material"], r["mode"]) == (map_label, material_label, mode):
                        color, line, label = style[key]
                        ax.loglog(r["samples"], [100 * e for e in r["relative_rmse"]], line, color=color, marker="o",
                                  ms=3, label=f"{label} (bias@16 {100 * r['mean_bias_at_16']:+.1f}%)")
            ax.set_title(f"{material_label} — {map_label}", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
            if j == 0:
                ax.set_ylabel("relative RMSE (%)")
            if i == len(MAPS) - 1:
                ax.set_xlabel("samples per pixel")
    fig.suptitle(f"FIS vs MIS against texel quadrature ({SIZE}² reference view, maps at {MAP_SIZE[0]}×{MAP_SIZE[1]})")
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modes", default="fis,mis")
    parser.add_argument("--json", type=Path, default=ROOT / "docs" / "bench" / "mis.json")
    parser.add_argument("--chart", type=Path, default=ROOT / "docs" / "bench" / "mis.png")
    parser.add_argument("--before", type=Path, help="JSON of an older revision's run, overlaid on the chart")
    args = parser.parse_args()
    rows = measure(args.modes.split(","))
    before = json.loads(args.before.read_text())["rows"] if args.before else []
    ctx_info = create_context().info.get("GL_RENDERER", "")
    args.json.write_text(json.dumps({"renderer": ctx_info, "image": SIZE, "map_size": MAP_SIZE, "seeds": SEEDS,
                                     "rows": rows, "before": before}, indent=1))
    if "mis" in args.modes:
        chart(rows, before, args.chart)


if __name__ == "__main__":
    main()
