"""Scrambled 2-D Sobol' points in NumPy alone.

The albedo check and the SH tables integrate with a fixed scrambled Sobol' set; SciPy's
generator (scipy.stats.qmc) costs about 0.4 s of import on every `brdflab fit`, so the
set is built here: Sobol's generator matrices for the first two dimensions (the identity
and Pascal's triangle mod 2), a random linear matrix scramble and a random digital shift,
as SciPy does. Both keep the (0, m, 2)-net property: every elementary box of area 2^-m
holds exactly one of the 2^m points.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

BITS = 52  # output digits: every point is exact in a float64


@lru_cache(maxsize=None)
def _generator_matrices(m: int) -> np.ndarray:
    """(2, BITS, m) binary matrices: row r is the output digit 2^-(r+1), column j input digit j."""
    C = np.zeros((2, BITS, m), np.int64)
    C[0, np.arange(m), np.arange(m)] = 1  # van der Corput
    r, j = np.meshgrid(np.arange(BITS), np.arange(m), indexing="ij")
    C[1] = (r & j) == r  # binom(j, r) is odd exactly when r's bits are a subset of j's (Lucas)
    return C


def scrambled_sobol(n_log2: int, seed: int) -> np.ndarray:
    """2^n_log2 points in [0, 1)², shape (2^n_log2, 2), the same for the same seed."""
    if not 0 <= n_log2 <= 30:
        raise ValueError(f"2^{n_log2} points: n_log2 must be 0..30")
    m = n_log2
    rng = np.random.default_rng(seed)
    index = np.arange(2**m, dtype=np.int64)
    digits = (index[:, None] >> np.arange(m)) & 1  # (n, m), least significant first
    out = np.empty((2**m, 2))
    weights = 0.5 ** np.arange(1, BITS + 1)
    for d, C in enumerate(_generator_matrices(m)):
        x = (digits @ C.T) % 2  # (n, BITS) output digits
        scramble = np.tril(rng.integers(0, 2, size=(BITS, BITS)), -1) + np.eye(BITS, dtype=np.int64)
        y = (x @ scramble.T) % 2  # lower triangular, unit diagonal: a bijection on each digit prefix
        y ^= rng.integers(0, 2, size=BITS)  # digital shift
        out[:, d] = y @ weights
    return out
