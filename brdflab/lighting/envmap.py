"""HDR environment maps (lat-long, +Y up) and images: Radiance RGBE and OpenEXR.

Directions map to texture coordinates as in CONVENTIONS.md:
u = 0.5 + atan2(d.x, −d.z) / (2π), v = acos(d.y) / π, row 0 at the top.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.io.bounded import checked_size

MAX_PIXELS = 8192 * 4096  # the largest published lat-long maps; checked before decoding (an RLE file of 4 MB can declare 64 M)
MAX_MAP_BYTES = 1 << 30  # MAX_PIXELS of uncompressed float32 RGB is 403 MB
# Radiance above this is no real scene (the sun's disk is ~1e9 cd/m²); larger finite values
# (RGBE exponent 255, float32's max) overflow the renderers' sums into Inf and NaN.
MAX_RADIANCE = 1e12


@dataclass
class EnvironmentMap:
    """Linear radiance, float32, shape (H, W, 3), row 0 = top (v = 0)."""

    data: np.ndarray
    name: str = "environment"
    path: Path | None = None
    note: str = ""  # a doubt about the file's layout, for the user to see
    layout: str = "latlong"  # how the file was read (a probe is resampled to lat-long)

    @property
    def width(self) -> int:
        return self.data.shape[1]

    @property
    def height(self) -> int:
        return self.data.shape[0]

    @cached_property
    def mips(self) -> list[np.ndarray]:
        """Its mip levels averaged by solid angle (`mip_pyramid.solid_angle_mips`), computed
        once: the window computes them in the thread that reads the map, not while it draws."""
        from brdflab.lighting.mip_pyramid import solid_angle_mips

        return solid_angle_mips(self.data)

    def texel_directions(self) -> tuple[np.ndarray, np.ndarray]:
        """World direction of each texel centre (H, W, 3) and its solid angle (H, 1)."""
        h, w = self.height, self.width
        d = uv_to_direction(((np.arange(w) + 0.5) / w)[None, :], ((np.arange(h) + 0.5) / h)[:, None])
        return d, band_solid_angle(np.arange(h) / h, (np.arange(h) + 1) / h, w)[:, None]

    def downsampled(self, width: int, height: int) -> "EnvironmentMap":
        """Area-average to width × height (each output texel averages the input texels it
        covers, weighted by solid angle) — used for quadrature references."""
        if self.width % width or self.height % height:
            raise BRDFLabError(f"cannot reduce {self.width}×{self.height} to {width}×{height} evenly", self.path)
        fy, fx = self.height // height, self.width // width
        _, solid = self.texel_directions()
        weighted = (self.data * solid[:, :, None]).reshape(height, fy, width, fx, 3).sum(axis=(1, 3))
        area = np.broadcast_to(solid, (self.height, self.width)).reshape(height, fy, width, fx).sum(axis=(1, 3))
        return EnvironmentMap((weighted / area[:, :, None]).astype(np.float32), self.name, self.path)

    def downsampled_within(self, width: int, height: int) -> "EnvironmentMap":
        """`downsampled` to the largest sizes of at most width × height that divide the map's
        own evenly (a 1000-wide map goes to 125, not 128)."""
        w = max(d for d in range(1, min(width, self.width) + 1) if self.width % d == 0)
        h = max(d for d in range(1, min(height, self.height) + 1) if self.height % d == 0)
        return self.downsampled(w, h)

    def rotated(self, yaw_degrees: float) -> "EnvironmentMap":
        """The map turned about +Y (texel columns rolled; exact for multiples of a texel)."""
        shift = int(round(yaw_degrees / 360.0 * self.width))
        return EnvironmentMap(np.roll(self.data, shift, axis=1), self.name, self.path)


def uv_to_direction(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """World directions (..., 3) of lat-long coordinates u, v (broadcast together): the
    inverse of `direction_to_uv`."""
    theta, phi = v * np.pi, (u - 0.5) * 2.0 * np.pi
    st = np.sin(theta)
    return np.stack(np.broadcast_arrays(st * np.sin(phi), np.cos(theta), -st * np.cos(phi)), axis=-1)


def band_solid_angle(v_top: np.ndarray, v_bottom: np.ndarray, columns: int) -> np.ndarray:
    """Exact solid angle of one of `columns` equal cells of the lat-long band between v_top and v_bottom."""
    return (2.0 * np.pi / columns) * (np.cos(np.pi * v_top) - np.cos(np.pi * v_bottom))


def direction_to_uv(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    u = 0.5 + np.arctan2(d[..., 0], -d[..., 2]) / (2.0 * np.pi)
    v = np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / np.pi
    return u, v


def texel_of(d: np.ndarray, height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """(row, column) of the texel of a height × width lat-long map that holds each direction d (..., 3)."""
    u, v = direction_to_uv(np.asarray(d, float))
    cols = np.clip(np.floor(u * width).astype(int), 0, width - 1)
    rows = np.clip(np.floor(v * height).astype(int), 0, height - 1)
    return rows, cols


def constant(value: float | tuple = 1.0, width: int = 64, height: int = 32) -> EnvironmentMap:
    return EnvironmentMap(np.broadcast_to(np.asarray(value, np.float32), (height, width, 3)).copy(), "constant")


# --------------------------------------------------------------------------------------------
# Radiance RGBE

def _rgbe_to_float(rgbe: np.ndarray) -> np.ndarray:
    """RGBE → float32 RGB, a band of rows at a time (float64 temporaries for 33 M texels are GBs)."""
    scale_of = np.where(np.arange(256) > 0, np.ldexp(1.0, np.arange(256) - 136), 0.0).astype(np.float32)
    out = np.empty(rgbe.shape[:-1] + (3,), np.float32)
    for y in range(0, rgbe.shape[0], 256):
        band = rgbe[y:y + 256]
        np.multiply(band[..., :3], scale_of[band[..., 3]][..., None], out=out[y:y + 256], dtype=np.float32)
    return out


def read_hdr(path: str | os.PathLike) -> np.ndarray:
    """Radiance .hdr (RGBE, flat or new-style run-length encoded) → (H, W, 3) float32."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as e:
        raise BRDFLabError(f"cannot read: {e.strerror}", path) from None
    if not (data.startswith(b"#?RADIANCE") or data.startswith(b"#?RGBE")):
        raise BRDFLabError("not a Radiance HDR file (no #?RADIANCE signature)", path)
    pos = 0
    fmt = None
    while True:
        end = data.find(b"\n", pos)
        if end < 0:
            raise BRDFLabError("truncated header", path)
        line = data[pos:end].strip()
        pos = end + 1
        if not line:
            break
        if line.startswith(b"FORMAT="):
            fmt = line[7:]
    if fmt not in (None, b"32-bit_rle_rgbe"):
        raise BRDFLabError("unsupported FORMAT (the lab reads 32-bit_rle_rgbe)", path)
    end = data.find(b"\n", pos)
    if end < 0:
        raise BRDFLabError("truncated: no resolution line", path)
    res = data[pos:end].split()
    pos = end + 1
    if len(res) != 4 or res[0] not in (b"-Y", b"+Y") or res[2] not in (b"+X", b"-X"):
        raise BRDFLabError("unsupported resolution line (the lab reads -Y H +X W and its flips)", path)
    try:
        h, w = int(res[1]), int(res[3])
    except ValueError:
        raise BRDFLabError("bad resolution line", path) from None
    if h < 1 or w < 1 or h * w > MAX_PIXELS:
        raise BRDFLabError(f"the declared image size is outside 1..{MAX_PIXELS:,} texels (8192×4096), what the "
                           "lab reads", path)
    body = np.frombuffer(data, np.uint8, offset=pos)
    out = np.empty((h, w, 4), np.uint8)
    i = 0
    for y in range(h):
        if i + 4 > body.size:
            raise BRDFLabError(f"truncated at scanline {y} of {h}", path)
        if 8 <= w < 32768 and body[i] == 2 and body[i + 1] == 2 and (int(body[i + 2]) << 8 | int(body[i + 3])) == w:
            i += 4
            for c in range(4):
                x = 0
                row = out[y, :, c]
                while x < w:
                    if i >= body.size:
                        raise BRDFLabError(f"truncated at scanline {y} of {h}", path)
                    n = int(body[i])
                    i += 1
                    if n > 128:
                        n -= 128
                        if x + n > w or i >= body.size:
                            raise BRDFLabError(f"corrupt run at scanline {y}", path)
                        row[x:x + n] = body[i]
                        i += 1
                    else:
                        if n == 0 or x + n > w or i + n > body.size:
                            raise BRDFLabError(f"corrupt data at scanline {y}", path)
                        row[x:x + n] = body[i:i + n]
                        i += n
                    x += n
        else:
            if i + 4 * w > body.size:
                raise BRDFLabError(f"truncated at scanline {y} of {h}", path)
            out[y] = body[i:i + 4 * w].reshape(w, 4)
            i += 4 * w
    img = _rgbe_to_float(out)
    if res[0] == b"+Y":
        img = img[::-1]
    if res[2] == b"-X":
        img = img[:, ::-1]
    return np.ascontiguousarray(img)


# --------------------------------------------------------------------------------------------
# OpenEXR

def read_exr(path: str | os.PathLike) -> np.ndarray:
    """OpenEXR (any compression the library supports) → (H, W, 3) float32."""
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise BRDFLabError("no such file", path)
    try:
        # a Python file, not str(path): OpenEXR encodes a name as UTF-8 and refused a valid map
        # whose name is not UTF-8 (a Latin-1 name on a UTF-8 system) as "cannot decode"
        with open(path, "rb") as stream, _native_output_silenced(), OpenEXR.File(stream) as f:
            channels = f.channels()
            if "RGB" in channels:
                img = np.asarray(channels["RGB"].pixels, np.float32)
            elif "RGBA" in channels:
                img = np.asarray(channels["RGBA"].pixels, np.float32)[..., :3]
            elif all(c in channels for c in "RGB"):
                img = np.stack([np.asarray(channels[c].pixels, np.float32) for c in "RGB"], axis=-1)
            elif "Y" in channels:
                img = np.repeat(np.asarray(channels["Y"].pixels, np.float32)[..., None], 3, axis=-1)
            else:
                raise BRDFLabError(f"no RGB or Y channels ({len(channels)} others)", path)  # not the file's names
    except BRDFLabError:
        raise
    except Exception as e:  # the library reports corrupt files with assorted exception types
        raise BRDFLabError(f"cannot decode OpenEXR: {str(e).splitlines()[0] if str(e) else type(e).__name__}", path) from None
    if img.ndim != 3 or img.shape[0] < 1 or img.shape[1] < 1:
        raise BRDFLabError(f"unexpected image shape {img.shape}", path)
    return np.ascontiguousarray(img)


@contextmanager
def _native_output_silenced() -> Iterator[None]:
    """Send what native code writes to the process's stdout and stderr to /dev/null while the
    block runs: OpenEXR prints its own lines about a corrupt file (on stdout and stderr) before
    it raises, and the lab says what went wrong in one line of its own (stdout stays JSON)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    os.dup2(null, 2)
    try:
        yield
    finally:
        for fd, copy in zip((1, 2), saved):
            os.dup2(copy, fd)
            os.close(copy)
        os.close(null)


def write_exr(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write linear float32 RGB (H, W, 3) as OpenEXR (ZIP compression), atomically. Encoded
    in memory and written by atomic_write: OpenEXR opens a file by a name it encodes as
    UTF-8, so a name that is not UTF-8 could not be written (nor read) by name."""
    import io

    import OpenEXR

    from brdflab.io.atomic import atomic_write

    img = np.ascontiguousarray(image[..., :3], np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    buffer = io.BytesIO()
    with OpenEXR.File(header, {"RGB": img}) as f:
        f.write(buffer)
    atomic_write(path, buffer.getvalue())


def load_environment(path: str | os.PathLike, layout: str = "auto",
                     back: str | os.PathLike | None = None) -> EnvironmentMap:
    """An environment map from .hdr or .exr, checked for size and finite values.

    `layout`: latlong, angular (a light probe's disk), dual-paraboloid (a front and a back
    half), or auto (a square image whose disk has a dark surround is angular; a half named
    NAME-front / NAME-back whose other half exists is dual-paraboloid). A pair is `path`
    (front) and `back`, the halves found by name, or one image holding front | back.
    Probes are resampled to lat-long (brdflab/lighting/probes.py)."""
    from brdflab.lighting import probes

    path = Path(path)
    if layout not in probes.LAYOUTS:
        raise BRDFLabError(f"unknown map layout {layout!r}; one of {', '.join(probes.LAYOUTS)}", path)
    if back is not None and layout not in ("auto", "dual-paraboloid"):
        raise BRDFLabError(f"a second half is only for a dual-paraboloid pair, not a {layout} map", back)
    data = read_map(path)
    pair = probes.pair_path(path) if back is None and data.shape[0] == data.shape[1] else None
    if layout == "auto":
        layout = "dual-paraboloid" if back is not None or pair else probes.detect_layout(data)
    if layout == "dual-paraboloid" and back is None and pair:
        data = data if pair[0] == path else read_map(pair[0])
        path, back = pair
    if layout != "latlong":
        back_data = None if back is None else read_map(Path(back))
        data = probes.probe_to_latlong(data, layout, path, back_data, back)
    return EnvironmentMap(data, path.stem, path, latlong_doubt(data.shape), layout)


def read_map(path: Path) -> np.ndarray:
    """The texels of an .hdr or .exr file, checked for size and finite values, negatives clamped."""
    ext = path.suffix.lower()
    checked_size(path, MAX_MAP_BYTES, "an environment map")  # a FIFO or /dev/zero would never end
    if ext in (".hdr", ".pic", ".rgbe"):
        data = read_hdr(path)
    elif ext == ".exr":
        data = read_exr(path)
    else:
        raise BRDFLabError(f"unsupported environment map type {ext!r} (use .hdr or .exr)", path)
    if data.shape[0] < 2 or data.shape[1] < 4:
        raise BRDFLabError(f"map of {data.shape[1]}×{data.shape[0]} texels is too small", path)
    bad = ~np.isfinite(data)
    if bad.any():
        raise BRDFLabError(f"{int(bad.sum())} texel values are NaN or Inf", path)
    if data.max(initial=0.0) > MAX_RADIANCE:
        raise BRDFLabError(f"texel values above {MAX_RADIANCE:g}, beyond any real scene (they would overflow "
                           "the renderers' sums)", path)
    return np.maximum(data, 0.0) if (data < 0).any() else data


def latlong_doubt(shape: tuple) -> str:
    """Why a map read as lat-long may not be one: lat-long maps are twice as wide as tall."""
    h, w = shape[:2]
    if abs(w / h - 2.0) <= 0.02 * 2.0:
        return ""
    return (f"{w}×{h} texels is not the 2:1 shape of a lat-long map (a cross or a probe?): it is shown "
            "stretched; convert it, or open an angular or dual-paraboloid probe with its layout "
            "(the object view's map layout, or --env-layout)")
