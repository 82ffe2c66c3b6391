"""The fitter's non-negative least squares, batched over channels and perturbations."""

import numpy as np
import pytest
from scipy.optimize import nnls as scipy_nnls

from brdflab.fitting.nnls import SUBSETS_UP_TO, nnls_normal


def _problems(rng, n, count, collinear=False):
    A = rng.random((count, 300, n))
    if collinear and n > 1:
        A[:, :, 1] = A[:, :, 0] * (1.0 + 1e-4 * rng.random((count, 300)))  # two nearly identical lobes
    y = np.einsum("cmn,cn->cm", A, rng.normal(size=(count, n))) + 0.1 * rng.normal(size=(count, 300))
    return A, y


@pytest.mark.parametrize("n", [1, 2, 3, 4, SUBSETS_UP_TO + 1])
@pytest.mark.parametrize("collinear", [False, True])
def test_every_batch_member_is_scipys_minimum(n, collinear):
    """Each problem of a batch ends at SciPy's NNLS minimum (the objective to rounding), with
    s ≥ 0, whether its supports are enumerated or (more unknowns) it is solved by active sets."""
    rng = np.random.default_rng(n + 10 * collinear)
    A, y = _problems(rng, n, 24, collinear)
    G, b = np.einsum("cmn,cmk->cnk", A, A), np.einsum("cmn,cm->cn", A, y)
    s = nnls_normal(G.reshape(4, 6, n, n), b.reshape(4, 6, n)).reshape(24, n)
    assert (s >= 0).all() and s.shape == (24, n)
    for k in range(24):
        ref = scipy_nnls(A[k], y[k])[0]
        f = lambda x: x @ G[k] @ x - 2 * b[k] @ x
        assert f(s[k]) <= f(ref) + 1e-12 * abs(f(ref))


def test_a_zero_or_useless_row_gets_scale_zero_and_a_singular_member_does_not_spoil_the_others():
    G = np.array([[[1.0, 0.0], [0.0, 1.0]], [[0.0, 0.0], [0.0, 0.0]], [[2.0, 1.0], [1.0, 2.0]]])
    b = np.array([[1.0, -3.0], [0.0, 0.0], [np.nan, 1.0]])
    s = nnls_normal(G, b)
    assert s[0] == pytest.approx([1.0, 0.0])  # the row that only makes it worse is dropped
    assert (s[1] == 0.0).all()  # nothing to fit: zero
    assert np.isfinite(s).all()
