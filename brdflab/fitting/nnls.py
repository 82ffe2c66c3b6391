"""Non-negative least squares for the fitter's tiny problems (one unknown per lobe).

Lawson & Hanson's active-set method (1974, ch. 23), as scipy.optimize.nnls: importing
SciPy's optimiser costs about 0.4 s, several times the whole fit of a slice.
"""

from __future__ import annotations

import numpy as np


_EPS = float(np.finfo(float).eps)


def nnls(A: np.ndarray, y: np.ndarray, max_iterations: int | None = None) -> np.ndarray:
    """argmin ‖A s − y‖ subject to s ≥ 0, for A of shape (m, n) with small n.

    The choices (which variable enters, which are blocked) are made on Python floats: a fit
    solves hundreds of thousands of these (Auto: 412,000 on a slice), and NumPy's per-call cost
    on arrays of two to five numbers was most of their time. The arithmetic is NumPy's and
    LAPACK's as before, so every solution is the same to the last bit."""
    m, n = A.shape
    s = np.zeros(n)
    passive = [False] * n
    gradient = A.T @ (y - A @ s)
    tol = 10.0 * _EPS * max(float(np.abs(A).sum(axis=0).max(initial=0.0)), 1.0) * max(m, n)
    for _ in range(max_iterations or 3 * n):
        g = gradient.tolist()
        enter, most = -1, -np.inf  # the first free variable with the largest gradient above tol
        for j in range(n):
            if not passive[j] and g[j] > tol and g[j] > most:
                enter, most = j, g[j]
        if enter < 0:
            break
        passive[enter] = True
        while True:  # solve on the passive set; step back while a variable turns non-positive
            cols = [j for j in range(n) if passive[j]]
            z = np.zeros(n)
            z[cols] = np.linalg.lstsq(A[:, cols], y, rcond=None)[0]
            zl, sl = z.tolist(), s.tolist()
            if all(zl[j] > 0 for j in cols):
                s = z
                break
            # the largest step towards z that keeps every variable ≥ 0 (a gap of 0: no step)
            alpha = min(sl[j] / (sl[j] - zl[j]) if sl[j] - zl[j] > 0 else 0.0 for j in cols if zl[j] <= 0)
            s = s + alpha * (z - s)
            sl = s.tolist()
            for j in range(n):
                passive[j] = passive[j] and sl[j] > tol
            s[[j for j in range(n) if not passive[j]]] = 0.0
        gradient = A.T @ (y - A @ s)
    return s
