"""Pareto fronts of (cost, error) points, and where more cost stops paying.

A point is on the front when no other point is at most as costly and at most as wrong,
and better in one of the two. The "enough" point of a front is its cheapest point whose
error is within a tolerance of the best error: beyond it, more time, lobes or parameters
buy less than that tolerance.
"""

from __future__ import annotations

import numpy as np


def pareto_front(cost, error) -> np.ndarray:
    """Indices of the points on the front, from cheapest to most accurate (ties in cost:
    the lowest error only; exact duplicates: the first)."""
    cost, error = np.asarray(cost, float), np.asarray(error, float)
    order = np.lexsort((error, cost))  # by cost, then by error
    sorted_error = error[order]
    best_before = np.concatenate([[np.inf], np.minimum.accumulate(sorted_error)[:-1]])
    return order[sorted_error < best_before].astype(int)


def enough_point(cost, error, tolerance: float = 0.05) -> int:
    """Index of the cheapest point (of equally cheap ones, the most accurate) whose error
    is within `tolerance` (relative) of the lowest error: where paying more stops paying."""
    cost, error = np.asarray(cost, float), np.asarray(error, float)
    good = np.flatnonzero(error <= (1.0 + tolerance) * error.min())
    return int(good[np.lexsort((error[good], cost[good]))[0]])


def gain(simpler: float, richer: float) -> float:
    """The relative error reduction bought by a richer configuration (negative: worse)."""
    return 1.0 - richer / simpler if simpler > 0 else 0.0
