"""Light-probe layouts (Debevec's angular maps, dual-paraboloid pairs) resampled to the
renderer's lat-long map.

Conventions (world +Y up, the camera of a probe looking along −Z):
- angular: a square image holding a disk; the direction d sits at radius r = acos(−d.z)/π
  along (d.x, d.y)/|(d.x, d.y)|, image x to the right, y up.
- dual-paraboloid: one image, front half (around −Z) on the left, back half (around +Z)
  on the right, each a disk with (x, y) = (d.x, d.y)/(1 ∓ d.z) in [−1, 1]², y up.
Texels outside a disk are replaced by the nearest texel on its rim before bilinear
filtering, and each lat-long texel averages 3 × 3 sub-samples, so rims leave no seam.
"""

from __future__ import annotations

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.lighting.envmap import uv_to_direction

LAYOUTS = ("auto", "latlong", "angular", "dual-paraboloid")
SUPERSAMPLE = 3


def detect_layout(data: np.ndarray) -> str:
    """'angular' for a square image whose corners (outside the inscribed disk) are black,
    else 'latlong'. Dual-paraboloid pairs have lat-long's 2:1 shape: name them explicitly."""
    h, w = data.shape[:2]
    if h != w:
        return "latlong"
    r = _radius(h)
    outside = r > 1.02
    inside = r < 0.98
    dark = data[outside].mean() <= 1e-3 * max(float(data[inside].mean()), 1e-30)
    return "angular" if dark else "latlong"


def _radius(n: int) -> np.ndarray:
    c = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    return np.hypot(c[None, :], c[:, None])


def _fill_outside_disk(disk: np.ndarray) -> np.ndarray:
    """Each texel outside the inscribed disk takes the value of the rim texel on its ray."""
    n = disk.shape[0]
    c = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    x, y = np.meshgrid(c, c)
    r = np.maximum(np.hypot(x, y), 1e-12)
    shrink = np.minimum(1.0, (1.0 - 1.0 / n) / r)
    col = np.clip(np.floor(((x * shrink + 1.0) * 0.5 * n)).astype(int), 0, n - 1)
    row = np.clip(np.floor(((y * shrink + 1.0) * 0.5 * n)).astype(int), 0, n - 1)
    return disk[row, col]


def _bilinear(image: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Sample `image` at continuous pixel coordinates (x right, y down, centres at +0.5)."""
    h, w = image.shape[:2]
    fx = np.clip(x - 0.5, 0.0, w - 1.0)
    fy = np.clip(y - 0.5, 0.0, h - 1.0)
    x0 = np.minimum(fx.astype(int), w - 2) if w > 1 else np.zeros_like(fx, int)
    y0 = np.minimum(fy.astype(int), h - 2) if h > 1 else np.zeros_like(fy, int)
    tx, ty = (fx - x0)[..., None], (fy - y0)[..., None]
    top = image[y0, x0] * (1 - tx) + image[y0, x0 + 1] * tx
    bottom = image[y0 + 1, x0] * (1 - tx) + image[y0 + 1, x0 + 1] * tx
    return top * (1 - ty) + bottom * ty


def _latlong_directions(height: int) -> np.ndarray:
    """World directions of SUPERSAMPLE² sub-samples per texel of a 2h × h lat-long map."""
    width, s = 2 * height, SUPERSAMPLE
    v = (np.arange(height * s) + 0.5) / (height * s)
    u = (np.arange(width * s) + 0.5) / (width * s)
    return uv_to_direction(u[None, :], v[:, None])


def _disk_lookup(disk: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Sample a disk image at disk coordinates (x, y) in [−1, 1]², y up."""
    n = disk.shape[0]
    return _bilinear(_fill_outside_disk(disk), (x + 1.0) * 0.5 * n, (1.0 - y) * 0.5 * n)


def _sample(data: np.ndarray, layout: str, d: np.ndarray) -> np.ndarray:
    if layout == "angular":
        r = np.arccos(np.clip(-d[..., 2], -1.0, 1.0)) / np.pi
        rho = np.maximum(np.hypot(d[..., 0], d[..., 1]), 1e-12)
        return _disk_lookup(data, d[..., 0] / rho * r, d[..., 1] / rho * r)
    half = data.shape[1] // 2
    front = d[..., 2] <= 0.0
    denom = np.where(front, 1.0 - d[..., 2], 1.0 + d[..., 2])
    x, y = d[..., 0] / denom, d[..., 1] / denom
    out = np.where(front[..., None], _disk_lookup(data[:, :half], x, y), _disk_lookup(data[:, half:], x, y))
    return out


def probe_to_latlong(data: np.ndarray, layout: str, path=None) -> np.ndarray:
    """Resample an angular map or dual-paraboloid pair to a lat-long map (2n × n, n the
    probe's disk diameter in texels), averaging sub-samples so rims leave no seam."""
    h, w = data.shape[:2]
    if layout == "angular" and h != w:
        raise BRDFLabError(f"an angular map is square; this image is {w}×{h}", path)
    if layout == "dual-paraboloid" and w != 2 * h:
        raise BRDFLabError(f"a dual-paraboloid pair is two square halves side by side (2n × n); this image is {w}×{h}", path)
    height = h
    d = _latlong_directions(height)
    fine = _sample(data.astype(np.float32), layout, d)
    s = SUPERSAMPLE
    return fine.reshape(height, s, 2 * height, s, 3).mean(axis=(1, 3)).astype(np.float32)
