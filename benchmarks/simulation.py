"""Simulated materials: timings and the two figures of docs/simulation.md.

    python benchmarks/simulation.py [--out docs]

1. Lobe-viewer textures computed straight from the simulation (θi = 30°): SCATMECH's
   subsurface particle model at 32 × 32 and 150 × 150 (BRDFLab's Fig. 9 sizes), the
   ray-bounce height field at 12 × 24 and 32 × 64.
2. Half/difference table builds over every core (cache bypassed).
3. Figures: the subsurface-particle lobe, coarse and fine (as BRDFLab's Fig. 9); a
   ray-bounced Gaussian height field beside its Cook–Torrance (Beckmann) fit, as lobes
   and on a sphere, with the fit's Ngan error checked on the conventions' 16 × 16 × 64 grid.
Writes OUT/bench/simulation.json and OUT/images/simulated_*.png.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
from brdflab.fitting.samples import samples_of
from brdflab.simulation import scatmech
from brdflab.simulation.material import SimulationSpec, compute_table, simulated_material
from brdflab.simulation.texture import lobe_texture

PARTICLE = {"radius": 1.0, "depth": 1.2, "density": 0.1}  # a sphere larger than the wavelengths: Mie lobes
HEIGHT_FIELD = {"rms_slope": 0.3}


def ngan_grid(source, material) -> float:
    """The conventions' independent check: 16 θi × 16 θo × 64 φo cells (φi = 0), θ ≤ 80°,
    weights sin θi sin θo, Ngan's cos θi-weighted RMS over the channels."""
    t = (np.arange(16) + 0.5) / 16 * math.radians(80)
    p = (np.arange(64) + 0.5) / 64 * 2 * np.pi
    ti, to, po = np.meshgrid(t, t, p, indexing="ij")
    wi = np.stack([np.sin(ti), np.zeros_like(ti), np.cos(ti)], -1).reshape(-1, 3)
    wo = np.stack([np.sin(to) * np.cos(po), np.sin(to) * np.sin(po), np.cos(to)], -1).reshape(-1, 3)
    w = (np.sin(ti) * np.sin(to)).ravel()
    f, g = source.evaluate(wi, wo), material.evaluate(wi, wo)
    return float(np.sqrt(np.sum(w[:, None] * (wi[:, 2:3] * (f - g)) ** 2) / (np.sum(w) * f.shape[1])))


def lobe_image(viewer, original, fitted=None, size=420):
    viewer.set_original(original)
    viewer.set_fitted(fitted)
    return viewer.render(size, size)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default="docs")
    args = parser.parse_args()
    out = Path(args.out)
    (out / "bench").mkdir(parents=True, exist_ok=True)
    (out / "images").mkdir(parents=True, exist_ok=True)
    os.environ["BRDFLAB_CACHE"] = tempfile.mkdtemp()  # time real builds, not cache hits
    result: dict = {"cores": os.cpu_count(), "textures": [], "tables": []}
    theta = math.radians(30)

    from brdflab.render.context import create_context
    from brdflab.render.lobe_view import LobeViewer
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    viewer = LobeViewer(create_context())
    viewer.settings.theta_i = 30.0
    viewer.settings.transfer = "linear"

    if scatmech.available():
        viewer.settings.transfer = "cbrt"  # BRDFLab's transfer functions: show the weak Mie lobes
        particle = SimulationSpec("SubsurfaceParticle", PARTICLE)
        images = []
        for n in (32, 150):
            tex = lobe_texture(particle, theta, 0.0, n)
            result["textures"].append({"kind": "SubsurfaceParticle", "size": [n, n], "seconds": tex.seconds})
            images.append(lobe_image(viewer, tex))
        t0 = time.perf_counter()
        compute_table(SimulationSpec("SubsurfaceParticle", PARTICLE, resolution=16))
        result["tables"].append({"kind": "SubsurfaceParticle", "resolution": 16, "seconds": time.perf_counter() - t0})
        fig, axes = plt.subplots(1, 2, figsize=(9, 4.8))
        for ax, img, n, row in zip(axes, images, (32, 150), result["textures"]):
            ax.imshow(img)
            ax.set_title(f"{n} × {n} texture, {row['seconds']:.2f} s")
            ax.axis("off")
        fig.suptitle("SCATMECH subsurface particle (r = 1 µm, depth 1.2 µm, θi = 30°, cube-root transfer)")
        fig.tight_layout()
        fig.savefig(out / "images" / "simulated_subsurface_particle.png", dpi=100)
        plt.close(fig)
        viewer.settings.transfer = "linear"

    field = SimulationSpec("GaussianHeightField", HEIGHT_FIELD, seed=1)
    for n in (12, 32):
        tex = lobe_texture(field, theta, 0.0, n)
        result["textures"].append({"kind": "GaussianHeightField", "size": [n, 2 * n], "seconds": tex.seconds})
    t0 = time.perf_counter()
    material = simulated_material(SimulationSpec("GaussianHeightField", HEIGHT_FIELD, seed=1, samples=200_000, resolution=32))
    result["tables"].append({"kind": "GaussianHeightField", "resolution": 32, "samples": 200_000,
                             "seconds": time.perf_counter() - t0})

    start = material_from_lobes(["CookTorrance"], "Linear", 3)
    fitted = fit(start, samples_of(material, "grid", density=32), FitOptions(metric="Ngan"))
    check = ngan_grid(material, fitted.material)
    result["fit"] = {"lobes": "CookTorrance", "ngan_error": fitted.error, "ngan_grid_check": check,
                     "m": fitted.material.lobes[0].params["m"], "F0": fitted.material.lobes[0].params["F0"],
                     "scale": fitted.material.lobes[0].scale[0], "seconds": fitted.seconds}

    from brdflab.render.object_view import ObjectRenderer, RenderSettings
    from brdflab.lighting.tonemap import tonemap

    renderer = ObjectRenderer(viewer.ctx)
    settings = RenderSettings(mode="point", width=300, height=300, light=(0.5, 0.4, 1.0))
    spheres = []
    for source in (material, fitted.material):
        renderer.set_source(source)
        spheres.append(renderer.render(settings))
    exposure = 0.9 / max(float(spheres[0].max()), 1e-6)
    fig, axes = plt.subplots(1, 3, figsize=(12, 4.4))
    axes[0].imshow(lobe_image(viewer, material, fitted.material))
    axes[0].set_title("lobes θi = 30°: simulation (orange), fit (blue)")
    for ax, img, title in zip(axes[1:], spheres, ("ray-bounced height field (m = 0.3)",
                                                  f"Cook–Torrance fit (m = {result['fit']['m']:.3f})")):
        ax.imshow(tonemap(img * exposure))
        ax.set_title(title)
    for ax in axes:
        ax.axis("off")
    fig.suptitle(f"Gaussian height field, mirror facets (n = 1.5), 16 × 200 000 rays; fit Ngan error {fitted.error:.4f}")
    fig.tight_layout()
    fig.savefig(out / "images" / "simulated_heightfield_fit.png", dpi=100)
    plt.close(fig)
    (out / "bench" / "simulation.json").write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
