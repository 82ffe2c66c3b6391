"""The Mitsuba 3 export rendered by Mitsuba 3 next to the lab's own renders of the material.

Both draw CONVENTIONS.md's reference view under one lat-long map. Mitsuba renders the scene
file `brdflab export --format mitsuba` wrote (loaded as a user would, `mi.load_file`), twice
with different seeds; the lab renders the material with its MIS renderer at N and 4N samples
per pixel, and with its NumPy quadrature over the map's texels. Relative RMSEs count the
pixels whose whole square lies on the sphere (Mitsuba's box filter averages over the pixel,
the lab's reference view takes its centre). Noise is taken out: two Mitsuba renders with
independent seeds differ by √2 σ and their mean carries σ/√2; the lab's renders at N and 4N
differ by √(5/4) σ_N and the 4N one carries σ_N / 2. The quadrature has no noise, but takes
the map's radiance constant over each texel at its centre: for a lobe narrower than a texel
(a clear coat of gloss ≈ 1, α ≈ 0.002) it aliases, where both renderers interpolate the map.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdflab.export import export_source
from brdflab.lighting.reference_view import environment_image


@dataclass
class Comparison:
    name: str
    renderer_rmse: float  # the Mitsuba mean against the lab's MIS renderer (4N), noise taken out
    quadrature_rmse: float  # the Mitsuba mean against the lab's quadrature, Mitsuba's noise taken out
    raw_renderer_rmse: float  # before taking the noise out
    mitsuba_noise: float  # σ of one Mitsuba render, relative
    lab_noise: float  # σ of the lab's 4N render, relative
    mitsuba: np.ndarray
    lab: np.ndarray  # the lab's MIS render (4N)

    def as_dict(self) -> dict:
        return {"material": self.name, "relative_rmse": self.renderer_rmse, "raw_relative_rmse": self.raw_renderer_rmse,
                "relative_rmse_vs_quadrature": self.quadrature_rmse, "mitsuba_noise": self.mitsuba_noise,
                "lab_noise": self.lab_noise}


def inner_pixels(size: int) -> np.ndarray:
    """Pixels whose whole square lies on the unit sphere of the reference view."""
    x = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    X, Y = np.meshgrid(x, -x)
    return np.hypot(X, Y) + math.sqrt(2.0) / size < 1.0


def relative_rmse(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    d = a[mask] - b[mask]
    return float(np.sqrt((d * d).mean() / max((b[mask] ** 2).mean(), 1e-300)))


def mitsuba_renders(material, env, size: int, spp: int, folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """Two Mitsuba renders (independent seeds) of the scene the exporter writes."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    scene_path = folder / "scene.xml"
    export_source(material, "mitsuba", scene_path, env=env)
    scene = mi.load_file(str(scene_path), resx=size, resy=size, spp=spp)
    return tuple(np.array(mi.render(scene, seed=seed), dtype=float)[..., :3] for seed in (1, 2))


def lab_mis(material, env, size: int, samples: int) -> np.ndarray:
    from brdflab.render.context import create_context
    from brdflab.render.object_view import ObjectRenderer, RenderSettings

    renderer = ObjectRenderer(create_context())
    renderer.set_source(material)
    renderer.set_environment(env)
    return renderer.render(RenderSettings(mode="mis", width=size, height=size, samples=samples, reference_view=True))


def without_noise(raw: float, noise_variance: float) -> float:
    return math.sqrt(max(0.0, raw * raw - noise_variance))


def compare(name: str, material, env, size: int = 32, spp: int = 1024, lab_samples: int = 1024) -> Comparison:
    """Mitsuba against the lab's MIS renderer (at `lab_samples` and 4×) and its quadrature."""
    with tempfile.TemporaryDirectory() as tmp:
        first, second = mitsuba_renders(material, env, size, spp, Path(tmp))
    mask = inner_pixels(size)
    mean = 0.5 * (first + second)
    mitsuba_noise = relative_rmse(first, second, mask) / math.sqrt(2.0)
    coarse, fine = (lab_mis(material, env, size, n) for n in (lab_samples, 4 * lab_samples))
    lab_noise = relative_rmse(coarse, fine, mask) / math.sqrt(1.25) / 2.0
    raw = relative_rmse(mean, fine, mask)
    renderer = without_noise(raw, mitsuba_noise**2 / 2.0 + lab_noise**2)
    quadrature = without_noise(relative_rmse(mean, environment_image(material, env, size, size), mask), mitsuba_noise**2 / 2.0)
    return Comparison(name, renderer, quadrature, raw, mitsuba_noise, lab_noise, mean, fine)
