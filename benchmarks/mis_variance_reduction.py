"""What would bring MIS to 2 % per pixel at 64 samples (issue 36 goal 2)? Candidate variance
reductions measured in NumPy before any is built into the shader.

    python benchmarks/mis_variance_reduction.py [--json docs/bench/mis_variance_reduction.json]

Every estimator here is the MIS twin's (`auto_twins`: the renderer's 64-sample set, half from the
lobes and half from the map, each pixel's own Cranley–Patterson shift, the power heuristic, the map
texel by texel); only the map's strategy, the lobe's sampler or the integrand changes:

- `today`: the map drawn by its luminance (`environment_distribution`), as the renderer does;
- `product exact`: the map drawn by luminance × max(0, n·ω) for each pixel's own normal n, texel
  by texel — the best a product of the map and the cosine can do (it needs a table per pixel);
- `bins K²`: the same product for K² normals fixed in advance (an octahedral grid), over cells of
  32 × 16 of the map (a cell's cosine at its centre, + 0.05 so the pixel's own hemisphere is
  covered where its bin's is not), the texel inside a cell drawn by luminance: what a shader can
  hold in tables;
- `pixel cells R`: each pixel's own normal over cells of 2R × R (a table a shader would build per
  pixel);
- `SH control L`: the map's order-L projection as a control variate: its integral through the
  lobe by the subdivided quadrature (exact, so the estimate stays unbiased), Monte Carlo only for
  f·cos·(L − L_SH);
- `VNDF`: GGX's half vectors drawn from the visible normals (Heitz 2018) instead of D cos θh
  (the lab's sampler since this measurement; the other columns run with the sampler of the time).

Scored as the lab scores lighting: the reference view at 32², maps at 128 × 64, the RMS of each
pixel's relative error in luminance against the subdivided texel quadrature
(`refined_environment_image`). Only the tuning maps of `lighting.synthetic_maps` are used: the
held-out third stays for the check of whatever is built from this.
"""

from __future__ import annotations

import numpy as np

from json_output import measure_and_write

from brdflab.geometry.sampling import ggx_d, half_vector_pdf, reflect
from brdflab.lighting import auto_twins as twins
from brdflab.lighting import sh
from brdflab.lighting.env_sampling import LUMINANCE, environment_distribution, invert_in_rows, texel_point
from brdflab.lighting.envmap import EnvironmentMap, constant, texel_of
from brdflab.lighting.reference_view import pixel_relative_rmse, refined_environment_image, sphere_view
from brdflab.lighting.sampling_sets import pixel_shifts, sample_set
from brdflab.lighting.synthetic_maps import catalogue
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.models.cook_torrance import CookTorranceGGX

SIZE, SAMPLES, MAP_SIZE = 32, 64, (128, 64)
MAPS = ("overcast", "clear-noon-sky", "sun-high-small", "room-lamps", "city-night", "studio-two-boxes")


def lobe(model: str, **params: float) -> AnalyticMaterial:
    return AnalyticMaterial(model, "Linear", 3, [Lobe.create(model, [0.5] * 3, **params)])


MATERIALS = {"Lambertian": lambda: lobe("Lambertian"), "GGX m=0.3": lambda: lobe("CookTorranceGGX", m=0.3, F0=1.0),
             "GGX m=0.1": lambda: lobe("CookTorranceGGX", m=0.1, F0=1.0)}


# --- map strategies, as `auto_twins.mis_pixels` draws from a map's distribution: sample(u (pixels · n, 2),
# pixel by pixel) → world (pixels · n, 3); pdf(world (pixels, n, 3)) → (pixels, n). Per-pixel tables
# read the pixel of each point from its place. -------------------------------------------------------

def _pixel_of(u: np.ndarray, pixels: int) -> np.ndarray:
    return np.arange(len(u)) // (len(u) // pixels)


def _rising(cdf: np.ndarray) -> np.ndarray:
    """CDFs (..., m) ending at 1 exactly (as `environment_distribution`'s), so that rows laid end
    to end (`invert_in_rows`) never overlap."""
    cdf[..., -1] = 1.0
    return cdf


class ExactProduct:
    """Luminance × max(0, n·ω) per pixel, piecewise constant per texel (cosine at its centre)."""

    def __init__(self, env: EnvironmentMap, normals: np.ndarray) -> None:
        self.h, self.w = env.height, env.width
        d, omega = env.texel_directions()
        self.omega = np.broadcast_to(omega, (self.h, self.w)).ravel()
        weight = (np.maximum(env.data.astype(float) @ LUMINANCE, 0.0).ravel() * self.omega)[None] \
            * np.maximum(normals @ d.reshape(-1, 3).T, 0.0)
        weight /= weight.sum(1, keepdims=True)
        self.cdf, self.density = _rising(np.cumsum(weight, 1)), weight / self.omega

    def sample(self, u):
        index, t = invert_in_rows(self.cdf, _pixel_of(u, len(self.cdf)), u[:, 0])
        return texel_point(index // self.w, index % self.w, u[:, 1], t, self.h, self.w)

    def pdf(self, world):
        r, c = texel_of(world, self.h, self.w)
        return np.take_along_axis(self.density, r * self.w + c, 1)


def octahedral_normals(k: int) -> np.ndarray:
    g = (np.arange(k) + 0.5) / k * 2.0 - 1.0
    x, y = np.meshgrid(g, g, indexing="ij")
    z = 1.0 - np.abs(x) - np.abs(y)
    fold = np.maximum(-z, 0.0)
    v = np.stack([x - np.sign(x) * fold, y - np.sign(y) * fold, z], -1).reshape(-1, 3)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def octahedral_bin(n: np.ndarray, k: int) -> np.ndarray:
    v = n / np.abs(n).sum(-1, keepdims=True)
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    xo = np.where(z < 0, (1.0 - np.abs(y)) * np.where(x >= 0, 1.0, -1.0), x)
    yo = np.where(z < 0, (1.0 - np.abs(x)) * np.where(y >= 0, 1.0, -1.0), y)
    q = np.clip(((np.stack([xo, yo], -1) * 0.5 + 0.5) * k).astype(int), 0, k - 1)
    return q[:, 0] * k + q[:, 1]


class CellProduct:
    """Luminance × (max(0, n_b·cell centre) + floor) over coarse cells, one table per normal n_b
    (`normals`, each pixel reading table `bins[p]`); inside a cell a texel by luminance, from the
    map's own tables (`environment_distribution`)."""

    def __init__(self, env: EnvironmentMap, dist, normals: np.ndarray, bins: np.ndarray, rows: int = 32,
                 floor: float = 0.05) -> None:
        self.dist, self.bins = dist, bins
        h, w = env.height, env.width
        self.hc, self.wc = min(rows, h), 2 * min(rows, h)
        self.fy, self.fx = h // self.hc, w // self.wc
        row_share = np.diff(np.concatenate([[0.0], dist.marginal]))
        self.cond = np.concatenate([np.zeros((h, 1)), dist.conditional], 1)
        self.segment = row_share[:, None] * (self.cond[:, self.fx::self.fx] - self.cond[:, 0:-1:self.fx])
        self.cell = self.segment.reshape(self.hc, self.fy, self.wc).sum(1)
        centres, _ = EnvironmentMap(np.zeros((self.hc, self.wc, 3), np.float32), "cells").texel_directions()
        weight = self.cell.reshape(1, -1) * (np.maximum(normals @ centres.reshape(-1, 3).T, 0.0) + floor)
        self.share = (weight / weight.sum(1, keepdims=True)).reshape(-1, self.hc, self.wc)
        rows_sum = self.share.sum(2)
        self.marginal = _rising(np.cumsum(rows_sum, 1))
        self.conditional = _rising(np.cumsum(self.share, 2) / np.where(rows_sum > 0, rows_sum, 1.0)[..., None])

    def sample(self, u):
        b = self.bins[_pixel_of(u, len(self.bins))]
        every = np.arange(len(u))
        rc, t1 = invert_in_rows(self.marginal, b, u[:, 0])
        cc, s1 = invert_in_rows(self.conditional.reshape(-1, self.wc), b * self.hc + rc, u[:, 1])
        seg = np.cumsum(self.segment[rc[:, None] * self.fy + np.arange(self.fy), cc[:, None]], 1)
        fr, t2 = invert_in_rows(_rising(seg / np.where(seg[:, -1:] > 0, seg[:, -1:], 1.0)), every, t1)
        row = rc * self.fy + fr
        cols = self.cond[row[:, None], cc[:, None] * self.fx + np.arange(1, self.fx + 1)]  # up to the cell's edge
        start = self.cond[row, cc * self.fx]
        fc, s2 = invert_in_rows(cols, every, start + s1 * (cols[:, -1] - start), lowest=start)
        return texel_point(row, cc * self.fx + fc, t2, s2, self.dist.height, self.dist.width)

    def pdf(self, world):
        r, c = texel_of(world, self.dist.height, self.dist.width)
        rc, cc = r // self.fy, c // self.fx
        cell = self.cell[rc, cc]
        share = self.share[np.broadcast_to(self.bins[:, None], r.shape), rc, cc]
        return np.where(cell > 0, share * self.dist.density[r, c] / np.where(cell > 0, cell, 1.0), 0.0)


# --- the estimator ----------------------------------------------------------------------------

def mis(source, env: EnvironmentMap, frames, strategy, control: EnvironmentMap | None = None) -> np.ndarray:
    """The MIS twin with `strategy` for the map's half; with `control` (at twice the map's size),
    the radiance is the map's less the control's (its integral is added by the caller)."""
    if control is not None:
        fine = np.repeat(np.repeat(env.data.astype(float), 2, axis=0), 2, axis=1)  # texel of a direction: the same
        env = EnvironmentMap((fine - control.data).astype(np.float32), "residual")
    return twins.mis_pixels(source, source, env, strategy, frames, SAMPLES)


def lobes_only(source, env, frames) -> np.ndarray:
    """All 64 samples from the lobes (no map strategy)."""
    sampling, shares = twins.renderer_sampling(source, source)
    data, fractions = sample_set(shares, SAMPLES)
    pixels = len(frames[0])
    u = np.mod(data[None, :, :2] + pixel_shifts(np.arange(pixels), np.zeros(pixels))[:, None, :], 1.0)
    wi = twins._lobe_directions(sampling, frames, data, u)
    pdf = twins.mixture_pdf(sampling, wi, np.broadcast_to(twins._views(frames)[:, None], wi.shape), fractions)
    ok = (wi[..., 2] > 0) & (pdf > 0)
    radiance = env.data.astype(float)[texel_of(twins._to_world(frames, wi), env.height, env.width)]
    value = twins._f_cos(source, frames, wi) * radiance / np.where(ok, pdf, 1.0)[..., None]
    return np.where(ok[..., None], value, 0.0).sum(1) / SAMPLES


def sh_control(env: EnvironmentMap, order: int) -> EnvironmentMap:
    """The map's order-L projection, tabulated at twice the map's size (the control the estimate
    subtracts; `mis` reads the map at the same texels)."""
    grid = EnvironmentMap(np.zeros((2 * env.height, 2 * env.width, 3), np.float32), "sh")
    d, _ = grid.texel_directions()
    values = sh.evaluate(sh.project_environment(env, order), d.reshape(-1, 3)).reshape(grid.data.shape)
    return EnvironmentMap(values.astype(np.float32), f"sh{order}")


class HalfVectorsFromD:
    """GGX's sampler as it was when this was measured (before 7de08e0 built the visible normals):
    half vectors with density D(h) cos θh. Every column but `VNDF` runs with it."""

    @staticmethod
    def half(alpha, u):
        tan2 = alpha * alpha * u[..., 0] / np.maximum(1.0 - u[..., 0], 1e-12)
        cos_t = 1.0 / np.sqrt(1.0 + tan2)
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
        phi = 2.0 * np.pi * u[..., 1]
        return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)

    def __enter__(self):
        self.saved = CookTorranceGGX._sample, CookTorranceGGX._pdf
        CookTorranceGGX._sample = lambda model, wo, u, p: reflect(wo, self.half(p["m"], u))
        CookTorranceGGX._pdf = lambda model, wi, wo, p: half_vector_pdf(wi, wo, lambda h: ggx_d(h, p["m"]) * h[..., 2])
        return self

    def __exit__(self, *exc):
        CookTorranceGGX._sample, CookTorranceGGX._pdf = self.saved


def measure() -> dict:
    view = sphere_view(SIZE, SIZE)
    inside = view.inside
    frames = (view.normal[inside], view.tangent[inside], view.bitangent[inside])
    held_out = {m.name for m in catalogue(held_out=True)}
    assert not held_out & set(MAPS), "a held-out map in the tuning set"
    rows = []
    maps = [("constant", constant(1.0, *MAP_SIZE))] + [(m.name, m.build(*MAP_SIZE)) for m in catalogue() if m.name in MAPS]
    for name, env in maps:
        dist = environment_distribution(env)
        normals = frames[0]
        strategies = {"today": dist, "product exact": ExactProduct(env, normals)}
        for k in (8, 16):
            strategies[f"bins {k}²"] = CellProduct(env, dist, octahedral_normals(k), octahedral_bin(normals, k))
        for r in (16, 32):
            strategies[f"pixel cells {r}"] = CellProduct(env, dist, normals, np.arange(len(normals)), rows=r)
        controls = {order: sh_control(env, order) for order in (2, 4)} if name != "constant" else {}
        for material, make in MATERIALS.items():
            source = make()
            reference = refined_environment_image(source, env, SIZE, SIZE)

            def score(values, base=None):
                image = np.zeros_like(reference) if base is None else base.copy()
                image[inside] += values
                return round(100 * pixel_relative_rmse(image, reference, inside), 2)

            with HalfVectorsFromD():
                errors = {key: score(mis(source, env, frames, s)) for key, s in strategies.items()}
                errors["lobes only"] = score(lobes_only(source, env, frames))
                for order, control in controls.items():
                    integral = refined_environment_image(source, control, SIZE, SIZE)
                    errors[f"SH control {order}"] = score(mis(source, env, frames, strategies["today"], control), integral)
            if material.startswith("GGX"):  # the lab's own sampler: visible normals
                errors["VNDF"] = score(mis(source, env, frames, strategies["today"]))
                errors["VNDF lobes only"] = score(lobes_only(source, env, frames))
            rows.append({"map": name, "material": material, "errors": errors})
            print(f"{name:18s} {material:11s} " + "  ".join(f"{k} {v}" for k, v in errors.items()), flush=True)
    return {"size": SIZE, "samples": SAMPLES, "map_size": MAP_SIZE, "rows": rows}


if __name__ == "__main__":
    measure_and_write(measure, __doc__)
