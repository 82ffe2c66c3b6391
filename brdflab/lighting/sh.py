"""Real spherical harmonics for lighting (Kautz, Sloan & Snyder 2002).

Order L means L bands and L² coefficients; coefficient i = l² + l + m. The basis is the
real, orthonormal one with the Condon–Shortley phase:
y_l^m = √2 K_l^m cos(mφ) P_l^m(cos θ) (m > 0), √2 K_l^|m| sin(|m|φ) P_l^|m|(cos θ) (m < 0),
K_l^0 P_l^0 (m = 0), in whatever Cartesian frame the directions are given.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from brdflab.errors import BRDFLabError

MAX_ORDER = 16


def check_order(order: int) -> int:
    if not isinstance(order, (int, np.integer)) or not 1 <= order <= MAX_ORDER:
        raise BRDFLabError(f"SH order {order} is outside 1..{MAX_ORDER}")
    return int(order)


def index(l: int, m: int) -> int:
    return l * l + l + m


@lru_cache(maxsize=None)
def _norms(order: int) -> np.ndarray:
    k = np.zeros((order, order))
    for l in range(order):
        for m in range(l + 1):
            k[l, m] = math.sqrt((2 * l + 1) / (4 * math.pi) * math.factorial(l - m) / math.factorial(l + m))
    return k


def basis(order: int, d: np.ndarray) -> np.ndarray:
    """SH basis at unit directions d (..., 3) → (..., order²)."""
    order = check_order(order)
    d = np.asarray(d, float)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    shape = d.shape[:-1]
    out = np.empty(shape + (order * order,))
    k = _norms(order)
    # C_m + i S_m = (x + i y)^m = sin^m θ e^{imφ}; Q_l^m = P_l^m / sin^m θ (a polynomial in z)
    c_prev, s_prev = np.ones(shape), np.zeros(shape)
    q_mm = np.ones(shape)
    for m in range(order):
        if m > 0:
            c_prev, s_prev = c_prev * x - s_prev * y, c_prev * y + s_prev * x
            q_mm = q_mm * (-(2 * m - 1))
        q_lm2, q_lm1 = None, q_mm
        for l in range(m, order):
            if l == m:
                q = q_mm
            elif l == m + 1:
                q = z * (2 * m + 1) * q_mm
            else:
                q = ((2 * l - 1) * z * q_lm1 - (l + m - 1) * q_lm2) / (l - m)
            if l > m:
                q_lm2, q_lm1 = q_lm1, q
            if m == 0:
                out[..., index(l, 0)] = k[l, 0] * q
            else:
                out[..., index(l, m)] = math.sqrt(2.0) * k[l, m] * q * c_prev
                out[..., index(l, -m)] = math.sqrt(2.0) * k[l, m] * q * s_prev
    return out


def window(order: int, kind: str | None) -> np.ndarray:
    """Per-coefficient damping against ringing: None, 'hanning' or 'lanczos'."""
    l = np.repeat(np.arange(order), 2 * np.arange(order) + 1).astype(float)
    if kind in (None, "none"):
        return np.ones_like(l)
    if kind == "hanning":
        return 0.5 * (1.0 + np.cos(np.pi * l / order))
    if kind == "lanczos":
        return np.sinc(l / order)
    raise BRDFLabError(f"unknown SH window {kind!r} (none, hanning or lanczos)")


@lru_cache(maxsize=None)
def _from_map_frame(order: int) -> np.ndarray:
    """M (order², order²) with basis(d) = basis(Pd) @ M, Pd = (−d_z, d_x, d_y): the basis in the
    frame whose pole is the lat-long map's (world +Y) and whose azimuth is the map's φ − π,
    where every basis function is a function of the row times one of the column. Each band maps
    to itself under a rotation or reflection, so a least-squares fit at random directions is
    exact (residual ~1e-15)."""
    d = np.random.default_rng(order).normal(size=(4 * order * order + 64, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    pd = np.stack([-d[:, 2], d[:, 0], d[:, 1]], axis=1)
    return np.linalg.lstsq(basis(order, pd), basis(order, d), rcond=None)[0]


def project_environment(env, order: int, window_kind: str | None = None, rows: int = 256) -> np.ndarray:
    """SH coefficients (order², 3) of a lat-long map (world frame): each texel's radiance
    times the basis integrated over the texel (2 × 2 Gauss points in cos θ and φ).

    In the map's own frame (`_from_map_frame`) the basis function of (l, m) is a function of
    cos θ (K P_l^|m| sin^|m| θ) times one of φ (cos mφ, sin |m|φ or 1), and so is a texel's
    Gauss rule: the map is first summed along its rows against the 2·order − 1 functions of φ
    (one matrix product), then along its columns against those of θ. Equal to the texel-by-
    texel sum to rounding, at the cost of one pass over the map (a 2,000 × 1,000 map, order 8:
    0.3 s instead of 6.5 s; `benchmarks/sh_projection.py`)."""
    order = check_order(order)
    h, w = env.height, env.width
    n = order * order
    g = np.array([-1.0, 1.0]) / math.sqrt(3.0)
    m_of = np.concatenate([np.arange(-l, l + 1) for l in range(order)])
    # the φ part: column functions cos mφ' (m ≥ 0) and sin |m|φ' (m < 0), φ' = φ − π, summed over
    # each texel's two Gauss points and weighted by half the texel's width
    phi_edges = np.linspace(0.0, 2.0 * math.pi, w + 1)
    pp = 0.5 * (phi_edges[:-1, None] + phi_edges[1:, None]) + 0.5 * (phi_edges[1] - phi_edges[0]) * g[None, :] - math.pi
    ms = np.arange(-(order - 1), order)  # one column function per m
    trig = np.where(ms >= 0, np.cos(np.abs(ms)[None, None] * pp[..., None]), np.sin(np.abs(ms)[None, None] * pp[..., None]))
    columns = trig.sum(axis=1) * (0.5 * (phi_edges[1] - phi_edges[0]))  # (w, 2·order − 1)
    out = np.zeros((n, env.data.shape[2]))
    for r0 in range(0, h, rows):
        r = np.arange(r0, min(h, r0 + rows))
        z0, z1 = np.cos(math.pi * r / h), np.cos(math.pi * (r + 1) / h)
        z = 0.5 * (z0[:, None] + z1[:, None]) + 0.5 * (z1 - z0)[:, None] * g[None, :]  # (rows, 2)
        st = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        # the θ part: the basis at φ' = 0, whose m ≥ 0 entries are K P_l^m sin^m θ (× √2 for m > 0)
        at_zero = basis(order, np.stack([st, np.zeros_like(z), z], axis=-1))  # (rows, 2, n)
        l_of = np.repeat(np.arange(order), 2 * np.arange(order) + 1)
        row_part = at_zero[..., l_of * l_of + l_of + np.abs(m_of)].sum(axis=1) * (0.5 * np.abs(z0 - z1))[:, None]
        summed = np.einsum("rwc,wj->rjc", env.data[r].astype(float), columns)  # (rows, 2·order − 1, channels)
        out += np.einsum("rn,rnc->nc", row_part, summed[:, m_of + order - 1])
    return (_from_map_frame(order).T @ out) * window(order, window_kind)[:, None]


def legendre(l_max: int, x: float) -> np.ndarray:
    p = np.zeros(l_max + 2)
    p[0] = 1.0
    if l_max + 1 >= 1:
        p[1] = x
    for l in range(2, l_max + 2):
        p[l] = ((2 * l - 1) * x * p[l - 1] - (l - 1) * p[l - 2]) / l
    return p


def disk_light(direction, solid_angle: float, radiance, order: int) -> np.ndarray:
    """A circular light of constant radiance: its zonal harmonics in closed form
    (∫_{cos α}^1 P_l = (P_{l−1}(cos α) − P_{l+1}(cos α))/(2l + 1)), rotated to `direction`."""
    order = check_order(order)
    if not 0.0 < solid_angle <= 4.0 * math.pi:
        raise BRDFLabError(f"solid angle {solid_angle} must be in (0, 4π]")
    c = 1.0 - solid_angle / (2.0 * math.pi)  # cos of the half-angle
    p = legendre(order, c)
    z = np.array([2 * math.pi * math.sqrt((2 * l + 1) / (4 * math.pi)) * ((1.0 - c) if l == 0 else (p[l - 1] - p[l + 1]) / (2 * l + 1))
                  for l in range(order)])
    d = np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    y = basis(order, d)
    l_of = np.repeat(np.arange(order), 2 * np.arange(order) + 1)
    coeff = np.sqrt(4 * math.pi / (2 * l_of + 1)) * z[l_of] * y
    return coeff[:, None] * np.asarray(radiance, float).reshape(1, -1)


def evaluate(coefficients: np.ndarray, d: np.ndarray) -> np.ndarray:
    order = int(round(math.sqrt(coefficients.shape[0])))
    return basis(order, d) @ coefficients


# --- rotation ----------------------------------------------------------------------------------

@lru_cache(maxsize=4)
def _fit_directions(n: int = 400) -> np.ndarray:
    """Fibonacci directions: a well-conditioned set for fitting band rotations."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def rotation_matrix(R: np.ndarray, order: int) -> np.ndarray:
    """M (order² × order²) with coefficients(f ∘ R⁻¹) = M · coefficients(f): exact for any
    order, since each band is closed under rotation (solved band by band from samples)."""
    order = check_order(order)
    R = np.asarray(R, float)
    d = _fit_directions(max(400, 4 * order * order))
    A = basis(order, d)
    B = basis(order, d @ R)  # rows: R⁻¹ ω = Rᵀ ω
    M = np.zeros((order * order, order * order))
    for l in range(order):
        s = slice(l * l, (l + 1) * (l + 1))
        M[s, s] = np.linalg.lstsq(A[:, s], B[:, s], rcond=None)[0]
    return M


def rotate(coefficients: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Coefficients of the function turned by R (g(ω) = f(R⁻¹ ω))."""
    order = int(round(math.sqrt(coefficients.shape[0])))
    return rotation_matrix(R, order) @ coefficients


def axis_rotation(axis: str, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def zyz_angles(R: np.ndarray) -> tuple[float, float, float]:
    """α, β, γ with R = Rz(α) Ry(β) Rz(γ)."""
    beta = math.acos(max(-1.0, min(1.0, R[2, 2])))
    if abs(math.sin(beta)) < 1e-9:
        return math.atan2(R[1, 0], R[0, 0]) if R[2, 2] > 0 else math.atan2(-R[1, 0], -R[0, 0]), beta, 0.0
    return math.atan2(R[1, 2], R[0, 2]), beta, math.atan2(R[2, 1], -R[2, 0])


def _rotate_z_many(c: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotate (V, n, C) coefficient sets about z by per-set angles (V,)."""
    order = int(round(math.sqrt(c.shape[1])))
    out = c.copy()
    for l in range(1, order):
        for m in range(1, l + 1):
            ca, sa = np.cos(m * angle)[:, None], np.sin(m * angle)[:, None]
            n, p = index(l, -m), index(l, m)
            a, b = c[:, n], c[:, p]
            out[:, n] = ca * a + sa * b
            out[:, p] = -sa * a + ca * b
    return out


def rotate_many(c: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Coefficients (V, n, C) turned by V rotations R (V, 3, 3), through the zyz
    decomposition M(R) = Mz(α) M(Rx(−90°)) Mz(β) M(Rx(90°)) Mz(γ), vectorised."""
    order = int(round(math.sqrt(c.shape[1])))
    beta = np.arccos(np.clip(R[:, 2, 2], -1.0, 1.0))
    degenerate = np.abs(np.sin(beta)) < 1e-9
    alpha = np.where(degenerate, np.where(R[:, 2, 2] > 0, np.arctan2(R[:, 1, 0], R[:, 0, 0]), np.arctan2(-R[:, 1, 0], -R[:, 0, 0])),
                     np.arctan2(R[:, 1, 2], R[:, 0, 2]))
    gamma = np.where(degenerate, 0.0, np.arctan2(R[:, 2, 1], -R[:, 2, 0]))
    x90 = rotation_matrix(axis_rotation("x", math.pi / 2), order)
    xm90 = rotation_matrix(axis_rotation("x", -math.pi / 2), order)
    out = _rotate_z_many(c, gamma)
    out = np.einsum("ij,vjc->vic", x90, out)
    out = _rotate_z_many(out, beta)
    out = np.einsum("ij,vjc->vic", xm90, out)
    return _rotate_z_many(out, alpha)
