"""The reference view of CONVENTIONS.md, computed in NumPy: ground truth for renderers.

Orthographic camera along −Z over the unit sphere; pixel (i, j) of W × H has its centre
at x = (i + 0.5)/W·2 − 1, y = 1 − (j + 0.5)/H·2; wo = +Z; frame n = p,
t = normalize(X − (X·n) n), b = n × t.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.lighting.env_sampling import LUMINANCE
from brdflab.lighting.envmap import EnvironmentMap, band_solid_angle, uv_to_direction

# a pixel darker than this share of the view's mean luminance has its error counted against
# that share: at an exposure set by the mean it sits in a display's darkest codes, and a
# relative error of a near-black pixel (the side of a sphere facing away from a night's lamps)
# would otherwise judge the whole image
PIXEL_FLOOR = 0.01


@dataclass
class SphereView:
    inside: np.ndarray  # (H, W) bool
    normal: np.ndarray  # (H, W, 3)
    tangent: np.ndarray
    bitangent: np.ndarray

    def to_local(self, d_world: np.ndarray) -> np.ndarray:
        """World directions (..., 3) broadcast against the pixels → local frame."""
        return np.stack([(d_world * self.tangent).sum(-1), (d_world * self.bitangent).sum(-1),
                         (d_world * self.normal).sum(-1)], axis=-1)


def sphere_view(width: int, height: int) -> SphereView:
    x = (np.arange(width) + 0.5) / width * 2.0 - 1.0
    y = 1.0 - (np.arange(height) + 0.5) / height * 2.0
    X, Y = np.meshgrid(x, y)
    r2 = X * X + Y * Y
    inside = r2 <= 1.0
    n = np.stack([X, Y, np.sqrt(np.maximum(0.0, 1.0 - r2))], axis=-1)
    t = np.array([1.0, 0.0, 0.0]) - n[..., :1] * n
    tl = np.linalg.norm(t, axis=-1, keepdims=True)
    alt = np.array([0.0, 0.0, 1.0]) - n[..., 2:3] * n
    t = np.where(tl > 1e-6, t / np.maximum(tl, 1e-12), alt / np.maximum(np.linalg.norm(alt, axis=-1, keepdims=True), 1e-12))
    return SphereView(inside, n, t, np.cross(n, t))


def point_light_image(source, width: int, height: int, light) -> np.ndarray:
    """f(wi, wo) · max(0, n·L) per pixel (a directional light of irradiance 1)."""
    view = sphere_view(width, height)
    L = np.asarray(light, float)
    L = L / np.linalg.norm(L)
    wi = view.to_local(L)
    wo = view.to_local(np.array([0.0, 0.0, 1.0]))
    f = source.evaluate(wi[view.inside], wo[view.inside])
    img = np.zeros((height, width, f.shape[1]))
    img[view.inside] = f * np.maximum(0.0, view.normal[view.inside] @ L)[:, None]
    return img


def environment_image(source, env: EnvironmentMap, width: int, height: int, chunk: int = 64) -> np.ndarray:
    """∫ Lenv(ω) f(ω, wo) max(0, n·ω) dω per pixel, by quadrature over the map's texels
    (each texel's radiance times its exact solid angle, at its centre direction)."""
    view = sphere_view(width, height)
    d, solid = env.texel_directions()
    d = d.reshape(-1, 3)
    weight = (env.data * solid[:, :, None]).reshape(-1, 3)
    pix = np.argwhere(view.inside)
    wo_all = view.to_local(np.array([0.0, 0.0, 1.0]))
    out = np.zeros((height, width, 3))
    for s in range(0, len(pix), chunk):
        rows, cols = pix[s:s + chunk, 0], pix[s:s + chunk, 1]
        n, t, b = view.normal[rows, cols], view.tangent[rows, cols], view.bitangent[rows, cols]
        out[rows, cols] = by_texel_centres(source, d, weight, (t, b, n), wo_all[rows, cols])
    return out


def texel_f_cos(source, d: np.ndarray, frame: tuple, wo: np.ndarray,
                keep: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """f(ωt, wo) (RGB) and max(0, n·ωt) at each (texel, pixel) pair whose texel is above the
    pixel's horizon: (texel indices, pixel indices, f (pairs, 3), cosines (pairs,)); texel
    directions d (texels, 3), the pixels' frames (t, b, n) and views wo (pixels, 3); `keep`
    (texels, pixels) leaves pairs out. Only those pairs are evaluated (about half: the rest add
    nothing)."""
    t, b, n = frame
    wi = np.stack([d @ t.T, d @ b.T, d @ n.T], axis=-1)  # (texels, pixels, 3)
    seen = wi[..., 2] > 0.0
    if keep is not None:
        seen &= keep.astype(bool)
    texel, pixel = np.nonzero(seen)
    if not len(pixel):  # no texel above any pixel's horizon (a few pixels facing away from a lamp)
        return texel, pixel, np.zeros((0, 3)), np.zeros(0)
    return texel, pixel, _rgb(source.evaluate(wi[texel, pixel], wo[pixel]), (len(pixel),)), wi[texel, pixel, 2]


def by_texel_centres(source, d: np.ndarray, weight: np.ndarray, frame: tuple, wo: np.ndarray,
                      keep: np.ndarray | None = None) -> np.ndarray:
    """Σ over texels of f(ωt, wo) max(0, n·ωt) · radiance·solid angle, per pixel (pixels, 3):
    weight (texels, 3), the rest as `texel_f_cos`."""
    texel, pixel, f, cosine = texel_f_cos(source, d, frame, wo, keep)
    g = f * (cosine[:, None] * weight[texel])
    return np.stack([np.bincount(pixel, g[:, c], minlength=len(wo)) for c in range(3)], axis=-1)


CAP_DEGREES = 12.0  # texels reaching this close to a pixel's mirror direction are subdivided
SUBDIVISION = 16  # … into this many × this many parts, each at its own centre and exact solid angle
BRIGHT = 10.0  # … and, for every pixel, texels this many times the map's mean luminance (a sun, lamps)


def refined_environment_image(source, env: EnvironmentMap, width: int, height: int, cap_degrees: float = CAP_DEGREES,
                              subdivision: int = SUBDIVISION, chunk: int = 32) -> np.ndarray:
    """The same integral as `environment_image`, resolved for lobes narrower than a texel:
    per pixel, the texels that reach within `cap_degrees` of its mirror direction (where a
    sharp lobe is), and the map's bright texels (a sun or a lamp: at its centre alone the
    lobe's tail or the pixel's horizon crossing the texel is not seen, 2.3 % per pixel and
    13 % at the edge of a highlight under a one-texel sun), are each split `subdivision` ×
    `subdivision` in (u, v), every part evaluated at its centre with its exact solid angle; the others by their centres as
    before. The parts partition the texels exactly, so a bright texel (a sun) is counted
    once, and the quadrature converges as a midpoint rule does (error ∝ part size²)."""
    view = sphere_view(width, height)
    d, solid = env.texel_directions()
    d = d.reshape(-1, 3)
    weight = (env.data * solid[:, :, None]).reshape(-1, 3)
    h, w, k = env.height, env.width, subdivision
    # a texel is near when any of it may lie within the cone: its centre within the cone
    # widened by half a texel diagonal
    half_diagonal = 0.5 * np.hypot(np.pi / h, 2.0 * np.pi / w)
    cos_near, sin_half = np.cos(np.radians(cap_degrees) + half_diagonal), np.sin(half_diagonal)
    lum = env.data.reshape(-1, 3).astype(float) @ LUMINANCE
    bright = lum >= BRIGHT * max(float(lum.mean()), 1e-300)
    offsets = (np.arange(k) + 0.5) / k
    z = np.array([0.0, 0.0, 1.0])
    pix = np.argwhere(view.inside)
    out = np.zeros((height, width, 3))
    for s in range(0, len(pix), chunk):
        rows, cols = pix[s:s + chunk, 0], pix[s:s + chunk, 1]
        n, t, b = view.normal[rows, cols], view.tangent[rows, cols], view.bitangent[rows, cols]
        wo = np.stack([t @ z, b @ z, n @ z], axis=-1)  # (pixels, 3), local
        mirror = 2.0 * (n @ z)[:, None] * n - z  # world
        near = (d @ mirror.T) >= cos_near  # (texels, pixels)
        near[bright] = True
        total = by_texel_centres(source, d, weight, (t, b, n), wo, ~near)  # the near ones left out
        # the near texels, part by part: (pairs, k, k) sub-texel directions and solid angles;
        # a texel wholly below a pixel's horizon adds nothing there and is not split
        texel, pixel = np.nonzero(near & ((d @ n.T) > -sin_half))
        row, col = np.divmod(texel, w)
        v_edges = (row[:, None] + np.arange(k + 1) / k) / h  # (pairs, k + 1)
        part_solid = band_solid_angle(v_edges[:, :-1], v_edges[:, 1:], w * k)  # (pairs, k): per row of parts
        world = uv_to_direction(((col[:, None] + offsets) / w)[:, None, :],
                                ((row[:, None] + offsets) / h)[:, :, None]).reshape(len(pixel), k * k, 3)
        wi = world @ np.stack([t, b, n], axis=-1)[pixel]  # (pairs, k², 3) local: the pixel's frame
        f = _rgb(source.evaluate(wi.reshape(-1, 3), np.repeat(wo[pixel], k * k, axis=0)), (len(pixel), k * k))
        cos = np.maximum(wi[..., 2], 0.0)
        g = np.einsum("pqc,pq->pc", f, cos * np.repeat(part_solid, k, axis=1))  # (pairs, 3): ∫ f cos over the texel
        g *= env.data.reshape(-1, 3)[texel]
        for c in range(3):
            total[:, c] += np.bincount(pixel, g[:, c], minlength=len(rows))
        out[rows, cols] = total
    return out


def _rgb(f: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """Evaluated values (n, C) as (*shape, 3): the first three channels, or one repeated."""
    f = f.reshape(*shape, -1)
    return f[..., :3] if f.shape[-1] >= 3 else np.repeat(f, 3, -1)


def relative_rmse(image: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> float:
    diff = (image - reference)[mask]
    return float(np.sqrt(np.mean(diff**2)) / max(np.sqrt(np.mean(reference[mask] ** 2)), 1e-300))


def pixel_relative_rmse(image: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> float:
    """The error a user sees pixel by pixel: the RMS over the view of each pixel's relative
    error in luminance (`relative_rmse` divides by the view's RMS instead, so a few bright
    pixels can hide the rest of the sphere being 5 % off)."""
    lum = lambda rgb: rgb[mask][:, :3] @ LUMINANCE
    count = int(mask.sum())
    return weighted_pixel_error(lum(image), lum(reference), np.full(count, 1.0 / max(count, 1)))


def weighted_pixel_error(values: np.ndarray, truth: np.ndarray, weight: np.ndarray,
                         truth_variance: np.ndarray | float = 0.0) -> float:
    """`pixel_relative_rmse` over pixels standing for `weight` of the view each (luminances),
    less the truth's own squared error where the truth is an estimate (`truth_variance`:
    a method's error and the truth's are independent, their squares add)."""
    floor = PIXEL_FLOOR * max(float((weight * truth).sum()), 1e-300)
    square = (weight * ((values - truth) ** 2 - truth_variance) / np.maximum(truth, floor) ** 2).sum()
    return float(np.sqrt(max(float(square), 0.0)))
