"""The lobe viewer's surface in NumPy: its radius along each direction, how far its flat
triangles stray from the exact lobe, and the lowest subdivision that keeps them close.

The viewer (brdflab/render/lobe_view.py) draws a geodesic hemisphere whose vertices sit at
the lobe's radius; between vertices the surface is a flat triangle. Its error is measured
inside every triangle: at barycentric points p = Σ bᵢ rᵢ dᵢ, the distance to the exact lobe
point r(p̂) p̂ along the same direction, relative to the lobe's peak radius.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.geometry.geodesic import geodesic_hemisphere

CHANNELS = {"red": 0, "green": 1, "blue": 2, "luminance": 3}
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
LEVELS = range(2, 8)  # the viewer's subdivision levels
FINEST = 8  # the error is sought at points as dense as a level-8 hemisphere's vertices (~0.5° apart)


@dataclass(frozen=True)
class LobeShape:
    """What the viewer draws of a source: the incident direction and how values become radii."""

    wi: tuple[float, float, float]
    channel: str = "luminance"
    cosine: bool = False
    transfer: str = "cbrt"


def lobe_radii(source, shape: LobeShape, wo: np.ndarray) -> np.ndarray:
    """The surface's radius along each direction wo (N, 3), before the viewer's gain: what
    shaders/lobe_vertex.glsl computes per vertex (channel, cosine, transfer)."""
    wi = np.broadcast_to(np.asarray(shape.wi, float), wo.shape)
    f = np.asarray(source.evaluate(wi, wo), float)[:, :3]
    if f.shape[1] == 1:
        f = np.repeat(f, 3, axis=1)
    v = f @ LUMINANCE if shape.channel == "luminance" else f[:, CHANNELS[shape.channel]]
    v = np.maximum(v, 0.0) * (np.maximum(wo[:, 2], 0.0) if shape.cosine else 1.0)
    return {"linear": v, "cbrt": np.cbrt(v), "log": np.log1p(v)}[shape.transfer]


def surface_error(source, shape: LobeShape, level: int) -> tuple[float, float]:
    """(max, RMS) distance of the level-`level` surface from the exact lobe, relative to the
    peak radius, over barycentric points of every triangle (vertices excluded: exact there),
    as dense at every level as the finest hemisphere's vertices, so that a lobe narrower than
    a coarse triangle cannot hide between the points that look for it."""
    inside = 2 ** max(1, FINEST - level)
    dirs, faces = geodesic_hemisphere(level)
    dirs = dirs.astype(float)
    radii = lobe_radii(source, shape, dirs)
    i, j = np.meshgrid(np.arange(inside + 1), np.arange(inside + 1), indexing="ij")
    keep = (i + j <= inside) & ~(((i == inside) | (j == inside)) | ((i == 0) & (j == 0)))
    bary = np.stack([i[keep], j[keep], inside - i[keep] - j[keep]], axis=1) / inside  # (B, 3)
    corners = radii[faces][:, :, None] * dirs[faces]  # (T, 3 corners, 3)
    points = np.einsum("bk,tkc->tbc", bary, corners).reshape(-1, 3)
    length = np.linalg.norm(points, axis=1)
    direction = np.where(length[:, None] > 0, points / np.maximum(length, 1e-300)[:, None],
                         np.einsum("bk,tkc->tbc", bary, dirs[faces]).reshape(-1, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    exact = lobe_radii(source, shape, direction)
    peak = max(float(radii.max()), float(exact.max()), 1e-300)
    error = np.abs(length - exact) / peak
    return float(error.max()), float(np.sqrt(np.mean(error**2)))


def auto_level(sources, shape: LobeShape, tolerance: float = 0.01) -> tuple[int, float]:
    """The lowest level whose worst surface error, over every source drawn (an original and
    its fit), is within `tolerance` of the peak radius; the top level when none is. Returns
    (level, its worst error)."""
    worst = np.inf
    for level in LEVELS:
        worst = max(surface_error(s, shape, level)[0] for s in sources if s is not None)
        if worst <= tolerance:
            return level, worst
    return LEVELS[-1], worst
