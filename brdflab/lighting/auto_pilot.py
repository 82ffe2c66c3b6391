"""The pilot of the Auto lighting choice: what each lighting method would get wrong, estimated
before rendering at a few pixels of the reference view against a coarse copy of the map.

Per pilot pixel p and texel t of a PILOT_MAP-sized copy of the map (radiance luminance L_t,
solid angle Ω_t), with g_pt = f(ω_t, wo_p) cos θ_t (luminance): the pixel is estimated as
μ_p = A_p · Σ_t g_pt L_t Ω_t / Σ_t g_pt Ω_t, where A_p is the material's directional albedo
(importance-sampled, so a lobe narrower than a texel keeps its energy). From the same sums:
- SH at order L: the map replaced by its order-L projection (exactly the truncation the SH
  mode makes: Σ_lm B_lm L_lm = ∫ f cos · L_L), negative sums clamped as the renderer does;
Prefiltered, FIS and MIS are predicted by their NumPy twins instead (`auto_twins`). This is a few thousand texels at a few dozen pixels: milliseconds to a second, never the
reference (48² pixels or more against the full map).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.lighting.envmap import EnvironmentMap

PILOT_MAP = (64, 32)  # the map's copy the pilot integrates over
PILOT_GRID = 9  # pilot pixels: the centres of a 9 × 9 reference view inside the sphere (≈ 60)
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


@dataclass
class Pilot:
    """The per-pixel sums every prediction is made from."""

    g: np.ndarray  # (texels, pixels): f cos θ, luminance, 0 below the horizon
    solid: np.ndarray  # (texels,)
    radiance: np.ndarray  # (texels,) luminance of the pilot map
    directions: np.ndarray  # (texels, 3) world
    local: np.ndarray  # (texels, pixels, 3) the texel directions in each pixel's frame
    wo: np.ndarray  # (pixels, 3) the view in each pixel's frame
    albedo: np.ndarray  # (pixels,) luminance directional albedo
    env: EnvironmentMap  # the pilot map

    def estimate(self, radiance: np.ndarray) -> np.ndarray:
        """μ_p for a radiance per texel (the pilot map's, or an approximation of it)."""
        norm = self.g.T @ self.solid
        return self.albedo * (self.g.T @ (radiance * self.solid)) / np.maximum(norm, 1e-300)

    def relative_rmse(self, estimate: np.ndarray) -> float:
        """The error Auto judges by (`auto_twins.ViewPilot.error`) over the pilot pixels: the
        larger of the view's relative RMSE and the RMS of each pixel's relative error."""
        from brdflab.lighting.reference_view import weighted_pixel_error

        truth = self.estimate(self.radiance)
        rms = float(np.sqrt(np.mean((estimate - truth) ** 2)) / max(np.sqrt(np.mean(truth**2)), 1e-300))
        return max(rms, weighted_pixel_error(estimate, truth, np.full(len(truth), 1.0 / len(truth))))


def pilot_map(env: EnvironmentMap) -> EnvironmentMap:
    """The map area-averaged to PILOT_MAP (or the largest even divisors below it)."""
    return env.downsampled_within(*PILOT_MAP)


def pilot_pixels():
    """The pilot pixels' frames: (normal, tangent, bitangent) each (pixels, 3)."""
    from brdflab.lighting.reference_view import sphere_view

    view = sphere_view(PILOT_GRID, PILOT_GRID)
    return view.normal[view.inside], view.tangent[view.inside], view.bitangent[view.inside]


def material_albedo(source, wo: np.ndarray) -> np.ndarray:
    """Luminance directional albedo per view: importance-sampled for analytic lobes; by a
    fine product quadrature for measured data (which is never narrower than its table)."""
    from brdflab.material.albedo import directional_albedo
    from brdflab.material.analytic import AnalyticMaterial

    if isinstance(source, AnalyticMaterial):
        a = directional_albedo(source, wo)
        return (a[:, :3] if a.shape[1] >= 3 else np.repeat(a, 3, 1)) @ LUMINANCE
    fine = EnvironmentMap(np.ones((64, 128, 3), np.float32), "fine", None)
    d, solid = fine.texel_directions()
    d, solid = d.reshape(-1, 3), np.broadcast_to(solid, (64, 128)).reshape(-1)
    up = d[:, 1] > 0  # a hemisphere: +Y plays the normal
    local = np.stack([d[up, 0], d[up, 2], d[up, 1]], axis=-1)
    out = np.zeros(len(wo))
    for p, w in enumerate(wo):
        f = _luminance(source.evaluate(local, np.broadcast_to(w, local.shape)))
        out[p] = (f * local[:, 2] * solid[up]).sum()
    return out


def _luminance(f: np.ndarray) -> np.ndarray:
    return (f[..., :3] if f.shape[-1] >= 3 else np.repeat(f[..., :1], 3, -1)) @ LUMINANCE


def make_pilot(source, env: EnvironmentMap) -> Pilot:
    """The pilot sums of this material under this map."""
    small = pilot_map(env)
    d, solid = small.texel_directions()
    d = d.reshape(-1, 3)
    solid = np.broadcast_to(solid, (small.height, small.width)).reshape(-1).astype(float)
    radiance = small.data.reshape(-1, 3).astype(float) @ LUMINANCE
    n, t, b = pilot_pixels()
    local = np.stack([d @ t.T, d @ b.T, d @ n.T], axis=-1)  # (texels, pixels, 3)
    wo = np.stack([t[:, 2], b[:, 2], n[:, 2]], axis=-1)
    f = _luminance(source.evaluate(local.reshape(-1, 3), np.broadcast_to(wo[None], local.shape).reshape(-1, 3)))
    g = f.reshape(local.shape[:2]) * np.maximum(local[..., 2], 0.0)
    return Pilot(g, solid, radiance, d, local, wo, material_albedo(source, wo), small)
