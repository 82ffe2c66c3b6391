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
