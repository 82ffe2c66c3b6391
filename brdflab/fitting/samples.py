"""Sample sets that a fit runs over, delivered in chunks so that memory stays small.

A sample set yields chunks (wi, wo, values (n, C), weight (n,)); `weight` is the sample's
share of the (ωi, ωo) measure, which every metric weighs squared differences by.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.geometry.halfdiff import (N_PD, N_TD, N_TH, from_half_diff, phi_d_of_bin, theta_d_edge, theta_d_of_bin,
                                       theta_h_edge, theta_h_of_bin)
from brdflab.sources.measured import MeasuredTable, RawSamples
from brdflab.geometry.vec import spherical_to_cartesian

Chunk = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


MAX_DENSITY = N_TH  # a grid finer than MERL's 90 bins per angle adds nothing to a table
MAX_GRID_SAMPLES = 4_000_000  # an analytic grid's samples (an anisotropic density-32 grid has 2.1 M)

GOLDEN = 0.6180339887498949  # the golden ratio's fractional part: a low-discrepancy sequence


def phi_h_of(index: np.ndarray) -> np.ndarray:
    """The φh a sample gets: a golden-ratio sequence of its index (low discrepancy)."""
    return 2.0 * np.pi * np.mod(np.asarray(index, float) * GOLDEN, 1.0)


def rotate_about_normal(v: np.ndarray, cos_phi: np.ndarray, sin_phi: np.ndarray) -> np.ndarray:
    out = np.empty_like(v)
    out[:, 0] = cos_phi * v[:, 0] - sin_phi * v[:, 1]
    out[:, 1] = sin_phi * v[:, 0] + cos_phi * v[:, 1]
    out[:, 2] = v[:, 2]
    return out


def spread_phi_h(wi: np.ndarray, wo: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotate each pair about the normal by its own φh (`phi_h_of` its index). An isotropic
    source has the same value at every φh, so this changes no data value; it makes the
    samples cover φh, so that anisotropic lobes (Ward's ay, …) are fitted over the whole
    (ωi, ωo) measure instead of the plane φh = 0."""
    phi = phi_h_of(index)
    c, s = np.cos(phi), np.sin(phi)
    return rotate_about_normal(wi, c, s), rotate_about_normal(wo, c, s)


class SampleSet:
    """Base: a finite set of (wi, wo) with measured values, iterated in chunks."""

    n_channels: int
    size: int

    def chunks(self) -> Iterator[Chunk]:
        raise NotImplementedError

    def subset(self, size: int, seed: int = 0) -> "SampleSet":
        raise NotImplementedError

    def digest(self) -> str:
        """SHA-256 of what the samples are made of: equal digests, equal samples (fit_cache.py)."""
        raise NotImplementedError


def _digest(*arrays: np.ndarray) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(memoryview(a).cast("B"))
    return h.hexdigest()


@dataclass
class ArraySampleSet(SampleSet):
    """Samples held in arrays (raw measurements, subsets, grids over analytic sources)."""

    wi: np.ndarray
    wo: np.ndarray
    values: np.ndarray
    weight: np.ndarray
    chunk: int = 65536

    def __post_init__(self) -> None:
        self.size = int(self.values.shape[0])
        self.n_channels = int(self.values.shape[1])
        if self.size == 0:
            raise BRDFLabError("the source has no valid samples to fit")

    def chunks(self) -> Iterator[Chunk]:
        for s in range(0, self.size, self.chunk):
            e = s + self.chunk
            yield self.wi[s:e], self.wo[s:e], self.values[s:e], self.weight[s:e]

    def digest(self) -> str:
        return _digest(self.wi, self.wo, self.values, self.weight)

    def subset(self, size: int, seed: int = 0) -> "ArraySampleSet":
        if size >= self.size:
            return self
        idx = stratified_indices(self.size, size, seed)
        return ArraySampleSet(self.wi[idx], self.wo[idx], self.values[idx], self.weight[idx] * (self.size / size))


def _join(parts: list[Chunk]) -> Chunk:
    return tuple(np.concatenate(x) for x in zip(*parts))  # type: ignore[return-value]


def stratified_indices(n: int, k: int, seed: int = 0) -> np.ndarray:
    """One random index from each of k equal strata of range(n) (samples are ordered
    by θh, θd, φd, so strata spread the subset over the whole domain)."""
    rng = np.random.default_rng(seed)
    edges = np.linspace(0, n, k + 1)
    lo = np.floor(edges[:-1]).astype(np.int64)
    hi = np.maximum(np.floor(edges[1:]).astype(np.int64), lo + 1)
    return np.minimum(lo + (rng.random(k) * (hi - lo)).astype(np.int64), n - 1)


class TableSampleSet(SampleSet):
    """Every valid sample of a measured table at its bin centres, generated row by row
    (one θh bin per chunk) from the table itself: no per-sample arrays are kept.

    A bivariate slice stands for every φd: it is expanded over MERL's 180 φd bins, so
    that a slice and its full-table expansion are the same set of (ωi, ωo) samples.
    Each sample gets its own φh (see `spread_phi_h`)."""

    def __init__(self, table: MeasuredTable, theta_h_bins: np.ndarray | None = None,
                 theta_d_bins: np.ndarray | None = None, phi_d_bins: np.ndarray | None = None) -> None:
        self.table = table
        self.n_channels = table.n_channels
        self.ix = np.arange(N_TH) if theta_h_bins is None else np.asarray(theta_h_bins)
        self.iy = np.arange(N_TD) if theta_d_bins is None else np.asarray(theta_d_bins)
        self.iz = np.arange(N_PD) if phi_d_bins is None else np.asarray(phi_d_bins)
        iy, iz = np.meshgrid(np.arange(len(self.iy)), self.iz, indexing="ij")
        self._col_ypos, self._col_y, self._col_z = iy.ravel(), self.iy[iy.ravel()], iz.ravel()
        self._col_value_z = self._col_z if table.phi_d_samples > 1 else np.zeros_like(self._col_z)
        td, pd = theta_d_of_bin(self._col_y), phi_d_of_bin(self._col_z)
        self._d = spherical_to_cartesian(td, pd)  # difference vectors, shared by all rows
        # a column's value in a row of the table seen as (channels, θh, θd · φd): `np.take` of
        # these is 4–7× faster than indexing the table and `_d` with arrays of indices
        self._col_value_index = self._col_y * table.values.shape[3] + self._col_value_z
        # sample (row x, column j) has φh = phi_h_of(x·columns + j) = row phase + column phase
        col_phase = phi_h_of(np.arange(len(self._d)))
        self._col_cos, self._col_sin = np.cos(col_phase), np.sin(col_phase)
        # measure: each taken bin stands for the bins up to the next one taken (all, unless a grid)
        y_next = np.append(self.iy[1:], N_TD)[self._col_ypos]
        self._cell = 4.0 * 0.5 * (np.sin(theta_d_edge(y_next)) ** 2 - np.sin(theta_d_edge(self._col_y)) ** 2) \
            * 2.0 * np.pi * (2.0 * np.pi / len(self.iz))  # φd over [0, 2π) folded onto [0, π) by reciprocity
        self._row_weight = np.cos(theta_h_edge(self.ix)) - np.cos(theta_h_edge(np.append(self.ix[1:], N_TH)))
        # measured and geometrically meaningful: both directions above the surface
        th = theta_h_of_bin(self.ix)[:, None]
        a = np.cos(th) * np.cos(td)[None, :]
        b = np.sin(th) * (np.sin(td) * np.cos(pd))[None, :]
        above = (a - b > 1e-6) & (a + b > 1e-6)
        valid = table.valid[np.ix_(self.ix, self.iy)]  # (rows, θd taken, φd of the table)
        self._row_valid = valid[:, self._col_ypos, self._col_value_z] & above
        self._row_start = np.concatenate([[0], np.cumsum(self._row_valid.sum(axis=1))])
        self.size = int(self._row_start[-1])
        if self.size == 0:
            raise BRDFLabError("the source has no valid samples to fit", table.path)

    def _row(self, r: int, cols: np.ndarray) -> Chunk:
        """Samples of row r (θh bin self.ix[r]) at columns `cols`: wi is the difference
        vector rotated by θh about y, wo its mirror about h, both then turned by φh."""
        x = int(self.ix[r])
        th = float(theta_h_of_bin(x))
        c, s = np.cos(th), np.sin(th)
        d = np.take(self._d, cols, axis=0)
        wi = np.empty_like(d)
        wi[:, 0] = c * d[:, 0] + s * d[:, 2]
        wi[:, 1] = d[:, 1]
        wi[:, 2] = c * d[:, 2] - s * d[:, 0]
        wo = -wi
        k = 2.0 * (s * wi[:, 0] + c * wi[:, 2])
        wo[:, 0] += k * s
        wo[:, 2] += k * c
        row_phase = 2.0 * np.pi * ((x * len(self._d) * GOLDEN) % 1.0)
        cr, sr = np.cos(row_phase), np.sin(row_phase)
        cc, sc = np.take(self._col_cos, cols), np.take(self._col_sin, cols)
        cos_phi, sin_phi = cr * cc - sr * sc, sr * cc + cr * sc
        wi, wo = rotate_about_normal(wi, cos_phi, sin_phi), rotate_about_normal(wo, cos_phi, sin_phi)
        row_values = self.table.values[:, x].reshape(self.n_channels, -1)
        y = np.ascontiguousarray(np.take(row_values, np.take(self._col_value_index, cols), axis=1).T, dtype=float)
        return wi, wo, y, np.take(self._cell, cols) * self._row_weight[r]

    def chunks(self) -> Iterator[Chunk]:
        """One θh bin per chunk (at most 16,200 samples)."""
        for r in range(len(self.ix)):
            cols = np.flatnonzero(self._row_valid[r])
            if cols.size:
                yield self._row(r, cols)

    def digest(self) -> str:
        """The table's values and validity and the bins taken: the samples follow from them."""
        return _digest(self.table.values, self.table.valid, self.ix, self.iy, self.iz)

    def subset(self, size: int, seed: int = 0) -> ArraySampleSet:
        """A stratified subset of `size` samples, as arrays (weights scaled to the whole)."""
        pos = stratified_indices(self.size, min(size, self.size), seed)
        rows = np.searchsorted(self._row_start, pos, side="right") - 1
        parts = []
        for r in np.unique(rows):  # one θh row at a time: no array of every valid index
            cols = np.flatnonzero(self._row_valid[r])[pos[rows == r] - self._row_start[r]]
            parts.append(self._row(int(r), cols))
        wi, wo, values, weight = _join(parts)
        return ArraySampleSet(wi, wo, values, weight * (self.size / pos.size))


def analytic_grid(source, density: int = 32, phi_h_bins: int | None = None) -> ArraySampleSet:
    """Samples of any source on a half/difference grid: `density` θh and θd bins, 2·density
    φd bins, and (anisotropic sources) `phi_h_bins` φh bins."""
    d = int(density)
    if d < 2:
        raise BRDFLabError(f"grid density {d} is too small (at least 2)")
    nph = 1 if source.isotropic else (phi_h_bins or d)
    if 2 * d**3 * nph > MAX_GRID_SAMPLES:
        raise BRDFLabError(f"grid density {d} makes {2 * d**3 * nph:,} samples, more than the "
                           f"{MAX_GRID_SAMPLES:,} supported")
    x = (np.arange(d) + 0.5) / d
    th = x**2 * 0.5 * np.pi
    td = x * 0.5 * np.pi
    pd = (np.arange(2 * d) + 0.5) / (2 * d) * np.pi
    ph = (np.arange(nph) + 0.5) / nph * 2.0 * np.pi if nph > 1 else np.zeros(1)
    TH, PH, TD, PD = np.meshgrid(th, ph, td, pd, indexing="ij")
    wi, wo = from_half_diff(TH.ravel(), PH.ravel(), TD.ravel(), PD.ravel())
    if nph == 1:  # isotropic: any φh stands for all; spread them for anisotropic lobes
        wi, wo = spread_phi_h(wi, wo, np.arange(wi.shape[0]))
    keep = (wi[:, 2] > 1e-6) & (wo[:, 2] > 1e-6)
    wi, wo = wi[keep], wo[keep]
    # measure: 4 cos θd sin θh dθh sin θd dθd dφh dφd, with dθh = π x dx
    w = (4.0 * np.cos(TD) * np.sin(TH) * (np.pi * np.sqrt(TH / (0.5 * np.pi)) * 0.5 * np.pi / d)
         * np.sin(TD) * (0.5 * np.pi / d) * (2 * np.pi / nph) * (2 * np.pi / (2 * d))).ravel()[keep]
    values = source.evaluate(wi, wo)
    ok = np.all(np.isfinite(values), axis=1)
    return ArraySampleSet(wi[ok], wo[ok], values[ok], w[ok])


def samples_of(source, kind: str = "all", size: int | None = None, density: int | None = None) -> SampleSet:
    """The sample set of a source: 'all' valid samples, a stratified 'subset' of `size`,
    or a 'grid' of `density` bins per half/difference angle."""
    if kind not in ("all", "subset", "grid"):
        raise BRDFLabError(f"unknown sample set {kind!r} (all, subset or grid)")
    if size is not None and size < 1:
        raise BRDFLabError(f"a subset of {size} samples: the size must be at least 1")
    if density is not None and not 2 <= density <= MAX_DENSITY:
        raise BRDFLabError(f"grid density {density}: must be 2..{MAX_DENSITY} bins per angle")
    if isinstance(source, MeasuredTable):
        if kind == "grid":
            step = max(1, N_TH // max(2, density or 45))
            full = TableSampleSet(source, np.arange(0, N_TH, step), np.arange(0, N_TD, step),
                                  np.arange(0, N_PD, step))
        else:
            full = TableSampleSet(source)
        return full.subset(size or 50_000) if kind == "subset" else full
    if isinstance(source, RawSamples):
        wi, wo, v = source.sample_directions()
        full = ArraySampleSet(wi, wo, v.astype(float), np.full(v.shape[0], 4.0 * np.pi**2 / max(v.shape[0], 1)))
        return full.subset(size or 50_000) if kind == "subset" else full
    grid = analytic_grid(source, density or 32)
    return grid.subset(size) if kind == "subset" and size else grid
