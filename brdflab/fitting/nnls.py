"""Non-negative least squares for the fitter's tiny problems (one unknown per lobe).

Lawson & Hanson's active-set method (1974, ch. 23), as scipy.optimize.nnls: importing
SciPy's optimiser costs about 0.4 s, several times the whole fit of a slice.
"""

from __future__ import annotations

import numpy as np


def nnls(A: np.ndarray, y: np.ndarray, max_iterations: int | None = None) -> np.ndarray:
    """argmin ‖A s − y‖ subject to s ≥ 0, for A of shape (m, n) with small n."""
    m, n = A.shape
    s = np.zeros(n)
    passive = np.zeros(n, bool)
    gradient = A.T @ (y - A @ s)
    tol = 10.0 * np.finfo(float).eps * max(np.abs(A).sum(axis=0).max(initial=0.0), 1.0) * max(m, n)
    for _ in range(max_iterations or 3 * n):
        free = ~passive & (gradient > tol)
        if not free.any():
            break
        passive[np.argmax(np.where(free, gradient, -np.inf))] = True
        while True:  # solve on the passive set; step back while a variable turns non-positive
            z = np.zeros(n)
            z[passive] = np.linalg.lstsq(A[:, passive], y, rcond=None)[0]
            if (z[passive] > 0).all():
                s = z
                break
            blocked = passive & (z <= 0)
            gap = s[blocked] - z[blocked]  # > 0, or 0 for a variable at 0 that stays there
            alpha = np.min(np.where(gap > 0, s[blocked] / np.where(gap > 0, gap, 1.0), 0.0))
            s = s + alpha * (z - s)
            passive &= s > tol
            s[~passive] = 0.0
        gradient = A.T @ (y - A @ s)
    return s


SUBSETS_UP_TO = 6  # unknowns up to which `nnls_normal` tries every support (2⁶ − 1 batched solves)


def nnls_normal(G: np.ndarray, b: np.ndarray) -> np.ndarray:
    """argmin sᵀ G s − 2 bᵀ s subject to s ≥ 0, for a batch of small problems given by their
    normal equations: G (..., n, n) positive semidefinite, b (..., n) → s (..., n).

    The minimum is the unconstrained minimum on its own support, with every entry positive;
    and any such point is feasible, so the minimum is the cheapest of them over all supports
    (its cost there is −b_S·s_S). One batched solve per support serves every problem at once:
    the fitter solves one per channel and finite-difference perturbation in every pass, and
    one active-set run each cost a tenth of an image metric fit's time. A tiny ridge (1e-13 of
    the trace) keeps collinear rows solvable, as `lm._nnls`'s Cholesky does."""
    shape = np.shape(b)
    n = shape[-1]
    G, b = np.asarray(G, float).reshape(-1, n, n), np.asarray(b, float).reshape(-1, n)
    if n > SUBSETS_UP_TO:
        return np.array([_nnls_gram(g, v) for g, v in zip(G, b)]).reshape(shape)
    G = G + (1e-13 * np.maximum(np.trace(G, axis1=1, axis2=2), 1e-300))[:, None, None] * np.eye(n)
    best, best_cost = np.zeros(b.shape), np.zeros(len(b))  # s = 0 costs 0
    for support in range(1, 1 << n):
        S = [i for i in range(n) if support >> i & 1]
        GS, bS = G[:, S][:, :, S], b[:, S]
        try:
            s = np.linalg.solve(GS, bS[..., None])[..., 0]
        except np.linalg.LinAlgError:  # a singular member stops the batch: each solved alone
            s = np.stack([_solve_or_nan(g, v) for g, v in zip(GS, bS)])
        with np.errstate(invalid="ignore"):
            cost = -(bS * s).sum(-1)
            better = np.all(s > 0.0, axis=-1) & (cost < best_cost)
        best[better] = 0.0
        best[np.ix_(np.flatnonzero(better), S)] = s[better]
        best_cost[better] = cost[better]
    return best.reshape(shape)


def _solve_or_nan(G: np.ndarray, b: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.solve(G, b)
    except np.linalg.LinAlgError:
        return np.full(b.shape, np.nan)


def _nnls_gram(G: np.ndarray, b: np.ndarray) -> np.ndarray:
    """One problem of `nnls_normal` by the active-set method (more unknowns than supports pay)."""
    n = G.shape[0]
    jitter = 1e-13 * max(np.trace(G), 1e-300)
    try:
        R = np.linalg.cholesky(G + jitter * np.eye(n)).T
    except np.linalg.LinAlgError:
        return np.zeros(n)
    return nnls(R, np.linalg.solve(R.T, b), max_iterations=50 * n)
