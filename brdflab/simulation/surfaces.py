"""Periodic microgeometries that the ray-bounce simulator traces.

Each surface answers, for points p and unit directions d (arrays (N, 3)):
`gap(p)` a lower bound of the clearance above the surface (< 0 below it),
`step(p, d)` how far a ray may advance along d without crossing the surface
(inf when it can never meet it again), `normal(p)` the unit normal at a point on
it, and `top`, the height above which the surface is empty. Lengths are in
units of the tile's grid cell (height fields) or of the period (grooves, spheres).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.geometry.vec import normalize


def _lipschitz_step(gap: np.ndarray, d: np.ndarray, max_slope: float) -> np.ndarray:
    """Along d, z − h(x, y) falls at most at rate S·|d_xy| − d_z: advancing gap / rate
    never crosses a height field of slope ≤ S (inf where the rate is not positive)."""
    rate = max_slope * np.hypot(d[:, 0], d[:, 1]) - d[:, 2]
    with np.errstate(divide="ignore"):
        return np.where(rate > 0.0, gap / np.maximum(rate, 1e-300), np.inf)


@dataclass
class HeightField:
    """A periodic grid of heights, bilinearly interpolated (cell size 1)."""

    heights: np.ndarray  # (n, n)

    def __post_init__(self) -> None:
        h = self.heights
        dx = np.abs(np.roll(h, -1, axis=1) - h).max()
        dy = np.abs(np.roll(h, -1, axis=0) - h).max()
        self.max_slope = float(np.hypot(dx, dy))  # bounds |∇h| of the bilinear surface everywhere
        self.top = float(h.max())

    @property
    def size(self) -> float:
        return float(self.heights.shape[0])

    def _corners(self, p: np.ndarray):
        n = self.heights.shape[0]
        x, y = p[:, 0], p[:, 1]
        fx, fy = x - np.floor(x), y - np.floor(y)
        i0 = np.floor(x).astype(np.int64) % n
        j0 = np.floor(y).astype(np.int64) % n
        i1, j1 = (i0 + 1) % n, (j0 + 1) % n
        h = self.heights
        return fx, fy, h[j0, i0], h[j0, i1], h[j1, i0], h[j1, i1]

    def height(self, p: np.ndarray) -> np.ndarray:
        fx, fy, h00, h10, h01, h11 = self._corners(p)
        return (1 - fy) * ((1 - fx) * h00 + fx * h10) + fy * ((1 - fx) * h01 + fx * h11)

    def gap(self, p: np.ndarray) -> np.ndarray:
        return p[:, 2] - self.height(p)

    def step(self, p: np.ndarray, d: np.ndarray) -> np.ndarray:
        return _lipschitz_step(self.gap(p), d, self.max_slope)

    def normal(self, p: np.ndarray) -> np.ndarray:
        fx, fy, h00, h10, h01, h11 = self._corners(p)
        hx = (1 - fy) * (h10 - h00) + fy * (h11 - h01)
        hy = (1 - fx) * (h01 - h00) + fx * (h11 - h10)
        return normalize(np.stack([-hx, -hy, np.ones_like(hx)], axis=1))


def gaussian_height_field(n: int, correlation: float, rms_slope: float, rng: np.random.Generator) -> HeightField:
    """A periodic Gaussian random surface with Gaussian correlation exp(−r²/ℓ²) (ℓ in
    cells), scaled so that its RMS slope √(⟨h_x²⟩ + ⟨h_y²⟩), measured on the grid, is
    exactly `rms_slope` (the Beckmann roughness m of its slope distribution)."""
    noise = rng.standard_normal((n, n))
    k = 2 * np.pi * np.fft.fftfreq(n)
    kx, ky = np.meshgrid(k, k)
    filt = np.exp(-(kx**2 + ky**2) * correlation**2 / 8.0)  # √ of the Gaussian power spectrum
    h = np.real(np.fft.ifft2(np.fft.fft2(noise) * filt))
    h -= h.mean()
    sx = np.roll(h, -1, axis=1) - h
    sy = np.roll(h, -1, axis=0) - h
    measured = np.sqrt(np.mean(sx**2) + np.mean(sy**2))
    return HeightField(h * (rms_slope / measured))


@dataclass
class VGrooves:
    """Parallel symmetric V-grooves along y, period 1, facets tilted by `angle` (radians):
    h(x) = tan(angle) · |frac(x) − ½|. Facet normals (±sin a, 0, cos a)."""

    angle: float

    def __post_init__(self) -> None:
        self.max_slope = float(np.tan(self.angle))
        self.top = 0.5 * self.max_slope
        self.size = 1.0

    def height(self, p: np.ndarray) -> np.ndarray:
        u = p[:, 0] - np.floor(p[:, 0])
        return self.max_slope * np.abs(u - 0.5)

    def gap(self, p: np.ndarray) -> np.ndarray:
        return p[:, 2] - self.height(p)

    def step(self, p: np.ndarray, d: np.ndarray) -> np.ndarray:
        return _lipschitz_step(self.gap(p), d, self.max_slope)

    def normal(self, p: np.ndarray) -> np.ndarray:
        u = p[:, 0] - np.floor(p[:, 0])
        side = np.where(u < 0.5, 1.0, -1.0)
        s, c = np.sin(self.angle), np.cos(self.angle)
        return np.stack([side * s, np.zeros_like(u), np.full_like(u, c)], axis=1)


@dataclass
class SpheresOnPlane:
    """Spheres of radius r resting on the plane z = 0, one per cell of a periodic k × k
    grid of cells of side s = r·√(π / coverage), jittered inside their cell (no overlap)."""

    radius: float
    coverage: float
    rng: np.random.Generator
    cells: int = 16

    def __post_init__(self) -> None:
        r = self.radius
        self.cell = r * np.sqrt(np.pi / self.coverage)
        room = 0.5 * self.cell - r
        k = self.cells
        ii, jj = np.meshgrid(np.arange(k), np.arange(k), indexing="xy")
        jitter = self.rng.uniform(-room, room, size=(2, k, k))
        self.centres = np.stack([(ii + 0.5) * self.cell + jitter[0], (jj + 0.5) * self.cell + jitter[1]], axis=-1)  # [j, i]
        self.top = 2.0 * r
        self.max_slope = np.inf

    def _nearest(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance to the nearest sphere of the 3 × 3 cells around p, and its centre."""
        k, s = self.cells, self.cell
        ci = np.floor(p[:, 0] / s).astype(np.int64)
        cj = np.floor(p[:, 1] / s).astype(np.int64)
        best = np.full(p.shape[0], np.inf)
        centre = np.zeros_like(p)
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                i, j = ci + di, cj + dj
                c = self.centres[j % k, i % k]
                cx = c[:, 0] + (i - i % k) * s  # the periodic image next to p
                cy = c[:, 1] + (j - j % k) * s
                dist = np.sqrt((p[:, 0] - cx) ** 2 + (p[:, 1] - cy) ** 2 + (p[:, 2] - self.radius) ** 2) - self.radius
                closer = dist < best
                best = np.where(closer, dist, best)
                centre[closer] = np.stack([cx, cy, np.full_like(cx, self.radius)], axis=1)[closer]
        return best, centre

    def gap(self, p: np.ndarray) -> np.ndarray:
        # spheres outside the 3 × 3 block are at least one cell away
        return np.minimum(np.minimum(p[:, 2], self._nearest(p)[0]), self.cell)

    def step(self, p: np.ndarray, d: np.ndarray) -> np.ndarray:
        return self.gap(p)  # a distance bound is a safe step in any direction

    def normal(self, p: np.ndarray) -> np.ndarray:
        dist, centre = self._nearest(p)
        on_sphere = dist < p[:, 2]
        return np.where(on_sphere[:, None], normalize(p - centre), np.array([0.0, 0.0, 1.0]))

    @property
    def size(self) -> float:
        return self.cells * self.cell
