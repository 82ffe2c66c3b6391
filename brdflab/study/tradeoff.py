"""Cost against error: the Pareto front of a set of measured methods, and the cheapest one
that reaches an error target. Plain functions over rows (dicts with a cost and an error
key), so every study part and the next issue's automatic choice read the trade-off one way.
"""

from __future__ import annotations

from collections.abc import Sequence


def pareto_front(rows: Sequence[dict], cost: str = "ms", error: str = "error") -> list[dict]:
    """The rows no other row beats on both cost and error (ties: the first kept), cheapest
    first. A row with error None (not measured) is never on the front."""
    ranked = sorted((r for r in rows if r.get(error) is not None), key=lambda r: (r[cost], r[error]))
    front: list[dict] = []
    for row in ranked:
        if not front or row[error] < front[-1][error]:
            front.append(row)
    return front


def cheapest_under(rows: Sequence[dict], target: float, cost: str = "ms", error: str = "error") -> dict | None:
    """The cheapest row whose error is at most `target`, or None when none reaches it."""
    good = [r for r in rows if r.get(error) is not None and r[error] <= target]
    return min(good, key=lambda r: (r[cost], r[error])) if good else None
