"""Auto SH tables: the cheapest table setting (parabolic-map size, samples per integral) whose
estimated error stays within a tolerance.

The error of a table (the stated error, `relative_rms`): over view directions uniform in solid
angle with θ ≤ 80° (the fit-error domain), the RMS length of the difference between the
table's bilinear lookup and the exact integrals c(v), relative to the RMS length of c(v),
on the coefficients' luminance. It is the relative RMS of the rendered radiance c(v)·L over
those views and over lightings L whose SH coefficients are independent with equal variance;
real maps put less energy into high bands, so for them it errs on the safe side.

The estimate needs no converged table: error² = resolution² + sampling², each measured at a
few dozen spot views.
- sampling(2^k): the Monte Carlo error of the table's own scrambled Sobol' set, against an
  independent scrambling of 2^(k+4) samples. One scrambling's error is one draw, far from
  its RMS over scramblings when few integrals carry it (a Lambertian's is the same at every
  view), so the table's own draw is measured; and against more samples, since scramblings at
  one count share what that count misses (a measured spike its proxy samples poorly).
- resolution(size): the table's own lookup at spot views between texels (the four texels'
  integrals, isotropic sources: interpolated between the size's elevations and turned about
  z, exactly as the table is built) against the spot views' own integrals, all with one
  scrambling: the Monte Carlo error is common to both and cancels, the interpolation's stays.
Settings are tried in order of build cost, the estimates computed as needed and remembered;
every sample set is seeded, so the decision is deterministic.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.lighting import sh
from brdflab.lighting.sh_tables import (TABLE_SEED, TableSetting, isotropic_values, lookup, lookup_corners,
                                        material_identity, parabolic_views, sampling_proxy, table_for,
                                        texel_centre_views, view_integrals)

DEFAULT_TOLERANCE = 0.01
MAX_VIEW_THETA_DEG = 80.0  # the error's view domain, as the fit errors' (CONVENTIONS.md)
ISOTROPIC_SIZES = (16, 32, 64, 128, 256)
ISOTROPIC_SAMPLES_LOG2 = (6, 8, 10, 12, 14)  # per elevation
ANISOTROPIC_SIZES = (16, 32, 64, 128)
ANISOTROPIC_SAMPLES_LOG2 = (4, 6, 8, 10, 12)  # per texel
TEXEL_COST = 3  # a texel turned about z costs about three samples (measured at orders 4 and 8)
MAX_BUILD_SAMPLES = 1 << 24  # no rung integrates more (about 45 s at order 8 on the lab's machine)
RESOLUTION_VIEWS = 32
RESOLUTION_SAMPLES_LOG2 = 10
SAMPLING_VIEWS = 12
FINER_LOG2 = 4  # the sampling error is measured against 2^4 times the samples
RESOLUTION_SEED = 2027
FINER_SEED = 3001
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


@dataclass(frozen=True)
class AutoTable:
    """Ask for the cheapest table whose estimated error is within `tolerance`."""

    tolerance: float = DEFAULT_TOLERANCE


@dataclass(frozen=True)
class TableChoice:
    """Auto's pick, its estimated error (and the two parts), whether that is within the
    tolerance, and every setting weighed: (label, estimate or None where a part alone failed)."""

    setting: TableSetting
    estimated_error: float
    resolution_error: float
    sampling_error: float
    tolerance: float
    within: bool
    seconds: float
    weighed: tuple = field(default=())

    @property
    def label(self) -> str:
        return (f"{self.setting.text}, est. error {100 * self.estimated_error:.2f} %"
                + ("" if self.within else f" (above {100 * self.tolerance:g} %)"))

    def as_dict(self) -> dict:
        return {"size": self.setting.size, "samples_log2": self.setting.samples_log2,
                "estimated_error": self.estimated_error, "resolution_error": self.resolution_error,
                "sampling_error": self.sampling_error, "tolerance": self.tolerance, "within": self.within,
                "seconds": self.seconds, "weighed": [list(w) for w in self.weighed]}


# --- the stated error ----------------------------------------------------------------------------

def error_views(n: int) -> np.ndarray:
    """n view directions (n, 3) uniform in solid angle over θ ≤ MAX_VIEW_THETA_DEG (Fibonacci)."""
    lowest = math.cos(math.radians(MAX_VIEW_THETA_DEG))
    i = np.arange(n) + 0.5
    z = 1.0 - (1.0 - lowest) * i / n
    phi = i * math.pi * (3.0 - math.sqrt(5.0)) + 0.3  # offset: off the texel grid's symmetry lines
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def luminance(c: np.ndarray) -> np.ndarray:
    """Coefficients (…, n, C) → their luminance (…, n) (one channel: itself)."""
    return c[..., 0] if c.shape[-1] < 3 else c[..., :3] @ LUMINANCE


def relative_rms(estimate: np.ndarray, truth: np.ndarray) -> float:
    """The stated error of coefficient sets (V, n, C) against the truth at the same views."""
    d, t = luminance(estimate) - luminance(truth), luminance(truth)
    return float(np.sqrt(np.sum(d * d) / max(np.sum(t * t), 1e-300)))


def table_error(table: np.ndarray, truth: np.ndarray, views: np.ndarray) -> float:
    """The stated error of a built table at views (V, 3) whose exact integrals are `truth`."""
    return relative_rms(lookup(table, views), truth)


# --- the ladder ------------------------------------------------------------------------------------

def build_cost(source, setting: TableSetting) -> int:
    """A build's cost in samples evaluated; isotropic sources add TEXEL_COST per texel turned."""
    n = 1 << setting.samples_log2
    if getattr(source, "isotropic", False):
        return setting.profile_angles * n + TEXEL_COST * setting.size**2
    return setting.size**2 * n


def ladder(source) -> list[TableSetting]:
    """Every candidate setting for this source, cheapest build first."""
    iso = getattr(source, "isotropic", False)
    sizes, logs = (ISOTROPIC_SIZES, ISOTROPIC_SAMPLES_LOG2) if iso else (ANISOTROPIC_SIZES, ANISOTROPIC_SAMPLES_LOG2)
    settings = [TableSetting(s, k) for s in sizes for k in logs
                if build_cost(source, TableSetting(s, k)) <= MAX_BUILD_SAMPLES + TEXEL_COST * s * s]
    return sorted(settings, key=lambda t: (build_cost(source, t), t.size))


# --- the estimate ----------------------------------------------------------------------------------

class ErrorEstimate:
    """Resolution and sampling errors of one source at one order, measured as asked for and
    remembered: the building blocks of every setting's estimate."""

    def __init__(self, source, order: int) -> None:
        self.source, self.order = source, sh.check_order(order)
        self.proxy = sampling_proxy(source)
        self.isotropic = bool(getattr(source, "isotropic", False))
        self._resolution: dict[int, float] = {}
        self._sampling: dict[int, float] = {}
        self._spots = error_views(RESOLUTION_VIEWS)
        self._spot_values = self._exact(self._spots, RESOLUTION_SAMPLES_LOG2, RESOLUTION_SEED)

    def _exact(self, views: np.ndarray, samples_log2: int, seed: int) -> np.ndarray:
        """Integrals at views; isotropic sources at the view's elevation, turned about z (as
        the table's texels are), so that one scrambling errs alike at nearby views."""
        if not self.isotropic:
            return view_integrals(self.source, self.proxy, views, self.order, samples_log2, seed=seed)
        theta = np.arccos(np.clip(views[:, 2], -1.0, 1.0))
        at = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], axis=-1)
        c = view_integrals(self.source, self.proxy, at, self.order, samples_log2, seed=seed)
        return sh._rotate_z_many(c, np.arctan2(views[:, 1], views[:, 0]))

    def resolution(self, size: int) -> float:
        """The interpolation error of a size² table (its elevations too, isotropic sources)."""
        if size not in self._resolution:
            rows, columns, weights = lookup_corners(size, self._spots)
            corners = texel_centre_views(size, rows, columns).reshape(-1, 3)
            if self.isotropic:
                setting = TableSetting(size, RESOLUTION_SAMPLES_LOG2)
                theta_max = float(np.arccos(np.clip(parabolic_views(size)[0][..., 2], -1.0, 1.0)).max())
                values = isotropic_values(self.source, self.proxy, corners, theta_max, self.order,
                                          RESOLUTION_SAMPLES_LOG2, setting.profile_angles, seed=RESOLUTION_SEED)
            else:
                values = view_integrals(self.source, self.proxy, corners, self.order, RESOLUTION_SAMPLES_LOG2,
                                        seed=RESOLUTION_SEED)
            values = values.reshape(len(self._spots), 4, *values.shape[1:])
            self._resolution[size] = relative_rms(np.einsum("vk,vknc->vnc", weights, values), self._spot_values)
        return self._resolution[size]

    def sampling(self, samples_log2: int) -> float:
        """The Monte Carlo error of the table's own scrambling at 2^samples_log2 samples per
        integral: its integrals at spot views against an independent scrambling with
        2^FINER_LOG2 times the samples. Not the same count: where the proxy's sampling misses
        a measured spike, every scrambling at one count misses it alike (the mean of four hid
        most of chrome-steel's error at 2^10). The finer run errs too, by about a quarter of
        the table's error or less: a small margin."""
        if samples_log2 not in self._sampling:
            views = error_views(SAMPLING_VIEWS)
            if self.isotropic:  # the error's length does not change when turned about z
                theta = np.arccos(views[:, 2])
                views = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], axis=-1)

            def run(log2: int, seed: int) -> np.ndarray:
                return luminance(view_integrals(self.source, self.proxy, views, self.order, log2, seed=seed))

            finer = run(samples_log2 + FINER_LOG2, FINER_SEED)
            error = run(samples_log2, TABLE_SEED) - finer
            self._sampling[samples_log2] = float(np.sqrt(np.sum(error * error) / max(np.sum(finer * finer), 1e-300)))
        return self._sampling[samples_log2]


def choose_table(source, order: int, tolerance: float = DEFAULT_TOLERANCE) -> TableChoice:
    """The cheapest setting of the ladder whose estimated error is within `tolerance`; when
    none is, the one estimated best (flagged not within)."""
    if not (math.isfinite(tolerance) and tolerance > 0):
        raise BRDFLabError(f"SH table tolerance {tolerance} must be a positive number")
    began = time.perf_counter()
    estimate = ErrorEstimate(source, order)
    weighed, best = [], None
    for setting in ladder(source):
        resolution = estimate.resolution(setting.size)
        if resolution > tolerance:  # no sample count can help: skip measuring this one's sampling
            weighed.append((setting.label, None))
            continue
        sampling = estimate.sampling(setting.samples_log2)
        total = math.hypot(resolution, sampling)
        weighed.append((setting.label, total))
        if best is None or total < best[1]:
            best = (setting, total, resolution, sampling)
        if total <= tolerance:
            break
    if best is None:  # every size alone was above the tolerance: the finest, measured
        setting = max(ladder(source), key=lambda t: build_cost(source, t))
        resolution, sampling = estimate.resolution(setting.size), estimate.sampling(setting.samples_log2)
        best = (setting, math.hypot(resolution, sampling), resolution, sampling)
    setting, total, resolution, sampling = best
    return TableChoice(setting, total, resolution, sampling, tolerance, total <= tolerance,
                       time.perf_counter() - began, tuple(weighed))


_CHOICES: dict = {}


def resolve(source, order: int, table: TableSetting | AutoTable) -> TableSetting:
    """The concrete setting a table request stands for: Auto's pick, remembered per
    (material, order, tolerance), or the setting itself."""
    if not isinstance(table, AutoTable):
        return table
    key = (material_identity(source), order, table.tolerance)
    if key not in _CHOICES:
        remember_choice(source, order, table, choose_table(source, order, table.tolerance))
    return _CHOICES[key].setting


def known_choice(source, order: int, table: AutoTable) -> TableChoice | None:
    """Auto's pick if it has been made (here, or in a worker and remembered)."""
    return _CHOICES.get((material_identity(source), order, table.tolerance))


def remember_choice(source, order: int, table: AutoTable, choice: TableChoice) -> None:
    if len(_CHOICES) > 32:
        _CHOICES.pop(next(iter(_CHOICES)))
    _CHOICES[(material_identity(source), order, table.tolerance)] = choice


def build_table(source, order: int, table: TableSetting | AutoTable) -> tuple[TableChoice | None, TableSetting, np.ndarray]:
    """Choose (when Auto) and build: what the GUI's worker process runs in one job."""
    choice = choose_table(source, order, table.tolerance) if isinstance(table, AutoTable) else None
    setting = choice.setting if choice is not None else table
    return choice, setting, table_for(source, order, setting)
