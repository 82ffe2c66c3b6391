"""BRDF product tables c_i(v) = ∫ y_i(s) f(s, v) max(0, s_z) ds over a parabolic map of
view directions v (Kautz et al. 2002), per channel, for any source.

The integrals are importance-sampled: samples are drawn from the material's own lobes
(measured sources: from a fitted proxy) as a mixture, weighted by the balance heuristic,
with one scrambled Sobol' set shared by all views. Results are cached per material.
"""

from __future__ import annotations

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
    r2 = px * px + py * py
    inside = r2 <= 1.0
    scale = np.where(inside, 1.0, 0.999 / np.sqrt(np.maximum(r2, 1e-12)))
    px, py = px * scale, py * scale
    r2 = px * px + py * py
    v = np.stack([2 * px, 2 * py, 1.0 - r2], axis=-1) / (1.0 + r2)[..., None]
    return v, inside


@lru_cache(maxsize=4)
def _sobol(n_log2: int) -> np.ndarray:
    return scrambled_sobol(n_log2, seed=11)


PROFILE_ANGLES = 96  # view elevations tabulated for isotropic sources
PROFILE_SAMPLES_LOG2 = 12  # samples per tabulated elevation (isotropic sources)


def brdf_table(source, order: int, size: int = DEFAULT_SIZE, samples_log2: int | None = None,
               chunk_samples: int = 1 << 17) -> np.ndarray:
    """c (size, size, order², C) for every texel of the parabolic view map.

    Isotropic sources: c(Rz(φ) v) = Mz(φ) c(v), so the integrals are computed once per view
    elevation (PROFILE_ANGLES of them, 2^12 samples each by default) and turned about z to
    every texel. With 2^8 samples per texel, as anisotropic sources still take, the
    Monte Carlo error of the high bands grew with the order faster than truncation fell
    (a Lambertian's SH image got worse from order 8 to 12)."""
    order = sh.check_order(order)
    views, _ = parabolic_views(size)
    views = views.reshape(-1, 3)
    proxy = proxy_lobes(source)
    if not proxy.lobes:
        raise BRDFLabError("the material has no lobes to tabulate")
    if getattr(source, "isotropic", False):
        log2 = PROFILE_SAMPLES_LOG2 if samples_log2 is None else samples_log2
        theta = np.arccos(np.clip(views[:, 2], -1.0, 1.0))
        grid = np.linspace(0.0, theta.max(), PROFILE_ANGLES)
        profile_views = np.stack([np.sin(grid), np.zeros_like(grid), np.cos(grid)], axis=-1)
        profile = _view_integrals(source, proxy, profile_views, order, log2, chunk_samples)
        position = np.interp(theta, grid, np.arange(PROFILE_ANGLES))
        below = np.minimum(position.astype(int), PROFILE_ANGLES - 2)
        t = (position - below)[:, None, None]
        out = sh._rotate_z_many((1.0 - t) * profile[below] + t * profile[below + 1],
                                np.arctan2(views[:, 1], views[:, 0]))
    else:
        out = _view_integrals(source, proxy, views, order, 8 if samples_log2 is None else samples_log2, chunk_samples)
    if not np.all(np.isfinite(out)):
        raise BRDFLabError("the BRDF table has non-finite values (check the material's parameters)")
    return out.reshape(size, size, order * order, source.n_channels)


def _view_integrals(source, proxy: AnalyticMaterial, views: np.ndarray, order: int, samples_log2: int,
                    chunk_samples: int) -> np.ndarray:
    """c_i(v) (V, order², C) for view directions v (V, 3), by the proxy's mixture sampling."""
    u = _sobol(samples_log2)
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
    size = table.shape[0]
    vz = np.maximum(v[..., 2], 0.0)
    p = v[..., :2] / (1.0 + vz)[..., None]
    x = (p[..., 0] + 1.0) * 0.5 * size - 0.5
    y = (p[..., 1] + 1.0) * 0.5 * size - 0.5
    x0 = np.clip(np.floor(x).astype(int), 0, size - 2)
    y0 = np.clip(np.floor(y).astype(int), 0, size - 2)
    fx = np.clip(x - x0, 0.0, 1.0)[..., None, None]
    fy = np.clip(y - y0, 0.0, 1.0)[..., None, None]
    return ((1 - fx) * (1 - fy) * table[y0, x0] + fx * (1 - fy) * table[y0, x0 + 1]
            + (1 - fx) * fy * table[y0 + 1, x0] + fx * fy * table[y0 + 1, x0 + 1])


_CACHE: dict = {}


def cached_table(source, order: int, size: int = DEFAULT_SIZE) -> np.ndarray:
    """brdf_table, remembered per (material description, order, size)."""
    key = (_identity(source), order, size)
    if key not in _CACHE:
        if len(_CACHE) > 8:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = brdf_table(source, order, size)
    return _CACHE[key]


def remember_table(source, order: int, table: np.ndarray, size: int = DEFAULT_SIZE) -> None:
    """Put a table built elsewhere (the GUI's worker process) where cached_table finds it."""
    if len(_CACHE) > 8:
        _CACHE.pop(next(iter(_CACHE)))
    _CACHE[(_identity(source), order, size)] = table


def is_cached(source, order: int, size: int = DEFAULT_SIZE) -> bool:
    return (_identity(source), order, size) in _CACHE


def _identity(source):
    if isinstance(source, AnalyticMaterial):
        import json

        return json.dumps(source.describe(), sort_keys=True)
    return ("object", id(source))
