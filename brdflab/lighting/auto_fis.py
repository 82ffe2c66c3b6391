"""The FIS mode's pilot: the renderer's own estimator, run in NumPy at a few hundred pixels.

A quadrature of the one-sample variance over a coarse copy of the map (what the MIS
prediction uses) cannot see a lobe narrower than the copy's texels: the lobe falls in one
texel, the radiance it gathers looks constant, and the predicted error was up to 7× too low
for a sharp lobe under a small sun. Here each pilot pixel is shaded as the renderer shades
it with N samples (its Hammersley set and lobe shares, each lobe's own sampler and the
mixture density, the full map read through `filtered_radiance` as shaders/object_fragment.glsl
reads it; the result equals the renderer's to 1e-5), and compared with a converged estimate
(`converged_pixels`: TRUTH_SAMPLES per pixel, half from the lobes, half from the map). Both
are estimates, so the prediction carries the converged one's own error (≈ 0.3 %) and the
sampling of the pixels (the view's error is the RMS over all of its pixels).
"""

from __future__ import annotations

import numpy as np

from brdflab.geometry.sampling import cosine_hemisphere
from brdflab.lighting.envmap import EnvironmentMap, direction_to_uv, texel_of
from brdflab.lighting.mip_pyramid import solid_angle_mips

FIS_PILOT_GRID = 20  # the pilot pixels: the centres of a 20 × 20 reference view inside the sphere (≈ 310)
TRUTH_SAMPLES = 4096  # per pilot pixel, for the converged value FIS is measured against


def fis_frames():
    """The FIS pilot pixels' frames: (normal, tangent, bitangent), each (pixels, 3). A sharp
    highlight covers a few percent of the view: 9² pixels (the other modes' pilot) missed it
    and predicted a third of the error under a small sun."""
    from brdflab.lighting.reference_view import sphere_view

    view = sphere_view(FIS_PILOT_GRID, FIS_PILOT_GRID)
    return view.normal[view.inside], view.tangent[view.inside], view.bitangent[view.inside]


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


def _bilinear(level: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """GL's LINEAR lookup of one level: columns repeat, rows clamp."""
    h, w = level.shape[:2]
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    c0, c1 = x0.astype(int) % w, (x0.astype(int) + 1) % w
    r0, r1 = np.clip(y0.astype(int), 0, h - 1), np.clip(y0.astype(int) + 1, 0, h - 1)
    top = level[r0, c0] * (1 - fx) + level[r0, c1] * fx
    bottom = level[r1, c0] * (1 - fx) + level[r1, c1] * fx
    return top * (1 - fy) + bottom * fy


def filtered_radiance(levels: list[np.ndarray], d: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """The map as shaders/object_fragment.glsl `filtered_env` reads it: direction d (…, 3)
    filtered over solid angle omega (…); `levels` from `solid_angle_mips`."""
    height = levels[0].shape[0]
    u, v = direction_to_uv(d)
    max_lod = len(levels) - 1
    with np.errstate(divide="ignore"):
        lod = np.clip(np.log2(np.sqrt(omega) * height / np.pi), 0.0, max_lod)
    lod = np.nan_to_num(lod, nan=0.0)
    rows = np.clip(np.floor(v * height).astype(int), 0, height - 1)
    cols = np.clip(np.floor(u * levels[0].shape[1]).astype(int), 0, levels[0].shape[1] - 1)
    out = levels[0][rows, cols].astype(float)
    for k in range(max_lod):  # between levels k and k + 1: texel by texel at 0, bilinear above
        sel = (lod > k) & (lod <= k + 1)
        if not sel.any():
            continue
        lower = out[sel] if k == 0 else _bilinear(levels[k], u[sel], v[sel])
        t = (lod[sel] - k)[:, None]
        out[sel] = lower * (1 - t) + _bilinear(levels[k + 1], u[sel], v[sel]) * t
    return out


def _views(frames) -> np.ndarray:
    """The view (world +Z) in each pilot pixel's frame (pixels, 3)."""
    n, t, b = frames
    return np.stack([t[:, 2], b[:, 2], n[:, 2]], axis=-1)


def _lobe_directions(proxy, frames, data: np.ndarray) -> np.ndarray:
    """Local directions (pixels, n, 3) of the sample set `data` (n, 4: u1, u2, lobe, 0) as the
    renderer draws them at each pilot pixel: the lobe's own sampler, else cosine-weighted."""
    wo = _views(frames)
    u, lobe = data[:, :2].astype(float), data[:, 2].astype(int)
    wi = np.zeros((len(wo), len(data), 3))
    for k, item in enumerate(proxy.lobes):
        sel = lobe == k
        uk = np.broadcast_to(u[sel][None], (len(wo), int(sel.sum()), 2))
        wk = np.broadcast_to(wo[:, None], uk.shape[:2] + (3,))
        wi[:, sel] = item.model.sample(wk, uk, item.params) if item.model.samplable else cosine_hemisphere(uk)
    return np.where(np.isfinite(wi).all(axis=-1, keepdims=True), wi, np.array([0.0, 0.0, -1.0]))


def _f_cos(source, frames, wi: np.ndarray) -> np.ndarray:
    """RGB f(wi, wo) cos θi (pixels, n, 3) at local directions wi; 0 below the horizon."""
    wo = np.broadcast_to(_views(frames)[:, None], wi.shape)
    f = source.evaluate(wi.reshape(-1, 3), wo.reshape(-1, 3)).reshape(*wi.shape[:2], -1)
    f = f[..., :3] if f.shape[-1] >= 3 else np.repeat(f[..., :1], 3, -1)
    return np.where(wi[..., 2:] > 0, f * wi[..., 2:], 0.0)


def _to_world(frames, wi: np.ndarray) -> np.ndarray:
    n, t, b = frames
    return wi[..., :1] * t[:, None] + wi[..., 1:2] * b[:, None] + wi[..., 2:] * n[:, None]


def fis_pixels(source, proxy, levels: list[np.ndarray], frames, count: int) -> np.ndarray:
    """The FIS mode's RGB value (pixels, 3) at each pilot pixel with `count` samples: the
    renderer's own sample set, sampler, density and filtered lookups (`levels`: the map's
    mips)."""
    from brdflab.lighting.sampling_sets import lobe_shares, sample_set

    data, fractions = sample_set(lobe_shares(proxy), count)
    wi = _lobe_directions(proxy, frames, data)
    pdf = mixture_pdf(proxy, wi, np.broadcast_to(_views(frames)[:, None], wi.shape), fractions)
    ok = (wi[..., 2] > 0) & (pdf > 0)
    pdf = np.where(ok, pdf, 1.0)
    radiance = filtered_radiance(levels, _to_world(frames, wi), 1.0 / (len(data) * pdf))
    return np.where(ok[..., None], _f_cos(source, frames, wi) * radiance / pdf[..., None], 0.0).sum(axis=1) / len(data)


def converged_pixels(source, proxy, env: EnvironmentMap, frames, count: int = TRUTH_SAMPLES) -> np.ndarray:
    """The pilot pixels' RGB values (pixels, 3) by a large estimate against the map texel by
    texel: half the samples from the lobes, half from the map's luminance, each weighted by
    the mixture of both densities (robust to a small sun under a broad lobe, and to a sharp
    lobe under a broad map)."""
    from brdflab.lighting.env_sampling import environment_distribution
    from brdflab.lighting.sampling_sets import hammersley, lobe_shares, sample_set

    n, t, b = frames
    half = count // 2
    data, fractions = sample_set(lobe_shares(proxy), half)
    dist = environment_distribution(env)
    drawn = dist.sample(hammersley(half))  # world directions, shared by every pixel
    from_map = np.stack([np.einsum("jc,pc->pj", drawn, axis) for axis in (t, b, n)], axis=-1)
    wi = np.concatenate([_lobe_directions(proxy, frames, data), from_map], axis=1)
    world = _to_world(frames, wi)
    pdf_lobes = mixture_pdf(proxy, wi, np.broadcast_to(_views(frames)[:, None], wi.shape), fractions)
    pdf = 0.5 * pdf_lobes + 0.5 * dist.pdf(world)
    radiance = env.data.astype(float)[texel_of(world, env.height, env.width)]
    ok = (wi[..., 2] > 0) & (pdf > 0)
    value = np.where(ok[..., None], _f_cos(source, frames, wi) * radiance / np.where(ok, pdf, 1.0)[..., None], 0.0)
    return value.mean(axis=1)


def fis_errors(source, proxy, env: EnvironmentMap, counts, frames) -> dict[int, float]:
    """Per sample count N: the FIS mode's relative RMSE (RGB, as the reference view's error
    is measured) at the pilot pixels against
    `converged_pixels` (which carries its own small error into the prediction)."""
    truth = converged_pixels(source, proxy, env, frames)
    levels = [level.astype(float) for level in solid_angle_mips(env.data)]
    rms = max(float(np.sqrt(np.mean(truth**2))), 1e-300)
    return {count: float(np.sqrt(np.mean((fis_pixels(source, proxy, levels, frames, count) - truth) ** 2))) / rms
            for count in counts}
