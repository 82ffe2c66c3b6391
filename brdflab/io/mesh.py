"""Meshes for the object view: loaded through trimesh, checked, with normals and tangents.

Files a mesh names (an OBJ's mtllib, a glTF's buffers) are read from the mesh's folder and
below only, through the same bounded reads as the mesh (a FIFO there is refused); a PLY's
header is checked against its body before trimesh reads it.

Tangent frames come from UVs when the mesh has them; otherwise from a constant vector
projected into the tangent plane (as Kautz et al. do for brushed directions).
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.io.bounded import kind_problem, read_bounded
from brdflab.io.resources import data_dir

MAX_TRIANGLES = 20_000_000
MAX_MESH_BYTES = 2 << 30
FORMATS = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
TEXT_FORMATS = (".obj", ".off")  # decoded here: trimesh needs a charset detector for non-UTF-8 text


@dataclass
class Mesh:
    """Triangles with per-vertex position, normal and tangent (float32), unit-scaled."""

    positions: np.ndarray  # (V, 3)
    normals: np.ndarray  # (V, 3)
    tangents: np.ndarray  # (V, 3)
    faces: np.ndarray  # (F, 3) uint32
    name: str = "mesh"

    @property
    def n_vertices(self) -> int:
        return self.positions.shape[0]

    def interleaved(self) -> np.ndarray:
        return np.hstack([self.positions, self.normals, self.tangents]).astype(np.float32)


def tangents_from_constant(normals: np.ndarray, direction=(1.0, 0.0, 0.0)) -> np.ndarray:
    """normalize(X − (X·n) n); where X ∥ n, another axis is used."""
    x = np.asarray(direction, float)
    t = x - (normals @ x)[:, None] * normals
    bad = np.linalg.norm(t, axis=1) < 1e-6
    if bad.any():
        y = np.array([0.0, 0.0, 1.0])
        t[bad] = y - (normals[bad] @ y)[:, None] * normals[bad]
    return t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)


def tangents_from_uv(positions, normals, faces, uv) -> np.ndarray | None:
    """Per-vertex tangents along +u (Lengyel's method); None where UVs are degenerate."""
    p0, p1, p2 = (positions[faces[:, k]] for k in range(3))
    w0, w1, w2 = (uv[faces[:, k]] for k in range(3))
    e1, e2 = p1 - p0, p2 - p0
    d1, d2 = w1 - w0, w2 - w0
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(det) > 1e-12
    if not ok.any():
        return None
    r = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    t_face = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * r[:, None]
    t = np.zeros_like(positions)
    for k in range(3):
        np.add.at(t, faces[:, k], t_face)
    t -= (t * normals).sum(axis=1, keepdims=True) * normals
    norm = np.linalg.norm(t, axis=1)
    fallback = tangents_from_constant(normals)
    return np.where((norm > 1e-9)[:, None], t / np.maximum(norm, 1e-12)[:, None], fallback)


def from_arrays(positions, faces, normals=None, uv=None, name="mesh") -> Mesh:
    """Check, clean and complete raw arrays into a Mesh centred in the unit sphere."""
    positions = np.asarray(positions, float)
    faces = np.asarray(faces, np.int64)
    if positions.ndim != 2 or positions.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3:
        raise BRDFLabError(f"{name}: expected triangles, got vertex shape {positions.shape}, face shape {faces.shape}")
    if not np.all(np.isfinite(positions)):
        raise BRDFLabError(f"{name}: {int((~np.isfinite(positions)).any(axis=1).sum())} vertices are NaN or Inf")
    largest = float(np.abs(positions).max()) if positions.size else 0.0
    if largest > 0.0:  # the mesh is scaled to the unit sphere anyway; first, so that 1e308 cannot overflow
        positions = positions / largest
    if faces.size == 0 or faces.min() < 0 or faces.max() >= len(positions):
        raise BRDFLabError(f"{name}: faces index missing vertices (or there are no faces)")
    if len(faces) > MAX_TRIANGLES:
        raise BRDFLabError(f"{name}: {len(faces)} triangles is more than the {MAX_TRIANGLES} supported")
    # degenerate faces (repeated vertices or zero area) are dropped
    e1 = positions[faces[:, 1]] - positions[faces[:, 0]]
    e2 = positions[faces[:, 2]] - positions[faces[:, 0]]
    area = np.linalg.norm(np.cross(e1, e2), axis=1)
    keep = area > 1e-14 * max(float(np.ptp(positions, axis=0).max()) ** 2, 1e-300)
    faces = faces[keep]
    if faces.size == 0:
        raise BRDFLabError(f"{name}: every face is degenerate")
    if normals is None or np.shape(normals) != positions.shape or not np.all(np.isfinite(normals)):
        normals = np.zeros_like(positions)
        face_n = np.cross(e1[keep], e2[keep])  # area-weighted
        for k in range(3):
            np.add.at(normals, faces[:, k], face_n)
    normals = np.asarray(normals, float)
    nlen = np.linalg.norm(normals, axis=1)
    normals = np.where((nlen > 1e-12)[:, None], normals / np.maximum(nlen, 1e-12)[:, None], [0.0, 0.0, 1.0])
    centre = 0.5 * (positions.min(axis=0) + positions.max(axis=0))
    radius = float(np.linalg.norm(positions - centre, axis=1).max()) or 1.0
    positions = (positions - centre) / radius
    tangents = None
    if uv is not None and np.shape(uv) == (len(positions), 2) and np.all(np.isfinite(uv)):
        tangents = tangents_from_uv(positions, normals, faces, np.asarray(uv, float))
    if tangents is None:
        tangents = tangents_from_constant(normals)
    return Mesh(positions.astype(np.float32), normals.astype(np.float32), tangents.astype(np.float32),
                faces.astype(np.uint32), name)


def load_mesh(path: str | os.PathLike) -> Mesh:
    """Any mesh trimesh reads (OBJ, PLY, STL, OFF, GLB), as one triangle mesh."""
    import trimesh

    path = Path(path)
    if not path.exists():
        raise BRDFLabError("no such file", path)
    problem = kind_problem(path.stat().st_mode)  # a folder named like a mesh or not: said as what it is
    if problem:
        raise BRDFLabError(problem, path)
    if path.suffix.lower() not in FORMATS:
        raise BRDFLabError(f"unsupported mesh type {path.suffix!r} (use {', '.join(FORMATS)})", path)
    data = read_bounded(path, MAX_MESH_BYTES, "a mesh file")
    if path.suffix.lower() in TEXT_FORMATS:
        data = _utf8(data)
    if path.suffix.lower() == ".ply":
        check_ply_header(data, path)
    try:
        loaded = trimesh.load(io.BytesIO(data), file_type=path.suffix.lower()[1:], force="mesh", process=False,
                              resolver=_bounded_resolver(path))
    except MemoryError:
        raise BRDFLabError("the mesh is too large for memory", path) from None
    except Exception as e:  # trimesh raises many types for broken files
        raise BRDFLabError(f"cannot read mesh: {str(e).splitlines()[0] if str(e) else type(e).__name__}", path) from None
    if not hasattr(loaded, "faces") or len(getattr(loaded, "faces", [])) == 0:
        raise BRDFLabError("no triangles in the file", path)
    uv = None
    visual = getattr(loaded, "visual", None)
    if visual is not None and getattr(visual, "uv", None) is not None:
        uv = np.asarray(visual.uv)
    cache = getattr(getattr(loaded, "_cache", None), "cache", {})  # normals the file itself gave
    normals = np.asarray(cache["vertex_normals"]) if "vertex_normals" in cache else None
    try:
        return from_arrays(np.asarray(loaded.vertices), np.asarray(loaded.faces), normals, uv, path.name)
    except BRDFLabError as e:
        raise BRDFLabError(str(e).split(": ", 1)[1], path) from None


def _bounded_resolver(path: Path):
    """trimesh's resolver of the files a mesh names (its folder and below), reading them
    through read_bounded: a FIFO or a device named by an mtllib or a glTF buffer would block
    or never end."""
    import trimesh

    class BoundedResolver(trimesh.resolvers.FilePathResolver):
        def get(self, name: str) -> bytes:
            for candidate in (name.strip(), name.strip().lstrip("/"), os.path.split(name)[-1]):
                try:
                    found = self.absolute(candidate)
                except ValueError:  # outside the mesh's folder
                    continue
                if os.path.lexists(found):
                    return read_bounded(found, MAX_MESH_BYTES, "a file a mesh names")
            return super().get(name)  # says why it is not there

    return BoundedResolver(str(path))


PLY_FORMATS = ("ascii", "binary_little_endian", "binary_big_endian")
_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
              "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}


def check_ply_header(data: bytes, path: Path) -> None:
    """Refuse a PLY whose header is not version 1.0 of a known format, or whose element counts
    the body cannot hold: an ASCII body has exactly one line per element, a binary one at least
    the bytes its counts need (a lying face count made trimesh read whatever was there)."""
    end = data.find(b"end_header", 0, 1 << 16)
    if not data.startswith(b"ply") or end < 0:
        raise BRDFLabError("not a PLY file (no 'ply' ... 'end_header' header in its first 64 KB)", path)
    body_start = data.find(b"\n", end) + 1 or len(data)
    fmt, elements = None, []  # (count, bytes of its fixed part)
    for line in data[:end].decode("ascii", "replace").splitlines()[1:]:
        words = line.split()
        if words[:1] == ["format"]:
            fmt = words[1] if len(words) == 3 and words[1] in PLY_FORMATS and words[2] == "1.0" else "?"
        elif words[:1] == ["element"] and len(words) == 3 and words[2].isascii() and words[2].isdigit():
            elements.append([int(words[2]), 0])
        elif words[:1] == ["element"]:
            raise BRDFLabError("a PLY element line is not 'element NAME COUNT'", path)
        elif words[:1] == ["property"] and elements:
            size = words[2] if words[1:2] == ["list"] and len(words) == 5 else words[1] if len(words) == 3 else ""
            if size not in _PLY_SIZES:
                raise BRDFLabError("a PLY property of an unknown type", path)
            elements[-1][1] += _PLY_SIZES[size]
    if fmt not in PLY_FORMATS:
        raise BRDFLabError(f"unsupported PLY format line (the lab reads {', '.join(PLY_FORMATS)} 1.0)", path)
    body = data[body_start:]
    if fmt == "ascii":
        fits = sum(count for count, _ in elements) == sum(1 for line in io.BytesIO(body) if line.strip())
    else:
        fits = sum(count * size for count, size in elements) <= len(body)
    if not fits:
        raise BRDFLabError("the PLY header's element counts do not match its data (a wrong face or vertex count)",
                           path)


def _utf8(data: bytes) -> bytes:
    """Text mesh bytes as UTF-8: files from older exporters often have Latin-1 comments."""
    try:
        data.decode("utf-8")
        return data
    except UnicodeDecodeError:
        return data.decode("latin-1").encode("utf-8")


def uv_sphere(n_theta: int = 96, n_phi: int = 192) -> Mesh:
    """The unit sphere, with exact normals and the reference view's tangents (+X projected)."""
    theta = np.linspace(0.0, np.pi, n_theta + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, n_phi + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    pos = np.stack([np.sin(t) * np.cos(p), np.cos(t), -np.sin(t) * np.sin(p)], axis=-1).reshape(-1, 3)
    idx = np.arange((n_theta + 1) * (n_phi + 1)).reshape(n_theta + 1, n_phi + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return from_arrays(pos, faces, pos.copy(), None, "sphere")


def default_mesh(name: str = "sphere") -> Mesh:
    """'sphere' or a mesh shipped in resources/ (by file name)."""
    if name == "sphere":
        return uv_sphere()
    return load_mesh(data_dir("resources") / name)
