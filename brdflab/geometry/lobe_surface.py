"""The lobe viewer's surface in NumPy: its radius along each direction, how far its flat
triangles stray from the exact lobe, and the lowest subdivision that keeps them close.

The viewer (brdflab/render/lobe_view.py) draws a geodesic hemisphere whose vertices sit at
the lobe's radius; between vertices the surface is a flat triangle. Its error is measured
inside every triangle: at barycentric points p = Σ bᵢ rᵢ dᵢ, the distance to the exact lobe
point r(p̂) p̂ along the same direction, relative to the lobe's peak radius.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.geometry.geodesic import RIM_Z, geodesic_hemisphere

CHANNELS = {"red": 0, "green": 1, "blue": 2, "luminance": 3}
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
LEVELS = range(2, 8)  # the viewer's subdivision levels
FINEST = 8  # the error is sought at points as dense as a level-8 hemisphere's vertices (~0.5° apart)


@dataclass(frozen=True)
class LobeShape:
    """What the viewer draws of a source: the incident direction and how values become radii."""

    wi: tuple[float, float, float]
    channel: str = "luminance"
    cosine: bool = False
    transfer: str = "cbrt"


def lobe_radii(source, shape: LobeShape, wo: np.ndarray) -> np.ndarray:
    """The surface's radius along each direction wo (N, 3), before the viewer's gain: what
    shaders/lobe_vertex.glsl computes per vertex (channel, cosine, transfer)."""
    wi = np.broadcast_to(np.asarray(shape.wi, float), wo.shape)
    f = np.asarray(source.evaluate(wi, wo), float)[:, :3]
    if f.shape[1] == 1:
        f = np.repeat(f, 3, axis=1)
    v = f @ LUMINANCE if shape.channel == "luminance" else f[:, CHANNELS[shape.channel]]
    v = np.maximum(v, 0.0) * (np.maximum(wo[:, 2], 0.0) if shape.cosine else 1.0)
    return {"linear": v, "cbrt": np.cbrt(v), "log": np.log1p(v)}[shape.transfer]


def surface_error(source, shape: LobeShape, level: int) -> tuple[float, float]:
    """(max, RMS) distance of the level-`level` surface from the exact lobe, relative to the
    peak radius, over barycentric points of every triangle (vertices excluded: exact there),
    as dense at every level as the finest hemisphere's vertices, so that a lobe narrower than
    a coarse triangle cannot hide between the points that look for it."""
    inside = 2 ** max(1, FINEST - level)
    dirs, faces = geodesic_hemisphere(level)
    dirs = dirs.astype(float)
    radii = lobe_radii(source, shape, dirs)
    i, j = np.meshgrid(np.arange(inside + 1), np.arange(inside + 1), indexing="ij")
    keep = (i + j <= inside) & ~(((i == inside) | (j == inside)) | ((i == 0) & (j == 0)))
    bary = np.stack([i[keep], j[keep], inside - i[keep] - j[keep]], axis=1) / inside  # (B, 3)
    corners = radii[faces][:, :, None] * dirs[faces]  # (T, 3 corners, 3)
    points = np.einsum("bk,tkc->tbc", bary, corners).reshape(-1, 3)
    length = np.linalg.norm(points, axis=1)
    direction = np.where(length[:, None] > 0, points / np.maximum(length, 1e-300)[:, None],
                         np.einsum("bk,tkc->tbc", bary, dirs[faces]).reshape(-1, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    exact = lobe_radii(source, shape, direction)
    peak = max(float(radii.max()), float(exact.max()), 1e-300)
    error = np.abs(length - exact) / peak
    return float(error.max()), float(np.sqrt(np.mean(error**2)))


def auto_level(sources, shape: LobeShape, tolerance: float = 0.01) -> tuple[int, float]:
    """The lowest level whose worst surface error, over every source drawn (an original and
    its fit), is within `tolerance` of the peak radius; the top level when none is. Returns
    (level, its worst error)."""
    worst = np.inf
    for level in LEVELS:
        worst = max(surface_error(s, shape, level)[0] for s in sources if s is not None)
        if worst <= tolerance:
            return level, worst
    return LEVELS[-1], worst


REFINE_PASSES = 12  # each halves the triangles near the peak: level 5's 3.5° edges down to ~0.001°
REFINE_MAX_VERTICES = 250_000


def _radii(sources, shape: LobeShape, dirs: np.ndarray) -> np.ndarray:
    """(N, sources) radii along dirs."""
    return np.stack([lobe_radii(s, shape, dirs) for s in sources], axis=1)


def _unit(v: np.ndarray) -> np.ndarray:
    v = v / np.linalg.norm(v, axis=-1, keepdims=True)
    v[..., 2] = np.maximum(v[..., 2], RIM_Z)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _insert_mirror(dirs: np.ndarray, faces: np.ndarray, shape: LobeShape) -> tuple[np.ndarray, np.ndarray]:
    """The mirror direction of wi as a vertex (the face holding it split in three): a lobe
    narrower than a triangle, whose peak falls between vertices, is found there."""
    wi = np.asarray(shape.wi, float)
    p = _unit(np.array([-wi[0], -wi[1], wi[2]]))
    a, b, c = (dirs[faces[:, k]] for k in range(3))
    inside = ((np.einsum("ij,ij->i", np.cross(a, b), np.broadcast_to(p, a.shape)) >= 0)
              & (np.einsum("ij,ij->i", np.cross(b, c), np.broadcast_to(p, a.shape)) >= 0)
              & (np.einsum("ij,ij->i", np.cross(c, a), np.broadcast_to(p, a.shape)) >= 0))
    if not inside.any() or np.abs(dirs - p).max(axis=1).min() < 1e-9:
        return dirs, faces
    k = int(np.argmax(inside))
    i, j, m = faces[k]
    n = len(dirs)
    split = np.array([[i, j, n], [j, m, n], [m, i, n]], faces.dtype)
    return np.vstack([dirs, p]), np.vstack([np.delete(faces, k, axis=0), split])


def refined_surface(sources, shape: LobeShape, level: int, tolerance: float = 0.01) -> tuple[np.ndarray, np.ndarray, float]:
    """The level-`level` hemisphere refined where its flat triangles stray from the lobes by
    more than `tolerance` of the peak radius (edge midpoints and centroids checked; conforming:
    a triangle with two or three edges to split is split in four, one with one edge in two),
    seeded with the mirror direction. Returns (directions float32, faces uint32, peak radius):
    a lobe far narrower than the mesh (Ward ax = 0.001) is drawn whole, and framed by its peak."""
    sources = [s for s in sources if s is not None]
    dirs, faces = geodesic_hemisphere(level)
    dirs, faces = _insert_mirror(dirs.astype(float), faces.astype(np.int64), shape)
    radii = _radii(sources, shape, dirs)
    for _ in range(REFINE_PASSES):
        peak = max(float(radii.max()), 1e-300)
        key = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
        edges, inverse = np.unique(key, axis=0, return_inverse=True)
        inverse = inverse.reshape(3, -1)  # edge of (01, 12, 20) per face
        mid = _unit(dirs[edges[:, 0]] + dirs[edges[:, 1]])
        mid_radii = _radii(sources, shape, mid)
        split = (np.abs(mid_radii - 0.5 * (radii[edges[:, 0]] + radii[edges[:, 1]])).max(axis=1) > tolerance * peak)
        centre = _unit(dirs[faces].sum(axis=1))
        hidden = np.abs(_radii(sources, shape, centre) - radii[faces].mean(axis=1)).max(axis=1) > tolerance * peak
        split[inverse[:, hidden].ravel()] = True
        while True:  # conforming: a face with two split edges splits all three
            count = split[inverse].sum(axis=0)
            grow = (count == 2)
            if not grow.any():
                break
            split[inverse[:, grow].ravel()] = True
        if not split.any() or len(dirs) + int(split.sum()) > REFINE_MAX_VERTICES:
            break
        new_index = np.full(len(edges), -1)
        new_index[split] = len(dirs) + np.arange(int(split.sum()))
        dirs = np.vstack([dirs, mid[split]])
        radii = np.vstack([radii, mid_radii[split]])
        faces = _split_faces(faces, new_index[inverse], split[inverse].sum(axis=0))
    return dirs.astype(np.float32), faces.astype(np.uint32), float(radii.max())


def lobe_tips(sources, shape: LobeShape, dirs: np.ndarray) -> np.ndarray:
    """(sources, 3): each source's farthest surface point over the vertices `dirs`, before the
    viewer's gain. A lobe narrower than a pixel (Ward ax = 0.001) rasterises as a dotted line;
    the viewer draws the segment from the origin to its tip as a solid one."""
    radii = _radii(sources, shape, np.asarray(dirs, float))
    k = radii.argmax(axis=0)
    return np.asarray(dirs, float)[k] * radii[k, np.arange(radii.shape[1])][:, None]


def _split_faces(faces: np.ndarray, mids: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Faces with three split edges in four, with one in two, the rest kept. `mids`: (3, T)
    new vertex of edges 01, 12, 20 (-1: not split)."""
    a, b, c = faces.T
    m01, m12, m20 = mids
    four = count == 3
    quads = [np.stack(x, axis=1)[four] for x in ((a, m01, m20), (m01, b, m12), (m20, m12, c), (m01, m12, m20))]
    one = count == 1
    # rotate each once-split face so that its split edge is (p, q), r opposite
    k = np.argmax(mids >= 0, axis=0)
    p = np.choose(k, (a, b, c))
    q = np.choose(k, (b, c, a))
    r = np.choose(k, (c, a, b))
    m = np.choose(k, (m01, m12, m20))
    halves = [np.stack(x, axis=1)[one] for x in ((p, m, r), (m, q, r))]
    return np.vstack([faces[count == 0], *quads, *halves])
