"""Mip levels of a lat-long map that average by solid angle.

GL's own mip generation averages 2 × 2 texels with equal weights, but a lat-long texel's
solid angle shrinks with sin θ: its coarse levels over-weight the poles (a ceiling lamp
near the zenith gained 2.6× its light in FIS at 16 samples, docs/mis.md). Here every
texel of level k is the solid-angle-weighted mean of the level-0 texels it covers, so a
level holds the same energy as the map, whatever its size (odd sizes included).
"""

from __future__ import annotations

import numpy as np

from brdflab.lighting.env_sampling import row_solid_angles


def level_sizes(width: int, height: int) -> list[tuple[int, int]]:
    """(width, height) of every mip level, as OpenGL sizes them, down to 1 × 1."""
    sizes = [(width, height)]
    while sizes[-1] != (1, 1):
        w, h = sizes[-1]
        sizes.append((max(1, w // 2), max(1, h // 2)))
    return sizes


def solid_angle_mips(data: np.ndarray) -> list[np.ndarray]:
    """Levels (h_k, w_k, C) float32 of an (H, W, C) map, level 0 the map itself."""
    height, width = data.shape[:2]
    solid = row_solid_angles(height, width)
    weighted = np.asarray(data, float) * solid[:, None, None]
    levels = []
    for w, h in level_sizes(width, height):
        row_starts = (np.arange(h) * height) // h
        col_starts = (np.arange(w) * width) // w
        energy = np.add.reduceat(np.add.reduceat(weighted, row_starts, axis=0), col_starts, axis=1)
        area = np.add.reduceat(solid, row_starts)[:, None] * np.diff(np.append(col_starts, width))[None, :]
        levels.append((energy / area[:, :, None]).astype(np.float32))
    return levels
