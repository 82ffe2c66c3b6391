"""The reference view of CONVENTIONS.md, computed in NumPy: ground truth for renderers.

Orthographic camera along −Z over the unit sphere; pixel (i, j) of W × H has its centre
at x = (i + 0.5)/W·2 − 1, y = 1 − (j + 0.5)/H·2; wo = +Z; frame n = p,
t = normalize(X − (X·n) n), b = n × t.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.lighting.envmap import EnvironmentMap


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
        wi = np.stack([d @ t.T, d @ b.T, d @ n.T], axis=-1)  # (texels, pixels, 3)
        wo = np.broadcast_to(wo_all[rows, cols][None], wi.shape)
        f = source.evaluate(wi.reshape(-1, 3), wo.reshape(-1, 3)).reshape(wi.shape[0], wi.shape[1], -1)
        cos = np.maximum(wi[..., 2], 0.0)
        out[rows, cols] = np.einsum("tpc,tp,tc->pc", f[..., :3] if f.shape[-1] >= 3 else np.repeat(f, 3, -1), cos, weight)
    return out


def relative_rmse(image: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> float:
    diff = (image - reference)[mask]
    return float(np.sqrt(np.mean(diff**2)) / max(np.sqrt(np.mean(reference[mask] ** 2)), 1e-300))
