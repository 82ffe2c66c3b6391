"""Light-probe layouts (Debevec's angular maps, dual-paraboloid pairs) resampled to the
renderer's lat-long map.

Conventions (world +Y up; Debevec's and BRDFLab's worlds are this one with z negated):
- angular (Debevec, debevec.org/Probes): a square image holding a disk; the direction d sits
  at radius r = acos(−d.z)/π along (d.x, d.y)/|(d.x, d.y)|, image x to the right, y up.
- dual-paraboloid (Heidrich–Seidel 1998, as BRDFLab's shaders read its shipped
  `NAME-front.hdr` / `NAME-back.hdr`): the front half holds d.z ≥ 0 at paraboloid
  coordinates (x, y) = (d.x, d.y)/(1 + d.z), the back half d.z < 0 at
  (x, y) = (−d.x, −d.y)/(1 − d.z); image x to the right, y down (front upside down in a
  viewer, back upright). The square spans (x, y) ∈ [−E, E]²: BRDFLab's halves reach E = 1.2
  (past the hemisphere), others stop at E = 1; E is found from where the halves agree.
  One 2n × n image holds front | back side by side.
Texels outside a disk are replaced by the nearest texel on its rim before bilinear
filtering, and each lat-long texel averages 3 × 3 sub-samples, so rims leave no seam.
The resampling runs in float32, a band of rows at a time: the whole sub-sample grid of a
1000 × 1000 probe (6000 × 3000 directions, float64 temporaries) needed more than 3 GB.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.lighting.envmap import MAX_PIXELS, uv_to_direction

LAYOUTS = ("auto", "latlong", "angular", "dual-paraboloid")
SUPERSAMPLE = 3
BAND_TEXELS = 1 << 15  # lat-long texels resampled at once (~150 bytes per sub-sample in temporaries)
MAX_HEIGHT = int(np.sqrt(MAX_PIXELS // 2))  # the largest 2h × h map the lab reads (4096)
EXTENTS = np.round(np.arange(1.0, 1.501, 0.01), 2)  # the dual-paraboloid spans tried
_HALF = re.compile(r"^(.*[-_ .])(front|back)$", re.IGNORECASE)


def detect_layout(data: np.ndarray) -> str:
    """'angular' when a square image holds a centred disk: all round its rim the ring just
    outside is dark against the ring just inside (text in a corner does not matter), else
    'latlong'. Dual-paraboloid halves are told by their names (`pair_path`)."""
    h, w = data.shape[:2]
    if h != w or h < 16:
        return "latlong"
    return "angular" if disk_edge(data) >= 0.75 else "latlong"


def disk_edge(data: np.ndarray, sectors: int = 32) -> float:
    """The fraction of rim sectors (those with texels outside the inscribed disk) where most
    texels of the ring r ∈ [1.02, 1.07] are below 2 % of the ring r ∈ [0.93, 0.98]."""
    n = data.shape[0]
    c = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    x, y = np.meshgrid(c, c)
    r = np.hypot(x, y)
    sector = ((np.arctan2(y, x) / (2.0 * np.pi) + 0.5) * sectors).astype(int) % sectors
    lum = data[..., :3] @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    inner, outer = (r > 0.93) & (r < 0.98), (r > 1.02) & (r < 1.07)
    inside = np.bincount(sector[inner], lum[inner], sectors) / np.maximum(np.bincount(sector[inner], minlength=sectors), 1)
    dark = lum[outer] <= 0.02 * inside[sector[outer]]
    counted = np.bincount(sector[outer], minlength=sectors)
    fraction = np.bincount(sector[outer], dark, sectors)[counted > 0] / counted[counted > 0]
    return float(np.mean((fraction >= 0.5) & (inside[counted > 0] > 0))) if fraction.size else 0.0


def pair_path(path: Path) -> tuple[Path, Path] | None:
    """(front, back) for a file named like BRDFLab's halves (`NAME-front.hdr` ↔
    `NAME-back.hdr`, also `_`, space or `.` before the word) whose other half exists."""
    m = _HALF.match(path.stem)
    if not m:
        return None
    word = m.group(2)
    swapped = "back" if word.lower() == "front" else "front"
    swapped = swapped.upper() if word.isupper() else swapped.capitalize() if word[0].isupper() else swapped
    other = path.with_name(m.group(1) + swapped + path.suffix)
    if not other.is_file():
        return None
    return (path, other) if word.lower() == "front" else (other, path)


def _fill_outside_disk(disk: np.ndarray) -> np.ndarray:
    """Each texel outside the inscribed disk takes the value of the rim texel on its ray."""
    n = disk.shape[0]
    c = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    x, y = np.meshgrid(c, c)
    r = np.maximum(np.hypot(x, y), 1e-12)
    shrink = np.minimum(1.0, (1.0 - 1.0 / n) / r)
    col = np.clip(np.floor((x * shrink + 1.0) * 0.5 * n).astype(int), 0, n - 1)
    row = np.clip(np.floor((y * shrink + 1.0) * 0.5 * n).astype(int), 0, n - 1)
    return disk[row, col]


def _bilinear(image: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Sample `image` at continuous pixel coordinates (x right, y down, centres at +0.5).
    The four neighbours are taken from the flattened image by one index each (indexing by
    row and column arrays took twice as long: a 1,000² probe's lat-long map, 18 M lookups)."""
    h, w = image.shape[:2]
    fx = np.clip(x - 0.5, 0.0, w - 1.0)
    fy = np.clip(y - 0.5, 0.0, h - 1.0)
    x0 = np.minimum(fx.astype(np.intp), max(w - 2, 0))
    y0 = np.minimum(fy.astype(np.intp), max(h - 2, 0))
    tx, ty = (fx - x0)[..., None], (fy - y0)[..., None]
    flat = image.reshape(h * w, -1)
    right, down = min(1, w - 1), min(1, h - 1) * w  # a one-texel-wide image has no second neighbour
    i = y0 * w + x0
    top = flat.take(i, axis=0) * (1 - tx) + flat.take(i + right, axis=0) * tx
    i += down
    bottom = flat.take(i, axis=0) * (1 - tx) + flat.take(i + right, axis=0) * tx
    return top * (1 - ty) + bottom * ty


def _latlong_directions(height: int, rows: range) -> np.ndarray:
    """World directions (float32) of SUPERSAMPLE² sub-samples per texel of `rows` of a 2h × h
    lat-long map."""
    width, s = 2 * height, SUPERSAMPLE
    v = (np.arange(rows.start * s, rows.stop * s, dtype=np.float32) + 0.5) / np.float32(height * s)
    u = (np.arange(width * s, dtype=np.float32) + 0.5) / np.float32(width * s)
    return uv_to_direction(u[None, :], v[:, None])


def _disk_lookup(disk: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Sample a disk image (rim-filled) at coordinates (x, y) in [−1, 1]², x right, y down."""
    n = disk.shape[0]
    return _bilinear(disk, (x + 1.0) * 0.5 * n, (y + 1.0) * 0.5 * n)


def _paraboloid(d: np.ndarray, front: bool) -> tuple[np.ndarray, np.ndarray]:
    """Image coordinates (x right, y down, the hemisphere's rim at radius 1) of directions d
    on a dual-paraboloid half, BRDFLab's convention (module docstring)."""
    sign = 1.0 if front else -1.0
    denom = 1.0 + sign * d[..., 2]
    return sign * d[..., 0] / denom, sign * d[..., 1] / denom


def paraboloid_extent(front: np.ndarray, back: np.ndarray) -> float:
    """The span E of a dual-paraboloid pair (rim-filled halves): the one of EXTENTS at which
    both halves show the same radiance on the equator d.z = 0 (log-luminance, 1,440 directions)."""
    a = np.linspace(0.0, 2.0 * np.pi, 1440, endpoint=False)
    d = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=-1)
    weights = np.array([0.2126, 0.7152, 0.0722], np.float32)
    looks = []
    for half, is_front in ((front, True), (back, False)):
        x, y = _paraboloid(d, is_front)
        looks.append(np.stack([_disk_lookup(half, x / e, y / e) @ weights for e in EXTENTS]))
    floor = 1e-3 * max(float(np.mean(looks[0])), 1e-30)
    mismatch = np.mean(np.abs(np.log(looks[0] + floor) - np.log(looks[1] + floor)), axis=1)
    return float(EXTENTS[int(np.argmin(mismatch))])


def _sample(halves: list[np.ndarray], layout: str, d: np.ndarray, extent: float) -> np.ndarray:
    if layout == "angular":
        rho = np.hypot(d[..., 0], d[..., 1])
        r = np.arctan2(rho, -d[..., 2]) / np.float32(np.pi)  # acos(−d.z)/π, exact near the disk's centre
        scale = r / np.maximum(rho, np.float32(1e-12))
        return _disk_lookup(halves[0], d[..., 0] * scale, -d[..., 1] * scale)
    front = d[..., 2] >= 0.0
    out = np.empty(d.shape[:-1] + (3,), np.float32)
    for half, is_front, where in ((halves[0], True, front), (halves[1], False, ~front)):
        x, y = _paraboloid(d[where], is_front)
        out[where] = _disk_lookup(half, x / extent, y / extent)
    return out


def probe_to_latlong(data: np.ndarray, layout: str, path=None, back: np.ndarray | None = None,
                     back_path=None) -> np.ndarray:
    """Resample an angular map or dual-paraboloid pair to a lat-long map (2n × n, n the
    probe's side in texels, at most MAX_HEIGHT), averaging sub-samples so rims leave no seam. A pair is `data`
    (front, from `path`) and `back` (from `back_path`), or one 2n × n image holding front | back."""
    h, w = data.shape[:2]
    if layout == "angular" and h != w:
        raise BRDFLabError(f"an angular map is square; this image is {w}×{h}", path)
    if layout == "dual-paraboloid":
        if back is None and w == 2 * h:
            data, back = data[:, :h], data[:, h:]
        elif back is None:
            raise BRDFLabError(f"a dual-paraboloid probe is two square halves, as files NAME-front / NAME-back or "
                               f"side by side (2n × n); this {w}×{h} image has no other half", path)
        elif h != w or back.shape != data.shape:
            raise BRDFLabError(f"the halves of a dual-paraboloid pair are squares of one size; these are "
                               f"{w}×{h} and {back.shape[1]}×{back.shape[0]}", back_path or path)
    halves = [_fill_outside_disk(x.astype(np.float32)) for x in ((data,) if back is None else (data, back))]
    extent = 1.0 if back is None else paraboloid_extent(*halves)
    height, s = min(data.shape[0], MAX_HEIGHT), SUPERSAMPLE
    out = np.empty((height, 2 * height, 3), np.float32)
    step = max(1, BAND_TEXELS // (2 * height))
    for top in range(0, height, step):
        rows = range(top, min(top + step, height))
        fine = _sample(halves, layout, _latlong_directions(height, rows), np.float32(extent))
        out[rows.start:rows.stop] = fine.reshape(len(rows), s, 2 * height, s, 3).mean(axis=(1, 3))
    return out
