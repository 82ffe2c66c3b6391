"""Low-discrepancy sample sets shared by every pixel, split across a material's lobes."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from brdflab.material.albedo import lobe_albedo
from brdflab.material.analytic import AnalyticMaterial


def radical_inverse_2(i: np.ndarray) -> np.ndarray:
    """Van der Corput sequence in base 2 (bit reversal of 32-bit integers)."""
    i = i.astype(np.uint32)
    i = ((i << 16) | (i >> 16)) & 0xFFFFFFFF
    i = ((i & 0x55555555) << 1) | ((i & 0xAAAAAAAA) >> 1)
    i = ((i & 0x33333333) << 2) | ((i & 0xCCCCCCCC) >> 2)
    i = ((i & 0x0F0F0F0F) << 4) | ((i & 0xF0F0F0F0) >> 4)
    i = ((i & 0x00FF00FF) << 8) | ((i & 0xFF00FF00) >> 8)
    return i.astype(np.float64) / 4294967296.0


def _pcg_hash(v: np.ndarray) -> np.ndarray:
    """PCG's 32-bit output hash, as shaders/object_fragment.glsl's pcg_hash (uint32 wraps)."""
    with np.errstate(over="ignore"):
        state = v.astype(np.uint32) * np.uint32(747796405) + np.uint32(2891336453)
        word = ((state >> ((state >> np.uint32(28)) + np.uint32(4))) ^ state) * np.uint32(277803737)
    return (word >> np.uint32(22)) ^ word


def pixel_shifts(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The MIS shader's Cranley–Patterson shift (n, 2) of pixels (x, y), y counted from the
    bottom as gl_FragCoord is (its `pixel_shift`, in float32 as the shader computes it): each
    pixel turns the shared set by its own amount, so neighbours' errors are independent."""
    a = _pcg_hash(np.asarray(x, np.uint32) + _pcg_hash(np.asarray(y, np.uint32)))
    return np.stack([a, _pcg_hash(a)], axis=-1).astype(np.float32) * np.float32(1.0 / 4294967296.0)


def hammersley(n: int) -> np.ndarray:
    i = np.arange(n)
    return np.stack([(i + 0.5) / n, radical_inverse_2(i)], axis=1)


SPREAD_LIMIT = 4096  # points of one strategy ordered by `spread_order` (its cost grows as n²: 0.4 s at 4,096)


@lru_cache(maxsize=32)
def spread_order(n: int) -> np.ndarray:
    """An order of hammersley(n)'s points in which every run from the first is spread over the
    unit square: greedy farthest point, distances on the torus (so a Cranley–Patterson rotation
    of the set keeps the order good). Hammersley's set is stratified only whole — its first
    quarter lies in u1 < 0.25 — so an image drawn in pieces needs another order than the set's."""
    points = hammersley(n)
    order = np.zeros(n, int)
    nearest = np.full(n, np.inf)
    for k in range(n):
        if k:
            order[k] = int(np.argmax(nearest))
        d = np.abs(points - points[order[k]])
        np.minimum(nearest, (np.minimum(d, 1.0 - d) ** 2).sum(axis=1), out=nearest)
    return order


def pieces_order(data: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The row order in which a set (`sample_set` or `mis_sample_set` rows) is drawn in pieces:
    each strategy's rows keep their places in the interleaving, and its points go in
    `spread_order`, so every image on the way is a spread part of the set (64 of 256 rows in a
    random order, as before, were 2.8× noisier per pixel on the default scene than in this one,
    docs/mis.md); beyond SPREAD_LIMIT points, a random order. The set drawn whole is unchanged."""
    order = np.arange(len(data))
    for strategy in np.unique(data[:, 2]):
        places = np.flatnonzero(data[:, 2] == strategy)
        n = len(places)
        order[places] = places[spread_order(n) if n <= SPREAD_LIMIT else rng.permutation(n)]
    return order


def lobe_shares(material: AnalyticMaterial, floor: float = 0.05) -> np.ndarray:
    """How many of the samples each lobe gets: its share of the material's luminance
    albedo at normal incidence (at least `floor` each, so no lobe is starved)."""
    lum = np.array([0.2126, 0.7152, 0.0722])
    weights = []
    for lobe in material.lobes:
        a = float(lobe_albedo(lobe, np.array([[0.0, 0.0, 1.0]]), samples_log2=8)[0])
        if material.combination == "Linear":
            s = np.asarray(lobe.scale[:3] if len(lobe.scale) >= 3 else lobe.scale * 3, float)
            weights.append(max(a, 0.0) * float(abs(s) @ lum))
        else:
            weights.append(max(a, 0.0) * abs(lobe.scale[0]))
    w = np.asarray(weights)
    w = w / w.sum() if w.sum() > 0 else np.full(len(w), 1.0 / len(w))
    w = np.maximum(w, floor)
    return w / w.sum()


def sample_set(shares: np.ndarray, n: int, rotation: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """n samples (u1, u2, lobe, 0), a Hammersley set per lobe, interleaved so that every
    prefix holds the lobes in proportion; and the exact fraction each lobe received.
    `rotation` (2,) shifts the points (Cranley–Patterson) for progressive refinement."""
    n = max(int(n), len(shares))
    raw = shares * n
    counts = np.maximum(np.floor(raw).astype(int), 1)
    while counts.sum() > n:
        counts[np.argmax(counts)] -= 1
    while counts.sum() < n:
        counts[np.argmax(raw - counts)] += 1
    rows = []
    for k, c in enumerate(counts):
        pts = hammersley(int(c))
        if rotation is not None:
            pts = np.mod(pts + rotation, 1.0)
        # position of each point within the whole set, so lobes interleave evenly
        order = (np.arange(c) + 0.5) / c
        rows.append(np.column_stack([order, pts, np.full(c, k, float)]))
    allrows = np.concatenate(rows)
    allrows = allrows[np.argsort(allrows[:, 0], kind="stable")]
    out = np.zeros((n, 4), np.float32)
    out[:, :3] = allrows[:, 1:4]
    return out, counts / n


def mis_sample_set(shares: np.ndarray, n: int, rotation: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """n samples for multiple importance sampling: half (rounded down) drawn from the
    environment's luminance (rows (u1, u2, −1, 0)), the rest from the BRDF as in
    `sample_set`, interleaved by position within their own set. Returns the rows, each
    lobe's fraction of the BRDF samples and the environment's fraction of all n."""
    brdf, fractions = sample_set(shares, max(int(n) - int(n) // 2, 1), rotation)
    n_env = max(int(n) - len(brdf), 0)
    env = hammersley(n_env)
    if rotation is not None:
        env = np.mod(env + rotation, 1.0)
    keys = np.concatenate([(np.arange(len(brdf)) + 0.5) / len(brdf), (np.arange(n_env) + 0.5) / max(n_env, 1)])
    rows = np.concatenate([brdf, np.column_stack([env, np.full(n_env, -1.0), np.zeros(n_env)]).astype(np.float32)])
    out = rows[np.argsort(keys, kind="stable")]
    return out, fractions, n_env / len(out)
