"""Direction-pair files for `brdflab eval`: an (N, 6) .npy array [wi | wo], checked before it is read.

The header is parsed on its own and the size it promises compared with the file's, so an
archive, an empty file, an object array or a header claiming 10¹² rows is one clear error,
never an allocation.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.lib import format as npy

from brdflab.errors import BRDFLabError
from brdflab.io.bounded import BoundedFile

MAX_PAIRS = 1 << 24  # 16,777,216 pairs: 805 MB of float64 input
_MAX_HEADER = 10_000  # NumPy's own limit for untrusted headers


def read_pairs(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Unit (wi, wo), each (N, 3) float64, from a .npy file of N rows [wi | wo]."""
    path = Path(path)
    with BoundedFile(path, MAX_PAIRS * 6 * 8 + _MAX_HEADER + 16, f"a file of {MAX_PAIRS:,} pairs") as f:
        if f.size == 0:
            raise BRDFLabError("the file is empty; expected an (N, 6) .npy array", path)
        shape, fortran, dtype = _header(f, path)
        if len(shape) != 2 or shape[1] != 6:
            raise BRDFLabError(f"expected an (N, 6) array [wi | wo], got shape {shape}", path)
        if dtype.hasobject or dtype.kind not in "fiu":
            raise BRDFLabError(f"expected a numeric array, got dtype {dtype}", path)
        data_bytes = shape[0] * 6 * dtype.itemsize
        left = f.size - f.tell()
        if data_bytes != left:
            raise BRDFLabError(f"the header promises {data_bytes} bytes of data, the file holds {left} bytes", path)
        if shape[0] > MAX_PAIRS:
            raise BRDFLabError(f"{shape[0]:,} pairs is more than the {MAX_PAIRS:,} supported", path)
        pairs = np.frombuffer(f.read(data_bytes), dtype).reshape(shape, order="F" if fortran else "C")
    pairs = pairs.astype(float)
    if not np.all(np.isfinite(pairs)):
        raise BRDFLabError("the pairs contain NaN or Inf", path)
    wi, wo = pairs[:, :3], pairs[:, 3:]
    out = []
    for name, w in (("wi", wi), ("wo", wo)):
        largest = np.abs(w).max(axis=1, keepdims=True)  # scaled first: squares of 1e200 overflow
        if np.any(largest < 1e-9):
            raise BRDFLabError(f"a {name} direction has zero length", path)
        w = w / largest
        out.append(w / np.linalg.norm(w, axis=1, keepdims=True))
    return out[0], out[1]


def _header(f: BoundedFile, path: Path) -> tuple[tuple, bool, np.dtype]:
    """(shape, fortran_order, dtype) of a .npy header, or a one-line error."""
    magic = f.read(min(f.size, 6))
    if magic.startswith(b"PK"):
        raise BRDFLabError("an .npz archive, not a .npy array; save the pairs with numpy.save", path)
    if magic != npy.MAGIC_PREFIX:
        raise BRDFLabError("not a .npy array (no NumPy magic string)", path)
    f.stream.seek(0)
    try:
        version = npy.read_magic(f.stream)
        if version == (1, 0):
            return npy.read_array_header_1_0(f.stream, max_header_size=_MAX_HEADER)
        if version == (2, 0):
            return npy.read_array_header_2_0(f.stream, max_header_size=_MAX_HEADER)
    except (ValueError, EOFError, OSError):
        raise BRDFLabError("not a valid .npy header", path) from None
    raise BRDFLabError(f".npy format version {version[0]}.{version[1]} is not supported", path)
