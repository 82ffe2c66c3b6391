"""A fitting pass computes each chunk's half vectors once for all of its lobe evaluations
(geometry.vec.shared_half_vectors): every built-in model must give exactly what it gives alone."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.geometry.vec import half_vector, shared_half_vectors
from brdflab.models.registry import all_models


def directions(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(2, n, 3))
    v[..., 2] = np.abs(v[..., 2])
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    return v[0], v[1]


def test_every_model_is_unchanged_by_shared_half_vectors():
    wi, wo = directions(2000, 1)
    other_wi, other_wo = directions(2000, 2)
    for model in all_models():
        alone = model.evaluate(wi, wo)
        other_alone = model.evaluate(other_wi, other_wo)
        with shared_half_vectors():
            first = model.evaluate(wi, wo)
            again = model.evaluate(wi, wo)
            other = model.evaluate(other_wi, other_wo)  # new arrays: the shared value is not reused
        np.testing.assert_array_equal(first, alone, err_msg=model.name)
        np.testing.assert_array_equal(again, alone, err_msg=model.name)
        np.testing.assert_array_equal(other, other_alone, err_msg=model.name)


def test_shared_half_vectors_are_read_only_and_end_with_the_block():
    wi, wo = directions(10, 3)
    with shared_half_vectors():
        h = half_vector(wi, wo)
        assert half_vector(wi, wo) is h
        with pytest.raises(ValueError):
            h[0, 0] = 1.0
    assert half_vector(wi, wo) is not h and half_vector(wi, wo).flags.writeable
