"""BRDF product tables c_i(v) = ∫ y_i(s) f(s, v) max(0, s_z) ds over a parabolic map of
view directions v (Kautz et al. 2002), per channel, for any source.

The integrals are importance-sampled: samples are drawn from the material's own lobes
(measured sources: from a fitted proxy) as a mixture, weighted by the balance heuristic,
with one scrambled Sobol' set shared by all views. Results are cached per material.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from brdflab.geometry.sampling import cosine_hemisphere
from brdflab.geometry.sobol import scrambled_sobol
from brdflab.lighting import sh
from brdflab.errors import BRDFLabError
from brdflab.material.analytic import AnalyticMaterial
from brdflab.sources.proxy import proxy_lobes
from brdflab.lighting.sampling_sets import lobe_shares, sample_set

DEFAULT_SIZE = 128


def parabolic_views(size: int) -> tuple[np.ndarray, np.ndarray]:
    """View direction of each texel (size, size, 3), row = y, column = x, and whether the
    texel lies inside the unit disk (outside texels repeat the rim, for filtering)."""
    c = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    px, py = np.meshgrid(c, c)
    return texel_views(px, py), px * px + py * py <= 1.0


def texel_views(px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """View directions (…, 3) of parabolic-map points (px, py); points outside the unit disk
    are pulled onto the rim, as the table's outside texels are."""
    r2 = px * px + py * py
    scale = np.where(r2 <= 1.0, 1.0, 0.999 / np.sqrt(np.maximum(r2, 1e-12)))
    px, py = px * scale, py * scale
    r2 = px * px + py * py
    return np.stack([2 * px, 2 * py, 1.0 - r2], axis=-1) / (1.0 + r2)[..., None]


TABLE_SEED = 11  # the scrambling every built table uses


@lru_cache(maxsize=8)
def _sobol(n_log2: int, seed: int = TABLE_SEED) -> np.ndarray:
    return scrambled_sobol(n_log2, seed=seed)


PROFILE_ANGLES = 96  # view elevations tabulated for isotropic sources
PROFILE_SAMPLES_LOG2 = 12  # samples per tabulated elevation (isotropic sources)
TEXEL_SAMPLES_LOG2 = 8  # samples per texel (anisotropic sources)
TURN_CHUNK = 2048  # texels turned about z at a time (isotropic sources)


@dataclass(frozen=True)
class TableSetting:
    """How finely a table is built: the parabolic map's size (texels per side) and 2^samples_log2
    samples per integral (None: the source's default, see brdf_table). Isotropic sources
    integrate profile_angles elevations, in proportion to the size (96 at the default 128)."""

    size: int = DEFAULT_SIZE
    samples_log2: int | None = None

    @property
    def profile_angles(self) -> int:
        return max(8, PROFILE_ANGLES * self.size // DEFAULT_SIZE)

    @property
    def label(self) -> str:
        return f"{self.size}×2^{self.samples_log2}" if self.samples_log2 is not None else f"{self.size}×default"

    @property
    def text(self) -> str:
        """For people: '64² texels × 2^10 samples'."""
        texels = f"{self.size}² texels"
        return texels if self.samples_log2 is None else f"{texels} × 2^{self.samples_log2} samples"

    def of(self, source) -> "TableSetting":
        """The same setting with the source's default sample count filled in."""
        if self.samples_log2 is not None:
            return self
        iso = getattr(source, "isotropic", False)
        return TableSetting(self.size, PROFILE_SAMPLES_LOG2 if iso else TEXEL_SAMPLES_LOG2)


def parse_setting(text: str) -> TableSetting:
    """'SIZExLOG2' (e.g. 64x10: a 64² map, 2^10 samples per integral) → TableSetting."""
    try:
        size, log2 = (int(x) for x in text.lower().replace("×", "x").split("x"))
    except ValueError:
        raise BRDFLabError(f"SH table {text!r}: expected auto or SIZExLOG2, e.g. 64x10") from None
    if not 2 <= size <= 1024 or not 0 <= log2 <= 20:
        raise BRDFLabError(f"SH table {text!r}: SIZE must be 2..1024 and LOG2 0..20")
    return TableSetting(size, log2)


def brdf_table(source, order: int, size: int = DEFAULT_SIZE, samples_log2: int | None = None,
               chunk_samples: int = 1 << 17, angles: int | None = None) -> np.ndarray:
    """c (size, size, order², C) for every texel of the parabolic view map.

    Isotropic sources: c(Rz(φ) v) = Mz(φ) c(v), so the integrals are computed once per view
    elevation (`angles` of them, PROFILE_ANGLES by default, 2^12 samples each by default) and
    turned about z to every texel. With 2^8 samples per texel, as anisotropic sources still
    take, the Monte Carlo error of the high bands grew with the order faster than truncation
    fell (a Lambertian's SH image got worse from order 8 to 12)."""
    order = sh.check_order(order)
    views, _ = parabolic_views(size)
    views = views.reshape(-1, 3)
    proxy = sampling_proxy(source)
    if getattr(source, "isotropic", False):
        log2 = PROFILE_SAMPLES_LOG2 if samples_log2 is None else samples_log2
        out = isotropic_values(source, proxy, views, float(np.arccos(np.clip(views[:, 2], -1.0, 1.0)).max()),
                               order, log2, PROFILE_ANGLES if angles is None else angles, chunk_samples=chunk_samples)
    else:
        log2 = TEXEL_SAMPLES_LOG2 if samples_log2 is None else samples_log2
        out = view_integrals(source, proxy, views, order, log2, chunk_samples)
    if not np.all(np.isfinite(out)):
        raise BRDFLabError("the BRDF table has non-finite values (check the material's parameters)")
    return out.reshape(size, size, order * order, source.n_channels)


def table_for(source, order: int, setting: TableSetting) -> np.ndarray:
    """brdf_table at a TableSetting (isotropic sources: its elevation count too)."""
    return brdf_table(source, order, setting.size, setting.samples_log2, angles=setting.profile_angles)


def sampling_proxy(source) -> AnalyticMaterial:
    """The lobes whose mixture samples the source's integrals (its own, or a fitted proxy)."""
    proxy = proxy_lobes(source)
    if not proxy.lobes:
        raise BRDFLabError("the material has no lobes to tabulate")
    return proxy


def isotropic_values(source, proxy: AnalyticMaterial, views: np.ndarray, theta_max: float, order: int,
                     samples_log2: int, angles: int, seed: int = TABLE_SEED,
                     chunk_samples: int = 1 << 17) -> np.ndarray:
    """What an isotropic source's table holds at views (V, 3): the integrals at `angles`
    elevations from 0 to theta_max, linearly interpolated in elevation and turned about z.
    Only the elevations the views fall between are integrated."""
    theta = np.arccos(np.clip(views[:, 2], -1.0, 1.0))
    grid = np.linspace(0.0, theta_max, angles)
    position = np.interp(theta, grid, np.arange(angles))
    below = np.minimum(position.astype(int), angles - 2)
    needed, slot = np.unique(np.concatenate([below, below + 1]), return_inverse=True)
    profile_views = np.stack([np.sin(grid[needed]), np.zeros(len(needed)), np.cos(grid[needed])], axis=-1)
    profile = view_integrals(source, proxy, profile_views, order, samples_log2, chunk_samples, seed)
    t = (position - below)[:, None, None]
    low, high, angle = slot[:len(views)], slot[len(views):], np.arctan2(views[:, 1], views[:, 0])
    out = np.empty((len(views),) + profile.shape[1:])
    for start in range(0, len(views), TURN_CHUNK):  # in chunks: the temporaries stay in cache
        part = slice(start, start + TURN_CHUNK)
        out[part] = sh._rotate_z_many((1.0 - t[part]) * profile[low[part]] + t[part] * profile[high[part]], angle[part])
    return out


def view_integrals(source, proxy: AnalyticMaterial, views: np.ndarray, order: int, samples_log2: int,
                   chunk_samples: int = 1 << 17, seed: int = TABLE_SEED) -> np.ndarray:
    """c_i(v) (V, order², C) for view directions v (V, 3), by the proxy's mixture sampling
    with 2^samples_log2 points of the Sobol' set scrambled by `seed`."""
    u = _sobol(samples_log2, seed)
    n = len(u)
    split, fractions = sample_set(lobe_shares(proxy), n)
    # each lobe takes a contiguous block of the Sobol' points (better stratified than interleaved)
    lobe_of = np.sort(split[:, 2].astype(int))
    n_ch = source.n_channels
    out = np.zeros((len(views), order * order, n_ch))
    chunk = max(1, chunk_samples // n)
    for start in range(0, len(views), chunk):
        v = views[start:start + chunk]
        wo = np.broadcast_to(v[:, None, :], (len(v), n, 3))
        wi = np.empty((len(v), n, 3))
        for k, lobe in enumerate(proxy.lobes):
            sel = lobe_of == k
            model = lobe.model
            if model.samplable:
                wi[:, sel] = model.sample(wo[:, sel], u[sel][None], lobe.params)
            else:
                wi[:, sel] = cosine_hemisphere(np.broadcast_to(u[sel][None], (len(v), sel.sum(), 2)))
        pdf = np.zeros((len(v), n))
        for k, lobe in enumerate(proxy.lobes):
            model = lobe.model
            if model.samplable:
                pdf += fractions[k] * model.pdf(wi, wo, lobe.params)
            else:
                pdf += fractions[k] * np.maximum(wi[..., 2], 0.0) / np.pi
        f = source.evaluate(wi.reshape(-1, 3), wo.reshape(-1, 3)).reshape(len(v), n, n_ch)
        weight = np.where(pdf > 0, np.maximum(wi[..., 2], 0.0) / np.where(pdf > 0, pdf, 1.0), 0.0) / n
        Y = sh.basis(order, wi)
        out[start:start + chunk] = np.einsum("vkn,vkc->vnc", Y, f * weight[..., None])
    return out


def lookup(table: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear lookup of c(v) (…, order², C) for view directions v (…, 3), as the GPU does."""
    rows, columns, weights = lookup_corners(table.shape[0], v)
    return np.einsum("...k,...knc->...nc", weights, table[rows, columns])


def lookup_corners(size: int, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The four texels a bilinear lookup at views v (…, 3) blends: rows, columns and weights,
    each (…, 4), in the order (x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1)."""
    vz = np.maximum(v[..., 2], 0.0)
    p = v[..., :2] / (1.0 + vz)[..., None]
    x = (p[..., 0] + 1.0) * 0.5 * size - 0.5
    y = (p[..., 1] + 1.0) * 0.5 * size - 0.5
    x0 = np.clip(np.floor(x).astype(int), 0, size - 2)
    y0 = np.clip(np.floor(y).astype(int), 0, size - 2)
    fx = np.clip(x - x0, 0.0, 1.0)
    fy = np.clip(y - y0, 0.0, 1.0)
    rows = np.stack([y0, y0, y0 + 1, y0 + 1], axis=-1)
    columns = np.stack([x0, x0 + 1, x0, x0 + 1], axis=-1)
    weights = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], axis=-1)
    return rows, columns, weights


def texel_centre_views(size: int, rows: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """View directions (…, 3) of texels (rows, columns) of a size² parabolic map."""
    return texel_views((columns + 0.5) / size * 2.0 - 1.0, (rows + 0.5) / size * 2.0 - 1.0)


_CACHE: dict = {}
STANDARD = TableSetting()


def cached_table(source, order: int, setting: TableSetting = STANDARD) -> np.ndarray:
    """table_for, remembered per (material description, order, setting)."""
    key = _key(source, order, setting)
    if key not in _CACHE:
        remember_table(source, order, table_for(source, order, setting), setting)
    return _CACHE[key]


def remember_table(source, order: int, table: np.ndarray, setting: TableSetting = STANDARD) -> None:
    """Put a table built elsewhere (the GUI's worker process) where cached_table finds it."""
    if len(_CACHE) > 8:
        _CACHE.pop(next(iter(_CACHE)))
    _CACHE[_key(source, order, setting)] = table


def is_cached(source, order: int, setting: TableSetting = STANDARD) -> bool:
    """Whether cached_table would return at once."""
    return _key(source, order, setting) in _CACHE


def _key(source, order: int, setting: TableSetting) -> tuple:
    return material_identity(source), order, setting.of(source)


def material_identity(source):
    """What a table is remembered by: an analytic material's description, else the object."""
    if isinstance(source, AnalyticMaterial):
        import json

        return json.dumps(source.describe(), sort_keys=True)
    return ("object", id(source))
