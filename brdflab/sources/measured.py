"""Measured BRDFs: MERL `.binary` tables, bivariate (θh × θd) slices, raw samples and
MPI car-paint files, all behind the same `evaluate(wi, wo) → (N, C)` interface."""

from __future__ import annotations

import io
import os
import warnings
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.io.bounded import MAX_DATA_BYTES, BoundedFile, read_bounded
from brdflab.geometry.halfdiff import N_PD, N_TD, N_TH, continuous_bins, from_half_diff, half_and_difference_angles, phi_d_of_bin, theta_d_of_bin, theta_h_of_bin, to_half_diff
from brdflab.geometry.vec import spherical_to_cartesian

MERL_SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
MERL_HEADER = np.array([N_TH, N_TD, N_PD], dtype="<i4")
MERL_COUNT = N_TH * N_TD * N_PD
SLICE_BYTES = N_TH * N_TD * 3 * 4
CARPAINT_HEADER = 84
CARPAINT_BYTES = CARPAINT_HEADER + N_PD * N_TH * N_TD * 3 * 4
MERL_BYTES = 12 + 3 * MERL_COUNT * 8
# A measured BRDF value above this (1/sr) is corrupt data, not a material: a mirror's peak bin
# in MERL's finest θh bin is ~1e7. Larger values would overflow float32 textures and squares.
MAX_BRDF_VALUE = 1e10
MAX_SAMPLE_CHANNELS = 64


@dataclass
class MeasuredTable:
    """An isotropic BRDF tabulated on MERL's (θh, θd, φd) grid, per channel, in 1/sr.

    `values` has shape (C, 90, 90, 180), float32; `valid` marks measured samples.
    `phi_d_samples` is 180 for a full table, 1 for a bivariate slice (constant in φd).
    """

    values: np.ndarray
    valid: np.ndarray
    name: str = "measured"
    source_type: str = "MERLBRDFDatabase"
    path: Path | None = None
    interpolation: str = "trilinear"
    meta: dict = field(default_factory=dict)

    isotropic = True
    kind = "Measured"

    @property
    def n_channels(self) -> int:
        return self.values.shape[0]

    @property
    def phi_d_samples(self) -> int:
        return self.values.shape[3]

    def describe(self) -> dict:
        return {
            "type": self.source_type,
            "name": self.name,
            "file": None if self.path is None else str(self.path),
            "channels": self.n_channels,
            "shape": list(self.values.shape[1:]),
            "valid_samples": int(self.valid.sum()),
            "total_samples": int(self.valid.size),
            "max_value": [float(self.values[c][self.valid].max()) if self.valid.any() else None for c in range(self.n_channels)],
            "interpolation": self.interpolation,
            "domain": (f"isotropic; MERL's θh × θd × φd grid ({'φd-independent slice' if self.phi_d_samples == 1 else 'φd folded to [0, π)'}); "
                       f"{int(self.valid.sum())} of {self.valid.size} samples measured, others read as 0"),
            **self.meta,
        }

    # --- lookup ---------------------------------------------------------------------
    def evaluate(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """Values at direction pairs (N, C); 0 below the surface or where nothing was measured."""
        wi = np.asarray(wi, float)
        wo = np.asarray(wo, float)
        if self.phi_d_samples == 1:  # a slice needs no φd: θh and θd from the half vector alone
            th, td = half_and_difference_angles(wi, wo)
            x, y, _ = continuous_bins(th, td, 0.0)
            z = np.zeros_like(x)
        else:
            th, _, td, pd = to_half_diff(wi, wo)
            x, y, z = continuous_bins(th, td, pd)
        out = self._trilinear(x, y, z) if self.interpolation == "trilinear" else self._nearest(x, y, z)
        above = (wi[..., 2] > 0) & (wo[..., 2] > 0)
        return np.where(above[..., None], out, 0.0)

    def _nearest(self, x, y, z) -> np.ndarray:
        # x, y, z put bin centres on integers: floor(x + ½) is MERL's own floor lookup
        ix = np.clip(np.floor(x + 0.5).astype(int), 0, N_TH - 1)
        iy = np.clip(np.floor(y + 0.5).astype(int), 0, N_TD - 1)
        iz = np.floor(z + 0.5).astype(int) % self.phi_d_samples
        vals = self.values[:, ix, iy, iz]
        ok = self.valid[ix, iy, iz]
        return np.where(ok, vals, 0.0).T.astype(float)

    def _corner_table(self) -> tuple[np.ndarray, np.ndarray]:
        """The table as rows of bins (bins, C), unmeasured bins zeroed, and the validity as
        float32 (bins,): a corner's channels are one row, and validity needs no second product
        per corner. Made on the first lookup and kept while `values` and `valid` are the same
        arrays (they are not edited in place after a lookup)."""
        cached = self.__dict__.get("_corners")
        if cached is None or cached[0] is not self.values or cached[1] is not self.valid:
            rows = np.ascontiguousarray((self.values.reshape(self.n_channels, -1) * self.valid.reshape(-1)).T)
            cached = (self.values, self.valid, rows, self.valid.reshape(-1).astype(np.float32))
            self.__dict__["_corners"] = cached
        return cached[2], cached[3]

    def __getstate__(self) -> dict:
        """What pickling carries (to a worker process): the table without its lookup cache."""
        state = dict(self.__dict__)
        state.pop("_corners", None)
        return state

    def _trilinear(self, x, y, z) -> np.ndarray:
        x = np.clip(x, 0.0, N_TH - 1.0)
        y = np.clip(y, 0.0, N_TD - 1.0)
        x0 = np.minimum(np.floor(x).astype(int), N_TH - 2)
        y0 = np.minimum(np.floor(y).astype(int), N_TD - 2)
        fx, fy = x - x0, y - y0
        npd = self.phi_d_samples
        if npd == 1:
            z0 = np.zeros_like(x0)
            fz = np.zeros_like(fx)
        else:
            z0 = np.floor(z).astype(int) % npd
            fz = z - np.floor(z)
        acc = np.zeros(x.shape + (self.n_channels,))
        wsum = np.zeros(x.shape)
        table, valid = self._corner_table()
        for dx, wx in ((0, 1 - fx), (1, fx)):
            for dy, wy in ((0, 1 - fy), (1, fy)):
                for dz, wz in ((0, 1 - fz), (1, fz)):
                    if npd == 1 and dz == 1:
                        continue
                    flat = ((x0 + dx) * N_TD + (y0 + dy)) * npd + (z0 + dz) % npd
                    w = wx * wy * wz
                    acc += w[..., None] * np.take(table, flat, axis=0)
                    wsum += w * np.take(valid, flat)
        return np.where(wsum[..., None] > 1e-12, acc / np.maximum(wsum, 1e-12)[..., None], 0.0)

    # --- sample sets ------------------------------------------------------------------
    def sample_directions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All valid grid samples as (wi, wo, values (N, C)), with φh = 0 (isotropic)."""
        ix, iy, iz = np.nonzero(self.valid)
        wi, wo = from_half_diff(theta_h_of_bin(ix), 0.0, theta_d_of_bin(iy), phi_d_of_bin(iz) if self.phi_d_samples > 1 else np.full(ix.shape, 0.5 * np.pi))
        vals = self.values[:, ix, iy, iz].T
        keep = (wi[:, 2] > 1e-6) & (wo[:, 2] > 1e-6)
        return wi[keep], wo[keep], vals[keep].astype(float)

    def to_full(self) -> "MeasuredTable":
        """A full 180-φd table (a bivariate slice repeated along φd)."""
        if self.phi_d_samples == N_PD:
            return self
        values = np.repeat(self.values, N_PD, axis=3)
        valid = np.repeat(self.valid, N_PD, axis=2)
        return MeasuredTable(values, valid, self.name, "MERLBRDFDatabase", None, self.interpolation, dict(self.meta))

    @cached_property
    def theta_h_step(self) -> float:
        """The largest brightness ratio between neighbouring θh bins (luminance of the first
        three channels, θd below 80°, values above 1e-3 of the peak): how far MERL's θh
        binning shows as rings around a highlight (MERL chrome: 3.0; a diffuse paint: 1.2)."""
        weights = np.array([0.2126, 0.7152, 0.0722])[: self.n_channels]
        lum = np.einsum("c...,c->...", self.values[: len(weights)], weights / weights.sum())[:, :80]
        lum = np.where(self.valid[:, :80], lum, np.nan)
        floor = 1e-3 * np.nanmax(lum) if np.isfinite(lum).any() else 0.0
        if floor <= 0.0:
            return 1.0
        v = np.maximum(lum, floor)
        ratio = np.fmax(v[1:] / v[:-1], v[:-1] / v[1:])
        return float(np.nanmax(ratio)) if np.isfinite(ratio).any() else 1.0


# --------------------------------------------------------------------------------------
# readers

def _read_exactly(path: Path, size: int, what: str) -> bytes:
    """The whole file, which must be exactly `size` bytes (checked before reading)."""
    with BoundedFile(path, size, what) as f:
        if f.size != size:
            raise BRDFLabError(f"truncated: {f.size} bytes, {what} is {size}", path)
        return f.read(size)


def _checked_values(raw: np.ndarray, path: Path, scale=1.0) -> tuple[np.ndarray, np.ndarray]:
    """Decoded raw values (C, ...) as float32 BRDF values (raw × per-channel `scale`) and the
    mask of measured samples. NaN/Inf are errors; a sample with a negative channel is
    unmeasured (read as 0); a measured value beyond MAX_BRDF_VALUE is an error."""
    finite = np.isfinite(raw)
    if not finite.all():
        raise BRDFLabError(f"{int(np.count_nonzero(~finite))} values are NaN or Inf", path)
    valid = np.all(raw >= 0.0, axis=0)
    if not valid.any():
        raise BRDFLabError("every sample is negative (nothing was measured)", path)
    scale = np.broadcast_to(np.asarray(scale, float), (raw.shape[0],))
    measured = np.broadcast_to(valid, raw.shape)
    _check_peaks(np.max(raw.reshape(raw.shape[0], -1), axis=1, where=measured.reshape(raw.shape[0], -1), initial=0.0),
                 scale, path)
    # raw × scale in float64, rounded once to float32, unmeasured samples 0, the same values as
    # before without the two float64 copies of the table they were made through (70 MB for MERL)
    values = np.empty(raw.shape, np.float32)
    with np.errstate(over="ignore"):  # only an unmeasured (negative) value can pass float32's range: zeroed next
        np.multiply(raw, scale.reshape((-1,) + (1,) * (raw.ndim - 1)), out=values, casting="same_kind")
    np.copyto(values, 0.0, where=~measured)
    return values, valid


def _check_peaks(peaks: np.ndarray, scale: np.ndarray, path: Path) -> None:
    """Refuse a channel whose largest raw value (× its scale) is beyond MAX_BRDF_VALUE."""
    over = np.flatnonzero(peaks * scale > MAX_BRDF_VALUE)
    if over.size:
        c = int(over[0])
        raise BRDFLabError(f"channel {c} holds a value beyond any real BRDF "
                           f"(values above {MAX_BRDF_VALUE:g} 1/sr are refused)", path)


def read_merl_binary(path: str | os.PathLike) -> MeasuredTable:
    """MERL `.binary`: three int32 dims (90, 90, 180), then 3·90·90·180 float64."""
    path = Path(path)
    with BoundedFile(path, MERL_BYTES, "a MERL table") as f:
        if f.size < 12:
            raise BRDFLabError(f"truncated: {f.size} bytes, a MERL header alone is 12", path)
        dims = np.frombuffer(f.read(12), dtype="<i4")
        if not np.array_equal(dims, MERL_HEADER):
            raise BRDFLabError("the header's dimensions are not MERL's (90, 90, 180)", path)
        if f.size != MERL_BYTES:
            raise BRDFLabError(f"truncated: {f.size} bytes, expected {MERL_BYTES}", path)
        raw = np.frombuffer(f.read_rest(), dtype="<f8").reshape(3, N_TH, N_TD, N_PD)
    values, valid = _checked_values(raw, path, MERL_SCALE)
    return MeasuredTable(values, valid, path.stem, "MERLBRDFDatabase", path)


def write_merl_binary(table: MeasuredTable, path: str | os.PathLike) -> None:
    """Write a full 3-channel table as MERL `.binary` (unmeasured samples as −1)."""
    from brdflab.io.atomic import atomic_write

    full = table.to_full()
    if full.n_channels != 3:
        raise BRDFLabError(f"MERL files hold 3 channels, the table has {full.n_channels}", path)
    raw = full.values.astype("<f8") / MERL_SCALE[:, None, None, None]
    raw[:, ~full.valid] = -1.0
    atomic_write(Path(path), MERL_HEADER.tobytes() + raw.astype("<f8").tobytes())


def read_slice(path: str | os.PathLike) -> MeasuredTable:
    """A bivariate MERL slice: 90 × 90 RGB float32, index 3·(90·θd_bin + θh_bin) + c."""
    path = Path(path)
    data = _read_exactly(path, SLICE_BYTES, "a slice")
    raw = np.frombuffer(data, dtype="<f4").reshape(N_TD, N_TH, 3)  # [θd, θh, c]
    values, valid = _checked_values(raw.transpose(2, 1, 0)[..., None], path)  # (3, θh, θd, 1)
    return MeasuredTable(values, valid, path.stem, "BivariateSlice", path)


def read_carpaint(path: str | os.PathLike) -> MeasuredTable:
    """MPI car paint: 84-byte header, then float32 RGB over φd (180) × θh (90) × θd (90)."""
    path = Path(path)
    data = _read_exactly(path, CARPAINT_BYTES, "an MPI car paint file")
    raw = np.frombuffer(data, dtype="<f4", offset=CARPAINT_HEADER).reshape(N_PD, N_TH, N_TD, 3)
    values, _ = _checked_values(np.maximum(raw, 0.0).transpose(3, 1, 2, 0), path)  # negatives read as 0
    if not values.any():
        raise BRDFLabError("every value is negative or zero (nothing was measured)", path)
    valid = np.ones(values.shape[1:], bool)
    return MeasuredTable(np.ascontiguousarray(values), valid, path.stem, "MPICarPaint", path)


@dataclass
class RawSamples:
    """Scattered measurements `θi, φi, θo, φo, r, g, b` (radians), looked up by nearest sample."""

    wi: np.ndarray
    wo: np.ndarray
    samples: np.ndarray  # (N, C)
    name: str = "samples"
    path: Path | None = None

    source_type = "RawSamples"
    kind = "Measured"

    def __post_init__(self) -> None:
        from scipy.spatial import cKDTree

        self._tree = cKDTree(np.concatenate([self.wi, self.wo], axis=1))

    @property
    def n_channels(self) -> int:
        return self.samples.shape[1]

    @property
    def isotropic(self) -> bool:
        return False

    def evaluate(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        wi = np.asarray(wi, float)
        wo = np.asarray(wo, float)
        q = np.concatenate(np.broadcast_arrays(wi, wo), axis=-1)
        _, idx = self._tree.query(q.reshape(-1, 6))
        out = self.samples[idx].reshape(q.shape[:-1] + (self.n_channels,))
        above = (wi[..., 2] > 0) & (wo[..., 2] > 0)
        return np.where(above[..., None], out, 0.0)

    def sample_directions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.wi, self.wo, self.samples

    def describe(self) -> dict:
        return {"type": self.source_type, "name": self.name, "file": None if self.path is None else str(self.path),
                "channels": self.n_channels, "samples": int(self.samples.shape[0]),
                "domain": "scattered measurements; other pairs take the nearest sample's value"}


def read_raw_samples(path: str | os.PathLike) -> RawSamples:
    """Text rows `θi φi θo φo v0 v1 …` (radians; spaces or commas; `#` comments), parsed by NumPy.

    Errors name the line and the field, never the line's text (the file may be anybody's).
    """
    path = Path(path)
    text = read_bounded(path, MAX_DATA_BYTES, "a raw sample file").decode("utf-8", errors="replace")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "input contained no data" is reported below
            a = np.loadtxt(io.StringIO(text.replace(",", " ")), comments="#", ndmin=2)
    except ValueError:
        raise BRDFLabError(_first_bad_line(text), path) from None
    if a.size == 0:
        raise BRDFLabError("no samples", path)
    if not 5 <= a.shape[1] <= 4 + MAX_SAMPLE_CHANNELS:
        raise BRDFLabError(_first_bad_line(text), path)
    finite = np.isfinite(a).all(axis=1)
    if not finite.all():
        raise BRDFLabError(f"sample {int(np.argmin(finite)) + 1}: NaN or Inf", path)
    problem = _sample_problem(a)
    if problem:
        raise BRDFLabError(problem, path)
    _check_peaks(a[:, 4:].max(axis=0), np.ones(a.shape[1] - 4), path)
    wi = spherical_to_cartesian(a[:, 0], a[:, 1])
    wo = spherical_to_cartesian(a[:, 2], a[:, 3])
    if not ((wi[:, 2] > 0.0) & (wo[:, 2] > 0.0)).any():
        raise BRDFLabError("every sample has θi or θo at or below the horizon (π/2): nothing to look up", path)
    return RawSamples(wi, wo, a[:, 4:], path.stem, path)


def _sample_problem(a: np.ndarray) -> str | None:
    """The first sample (row) whose angles are not radians on the sphere (θ in [0, π], φ in
    [−2π, 2π]: degrees or 1e300 are not) or whose value is negative, by row and field number."""
    theta, phi = a[:, [0, 2]], a[:, [1, 3]]
    bad_angle = ((theta < 0.0) | (theta > np.pi)).any(axis=1) | (np.abs(phi) > 2.0 * np.pi).any(axis=1)
    negative = (a[:, 4:] < 0.0).any(axis=1)
    if bad_angle.any():
        return (f"sample {int(np.argmax(bad_angle)) + 1}: an angle outside θ ∈ [0, π], φ ∈ [−2π, 2π] "
                "(angles are radians)")
    if negative.any():
        return f"sample {int(np.argmax(negative)) + 1}: a negative value (a BRDF is ≥ 0)"
    return None


def _first_bad_line(text: str) -> str:
    """Where a raw sample file stops being numbers: 'line N: …', without the line's text."""
    width = None
    for lineno, line in enumerate(text.splitlines(), 1):
        fields = line.split("#", 1)[0].replace(",", " ").split()
        if not fields:
            continue
        for k, f in enumerate(fields, 1):
            try:
                float(f)
            except ValueError:
                return f"line {lineno}: not a number (field {k})"
        if not 5 <= len(fields) <= 4 + MAX_SAMPLE_CHANNELS:
            return (f"line {lineno}: expected θi, φi, θo, φo and 1..{MAX_SAMPLE_CHANNELS} values, "
                    f"got {len(fields)} fields")
        if width is not None and len(fields) != width:
            return f"line {lineno}: {len(fields)} fields, earlier lines have {width}"
        width = len(fields)
    return "not a table of numbers"


READERS = {
    ".binary": read_merl_binary,
    ".slice": read_slice,
    ".txt": read_raw_samples,
    ".csv": read_raw_samples,
    ".carpaint": read_carpaint,
    ".bin": read_carpaint,
}

TYPE_READERS = {
    "MERLBRDFDatabase": read_merl_binary,
    "BivariateSlice": read_slice,
    "RawSamples": read_raw_samples,
    "MPICarPaint": read_carpaint,
}


def read_measured(path: str | os.PathLike, source_type: str | None = None):
    """Read any measured file, by its declared type or else by its extension."""
    path = Path(path)
    reader = TYPE_READERS.get(source_type or "") or READERS.get(path.suffix.lower())
    if reader is None:
        raise BRDFLabError(f"unknown measured data type {source_type or path.suffix!r}", path)
    return reader(path)


def tabulate(source, phi_d_samples: int = N_PD, name: str = "tabulated") -> MeasuredTable:
    """Sample any isotropic source on MERL's grid (φh = 0), as a measured table.

    Used to build MERL files from analytic models (tests, simulated materials) and to
    turn any source into a texture for the renderers.
    """
    ix, iy, iz = np.meshgrid(np.arange(N_TH), np.arange(N_TD), np.arange(phi_d_samples), indexing="ij")
    pd = phi_d_of_bin(iz) if phi_d_samples > 1 else np.full(iz.shape, 0.5 * np.pi)
    wi, wo = from_half_diff(theta_h_of_bin(ix), 0.0, theta_d_of_bin(iy), pd)
    values = np.moveaxis(source.evaluate(wi.reshape(-1, 3), wo.reshape(-1, 3)), -1, 0)
    values = values.reshape((-1, N_TH, N_TD, phi_d_samples)).astype(np.float32)
    above = (wi[..., 2] > 0) & (wo[..., 2] > 0)
    return MeasuredTable(values, above & np.all(np.isfinite(values), axis=0), name, "MERLBRDFDatabase")
