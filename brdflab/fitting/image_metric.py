"""The image metric: a fit judged by the picture a user looks at, not by BRDF samples.

A material is rendered as the reference view (CONVENTIONS.md: the unit sphere, orthographic
camera, wo = +Z) under a few environment maps, and compared with the source rendered the
same way, pixel by pixel and channel by channel after a cube-root tone curve: perceived
lightness follows the cube root of luminance (CIE L*, and the cube root is what Forés et
al. 2012 found closest to perceived BRDF differences among the simple metrics), so a
pixel 10 % too bright costs alike in a shadow and in a highlight, and a dark mirror that
renders as a bright ceramic costs what it looks like. The error is

    sqrt( mean over maps of Σ (∛a − ∛y)² / Σ (∛y)² )   (sums over pixels and channels),

relative to the toned measurement, so a zero BRDF scores 1 under every map.

A render under a map is linear in the BRDF: each pixel is Σ_k w_k f(ωi_k, ωo) over fixed
pairs and weights (a texel's radiance × solid angle × cos θi). `MapQuadrature` holds those
pairs: the map's bright texels (a sun, lamps: ≥ BRIGHT × the mean luminance) one by one,
the rest reduced to DIM_WIDTH, but at FINE_WIDTH near each pixel's mirror direction. `SceneImages` is what the fitter runs over in
place of samples: lm.py evaluates each lobe at the pairs once per pass, sums images, and
takes the residuals through the tone curve (its finite differences see the curve exactly).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.fitting.samples import SampleSet
from brdflab.lighting.env_sampling import LUMINANCE
from brdflab.lighting.envmap import EnvironmentMap
from brdflab.lighting.reference_view import BRIGHT, sphere_view
from brdflab.lighting.synthetic_maps import spec

# the default scene: three maps of different character the lab tunes on (none held out):
# an outdoor sky with a small sun, an interior lit by a window, a studio with two soft boxes
DEFAULT_MAPS = ("sun-high-small", "room-one-window", "studio-two-boxes")
DEFAULT_MAP_SIZE = (256, 128)  # the synthetic maps are built at this size
VIEW = 32  # the sphere's image, VIEW × VIEW pixels (812 on the sphere; at 16 a metal's error moved 10–40 % when doubled)
DIM_WIDTH = 32  # the map without its bright texels, reduced to DIM_WIDTH × DIM_WIDTH/2 …
FINE_WIDTH = 256  # … and to FINE_WIDTH near each pixel's mirror direction; bright texels at FINE_WIDTH
MAX_BRIGHT = 512  # (halved until at most this many)
CAP_DEGREES = 6.0  # near: a coarse texel reaching this close to the mirror direction (12: 1.6 × the pairs, same error)
PAIR_BLOCK = 65_536  # pairs per block of a pass (memory stays a few blocks)
SPHERE = "the sphere"  # what the reference view's pixels show (a mesh's are named by its file)
TONE_FLOOR = 1e-3  # the tone curve's slope is taken no lower than at this share of a map's mean


def tone(x: np.ndarray) -> np.ndarray:
    """The tone curve: the cube root (of a non-negative radiance)."""
    return np.cbrt(np.maximum(x, 0.0))


@dataclass
class MapQuadrature:
    """One map's render of the reference view as pairs: pixel p of the view gets
    Σ weight[k, c] f(wi[k], wo[k])_c over the pairs k with pixel[k] = p."""

    name: str
    inside: np.ndarray  # (H, W) bool: the pixels on the object, in row-major order
    pixel: np.ndarray  # (pairs,) index among the inside pixels, in order (the fitter sums runs of them)
    wi: np.ndarray  # (pairs, 3) local frame
    wo: np.ndarray  # (pairs, 3)
    weight: np.ndarray  # (pairs, 3): radiance × solid angle × cos θi

    @property
    def pixels(self) -> int:
        return int(self.inside.sum())

    def render(self, evaluate: Callable[[np.ndarray, np.ndarray], np.ndarray], channels: int) -> np.ndarray:
        """(channels, pixels): the view under this map of a BRDF given by `evaluate`."""
        out = np.zeros((channels, self.pixels))
        weight = self.weights(channels)
        for s in range(0, len(self.pixel), PAIR_BLOCK):
            e = s + PAIR_BLOCK
            f = np.asarray(evaluate(self.wi[s:e], self.wo[s:e]), float).reshape(len(self.pixel[s:e]), -1)
            for c in range(channels):
                out[c] += np.bincount(self.pixel[s:e], f[:, min(c, f.shape[1] - 1)] * weight[s:e, c],
                                      minlength=self.pixels)
        return out

    def weights(self, channels: int) -> np.ndarray:
        """(pairs, channels): the pairs' weights for a `channels`-channel BRDF (luminance for one)."""
        return self.weight if channels == 3 else (self.weight @ LUMINANCE)[:, None]

    def pick(self, keep: np.ndarray) -> tuple["MapQuadrature", np.ndarray]:
        """The quadrature of the pixels where `keep` (H, W) is set, and which of the
        present pixels those are (a bool per pixel)."""
        chosen = keep[self.inside]
        index = np.cumsum(chosen) - 1
        pairs = chosen[self.pixel]
        return MapQuadrature(self.name, self.inside & keep, index[self.pixel[pairs]], self.wi[pairs],
                             self.wo[pairs], self.weight[pairs]), chosen

    def image(self, values: np.ndarray) -> np.ndarray:
        """(channels, pixels) → (H, W, channels), 0 off the object."""
        out = np.zeros((*self.inside.shape, values.shape[0]))
        out[self.inside] = values.T
        return out


@dataclass
class _Layers:
    """A map split for quadrature: its bright texels one by one, and the rest at two levels,
    coarse (DIM_WIDTH) and fine (FINE_WIDTH), each coarse texel the union of fy × fx fine ones."""

    bright_dirs: np.ndarray  # (B, 3) world
    bright_energy: np.ndarray  # (B, 3) radiance × solid angle
    coarse: EnvironmentMap
    fine: EnvironmentMap


def _regular(env: EnvironmentMap, width: int) -> EnvironmentMap:
    """The map at width × width/2 by area: directly when its size divides evenly, else first
    sampled at four times that size by nearest texel (a user's 1000 × 500 map)."""
    if env.width % width == 0 and env.height % (width // 2) == 0:
        return env.downsampled(width, width // 2)
    big = 4 * width
    u = (np.arange(big) + 0.5) / big
    v = (np.arange(big // 2) + 0.5) / (big // 2)
    rows = np.minimum((v * env.height).astype(int), env.height - 1)
    cols = np.minimum((u * env.width).astype(int), env.width - 1)
    return EnvironmentMap(env.data[rows][:, cols], env.name).downsampled(width, width // 2)


def _layers(env: EnvironmentMap, dim_width: int, fine_width: int) -> _Layers:
    """Bright texels (≥ BRIGHT × the mean luminance) at `fine_width`, halved until at most
    MAX_BRIGHT of them; the rest of the map at `fine_width` and `dim_width`. The parts sum to
    the map's whole energy."""
    fine = _regular(env, fine_width)
    level = fine
    while True:
        lum = level.data.astype(float) @ LUMINANCE
        bright = lum >= BRIGHT * max(float(lum.mean()), 1e-300)
        if bright.sum() <= MAX_BRIGHT or level.width <= dim_width:
            break
        level = level.downsampled(level.width // 2, level.height // 2)
    d, solid = level.texel_directions()
    # the bright texels' area taken out of the fine level: each fine texel is inside one of them
    f = fine.width // level.width
    bright_fine = np.repeat(np.repeat(bright, f, axis=0), f, axis=1)
    rest = EnvironmentMap(np.where(bright_fine[..., None], 0.0, fine.data).astype(np.float32), env.name)
    return _Layers(d[bright], (level.data * solid[:, :, None])[bright].astype(float),
                   rest.downsampled(dim_width, dim_width // 2), rest)


def _energy(env: EnvironmentMap) -> tuple[np.ndarray, np.ndarray]:
    """Texel directions (T, 3) and radiance × solid angle (T, 3), row-major."""
    d, solid = env.texel_directions()
    return d.reshape(-1, 3), (env.data * solid[:, :, None]).reshape(-1, 3).astype(float)


@dataclass(frozen=True)
class PixelFrames:
    """What a render needs of a view's pixels: which pixels show the object, and at each
    (row-major) its shading frame and the direction towards the camera, in world space.
    The reference view's (`sphere_frames`) or a mesh's seen by a camera (the render layer's
    `render.gbuffer.mesh_frames`, rasterised as the object view draws it)."""

    inside: np.ndarray  # (H, W) bool
    normal: np.ndarray  # (pixels, 3)
    tangent: np.ndarray  # (pixels, 3)
    bitangent: np.ndarray  # (pixels, 3)
    view: np.ndarray  # (pixels, 3): towards the camera
    name: str = SPHERE


def sphere_frames(view: int = VIEW) -> PixelFrames:
    """The reference view at view × view pixels: the unit sphere, wo = +Z everywhere."""
    sphere = sphere_view(view, view)
    n, t, b = (a[sphere.inside] for a in (sphere.normal, sphere.tangent, sphere.bitangent))
    return PixelFrames(sphere.inside, n, t, b, np.broadcast_to(np.array([0.0, 0.0, 1.0]), n.shape))


def map_quadrature(env: EnvironmentMap, view: int | PixelFrames = VIEW, dim_width: int = DIM_WIDTH,
                   fine_width: int = FINE_WIDTH, cap_degrees: float = CAP_DEGREES) -> MapQuadrature:
    """The pairs and weights of a view (the reference view at `view` × `view`, or the given
    frames) under `env`: the bright texels for every pixel; of the rest, per pixel, the coarse
    texels that reach within `cap_degrees` of its mirror direction (where a sharp lobe is) are
    replaced by their fine ones, the others taken whole. Every texel at its centre, with its
    exact solid angle."""
    frames = sphere_frames(view) if isinstance(view, int) else view
    n, t, b, v = frames.normal, frames.tangent, frames.bitangent, frames.view
    layers = _layers(env, dim_width, fine_width)
    coarse_d, coarse_e = _energy(layers.coarse)
    fine_d, fine_e = _energy(layers.fine)
    hc, wc = layers.coarse.height, layers.coarse.width
    fy, fx = layers.fine.height // hc, layers.fine.width // wc
    mirror = 2.0 * (n * v).sum(axis=1, keepdims=True) * n - v
    near = coarse_d @ mirror.T >= np.cos(np.radians(cap_degrees) + 0.5 * np.hypot(np.pi / hc, 2.0 * np.pi / wc))
    # (pixel, texel) of every part: bright ones, coarse ones not near, fine children of near ones
    pix_b, tex_b = np.nonzero(np.ones((len(n), len(layers.bright_dirs)), bool))
    tex_c, pix_c = np.nonzero(~near)
    parent, pix_f = np.nonzero(near)
    row, col = np.divmod(parent, wc)
    child = ((row[:, None, None] * fy + np.arange(fy)[None, :, None]) * layers.fine.width
             + col[:, None, None] * fx + np.arange(fx)[None, None, :]).reshape(len(parent), -1)
    pix_f = np.repeat(pix_f, fy * fx)
    pixel = np.concatenate([pix_b, pix_c, pix_f])
    world = np.concatenate([layers.bright_dirs[tex_b], coarse_d[tex_c], fine_d[child.ravel()]])
    energy = np.concatenate([layers.bright_energy[tex_b], coarse_e[tex_c], fine_e[child.ravel()]])
    cos = _rowdot(world, np.take(n, pixel, axis=0))
    kept = np.flatnonzero((cos > 0.0) & (energy.max(axis=1) > 0.0))
    kept = kept[np.argsort(pixel[kept], kind="stable")]  # the kept pairs, pixel by pixel
    pixel, world, energy, cos = (np.take(a, kept, axis=0) for a in (pixel, world, energy, cos))
    tp, bp, np_, vp = (np.take(a, pixel, axis=0) for a in (t, b, n, v))
    wi = np.stack([_rowdot(world, tp), _rowdot(world, bp), cos], axis=1)
    wo = np.stack([_rowdot(vp, tp), _rowdot(vp, bp), _rowdot(vp, np_)], axis=1)  # the view in each pixel's frame
    return MapQuadrature(env.name, frames.inside, pixel, wi, wo, energy * cos[:, None])


def _rowdot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(a * b).sum(axis=1) of (N, 3) arrays, bit for bit (NumPy adds a row's three products in
    order onto 0.0), in a third of its time: three columns instead of a reduction per row."""
    return 0.0 + a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def default_maps() -> list[EnvironmentMap]:
    return [spec(name).build(*DEFAULT_MAP_SIZE) for name in DEFAULT_MAPS]


def fit_target(source, metric: str, sampling: dict | None = None, maps: Sequence[EnvironmentMap] | None = None,
               view: int | PixelFrames = VIEW):
    """What a fit by `metric` runs over: the source's renders (the image metric, under `maps`,
    default DEFAULT_MAPS, seen in `view`) or its samples (`sampling`: samples_of's keyword
    arguments)."""
    from brdflab.fitting.samples import samples_of

    if metric == "image":
        return SceneImages.of_source(source, maps, view)
    if maps:
        raise BRDFLabError(f"maps are for the image metric; the {metric} metric fits samples")
    return samples_of(source, **(sampling or {}))


class SceneImages(SampleSet):
    """What a fit by the image metric runs over: the source's renders under the maps.

    `size` counts pixels (a fit never subsets them); `chunks` is not available: the fitter and
    the metric functions ask for images (`row_images`, `errors`)."""

    def __init__(self, quadratures: Sequence[MapQuadrature], target: np.ndarray, seen: str = SPHERE) -> None:
        self.quadratures = list(quadratures)
        self.seen = seen  # what the pixels show: the reference sphere, or a mesh by name
        self.n_channels = int(target.shape[0])
        self.target = target  # (C, P): the source's images, all maps' pixels end to end
        self.size = int(target.shape[1])
        self.bounds = np.cumsum([0] + [q.pixels for q in self.quadratures])
        toned = tone(target)
        self.pixel_weight = np.empty_like(target)  # each map counts alike: Σ pw (∛y)² = 1 / maps
        self.linear_weight = np.empty_like(target)  # pw × the tone's slope² at the source (for NNLS)
        self.tone_floor = np.empty_like(target)  # the slope is taken no steeper than at this radiance
        for m, (s, e) in enumerate(zip(self.bounds[:-1], self.bounds[1:])):
            energy = float((toned[:, s:e] ** 2).sum())
            if not energy > 0.0:
                raise BRDFLabError(f"the source renders black under {self.quadratures[m].name}: nothing to compare")
            self.pixel_weight[:, s:e] = 1.0 / (len(self.quadratures) * energy)
            floor = TONE_FLOOR * float(target[:, s:e].mean())
            self.tone_floor[:, s:e] = floor
            slope = (1.0 / 3.0) * np.maximum(target[:, s:e], floor) ** (-2.0 / 3.0)
            self.linear_weight[:, s:e] = self.pixel_weight[:, s:e] * slope ** 2
        self.toned = toned

    @classmethod
    def of_source(cls, source, maps: Sequence[EnvironmentMap] | None = None, view: int | PixelFrames = VIEW,
                  dim_width: int = DIM_WIDTH, fine_width: int = FINE_WIDTH) -> "SceneImages":
        """The scene of `maps` (default: DEFAULT_MAPS) with `source` rendered as its target,
        seen in `view` (the reference view at that size, or a mesh's frames)."""
        if source.n_channels not in (1, 3):
            raise BRDFLabError(f"the image metric renders 1 or 3 channels, not {source.n_channels}")
        frames = sphere_frames(view) if isinstance(view, int) else view
        quadratures = [map_quadrature(env, frames, dim_width, fine_width) for env in (maps or default_maps())]
        target = np.concatenate([q.render(source.evaluate, source.n_channels) for q in quadratures], axis=1)
        return cls(quadratures, target, frames.name)

    # --- what a SampleSet offers ---------------------------------------------------------
    def chunks(self) -> Iterator:
        raise BRDFLabError("the image metric compares renders, not BRDF samples")

    def subset(self, size: int, seed: int = 0) -> "SceneImages":
        """The pixels of every `step`-th row and column (step 2 for a quarter of `size` or
        fewer, …; a smaller step where a map would keep no lit pixel), with their pairs and
        target: the same renders, sampled more coarsely."""
        for step in range(max(1, int(math.sqrt(self.size / max(size, 1)))), 1, -1):
            keep = np.zeros(self.quadratures[0].inside.shape, bool)
            keep[step // 2::step, step // 2::step] = True
            picked = [q.pick(keep) for q in self.quadratures]
            parts = [self.target[:, s:e][:, chosen] for (_, chosen), s, e in zip(picked, self.bounds[:-1], self.bounds[1:])]
            if all(part.max(initial=0.0) > 0.0 for part in parts):  # every map keeps lit pixels
                return SceneImages([q for q, _ in picked], np.concatenate(parts, axis=1), self.seen)
        return self

    def digest(self) -> str:
        h = hashlib.sha256()
        for q in self.quadratures:
            for a in (q.wi, q.wo, q.weight):
                h.update(np.ascontiguousarray(a).tobytes())
        h.update(np.ascontiguousarray(self.target).tobytes())
        return h.hexdigest()

    # --- renders ---------------------------------------------------------------------------
    def render(self, evaluate: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
        """(C, P): a BRDF's images under every map, end to end."""
        return np.concatenate([q.render(evaluate, self.n_channels) for q in self.quadratures], axis=1)

    def blocks(self) -> Iterator[tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """(first pixel, pixel index, wi, wo, weight) of every block of pairs, for the fitter."""
        for q, first in zip(self.quadratures, self.bounds[:-1]):
            weight = q.weights(self.n_channels)
            for s in range(0, len(q.pixel), PAIR_BLOCK):
                e = s + PAIR_BLOCK
                yield int(first), q.pixel[s:e], q.wi[s:e], q.wo[s:e], weight[s:e]

    def block_images(self, block, values: np.ndarray) -> np.ndarray:
        """(C, R, P) images of R rows of BRDF values (K, R, pairs) at one block's pairs;
        K = 1 (one value for every channel) or C."""
        first, pixel, _, _, weight = block
        C, R = self.n_channels, values.shape[1]
        out = np.zeros((C, R, self.size))
        starts = np.flatnonzero(np.r_[True, pixel[1:] != pixel[:-1]])  # pairs come ordered by pixel
        index = first + pixel[starts]
        for c in range(C):  # every row's sums per pixel in one call (a bincount per row cost 3× the fit's lobes)
            out[c][:, index] = np.add.reduceat(values[min(c, values.shape[0] - 1)] * weight[:, c], starts, axis=1)
        return out

    # --- the metric ------------------------------------------------------------------------
    def toned_residuals(self, images: np.ndarray) -> np.ndarray:
        """(..., C, P) images → weighted residuals (..., C·P): Σ of their squares is the error²."""
        r = (tone(images) - self.toned) * np.sqrt(self.pixel_weight)
        return r.reshape(*images.shape[:-2], -1)

    def error_of_images(self, images: np.ndarray) -> float:
        return math.sqrt(float((self.toned_residuals(images) ** 2).sum()))

    def errors(self, materials: list) -> list[float]:
        """The image error of each material (None: a zero BRDF, which scores 1)."""
        return [self.error_of_images(np.zeros_like(self.target) if m is None else self.render(m.evaluate))
                for m in materials]

    def lobe_shares(self, material, contribution: Callable) -> np.ndarray:
        """Each lobe's share of the material's images (weighted as the fitter's linear
        problem weighs them): Σ lw ‖its image‖² / Σ lw ‖the material's image‖²."""
        parts = [self.render(lambda wi, wo, lobe=lobe: contribution(material, lobe, wi, wo)) for lobe in material.lobes]
        total = float((self.linear_weight * sum(parts) ** 2).sum())
        return np.array([float((self.linear_weight * p ** 2).sum()) for p in parts]) / max(total, 1e-300)
