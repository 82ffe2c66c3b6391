"""Importance sampling of an environment map by its luminance (pbrt-v4, Mitsuba 3 style).

The density over the sphere is piecewise constant: in texel (i, j) it is
lum_ij / Σ lum·Ω, Ω being the texel's exact solid angle, so texels are chosen in
proportion to the energy they hold (luminance × solid angle, the sin θ weighting of a
lat-long map). The renderer's MIS mode reads the same piecewise-constant map (the
texel a direction falls in, as the quadrature ground truth does), so the density is
exactly proportional to what it looks up. A sample picks a row by the marginal CDF, a column by that row's
conditional CDF, and then a point uniform in the texel's solid angle (cos θ uniform
between the row's edges, φ uniform across the column), which keeps the density constant
inside each texel: it integrates to 1 over the sphere exactly. The GLSL twin lives in
shaders/env_sampling.glsl and reads the tables this module builds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.lighting.envmap import EnvironmentMap, band_solid_angle, texel_of

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


@dataclass(frozen=True)
class EnvironmentDistribution:
    """Sampling tables of one map (H × W texels, row 0 at the top)."""

    density: np.ndarray  # (H, W) probability per steradian inside each texel
    conditional: np.ndarray  # (H, W) each row's CDF over columns, at each texel's right edge
    marginal: np.ndarray  # (H,) CDF over rows, at each row's lower edge

    @property
    def height(self) -> int:
        return self.density.shape[0]

    @property
    def width(self) -> int:
        return self.density.shape[1]

    def pdf(self, d: np.ndarray) -> np.ndarray:
        """Density per steradian of map directions d (..., 3) (+Y up, the map's own frame)."""
        return self.density[texel_of(d, self.height, self.width)]

    def sample(self, u: np.ndarray) -> np.ndarray:
        """Map directions (n, 3) from uniform points u (n, 2) in [0, 1)²."""
        u = np.asarray(u, float)
        rows, t_row = _invert(self.marginal, u[:, 0])
        cols, t_col = invert_in_rows(self.conditional, rows, u[:, 1])
        return texel_point(rows, cols, t_row, t_col, self.height, self.width)


def texel_point(rows: np.ndarray, cols: np.ndarray, t_row: np.ndarray, t_col: np.ndarray, height: int,
                width: int) -> np.ndarray:
    """Map directions (n, 3) in texels (rows, cols) of a height × width lat-long map, at fractions
    (t_row, t_col) across them: cos θ and φ linear in them, so uniform fractions give a point
    uniform in the texel's solid angle."""
    cos_top = np.cos(np.pi * rows / height)
    cos_bottom = np.cos(np.pi * (rows + 1) / height)
    cos_theta = cos_top + t_row * (cos_bottom - cos_top)
    sin_theta = np.sqrt(np.maximum(0.0, 1.0 - cos_theta**2))
    phi = ((cols + t_col) / width - 0.5) * 2.0 * np.pi
    return np.stack([sin_theta * np.sin(phi), cos_theta, -sin_theta * np.cos(phi)], axis=-1)


def invert_in_rows(table: np.ndarray, row: np.ndarray, u: np.ndarray,
                   lowest: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """`_invert` of row `row` of a table of CDFs (R, m), each rising within [0, 1] to 1, at each u:
    the column and u's fraction across it. Row k offset by k makes the table one rising CDF, so
    no row is copied per sample. `lowest`: the lower edge of a sample's first possible bin."""
    flat, t = _invert((table + np.arange(table.shape[0])[:, None]).ravel(), u + row, lowest=row + lowest)
    return flat - row * table.shape[1], t


def _invert(cdf: np.ndarray, u: np.ndarray, lowest: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of a rising piecewise-constant CDF (values at each bin's upper edge): the
    first bin whose value exceeds u, and u's fraction across it (`lowest`: the lower edge
    of a sample's first possible bin)."""
    index = np.minimum(np.searchsorted(cdf, u, side="right"), len(cdf) - 1)
    lower = np.where(index > 0, cdf[np.maximum(index - 1, 0)], 0.0)
    lower = np.maximum(lower, lowest)
    width = cdf[index] - lower
    t = np.where(width > 0, (u - lower) / np.where(width > 0, width, 1.0), 0.5)
    return index, np.clip(t, 0.0, 1.0)


def row_solid_angles(height: int, width: int) -> np.ndarray:
    """Exact solid angle of one texel in each row (H,) of a lat-long map."""
    return band_solid_angle(np.arange(height) / height, (np.arange(height) + 1) / height, width)


def environment_distribution(env: EnvironmentMap) -> EnvironmentDistribution:
    """The luminance distribution of a map (a black map falls back to uniform)."""
    lum = np.maximum(np.asarray(env.data, float) @ LUMINANCE, 0.0)
    if not lum.sum() > 0:
        lum = np.ones_like(lum)
    weights = lum * row_solid_angles(env.height, env.width)[:, None]
    total = weights.sum()
    row_sums = weights.sum(axis=1)
    uniform_row = np.arange(1, env.width + 1) / env.width
    conditional = np.where(row_sums[:, None] > 0,
                           np.cumsum(weights, axis=1) / np.where(row_sums > 0, row_sums, 1.0)[:, None],
                           uniform_row[None, :])
    conditional[:, -1] = 1.0
    marginal = np.cumsum(row_sums) / total
    marginal[-1] = 1.0
    return EnvironmentDistribution(lum / total, conditional, marginal)
