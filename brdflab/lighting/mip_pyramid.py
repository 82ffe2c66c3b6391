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
    """Levels (h_k, w_k, C) float32 of an (H, W, C) map, level 0 the map itself. Each level
    sums the energy (radiance × solid angle) of the one above when its blocks tile it
    evenly (power-of-two maps: every level), else of level 0."""
    height, width = data.shape[:2]
    solid = row_solid_angles(height, width)
    top = (np.asarray(data, float) * solid[:, None, None], solid, np.ones(width))  # energy, row area, columns
    levels, source = [np.asarray(data, np.float32)], top
    for w, h in level_sizes(width, height)[1:]:
        energy, row_area, columns = source
        if energy.shape[0] % h or energy.shape[1] % w:
            energy, row_area, columns = top
            rows, cols = (np.arange(h) * height) // h, (np.arange(w) * width) // w
            source = (np.add.reduceat(np.add.reduceat(energy, rows, axis=0), cols, axis=1),
                      np.add.reduceat(row_area, rows), np.add.reduceat(columns, cols))
        else:
            fy, fx = energy.shape[0] // h, energy.shape[1] // w
            source = (energy.reshape(h, fy, w, fx, -1).sum(axis=(1, 3)), row_area.reshape(h, fy).sum(axis=1),
                      columns.reshape(w, fx).sum(axis=1))
        area = source[1][:, None] * source[2][None, :]
        levels.append((source[0] / area[:, :, None]).astype(np.float32))
    return levels
