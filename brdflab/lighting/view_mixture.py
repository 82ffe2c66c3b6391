"""A rough lobe's shape at every view as a few lookups of the prefiltered stack.

The split sum reads one layer of the stack at one direction: the lobe as it is at normal view
(n = v = r), moved toward n. A real lobe changes with the view: it narrows across the plane of
incidence, slides toward the normal, and the horizon cuts it. Below 60°, on the synthetic
maps a rough lobe was 5–12 % off per pixel under skies and suns (GGX, Beckmann and Ward, m = 0.3;
docs/prefiltered.md), and up to 107 % in a studio whose soft boxes sit in a lobe's tail.

Here, per lobe and at COSINES view cosines, the lobe's f(l, wo) max(0, l_z) is fitted, over
directions l of a Fibonacci sphere (the half y ≥ 0: an isotropic lobe is symmetric about the
plane of incidence), by a non-negative sum of at most LOOKUPS of the stack's own kernels —
the lobe's kernel family at the layers' α, centred in the plane of incidence at angles ψ from
n toward the mirror direction (`greedy_nnls`: non-negative least squares, one lookup added at a
time). The fit weighs each direction by
T^−WEIGHT_POWER (floored at FLOOR × the peak): a dim pixel is lit by the lobe's tail, and a
kernel that reaches below the horizon lights it from where the lobe does not. The weights are
normalised to sum to 1, so the energy stays the albedo table's. The shader (and the NumPy twin,
`split_sum.prefiltered_pixels`) reads each lookup's layer at its direction and blends the two
nearest cosines, each lookup turned by the pixel's view angle less its row's: the lobe moves with
the view between rows (blended in place, two rows 15° apart near the normal drew two highlights:
Blinn–Phong n = 100 under forest, θo < 15°, 6.7 % where the split sum was 2.4 %).

Only isotropic lobes of a half-vector kernel (Beckmann, GGX), with no diffuse share and of
roughness ≥ MIN_ROUGHNESS, are fitted (`fits`): a sharper lobe is close to its normal-view
shape and narrower than the fitting grid resolves; a Phong-kernel lobe (a wi-space lobe) keeps its
shape at every view; anisotropic lobes keep their taps.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from brdflab.fitting.nnls import nnls
from brdflab.lighting.env_sampling import LUMINANCE
from brdflab.lighting.prefilter import ALPHAS, KERNEL_FUNCTIONS, layer_of, phong_exponent

COSINES = 32  # view cosines 0, 1/31, …, 1 (the last fitted with lookups along n only: its plane is any)
LOOKUPS = 8  # lookups per cosine at most
GRID_POINTS = 2000  # Fibonacci sphere; the half y ≥ 0 is fitted
PSI_DEGREES = 2.5  # the candidates' spacing in ψ, −90° … 90°
WEIGHT_POWER = 0.35  # chosen on the tuning maps only, against 0.25 and 0.5 (docs/prefiltered.md)
FLOOR = 1e-3
MIN_ROUGHNESS = 0.1  # below, the fit's grid (~4.5°) and the layers' spacing cost more at normal views than the fit gains (docs/prefiltered.md)
MIN_COS = 0.01  # the fit at cos θo = 0 is made at this cosine


def fibonacci_half_sphere(n: int = GRID_POINTS) -> np.ndarray:
    """The points of an n-point Fibonacci sphere with y ≥ 0 (about n / 2)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (1.0 + np.sqrt(5.0)) * i
    d = np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)
    return d[d[:, 1] >= 0.0]


GRID = fibonacci_half_sphere()
ROW_ANGLES = np.arccos(np.maximum(np.linspace(0.0, 1.0, COSINES), MIN_COS))  # θo each row is fitted at


def in_plane(psi: np.ndarray) -> np.ndarray:
    """Directions (…, 3) at angles ψ from n (+Z) toward −X, the mirror side of a view in +X."""
    psi = np.asarray(psi, float)
    return np.stack([-np.sin(psi), np.zeros_like(psi), np.cos(psi)], -1)


def kernel_values(kernel: str, alpha: float, c: np.ndarray) -> np.ndarray:
    """The stack's kernel of `kernel` and α at cosines c to its centre (prefilter.specular_kernel)."""
    if kernel == "phong":
        return np.where(c > 0.0, np.maximum(c, 1e-30) ** (phong_exponent(alpha) + 1.0), 0.0)
    return KERNEL_FUNCTIONS[kernel](np.sqrt(0.5 * (1.0 + c)), alpha) * np.maximum(c, 0.0)


@lru_cache(maxsize=3)
def atoms(kernel: str) -> tuple[np.ndarray, np.ndarray]:
    """Every candidate lookup of a kernel family: columns (grid points, candidates), each
    kernel normalised to sum to 1 over the grid, and (candidates, 2): its ψ and layer index in
    the family (1 … len(ALPHAS) − 1)."""
    psi = np.radians(np.arange(-90.0, 90.0 + 1e-9, PSI_DEGREES))  # 0 among them exactly
    c = GRID @ in_plane(psi).T  # (grid, ψ)
    columns, meta = [], []
    for index, alpha in enumerate(ALPHAS[1:], 1):
        k = kernel_values(kernel, alpha, c)
        columns.append(k / np.maximum(k.sum(axis=0), 1e-300))
        meta.append(np.stack([psi, np.full_like(psi, index)], -1))
    return np.concatenate(columns, axis=1), np.concatenate(meta)


def lobe_targets(lobe) -> np.ndarray:
    """f(l, wo) max(0, l_z) in luminance at the grid points, (COSINES, grid), each row summing to 1
    (or 0 where the lobe is black at that view)."""
    cos_o = np.cos(ROW_ANGLES)
    wo = np.stack([np.sqrt(1.0 - cos_o**2), np.zeros(COSINES), cos_o], -1)
    wi = np.broadcast_to(GRID, (COSINES, *GRID.shape)).reshape(-1, 3)
    f = lobe.model.evaluate(wi, np.repeat(wo, len(GRID), axis=0), lobe.params)
    f = f[:, :3] @ LUMINANCE if f.ndim == 2 and f.shape[1] >= 3 else f.reshape(len(wi), -1)[:, 0]
    t = (np.maximum(f, 0.0) * np.maximum(wi[:, 2], 0.0)).reshape(COSINES, len(GRID))
    total = t.sum(axis=1, keepdims=True)
    return np.where(total > 0.0, t / np.where(total > 0.0, total, 1.0), 0.0)


def fit_view(target: np.ndarray, kernel: str, along_normal: bool) -> np.ndarray:
    """(LOOKUPS, 3): ψ, layer index in the family, weight of each lookup (weight 0: none)."""
    table = np.zeros((LOOKUPS, 3))
    if not target.any():
        return table
    columns, meta = atoms(kernel)
    weight = np.maximum(target, FLOOR * target.max()) ** -WEIGHT_POWER
    # every candidate (a kernel that misses the lobe scores ≤ 0 in `greedy_nnls` and is never taken)
    candidates = np.flatnonzero(meta[:, 0] == 0.0) if along_normal else np.arange(len(meta))
    a = columns[:, candidates] * weight[:, None]
    b = target * weight
    keep, w_keep = greedy_nnls(a, b, LOOKUPS)
    if w_keep.sum() <= 0.0:
        return table
    table[:len(keep), :2] = meta[candidates[keep]]
    table[:len(keep), 2] = w_keep / w_keep.sum()
    return table


def greedy_nnls(a: np.ndarray, b: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """At most `count` columns of `a` and their non-negative weights, argmin ‖a w − b‖ over the
    chosen: each step takes the column most aligned with the residual and solves NNLS on those
    taken (orthogonal matching pursuit kept non-negative). Lawson–Hanson's full NNLS over all
    ~900 candidates, then its `count` largest refitted, took 20× as long (85 ms a cosine, 1–2 s a
    lobe) for images at most 1.7 points better (studio-two-boxes below 60°: GGX m = 0.3 5.8 against
    6.5 %, Ward 0.3 6.4 against 8.1 %) and the same within 0.3 points on the other tuning maps."""
    norms = np.maximum(np.linalg.norm(a, axis=0), 1e-300)
    chosen: list[int] = []
    w = np.zeros(0)
    residual = b
    for _ in range(count):
        score = (a.T @ residual) / norms
        score[chosen] = -np.inf
        j = int(np.argmax(score))
        if score[j] <= 0.0:
            break
        trial = nnls(a[:, chosen + [j]], b)
        chosen, w = [c for c, x in zip(chosen + [j], trial) if x > 0.0], trial[trial > 0.0]
        residual = b - a[:, chosen] @ w
    return np.array(chosen, int), w


def fits(lobe, rule=None) -> bool:
    """Whether the lobe is drawn by fitted lookups (without fitting them: Render Auto's frame
    cost counts them): isotropic, a half-vector kernel, no diffuse share, α ≥ MIN_ROUGHNESS.
    `rule`: the lobe's split-sum rule where the caller has it (a file model's measures its
    roughness on the lobe's values)."""
    rule = lobe.model.split_sum(lobe.params) if rule is None else rule
    return (rule.kernel in ("beckmann", "ggx") and rule.kind != "diffuse" and rule.diffuse_share == 0.0
            and max(rule.tilt) == 0.0 and rule.roughness >= MIN_ROUGHNESS and lobe.model.is_isotropic(lobe.params))


def view_mixture(lobe, rule=None) -> np.ndarray | None:
    """(COSINES, LOOKUPS, 3) for an isotropic glossy lobe: per view cosine i / (COSINES − 1),
    each lookup's ψ (radians from n toward the mirror side), its layer in the stack (an index of
    `PrefilteredStack.layers`) and its weight; None where the lobe is not fitted (`fits`).
    `rule`: the lobe's split-sum rule where the caller has it."""
    rule = lobe.model.split_sum(lobe.params) if rule is None else rule
    if not fits(lobe, rule):
        return None
    targets = lobe_targets(lobe)
    table = np.stack([fit_view(t, rule.kernel, i == COSINES - 1) for i, t in enumerate(targets)])
    table[..., 1] = np.where(table[..., 2] > 0.0, table[..., 1] + layer_of(rule.kernel, 0), 0.0)
    return table


def mixture_directions(psi: np.ndarray, normal: np.ndarray, toward_view: np.ndarray) -> np.ndarray:
    """World directions at angles ψ from `normal` away from the view (`toward_view`: the unit
    tangent toward the view's projection on the surface)."""
    return np.cos(psi)[..., None] * normal - np.sin(psi)[..., None] * toward_view
