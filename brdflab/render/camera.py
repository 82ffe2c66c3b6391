"""Orbit camera matrices (column-major for OpenGL)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


FOV = 35.0  # degrees, across the narrower side of the image
FILL = 0.9  # the framed sphere's radius, as a fraction of half the narrower side


def framing_distance(radius: float = 1.0, fov: float = FOV, fill: float = FILL) -> float:
    """The distance at which a sphere of `radius` (meshes are scaled into the unit sphere)
    fills `fill` of the narrower side: its silhouette's half-angle α has
    tan α = fill · tan(fov / 2), and sin α = radius / distance."""
    alpha = math.atan(fill * math.tan(math.radians(fov) / 2.0))
    return radius / math.sin(alpha)


@dataclass
class OrbitCamera:
    """Looks at the origin from `distance`, turned by yaw (about +Y) and pitch (degrees);
    by default far enough to show the whole unit sphere, whatever the image's aspect."""

    yaw: float = 30.0
    pitch: float = 20.0
    distance: float = framing_distance()
    fov: float = FOV

    @property
    def position(self) -> np.ndarray:
        y, p = math.radians(self.yaw), math.radians(self.pitch)
        return self.distance * np.array([math.cos(p) * math.sin(y), math.sin(p), math.cos(p) * math.cos(y)])

    def view(self) -> np.ndarray:
        eye = self.position
        f = -eye / np.linalg.norm(eye)
        up = np.array([0.0, 1.0, 0.0])
        s = np.cross(f, up)
        s /= max(np.linalg.norm(s), 1e-12)
        u = np.cross(s, f)
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = s, u, -f
        m[:3, 3] = -m[:3, :3] @ eye
        return m

    def projection(self, aspect: float) -> np.ndarray:
        """Perspective whose `fov` spans the narrower side, so a tall view crops nothing more
        than a wide one."""
        f = 1.0 / math.tan(math.radians(self.fov) / 2.0)
        near, far = 0.05, 50.0
        m = np.zeros((4, 4))
        m[0, 0], m[1, 1] = (f / aspect, f) if aspect >= 1.0 else (f, f * aspect)
        m[2, 2], m[2, 3] = (far + near) / (near - far), 2 * far * near / (near - far)
        m[3, 2] = -1.0
        return m

    def orbit(self, d_yaw: float, d_pitch: float) -> None:
        self.yaw = (self.yaw + d_yaw) % 360.0
        self.pitch = float(np.clip(self.pitch + d_pitch, -89.0, 89.0))

    def zoom(self, factor: float) -> None:
        self.distance = float(np.clip(self.distance * factor, 1.2, 20.0))


def gl_matrix(m: np.ndarray) -> bytes:
    """A row-major NumPy matrix as the column-major bytes OpenGL expects."""
    return np.ascontiguousarray(m.T, dtype=np.float32).tobytes()
