"""The Mitsuba 3 export rendered by Mitsuba 3 next to the lab's own renders of the material.

Both draw CONVENTIONS.md's reference view under one lat-long map. Mitsuba renders the scene
file `brdflab export --format mitsuba` wrote (loaded as a user would, `mi.load_file`), twice
with different seeds; the lab gives its NumPy quadrature over the map's texels (the ground
truth of every lighting benchmark) and its MIS renderer. The relative RMSE counts the pixels
whose whole square lies on the sphere (Mitsuba's box filter averages over the pixel, the
lab's reference view takes its centre), and Mitsuba's own noise is taken out: two renders
with independent seeds differ by √2 σ, their mean carries σ/√2, so the renderers' difference
is √(max(0, e² − σ²/2)) with e the mean's RMSE against the lab.
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
    quadrature_rmse: float  # the Mitsuba mean against the lab's quadrature, noise taken out
    raw_rmse: float  # the same before taking the noise out
    mitsuba_noise: float  # σ of one Mitsuba render, relative
    renderer_rmse: float | None  # against the lab's MIS renderer (None: not rendered)
    mitsuba: np.ndarray
    lab: np.ndarray

    def as_dict(self) -> dict:
        return {"material": self.name, "relative_rmse": self.quadrature_rmse, "raw_relative_rmse": self.raw_rmse,
                "mitsuba_noise": self.mitsuba_noise, "relative_rmse_vs_lab_mis": self.renderer_rmse}


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


def compare(name: str, material, env, size: int = 32, spp: int = 1024, lab_samples: int | None = None) -> Comparison:
    """Mitsuba against the lab's quadrature (and, given `lab_samples`, the lab's MIS renderer)."""
    with tempfile.TemporaryDirectory() as tmp:
        first, second = mitsuba_renders(material, env, size, spp, Path(tmp))
    lab = environment_image(material, env, size, size)
    mask = inner_pixels(size)
    mean = 0.5 * (first + second)
    noise = relative_rmse(first, second, mask) / math.sqrt(2.0)
    raw = relative_rmse(mean, lab, mask)
    corrected = math.sqrt(max(0.0, raw * raw - noise * noise / 2.0))
    rendered = None
    if lab_samples:
        rendered = relative_rmse(mean, lab_mis(material, env, size, lab_samples), mask)
    return Comparison(name, corrected, raw, noise, rendered, mean, lab)
