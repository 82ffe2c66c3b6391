"""Auto lighting's twins: the renderer's FIS and MIS estimators run in NumPy at a few hundred
pixels of the reference view, and the converged values they (and the prefiltered twin,
`split_sum.prefiltered_pixels`) are scored against.

A quadrature of the one-sample variance over a coarse copy of the map cannot see a lobe
narrower than the copy's texels: the lobe falls in one texel, the radiance it gathers looks
constant, and the predicted error was up to 13× too low for a sharp lobe under a small sun.
Here each pilot pixel is shaded as the renderer shades it with N samples — its Hammersley
sets and lobe shares, each lobe's own sampler, the mixture density; for FIS the full map
read through `filtered_radiance` as shaders/object_fragment.glsl reads it, for MIS half the
samples drawn from the map's luminance and weighted by the power heuristic — and the result
equals the renderer's to 1e-5 (tests/test_auto_twins.py). It is compared with a converged
estimate (`converged_pixels`: TRUTH_SAMPLES per pixel, half from the lobes, half from the
map), at pixels chosen so that a sun's highlight is not missed (`fis_pixels_of`). Both are
estimates: the prediction carries the converged one's own error (≈ 0.3 %) and the sampling
of the pixels (the view's error is the RMS over all of its pixels).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from brdflab.geometry.sampling import cosine_hemisphere
from brdflab.lighting.auto_pilot import LUMINANCE
from brdflab.lighting.envmap import EnvironmentMap, texel_of
from brdflab.lighting.mip_pyramid import solid_angle_mips
from brdflab.lighting.reference_view import weighted_pixel_error
from brdflab.lighting.split_sum import sample_latlong

FIS_PILOT_GRID = 20  # the pilot pixels: the centres of a 20 × 20 reference view inside the sphere (≈ 310)
HOT_GRID = 48  # … plus, at this finer grid, the pixels that mirror the map's brightest texels
HOT_LEVEL = 0.05  # texels at least this share of the map's peak luminance are bright …
HOT_CONTRAST = 20.0  # … and this many times its mean (a map without a small source has none)
HOT_DEGREES = 8.0  # a pixel is hot when its mirror direction is this close to a bright texel (plus a texel)
MAX_HOT = 300  # hot pixels at most (evenly thinned beyond), and as many bright texels
TRUTH_SAMPLES = 2048  # per pilot pixel, for the converged value the twins are measured against (4,096 took
# 1.75× as long to choose, for the same picks on 74 of 75 pairs of benchmarks/lighting_auto_pixels.py and
# predictions within 0.02 points median: the truth's own error is taken out of every prediction)
MIS_DRAWS = 4  # independent per-pixel shifts MIS's prediction is the RMS over
PIECE_SAMPLES = 32768  # samples per run of pilot pixels a twin shades at once (`in_pieces`)


@dataclass(frozen=True)
class PilotPixels:
    """The FIS pilot's pixels: frames (normal, tangent, bitangent), each (pixels, 3), and the
    share of the view each stands for (summing to 1)."""

    frames: tuple[np.ndarray, np.ndarray, np.ndarray]
    weight: np.ndarray


def _mirrors(normal: np.ndarray) -> np.ndarray:
    """World mirror directions of the view (+Z) about each normal."""
    return 2.0 * normal[:, 2:3] * normal - np.array([0.0, 0.0, 1.0])


def _hot(normal: np.ndarray, bright: np.ndarray, radius: float) -> np.ndarray:
    if not len(bright):
        return np.zeros(len(normal), bool)
    return (_mirrors(normal) @ bright.T).max(axis=1) >= np.cos(radius)


def fis_pixels_of(env: EnvironmentMap) -> PilotPixels:
    """A regular FIS_PILOT_GRID² grid, and where a small bright source is reflected, every
    HOT_GRID² pixel: a sharp highlight of the sun covers a few of the view's pixels and
    carries most of its error (at 9² or 20² alone, Blinn–Phong n = 1000 under a one-texel
    sun was predicted at a third of its error). Each part is weighted by the share of the
    view it stands for, so the estimate is still the RMS over the whole view."""
    from brdflab.lighting.reference_view import sphere_view

    lum = env.data.astype(float) @ LUMINANCE
    d, _ = env.texel_directions()
    order = np.argsort(lum, axis=None)[::-1][:MAX_HOT]
    order = order[lum.ravel()[order] >= max(HOT_LEVEL * float(lum.max()), HOT_CONTRAST * float(lum.mean()), 1e-300)]
    bright = d.reshape(-1, 3)[order]
    radius = np.radians(HOT_DEGREES) + np.pi / env.height * np.sqrt(2.0)
    coarse, fine = sphere_view(FIS_PILOT_GRID, FIS_PILOT_GRID), sphere_view(HOT_GRID, HOT_GRID)
    frames_of = lambda v, m: (v.normal[m], v.tangent[m], v.bitangent[m])
    fine_hot = _hot(fine.normal[fine.inside], bright, radius)
    share = fine_hot.mean()
    cool = coarse.inside.copy()
    cool[coarse.inside] = ~_hot(coarse.normal[coarse.inside], bright, radius)
    hot = fine.inside.copy()
    hot[fine.inside] = fine_hot
    picked = np.flatnonzero(hot.ravel())
    picked = picked[np.linspace(0, len(picked) - 1, min(len(picked), MAX_HOT)).astype(int)] if len(picked) else picked
    hot = np.zeros(hot.size, bool)
    hot[picked] = True
    hot = hot.reshape(fine.inside.shape)
    parts = [(frames_of(coarse, cool), (1.0 - share) / max(int(cool.sum()), 1)),
             (frames_of(fine, hot), share / max(int(hot.sum()), 1))]
    frames = tuple(np.concatenate([f[k] for f, _ in parts]) for k in range(3))
    weight = np.concatenate([np.full(len(f[0]), w) for f, w in parts])
    return PilotPixels(frames, weight / weight.sum())


class _SamplerModel:
    """A measured table's own sampler (`sources.proxy.measured_sampler`) standing as the one
    samplable lobe the renderer draws a measured source's BRDF samples from."""

    samplable = True

    def __init__(self, sampler) -> None:
        self.sampler = sampler

    def sample(self, wo: np.ndarray, u: np.ndarray, params: dict) -> np.ndarray:
        return self.sampler.sample(wo, u)

    def pdf(self, wi: np.ndarray, wo: np.ndarray, params: dict) -> np.ndarray:
        return self.sampler.pdf(wi, wo)


@dataclass(frozen=True)
class _SampledLobe:
    model: _SamplerModel
    params: dict


@dataclass(frozen=True)
class _TableSampling:
    lobes: list


def renderer_sampling(source, proxy) -> tuple[object, np.ndarray]:
    """What the renderer draws BRDF samples of `source` from, with each lobe's share: an
    analytic material's own lobes (`lobe_shares`), a measured table's own sampler alone (the
    renderer's `set_source`; the proxy lobes it once used fell 140× short of a paint's grazing
    highlight, and a twin sampling the proxy predicted another estimator)."""
    from brdflab.lighting.sampling_sets import lobe_shares
    from brdflab.material.analytic import AnalyticMaterial
    from brdflab.sources.proxy import measured_sampler

    if isinstance(source, AnalyticMaterial):
        return proxy, lobe_shares(proxy)
    return _TableSampling([_SampledLobe(_SamplerModel(measured_sampler(source)), {})]), np.ones(1)


def mixture_pdf(material, wi: np.ndarray, wo: np.ndarray, shares: np.ndarray) -> np.ndarray:
    """The renderer's BRDF sampling density at wi: the lobes mixed by their sample shares;
    lobes without a sampler draw cosine-weighted."""
    pdf = np.zeros(wi.shape[:-1])
    for share, lobe in zip(shares, material.lobes):
        if lobe.model.samplable:
            pdf += share * lobe.model.pdf(wi, wo, lobe.params)
        else:
            pdf += share * np.maximum(wi[..., 2], 0.0) / np.pi
    return pdf


def filtered_radiance(levels: list[np.ndarray], d: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """The map as shaders/object_fragment.glsl `filtered_env` reads it: direction d (…, 3)
    filtered over solid angle omega (…); `levels` from `solid_angle_mips`. A footprint of a
    texel or more: trilinear (bilinear within a level); below it, blended towards the texel
    itself, reached at half a texel."""
    height = levels[0].shape[0]
    max_lod = len(levels) - 1
    with np.errstate(divide="ignore"):
        lod = np.log2(np.sqrt(omega) * height / np.pi)
    lod = np.nan_to_num(lod, nan=-1.0, neginf=-1.0, posinf=float(max_lod))
    out = levels[0][texel_of(d, height, levels[0].shape[1])].astype(float)
    sub = (lod > -1.0) & (lod < 0.0)  # part texel, part bilinear at level 0
    if sub.any():
        t = (lod[sub] + 1.0)[:, None]
        out[sub] = out[sub] * (1 - t) + sample_latlong(levels[0], d[sub]) * t
    at_top = lod >= max_lod
    if at_top.any():
        out[at_top] = sample_latlong(levels[max_lod], d[at_top])
    for k in range(max_lod):  # trilinear between levels k and k + 1
        sel = (lod >= k) & (lod < k + 1)
        if sel.any():
            t = (lod[sel] - k)[:, None]
            out[sel] = sample_latlong(levels[k], d[sel]) * (1 - t) + sample_latlong(levels[k + 1], d[sel]) * t
    return out


def _views(frames) -> np.ndarray:
    """The view (world +Z) in each pilot pixel's frame (pixels, 3)."""
    n, t, b = frames
    return np.stack([t[:, 2], b[:, 2], n[:, 2]], axis=-1)


def _lobe_directions(sampling, frames, data: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
    """Local directions (pixels, n, 3) of the sample set `data` (n, 4: u1, u2, lobe, 0) as the
    renderer draws them at each pilot pixel: the lobe's own sampler, else cosine-weighted.
    `u` (pixels, n, 2): each pixel's own points (MIS's shifted set) instead of data's."""
    wo = _views(frames)
    lobe = data[:, 2].astype(int)
    u = np.broadcast_to(data[None, :, :2].astype(float), (len(wo), len(data), 2)) if u is None else u
    wi = np.zeros((len(wo), len(data), 3))
    for k, item in enumerate(sampling.lobes):
        sel = lobe == k
        uk = u[:, sel]
        wk = np.broadcast_to(wo[:, None], uk.shape[:2] + (3,))
        wi[:, sel] = item.model.sample(wk, uk, item.params) if item.model.samplable else cosine_hemisphere(uk)
    return np.where(np.isfinite(wi).all(axis=-1, keepdims=True), wi, np.array([0.0, 0.0, -1.0]))


def _f_cos(source, frames, wi: np.ndarray) -> np.ndarray:
    """RGB f(wi, wo) cos θi (pixels, n, 3) at local directions wi; 0 below the horizon."""
    wo = np.broadcast_to(_views(frames)[:, None], wi.shape)
    f = source.evaluate(wi.reshape(-1, 3), wo.reshape(-1, 3)).reshape(*wi.shape[:2], -1)
    f = f[..., :3] if f.shape[-1] >= 3 else np.repeat(f[..., :1], 3, -1)
    return np.where(wi[..., 2:] > 0, f * wi[..., 2:], 0.0)


def _to_local(frames, world: np.ndarray) -> np.ndarray:
    """World directions in each pilot pixel's frame (pixels, m, 3): (m, 3) shared by every
    pixel, or (pixels, m, 3) each pixel's own."""
    n, t, b = frames
    spec = "jc,pc->pj" if world.ndim == 2 else "pjc,pc->pj"
    return np.stack([np.einsum(spec, world, axis) for axis in (t, b, n)], axis=-1)


def _to_world(frames, wi: np.ndarray) -> np.ndarray:
    n, t, b = frames
    return wi[..., :1] * t[:, None] + wi[..., 1:2] * b[:, None] + wi[..., 2:] * n[:, None]


def fis_pixels(source, proxy, levels: list[np.ndarray], frames, count: int) -> np.ndarray:
    """The FIS mode's RGB value (pixels, 3) at each pilot pixel with `count` samples: the
    renderer's own sample set, sampler, density and filtered lookups (`levels`: the map's
    mips)."""
    from brdflab.lighting.sampling_sets import sample_set

    sampling, shares = renderer_sampling(source, proxy)
    data, fractions = sample_set(shares, count)
    wi = _lobe_directions(sampling, frames, data)
    pdf = mixture_pdf(sampling, wi, np.broadcast_to(_views(frames)[:, None], wi.shape), fractions)
    ok = (wi[..., 2] > 0) & (pdf > 0)
    pdf = np.where(ok, pdf, 1.0)
    radiance = filtered_radiance(levels, _to_world(frames, wi), 1.0 / (len(data) * pdf))
    return np.where(ok[..., None], _f_cos(source, frames, wi) * radiance / pdf[..., None], 0.0).sum(axis=1) / len(data)


def mis_pixels(source, proxy, env: EnvironmentMap, dist, frames, count: int,
               shifts: np.ndarray | None = None, control: tuple | None = None, terms=None) -> np.ndarray:
    """The MIS mode's RGB value (pixels, 3) at each pilot pixel with `count` samples: the
    renderer's own set (`mis_sample_set`: half from the lobes, half from the map's luminance
    `dist`) shifted per pixel as the shader does, Veach's multi-sample estimator with the power
    heuristic, the map texel by texel. `shifts` (pixels, 2): the window pixels' own
    (`pixel_shifts`); by default the shifts of pixels (0, 0), (1, 0), … (pilot pixels are
    not window pixels; what matters is that each has its own, as each pixel does).
    `control` (a `control_variate.MapControl`, its weight β): the estimate with the prefiltered
    control, β P + MIS[f·cos·L − β g]; `terms`: its `pixel_control` at these pixels, if made before."""
    plain, controlled, exact = mis_parts(source, proxy, env, dist, frames, count, shifts,
                                         None if control is None or control[1] == 0.0 else control[0], terms)
    return plain if exact is None else plain + control[1] * (exact - controlled)


def mis_parts(source, proxy, env: EnvironmentMap, dist, frames, count: int, shifts: np.ndarray | None = None,
              control=None, terms=None) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """MIS's estimate of the pixels (`mis_pixels` without a control), and with a
    `control_variate.MapControl` the same samples' estimate of the control and the control's
    integral (each (pixels, 3)), from which the estimate at any weight β is made (β is chosen
    by `control_weight` from these, on draws of their own); `terms`: the control at these pixels
    (`pixel_control`), made here unless given."""
    from brdflab.lighting.control_variate import control_values, pixel_control
    from brdflab.lighting.sampling_sets import mis_sample_set, pixel_shifts

    sampling, shares = renderer_sampling(source, proxy)
    data, fractions, env_fraction = mis_sample_set(shares, count)
    pixels = len(frames[0])
    if shifts is None:
        shifts = pixel_shifts(np.arange(pixels), np.zeros(pixels))
    u = np.mod(data[None, :, :2] + shifts[:, None, :], np.float32(1.0)).astype(float)  # float32, as fract()
    from_map = data[:, 2] < 0
    wi = _lobe_directions(sampling, frames, data, u)
    drawn = dist.sample(u[:, from_map].reshape(-1, 2)).reshape(pixels, -1, 3)  # world, each pixel its own
    wi[:, from_map] = _to_local(frames, drawn)
    world = _to_world(frames, wi)
    p_map = env_fraction * dist.pdf(world)
    p_lobes = (1.0 - env_fraction) * mixture_pdf(sampling, wi, np.broadcast_to(_views(frames)[:, None], wi.shape), fractions)
    p_lobes = np.where(wi[..., 2] > 0, p_lobes, 0.0)  # below the horizon the map's samples alone (weight 1)
    own = np.where(from_map, p_map, p_lobes)
    other = np.where(from_map, p_lobes, p_map)
    ok = own > 0
    own = np.where(ok, own, 1.0)
    weight = np.where(ok, 1.0 / (1.0 + (other / own) ** 2), 0.0) / own  # the power heuristic, as the shader writes it
    radiance = env.data.astype(float)[texel_of(world, env.height, env.width)]
    plain = (_f_cos(source, frames, wi) * radiance * weight[..., None]).sum(axis=1) / len(data)
    if control is None:
        return plain, None, None
    terms = pixel_control(proxy, control.stack, frames, lit=source) if terms is None else terms
    g = control_values(terms, control.stack, control.excess, frames, world)
    return plain, (g * weight[..., None]).sum(axis=1) / len(data), terms.exact


CONTROL_SAMPLES = 64  # samples per pixel of the draws the control's weight is chosen on …
CONTROL_DRAWS = 4  # … and how many (a family of shifts of their own: β is fixed before a render's samples)
CONTROL_FAMILY = 1 << 21  # their shifts' family (`pixel_shifts`), unrelated to a render's sets


def control_draws(source, proxy, env: EnvironmentMap, control, dist=None,
                  pixels: PilotPixels | None = None) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The draws the control's weight is chosen on: CONTROL_DRAWS independent draws of
    CONTROL_SAMPLES samples at the pilot pixels, each `mis_parts`' (plain estimate, control's
    estimate, control's integral), (pixels, 3) each. From them MIS's estimate at any weight β
    is plain + β (integral − control's estimate) (`weighted_draws`)."""
    from brdflab.lighting.env_sampling import environment_distribution

    pixels = pixels or fis_pixels_of(env)
    dist = dist or environment_distribution(env)
    terms = pilot_control(source, proxy, control, pixels.frames)
    estimate = lambda part, shifts, rows: np.stack(mis_parts(source, proxy, env, dist, part, CONTROL_SAMPLES, shifts,
                                                             control, terms.take(rows)), 1)
    stacked = independent_draws(estimate, pixels.frames, CONTROL_SAMPLES,
                                range(CONTROL_FAMILY, CONTROL_FAMILY + CONTROL_DRAWS))
    return [(parts[:, 0], parts[:, 1], parts[:, 2]) for parts in stacked]


def weighted_draws(draws: list[tuple[np.ndarray, np.ndarray, np.ndarray]], weight: float) -> list[np.ndarray]:
    """MIS's estimates (pixels, 3) with its control at `weight` in each of `control_draws`:
    what `mis_pixels` gives for the same samples (plain MIS where β = 0)."""
    return [plain if weight == 0.0 else plain + weight * (exact - controlled) for plain, controlled, exact in draws]


def control_weight(source, proxy, env: EnvironmentMap, control, dist=None, pixels: PilotPixels | None = None,
                   draws: list | None = None) -> float:
    """The control's weight β for this material and map, in [0, 1]: the β that makes the error
    Auto judges smallest — the larger of the view's relative RMSE and the RMS of each pixel's
    relative error (`ViewPilot.error`) — estimated from the variance of MIS with its control,
    Var(X) − 2β Cov(X, Y) + β² Var(Y) (X the plain estimate, Y the control's, over
    `control_draws`, made here unless given), summed over the pilot pixels weighted by their
    share of the view, once over the view's mean square and once over each pixel's value squared.
    Judged per pixel alone, β took dim pixels' variance and added its own to bright ones: Cook–Torrance
    m = 0.2 under the sunset went 3.0 → 2.4 % per pixel and 3.7 → 8.2 % over the view at 64 samples.
    0 where the control does not pay for its frames' cost (`control_variate.frame_cost`): when its
    error squared × the cost is no less than plain MIS's, plain MIS with as many more samples would
    do as well (a measured slice against its proxy, ρ² ≈ 0.1 for 1.5× the cost)."""
    from brdflab.lighting.control_variate import fitted_in_control, frame_cost

    pixels = pixels or fis_pixels_of(env)
    draws = draws if draws is not None else control_draws(source, proxy, env, control, dist, pixels)
    lum = np.stack([np.stack(parts[:2], 1) for parts in draws]) @ LUMINANCE  # (draws, pixels, 2): plain, control
    x, y = np.moveaxis(lum - lum.mean(0), -1, 0)
    mean = lum[..., 0].mean(0)
    scale = np.maximum(np.abs(mean), 1e-2 * max(float(np.median(np.abs(mean))), 1e-300))
    weightings = (pixels.weight / scale**2, pixels.weight / max(float((pixels.weight * mean**2).sum()), 1e-300))
    moments = np.array([[(w * (a * b).sum(0)).sum() for a, b in ((x, x), (x, y), (y, y))] for w in weightings])
    if not (moments[:, 0] > 0.0).all() or not (moments[:, 2] > 0.0).any():
        return 0.0
    betas = np.linspace(0.0, 1.0, 101)
    judged = (moments[:, :1] - 2.0 * betas * moments[:, 1:2] + betas**2 * moments[:, 2:]).max(axis=0)  # error², per β
    best = int(np.argmin(judged))
    return float(betas[best]) if judged[best] * frame_cost(fitted_in_control(proxy)) < judged[0] else 0.0


_WEIGHTS: dict = {}  # weight_for's answers: (material, lit source, map) → β
_WEIGHTS_KEPT = 16


def weight_for(source, proxy, env: EnvironmentMap, control=None, dist=None,
               draws: Callable[[], list] | None = None) -> float:
    """`control_weight` for this material and map (the map's control and distribution made
    here unless given: what the window's worker runs; `draws()`: its `control_draws`, asked
    for only when the weight is not remembered, from a caller that may have them), remembered
    for the (material, table, map) it was chosen for: Auto and the render it picks use the same
    β, computed once."""
    from brdflab.lighting.control_variate import map_control
    from brdflab.lighting.prefilter import map_key
    from brdflab.material.analytic import AnalyticMaterial

    lobes = tuple((lobe.model.name, tuple(sorted(lobe.params.items()))) for lobe in proxy.lobes)
    key = (lobes, proxy.rgb_scales().tobytes(), None if isinstance(source, AnalyticMaterial) else id(source), map_key(env))
    if key not in _WEIGHTS:
        while len(_WEIGHTS) >= _WEIGHTS_KEPT:
            _WEIGHTS.pop(next(iter(_WEIGHTS)))
        _WEIGHTS[key] = control_weight(source, proxy, env, control or map_control(env, proxy), dist,
                                       draws=None if draws is None else draws())
    return _WEIGHTS[key]


def _mixture_estimate(source, proxy, env: EnvironmentMap, dist, frames, count: int, shifts: np.ndarray) -> np.ndarray:
    """One estimate of the pilot pixels' RGB values (pixels, 3) against the map texel by
    texel: half the samples from the lobes, half from the map's luminance, each weighted by
    the mixture of both densities (robust to a small sun under a broad lobe, and to a sharp
    lobe under a broad map); each pixel's set shifted by its own amount (`shifts` (pixels, 2),
    `truth_shifts`: a family unrelated to MIS's, whose errors it must not share)."""
    from brdflab.lighting.sampling_sets import hammersley, sample_set

    half = count // 2
    sampling, shares = renderer_sampling(source, proxy)
    pixels = len(frames[0])
    data, fractions = sample_set(shares, half)
    u_lobes = np.mod(data[None, :, :2] + shifts[:, None], 1.0)
    u_map = np.mod(hammersley(half)[None] + shifts[:, None], 1.0)
    from_map = _to_local(frames, dist.sample(u_map.reshape(-1, 2)).reshape(pixels, half, 3))
    wi = np.concatenate([_lobe_directions(sampling, frames, data, u_lobes), from_map], axis=1)
    world = _to_world(frames, wi)
    pdf_lobes = mixture_pdf(sampling, wi, np.broadcast_to(_views(frames)[:, None], wi.shape), fractions)
    pdf = 0.5 * pdf_lobes + 0.5 * dist.pdf(world)
    radiance = env.data.astype(float)[texel_of(world, env.height, env.width)]
    ok = (wi[..., 2] > 0) & (pdf > 0)
    value = np.where(ok[..., None], _f_cos(source, frames, wi) * radiance / np.where(ok, pdf, 1.0)[..., None], 0.0)
    return value.mean(axis=1)


def truth_shifts(pixels: int, salt: int) -> np.ndarray:
    """The converged estimate's per-pixel shifts (pixels, 2) of family `salt`."""
    from brdflab.lighting.sampling_sets import pixel_shifts

    return pixel_shifts(np.arange(pixels), np.full(pixels, (1 << 20) + salt)).astype(float)


def in_pieces(estimate: Callable[..., np.ndarray], frames, count: int, *per_pixel: np.ndarray) -> list[Callable[[], np.ndarray]]:
    """`estimate(frames, *per_pixel)` of every pilot pixel as calls over runs of pixels, each
    about PIECE_SAMPLES samples, whose results stacked in order are the whole's (each pixel is
    its own estimate). Arrays of a piece stay in the processor's caches: one MIS draw of 511
    pixels at 1,024 samples took 0.46 s whole and 0.29 s in runs of 32 pixels (a measured slice)."""
    pixels = len(frames[0])
    step = max(1, PIECE_SAMPLES // max(count, 1))
    return [partial(estimate, tuple(axis[i:i + step] for axis in frames), *(a[i:i + step] for a in per_pixel))
            for i in range(0, pixels, step)]


def side_by_side_pieces(estimates: list[list[Callable[[], np.ndarray]]]) -> list[np.ndarray]:
    """Each estimate's pieces (`in_pieces`) made two at a time (`side_by_side`), stacked back
    into one (pixels, …) array per estimate."""
    flat = side_by_side([call for pieces in estimates for call in pieces])
    out, start = [], 0
    for pieces in estimates:
        out.append(np.concatenate(flat[start:start + len(pieces)]))
        start += len(pieces)
    return out


def side_by_side(calls: list[Callable[[], np.ndarray]]) -> list[np.ndarray]:
    """The calls' results, made two at a time in threads: the twins' estimates are independent
    and NumPy lets go of the GIL over arrays their size (a choice's time on 2 cores: a measured
    slice 1.65 → 1.15 s, docs/benchmarks.md)."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(2) as pool:
        return list(pool.map(lambda call: call(), calls))


def _converged_halves(source, proxy, env: EnvironmentMap, dist, frames, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Two independent estimates of `count` / 2 samples each: their mean is the converged
    value, their difference measures its own error."""
    pixels = len(frames[0])
    return tuple(side_by_side_pieces([
        in_pieces(lambda part, shifts: _mixture_estimate(source, proxy, env, dist, part, count // 2, shifts),
                  frames, count // 2, truth_shifts(pixels, salt)) for salt in (1, 2)]))


def converged_pixels(source, proxy, env: EnvironmentMap, dist, frames, count: int = TRUTH_SAMPLES) -> np.ndarray:
    """The pilot pixels' RGB values (pixels, 3) by a large estimate (`count` samples per
    pixel, `_mixture_estimate`). `dist`: the map's luminance distribution."""
    return np.mean(_converged_halves(source, proxy, env, dist, frames, count), axis=0)


@dataclass(frozen=True)
class ViewPilot:
    """The pilot pixels and their converged values: what a mode's pixels are scored against."""

    pixels: PilotPixels
    truth: np.ndarray  # (pixels, 3) RGB
    dist: object  # the map's luminance distribution (env_sampling.EnvironmentDistribution), built once
    truth_variance: np.ndarray  # (pixels, 3): the converged value's own squared error, estimated
    lum_variance: np.ndarray  # (pixels,): the same for its luminance

    def error(self, values: np.ndarray) -> float:
        """The error Auto judges a mode by: the larger of the view's relative RMSE (RGB, as the
        reference view's error is measured) and the RMS of each pixel's relative error in
        luminance (`reference_view.pixel_relative_rmse`, the error a user sees: 2–3 times the
        first for FIS on a soft sky, where the dim rim is off and the bright centre is not),
        both with the converged value's own error taken out: a method's error and the truth's
        are independent, so their squares add (MIS at 256 samples, 0.44 % off the quadrature,
        was predicted 0.70 % against a truth of 4,096 samples)."""
        w = self.pixels.weight[:, None]
        rms = max(float(np.sqrt((w * self.truth**2).sum() / 3)), 1e-300)
        square = float((w * (values - self.truth) ** 2).sum() / 3) - float((w * self.truth_variance).sum() / 3)
        lum = lambda rgb: rgb[:, :3] @ LUMINANCE
        per_pixel = weighted_pixel_error(lum(values), lum(self.truth), self.pixels.weight, self.lum_variance)
        return max(float(np.sqrt(max(square, 0.0))) / rms, per_pixel)


def view_pilot(source, proxy, env: EnvironmentMap, pixels: PilotPixels | None = None) -> ViewPilot:
    """The pilot pixels (`fis_pixels_of` unless given) with their converged values and those
    values' own error (from the difference of two independent halves)."""
    from brdflab.lighting.env_sampling import environment_distribution

    pixels = pixels or fis_pixels_of(env)
    dist = environment_distribution(env)
    a, b = _converged_halves(source, proxy, env, dist, pixels.frames, TRUTH_SAMPLES)
    half = (a - b) / 2
    return ViewPilot(pixels, (a + b) / 2, dist, half**2, (half[:, :3] @ LUMINANCE) ** 2)


def mis_errors(source, proxy, env: EnvironmentMap, counts, pilot: ViewPilot | None = None,
               control: tuple | None = None) -> dict[int, float]:
    """Per sample count N: the MIS mode's predicted relative RMSE over the view: the RMS over
    MIS_DRAWS independent draws of the pilot pixels' shifts (`mis_draws`, `draws_error`).
    `control`: (`control_variate.MapControl`, β), the renderer's estimator with its control."""
    pilot = pilot or view_pilot(source, proxy, env)
    return {count: draws_error(pilot, mis_draws(source, proxy, env, count, pilot, control)) for count in counts}


def mis_draws(source, proxy, env: EnvironmentMap, count: int, pilot: ViewPilot,
              control: tuple | None = None) -> list[np.ndarray]:
    """MIS's `count`-sample estimate of the pilot pixels (pixels, 3) in each of MIS_DRAWS
    independent draws of the pixels' shifts (`mis_pixels`). With each pixel its own shift an
    image is one draw, and under a sun a draw's error is heavy-tailed (a measured paint at 256
    samples: 0.6–6.5 % from one image to the next); one pilot draw predicted 0.67 % where the
    image came out 7.5 %, the RMS of six draws 5.0 % against the images' 3.3 %."""
    controlled = control is not None and control[1] != 0.0
    terms = pilot_control(source, proxy, control[0], pilot.pixels.frames) if controlled else None
    estimate = lambda part, shifts, rows: mis_pixels(source, proxy, env, pilot.dist, part, count, shifts, control,
                                                     terms.take(rows) if controlled else None)
    return independent_draws(estimate, pilot.pixels.frames, count, range(MIS_DRAWS))


def pilot_control(source, proxy, control, frames):
    """The control (`control_variate.pixel_control`) at the pilot pixels, made once for all of a
    set's draws and pieces (made per piece and draw, it was a quarter of a car paint's choice
    under a map whose lights are blocks)."""
    from brdflab.lighting.control_variate import pixel_control

    return pixel_control(proxy, control.stack, frames, lit=source)


def independent_draws(estimate: Callable[..., np.ndarray], frames, count: int, families) -> list[np.ndarray]:
    """`estimate(frames, shifts, rows)` of every pilot pixel at `count` samples (`rows`: the
    piece's indices among the pilot pixels), one draw per shift family (`pixel_shifts`: within a
    family each pixel has its own shift), made in pieces two at a time (`in_pieces`,
    `side_by_side_pieces`)."""
    from brdflab.lighting.sampling_sets import pixel_shifts

    pixels = len(frames[0])
    return side_by_side_pieces([in_pieces(estimate, frames, count, pixel_shifts(np.arange(pixels), np.full(pixels, family)),
                                          np.arange(pixels)) for family in families])


def draws_error(pilot: ViewPilot, images: list[np.ndarray]) -> float:
    """The error Auto judges (`ViewPilot.error`), RMS over independent draws."""
    return float(np.sqrt(np.mean([pilot.error(values) ** 2 for values in images])))


def pooled_error(pilot: ViewPilot, images: list[np.ndarray]) -> float:
    """MIS's predicted error at k times the sample count of `images` (k independent draws,
    `mis_draws`) without drawing it: the larger of their error over √k (k independent sets
    average to √k less noise, and one stratified set of k N does at least that well where the
    noise dominates) and the error of the k averaged (a set of k N samples of its own, which
    keeps what does not fall with N: the pilot's own floor, a bias). With k = MIS_DRAWS = 4, on
    the 75 pairs of benchmarks/lighting_auto_pixels.py the direct prediction at 1,024 samples
    was 0.51–0.88× this wherever the 256-sample one exceeded 2 %, and 0.5–1.02× elsewhere but on
    one heavy-tailed pair that 256 samples already satisfied (1.16×); drawing it was a third to
    two thirds of a choice's time."""
    return max(draws_error(pilot, images) / np.sqrt(len(images)), pilot.error(np.mean(images, axis=0)))


def fis_errors(source, proxy, env: EnvironmentMap, counts, pilot: ViewPilot | None = None,
               levels: list[np.ndarray] | None = None) -> dict[int, float]:
    """Per sample count N: the FIS mode's predicted relative RMSE over the view (`levels`: the
    map's mips in float64, made here unless given)."""
    pilot = pilot or view_pilot(source, proxy, env)
    levels = levels or [level.astype(float) for level in solid_angle_mips(env.data)]
    return {count: pilot.error(side_by_side_pieces([in_pieces(
                lambda part: fis_pixels(source, proxy, levels, part, count), pilot.pixels.frames, count)])[0])
            for count in counts}
