"""A sampler for any lobe, built from its own values: tabulated distributions of the half
vector per view direction, and an equivalent roughness measured on the lobe's shape.

For each tabulated view wo (elevations θv; and azimuths φv for anisotropic lobes) the
hemisphere of half vectors h is cut into N_THETA × N_PHI cells, finer near the normal (θ
edges at (π/2)(i/N_THETA)², so a sharp lobe spans many cells) and uniform in φ. A cell's
mass is what the lobe sends through it: f(wi, wo) cos θi · 4 (wo·h) · Δω_h at its centre,
with wi = wo reflected about h (the Jacobian dωi = 4 (wo·h) dωh). Tabulating h rather than
wi keeps a microfacet lobe's peak at the normal for every view, so interpolating between
neighbouring views does not blur it. A draw picks a table (between the two neighbouring
views, with probability by the interpolation weight, so the density is the same mix of both
tables), a cell by its mass, h uniformly in the cell's solid angle, and reflects wo about
it; a fixed share COSINE_SHARE is cosine-weighted, so every direction where the lobe can be
non-zero has a density. `pdf` is that mixture's density exactly, so the sampler is unbiased
whatever the lobe, and close to f cos θi where the cells resolve it.
"""

from __future__ import annotations

import math
from functools import lru_cache
import numpy as np

from brdflab.geometry.sampling import half_vector_pdf, reflect
from brdflab.geometry.vec import rotate_about_z

N_THETA, N_PHI = 64, 128
N_VIEWS = 24  # tabulated view elevations (isotropic lobes)
N_VIEW_PHI = 12  # and azimuths (anisotropic lobes)
COSINE_SHARE = 0.05
# views tabulated per evaluation: one pass holds the OpenGL evaluator ~8 ms, so the window's own
# requests (queued behind a table build in a thread) wait no longer than that
VIEWS_PER_PASS = 4
DIFFUSE_ALPHA = 0.5  # the equivalent α of a Lambertian: a lobe at least that flat is lit as diffuse


def theta_edges() -> np.ndarray:
    return 0.5 * math.pi * (np.arange(N_THETA + 1) / N_THETA) ** 2


@lru_cache(maxsize=1)
def cells():
    """Cell edges in θ, the cells' centre directions (N_THETA, N_PHI, 3) and solid angles."""
    t_edges = theta_edges()
    p_edges = np.linspace(0.0, 2.0 * math.pi, N_PHI + 1)
    t = 0.5 * (t_edges[:-1] + t_edges[1:])
    p = 0.5 * (p_edges[:-1] + p_edges[1:])
    solid = (np.cos(t_edges[:-1]) - np.cos(t_edges[1:]))[:, None] * np.diff(p_edges)[None, :]
    st = np.sin(t)
    dirs = np.stack([st[:, None] * np.cos(p)[None, :], st[:, None] * np.sin(p)[None, :],
                     np.broadcast_to(np.cos(t)[:, None], (N_THETA, N_PHI))], axis=-1)
    for a in (t_edges, dirs, solid):
        a.flags.writeable = False  # shared by every caller (cached)
    return t_edges, dirs, solid


def _theta_cell(cos_t: np.ndarray) -> np.ndarray:
    theta = np.arccos(np.clip(cos_t, -1.0, 1.0))
    return np.minimum((np.sqrt(theta / (0.5 * math.pi)) * N_THETA).astype(int), N_THETA - 1)


class TabulatedSampler:
    """Tabulated importance sampling of one lobe at fixed parameters. A view's table is built
    the first time a draw or a density needs it (an edit in the window asks for the normal
    view's alone; the renderers' FIS and MIS for all of them)."""

    def __init__(self, model, params: dict) -> None:
        self.model, self.params = model, dict(params)
        self.view_theta = np.linspace(0.0, math.radians(89.0), N_VIEWS)
        self.isotropic = bool(model.is_isotropic(params))
        self.view_phi = np.array([0.0]) if self.isotropic else np.arange(N_VIEW_PHI) * (2.0 * math.pi / N_VIEW_PHI)
        tables = len(self.view_theta) * len(self.view_phi)
        self._cdf = np.zeros((tables, N_THETA * N_PHI))  # rising to 1 (a table with no mass is uniform)
        self._density = np.zeros((tables, N_THETA * N_PHI))  # mass / solid angle: the density of h
        self._built = np.zeros(tables, bool)
        self._offsets: tuple[int, np.ndarray] | None = None  # `_offset_cdf` and how many tables were built then

    @property
    def cdf(self) -> np.ndarray:
        self.ensure_all()
        return self._cdf

    @property
    def density(self) -> np.ndarray:
        self.ensure_all()
        return self._density

    def ensure(self, tables, stop=None) -> bool:
        """Build the tables among `tables` (indices) that are not built yet; whether all are.
        `stop()`, asked between passes, abandons the rest (a build nobody waits for now)."""
        tables = np.asarray(tables, int).ravel()
        todo = np.unique(tables[~self._built[tables]])  # every draw and density asks: hashing all of its
        # tables (built the first time) was 6 % of a render Auto's time on a measured slice
        for start in range(0, todo.size, VIEWS_PER_PASS):
            if stop is not None and stop():
                return False
            self._build(todo[start:start + VIEWS_PER_PASS])
        return True

    def ensure_all(self, stop=None) -> bool:
        return self.ensure(np.arange(len(self._built)), stop)

    def _build(self, todo: np.ndarray) -> None:
        _, dirs, solid = cells()
        views = np.stack(np.meshgrid(self.view_theta, self.view_phi, indexing="ij"), -1).reshape(-1, 2)[todo]
        wo = np.stack([np.sin(views[:, 0]) * np.cos(views[:, 1]), np.sin(views[:, 0]) * np.sin(views[:, 1]),
                       np.cos(views[:, 0])], -1)
        h = np.broadcast_to(dirs.reshape(1, -1, 3), (len(wo), N_THETA * N_PHI, 3))
        wo_b = np.broadcast_to(wo[:, None], h.shape)
        wi = reflect(wo_b, h)
        f = self.model.evaluate(wi.reshape(-1, 3), wo_b.reshape(-1, 3), self.params).reshape(len(wo), -1)
        f = np.where(np.isfinite(f) & (f > 0), f, 0.0)
        jacobian = 4.0 * np.abs((wo_b * h).sum(-1))
        mass = f * np.maximum(wi[..., 2], 0.0) * jacobian * solid.reshape(1, -1)
        total = mass.sum(axis=1, keepdims=True)
        mass = np.where(total > 0, mass / np.where(total > 0, total, 1.0), solid.reshape(1, -1) / solid.sum())
        cdf = np.cumsum(mass, axis=1)
        cdf[:, -1] = 1.0
        self._cdf[todo] = cdf
        self._density[todo] = mass / solid.reshape(1, -1)
        self._built[todo] = True

    def _offset_cdf(self) -> np.ndarray:
        """Every table's CDF, table k offset by k, end to end: one sorted array in which a draw
        u from table k is found by searching u + k (a table not built yet is all k, which keeps
        it sorted). Made once per build instead of gathering the tables drawn from at every
        draw (a measured slice's 32,768 draws: 8.9 → 7.6 ms, the same directions). It is made
        again whenever more tables are built than when it was made; the count is read before the
        tables, and a table is marked built after it is written, so an array made while another
        thread builds (the twins draw in two threads) holds every table counted."""
        built = int(np.count_nonzero(self._built))
        if self._offsets is None or self._offsets[0] != built:
            self._offsets = (built, (self._cdf + np.arange(len(self._cdf))[:, None]).ravel())
        return self._offsets[1]

    # --- the views around wo, with their weights
    def _views(self, wo: np.ndarray):
        theta = np.arccos(np.clip(wo[..., 2], -1.0, 1.0))
        x = np.clip(theta / self.view_theta[-1] * (len(self.view_theta) - 1), 0.0, len(self.view_theta) - 1)
        i0 = np.minimum(np.floor(x).astype(int), len(self.view_theta) - 2)
        ti = x - i0
        phi = np.mod(np.arctan2(wo[..., 1], wo[..., 0]), 2.0 * math.pi)
        if self.isotropic:
            return [(i0, 1.0 - ti, phi), (i0 + 1, ti, phi)]
        P = len(self.view_phi)
        y = phi / (2.0 * math.pi) * P
        j0 = np.floor(y).astype(int) % P
        tj = y - np.floor(y)
        out = []
        for di, wi_ in ((0, 1.0 - ti), (1, ti)):
            for dj, wj in ((0, 1.0 - tj), (1, tj)):
                out.append(((i0 + di) * P + (j0 + dj) % P, wi_ * wj, self.view_phi[(j0 + dj) % P]))
        return out

    def sample(self, wo: np.ndarray, u: np.ndarray) -> np.ndarray:
        from brdflab.geometry.sampling import cosine_hemisphere

        shape = np.broadcast_shapes(wo.shape[:-1], u.shape[:-1])
        wo = np.broadcast_to(wo, shape + (3,)).reshape(-1, 3)
        u = np.broadcast_to(u, shape + (2,)).reshape(-1, 2).copy()
        n = len(wo)
        cosine = u[:, 1] < COSINE_SHARE
        u[:, 1] = np.where(cosine, u[:, 1] / COSINE_SHARE, (u[:, 1] - COSINE_SHARE) / (1.0 - COSINE_SHARE))
        # pick one of the neighbouring tables by its weight, reusing u.x
        table = np.zeros(n, int)
        rotation = np.zeros(n)
        below = np.zeros(n)
        pick = u[:, 0].copy()
        first = pick.copy()  # a cosine-weighted draw takes u.x as it came (as the GLSL twin does)
        views = self._views(wo)
        self.ensure([k for k, _, _ in views])
        for k, weight, phi in views:
            weight = np.broadcast_to(weight, (n,))
            take = (pick >= below) & (pick < below + weight)
            table = np.where(take, np.broadcast_to(k, (n,)), table)
            rotation = np.where(take, np.broadcast_to(phi, (n,)), rotation)
            u[:, 0] = np.where(take, (pick - below) / np.where(weight > 0, weight, 1.0), u[:, 0])
            below = below + weight
        u = np.clip(u, 0.0, np.nextafter(1.0, 0.0))
        cells = self._cdf.shape[1]
        cell = np.minimum(np.searchsorted(self._offset_cdf(), u[:, 0] + table, side="right") - table * cells, cells - 1)
        lo = np.where(cell > 0, self._cdf[table, np.maximum(cell - 1, 0)], 0.0)
        hi = self._cdf[table, cell]
        r = np.clip((u[:, 0] - lo) / np.where(hi > lo, hi - lo, 1.0), 0.0, 1.0)
        it, ip = np.divmod(cell, N_PHI)
        t_edges = theta_edges()
        c0, c1 = np.cos(t_edges[it]), np.cos(t_edges[it + 1])
        cos_t = c0 + r * (c1 - c0)
        phi = (ip + u[:, 1]) * (2.0 * math.pi / N_PHI)
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
        h = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], -1)
        h = rotate_about_z(h, rotation if self.isotropic else np.zeros(n))
        wi = reflect(wo, h)
        if cosine.any():
            wi[cosine] = cosine_hemisphere(np.stack([first[cosine], u[cosine, 1]], -1))
        return wi.reshape(shape + (3,))

    def pdf(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        shape = np.broadcast_shapes(wi.shape[:-1], wo.shape[:-1])
        wi = np.broadcast_to(wi, shape + (3,)).reshape(-1, 3)
        wo = np.broadcast_to(wo, shape + (3,)).reshape(-1, 3)
        n = len(wi)
        views = self._views(wo)
        self.ensure([k for k, _, _ in views])

        def density_h(h):
            out = np.zeros(n)
            cells_of = {}  # h's cell in a view's frame, once per frame: an isotropic source's views share one
            for k, weight, phi in views:
                frame = id(phi) if self.isotropic else None
                if frame not in cells_of:
                    local = rotate_about_z(h, -np.broadcast_to(phi, (n,))) if self.isotropic else h
                    it = _theta_cell(local[:, 2])
                    ip = np.minimum((np.mod(np.arctan2(local[:, 1], local[:, 0]), 2.0 * math.pi)
                                     / (2.0 * math.pi) * N_PHI).astype(int), N_PHI - 1)
                    cells_of[frame] = it * N_PHI + ip
                out += np.broadcast_to(weight, (n,)) * self._density[np.broadcast_to(k, (n,)), cells_of[frame]]
            return out

        tabulated = half_vector_pdf(wi, wo, density_h)
        out = (1.0 - COSINE_SHARE) * tabulated + COSINE_SHARE * np.maximum(wi[:, 2], 0.0) / math.pi
        return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), out, 0.0).reshape(shape)


def equivalent_roughness(model, params: dict) -> float | None:
    """The Beckmann α of a lobe for prefiltered lighting, measured on its own values at
    normal view: a microfacet lobe there has albedo ≈ F and peak f(n, n) ≈ F D(n) / 4 with
    D(n) = 1/(π α²) (Beckmann and GGX alike), so α = √(albedo / (4π f(n, n))). A lobe no
    sharper than a Lambertian (α ≥ 0.5, where a Lambertian gives exactly 0.5) is lit by the
    irradiance: None."""
    _, dirs, solid = cells()
    wi = dirs.reshape(-1, 3)
    up = np.array([[0.0, 0.0, 1.0]])
    f = model.evaluate(wi, np.broadcast_to(up, wi.shape), params)
    f = np.where(np.isfinite(f) & (f > 0), f, 0.0)
    albedo = float((f * wi[:, 2] * solid.ravel()).sum())
    peak = float(np.nan_to_num(model.evaluate(up, up, params)[0]))
    if albedo <= 0 or peak <= 0:
        return None
    alpha = math.sqrt(albedo / (4.0 * math.pi * peak))
    return None if alpha >= DIFFUSE_ALPHA else float(max(alpha, 0.01))
