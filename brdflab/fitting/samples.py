"""Sample sets that a fit runs over, delivered in chunks so that memory stays small.

A sample set yields chunks (wi, wo, values (n, C), weight (n,), cos_i (n,)); `weight`
is the sample's share of the (ωi, ωo) measure, used by the Ngan metric.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.geometry.halfdiff import N_PD, N_TD, N_TH, from_half_diff, phi_d_of_bin, theta_d_of_bin, theta_h_of_bin
from brdflab.sources.measured import MeasuredTable, RawSamples
from brdflab.geometry.vec import spherical_to_cartesian

Chunk = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def merl_cell_measure(ix: np.ndarray, iy: np.ndarray, n_pd: int) -> np.ndarray:
    """Measure of MERL cells in (ωi, ωo) space: dωi dωo = 4 cos θd dωh dωd (Rusinkiewicz),
    integrated over each θh and θd bin, 2π in φh and π/n_pd in φd."""
    th0, th1 = theta_h_of_bin(ix), theta_h_of_bin(np.minimum(ix + 1, N_TH))
    td0, td1 = theta_d_of_bin(iy), theta_d_of_bin(np.minimum(iy + 1, N_TD))
    dh = np.cos(th0) - np.cos(th1)
    dd = 0.5 * (np.sin(td1) ** 2 - np.sin(td0) ** 2)
    return 4.0 * dh * dd * 2.0 * np.pi * (np.pi / n_pd)


class SampleSet:
    """Base: a finite set of (wi, wo) with measured values, iterated in chunks."""

    n_channels: int
    size: int

    def chunks(self) -> Iterator[Chunk]:
        raise NotImplementedError

    def subset(self, size: int, seed: int = 0) -> "SampleSet":
        raise NotImplementedError


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
    """Every valid sample of a measured table, generated row by row (one θh bin per
    chunk) from the table itself: no per-sample arrays are kept."""

    def __init__(self, table: MeasuredTable, theta_h_bins: np.ndarray | None = None,
                 theta_d_bins: np.ndarray | None = None, phi_d_bins: np.ndarray | None = None) -> None:
        self.table = table
        self.n_channels = table.n_channels
        npd = table.phi_d_samples
        self.ix = np.arange(N_TH) if theta_h_bins is None else np.asarray(theta_h_bins)
        self.iy = np.arange(N_TD) if theta_d_bins is None else np.asarray(theta_d_bins)
        self.iz = np.arange(npd) if phi_d_bins is None else np.asarray(phi_d_bins)
        td, pd = np.meshgrid(theta_d_of_bin(self.iy), phi_d_of_bin(self.iz) if npd > 1 else np.array([0.5 * np.pi]), indexing="ij")
        self._td, self._pd = td.ravel(), pd.ravel()
        self._d = spherical_to_cartesian(self._td, self._pd)  # difference vectors, shared by all rows
        self._full_grid = len(self.iy) == N_TD and len(self.iz) == npd
        iy, _ = np.meshgrid(self.iy, self.iz, indexing="ij")
        self._cell = merl_cell_measure(np.zeros(1, int), iy.ravel(), npd)  # θh = bin 0; rescaled per row
        self._dh = (np.cos(theta_h_of_bin(self.ix)) - np.cos(theta_h_of_bin(np.minimum(self.ix + 1, N_TH)))) / (
            1.0 - np.cos(theta_h_of_bin(1)))
        # measured and geometrically meaningful: both directions above the surface
        th = theta_h_of_bin(self.ix)[:, None]
        a = np.cos(th) * np.cos(self._td)[None, :]
        b = np.sin(th) * (np.sin(self._td) * np.cos(self._pd))[None, :]
        above = (a - b > 1e-6) & (a + b > 1e-6)
        self._row_valid = table.valid[np.ix_(self.ix, self.iy, self.iz)].reshape(len(self.ix), -1) & above
        self.size = int(self._row_valid.sum())
        if self.size == 0:
            raise BRDFLabError("the source has no valid samples to fit", table.path)

    def chunks(self, target: int = 65536) -> Iterator[Chunk]:
        """Whole θh bins per chunk (about `target` samples): wi is the shared difference
        vectors rotated by θh about y (φh = 0), wo their mirror about h."""
        vals = self.table.values
        parts: list[Chunk] = []
        count = 0
        for r, x in enumerate(self.ix):
            ok = self._row_valid[r]
            if not ok.any():
                continue
            th = float(theta_h_of_bin(x))
            c, s = np.cos(th), np.sin(th)
            d = self._d[ok]
            wi = np.empty_like(d)
            wi[:, 0] = c * d[:, 0] + s * d[:, 2]
            wi[:, 1] = d[:, 1]
            wi[:, 2] = c * d[:, 2] - s * d[:, 0]
            wo = -wi
            k = 2.0 * (s * wi[:, 0] + c * wi[:, 2])
            wo[:, 0] += k * s
            wo[:, 2] += k * c
            block = vals[:, x] if self._full_grid else vals[:, x][:, self.iy][:, :, self.iz]
            y = block.reshape(self.n_channels, -1)[:, ok].T
            parts.append((wi, wo, y, self._cell[ok] * self._dh[r]))
            count += len(y)
            if count >= target:
                yield _join(parts)
                parts, count = [], 0
        if parts:
            yield _join(parts)

    def subset(self, size: int, seed: int = 0) -> ArraySampleSet:
        """A stratified subset of `size` samples, as arrays."""
        counts = self._row_valid.sum(axis=1)
        start = np.concatenate([[0], np.cumsum(counts)])
        pos = stratified_indices(self.size, min(size, self.size), seed)
        rows = np.searchsorted(start, pos, side="right") - 1
        cols = np.empty_like(pos)
        for r in np.unique(rows):  # one θh row at a time: no array of every valid index
            here = rows == r
            cols[here] = np.flatnonzero(self._row_valid[r])[pos[here] - start[r]]
        ix = self.ix[rows]
        iy = self.iy[cols // len(self.iz)]
        iz = self.iz[cols % len(self.iz)]
        pd = phi_d_of_bin(iz) if self.table.phi_d_samples > 1 else np.full(ix.shape, 0.5 * np.pi)
        wi, wo = from_half_diff(theta_h_of_bin(ix), 0.0, theta_d_of_bin(iy), pd)
        values = self.table.values[:, ix, iy, iz].T.astype(float)
        weight = merl_cell_measure(ix, iy, self.table.phi_d_samples) * (self.size / ix.size)
        return ArraySampleSet(wi, wo, values, weight)


def analytic_grid(source, density: int = 32, phi_h_bins: int | None = None) -> ArraySampleSet:
    """Samples of any source on a half/difference grid: `density` θh and θd bins, 2·density
    φd bins, and (anisotropic sources) `phi_h_bins` φh bins."""
    d = int(density)
    if d < 2:
        raise BRDFLabError(f"grid density {d} is too small (at least 2)")
    x = (np.arange(d) + 0.5) / d
    th = x**2 * 0.5 * np.pi
    td = x * 0.5 * np.pi
    pd = (np.arange(2 * d) + 0.5) / (2 * d) * np.pi
    nph = 1 if source.isotropic else (phi_h_bins or d)
    ph = (np.arange(nph) + 0.5) / nph * 2.0 * np.pi if nph > 1 else np.zeros(1)
    TH, PH, TD, PD = np.meshgrid(th, ph, td, pd, indexing="ij")
    wi, wo = from_half_diff(TH.ravel(), PH.ravel(), TD.ravel(), PD.ravel())
    keep = (wi[:, 2] > 1e-6) & (wo[:, 2] > 1e-6)
    wi, wo = wi[keep], wo[keep]
    # measure: 4 cos θd sin θh dθh sin θd dθd dφh dφd, with dθh = π x dx
    w = (4.0 * np.cos(TD) * np.sin(TH) * (np.pi * np.sqrt(TH / (0.5 * np.pi)) * 0.5 * np.pi / d)
         * np.sin(TD) * (0.5 * np.pi / d) * (2 * np.pi / nph) * (np.pi / (2 * d))).ravel()[keep]
    values = source.evaluate(wi, wo)
    ok = np.all(np.isfinite(values), axis=1)
    return ArraySampleSet(wi[ok], wo[ok], values[ok], w[ok])


def samples_of(source, kind: str = "all", size: int | None = None, density: int | None = None) -> SampleSet:
    """The sample set of a source: 'all' valid samples, a stratified 'subset' of `size`,
    or a 'grid' of `density` bins per half/difference angle."""
    if kind not in ("all", "subset", "grid"):
        raise BRDFLabError(f"unknown sample set {kind!r} (all, subset or grid)")
    if isinstance(source, MeasuredTable):
        if kind == "grid":
            step = max(1, N_TH // max(2, density or 45))
            full = TableSampleSet(source, np.arange(0, N_TH, step), np.arange(0, N_TD, step),
                                  np.arange(0, source.phi_d_samples, step))
        else:
            full = TableSampleSet(source)
        return full.subset(size or 50_000) if kind == "subset" else full
    if isinstance(source, RawSamples):
        wi, wo, v = source.sample_directions()
        full = ArraySampleSet(wi, wo, v.astype(float), np.full(v.shape[0], 4.0 * np.pi**2 / max(v.shape[0], 1)))
        return full.subset(size or 50_000) if kind == "subset" else full
    grid = analytic_grid(source, density or 32)
    return grid.subset(size) if kind == "subset" and size else grid
