"""A fitting pass computes each chunk's half vectors once for all of its lobe evaluations
(geometry.vec.shared_half_vectors): every built-in model must give exactly what it gives alone."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.geometry.vec import half_vector, shared_half_vectors
from brdflab.models.registry import all_models, get_model


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


def perturbed_rows(model, rng) -> list[dict]:
    """A fitting pass's evaluations of one lobe: its parameters (the defaults and its starts)
    and each of them moved by a finite-difference step, in a random order."""
    rows = []
    for p in [model.defaults(), *[{**model.defaults(), **s} for s in model.starts[:3]]]:
        rows.append(p)
        for q in model.parameters:
            step = 1e-5 if p[q.name] + 1e-5 <= q.upper else -1e-5
            rows.append({**p, q.name: p[q.name] + step})
    return [rows[k] for k in rng.permutation(len(rows))]


def test_a_fitting_pass_of_any_model_equals_its_evaluations_alone():
    """Terms that a perturbation leaves as they were are shared within a pass (Cook–Torrance's
    masking and Fresnel weight, its D·G when F0 moves; Principled's terms): every value must
    still be what an evaluation alone gives, bit for bit, so that no fit moves."""
    wi, wo = directions(3000, 4)
    rng = np.random.default_rng(5)
    for model in all_models():
        rows = perturbed_rows(model, rng)
        alone = [model.evaluate(wi, wo, p) for p in rows]
        with shared_half_vectors():
            shared = [model.evaluate(wi, wo, p) for p in rows]
        for p, a, s in zip(rows, alone, shared):
            np.testing.assert_array_equal(s, a, err_msg=f"{model.name} {p}")


@pytest.mark.parametrize("name, distribution", [("CookTorrance", "beckmann_d"), ("CookTorranceGGX", "ggx_d")])
def test_a_fresnel_step_does_not_compute_the_distribution_again(monkeypatch, name, distribution):
    """Within a pass, the lobe at F0 + step reuses D·G of the lobe at F0 (the same m)."""
    import brdflab.models.cook_torrance as ct

    calls = []
    original = getattr(ct, distribution)
    monkeypatch.setattr(ct, distribution, lambda *a: calls.append(a[1]) or original(*a))
    model = get_model(name)
    wi, wo = directions(500, 6)
    with shared_half_vectors():
        for p in ({"m": 0.2, "F0": 0.05}, {"m": 0.2, "F0": 0.05 + 1e-5}, {"m": 0.2 + 1e-5, "F0": 0.05}):
            model.evaluate(wi, wo, p)
    assert calls == [0.2, 0.2 + 1e-5]


def test_a_parameter_given_per_sample_is_evaluated_not_shared():
    """A pass may hold a lobe whose parameter is an array (one value per sample): `shared_term`
    computes such a term each time instead of keying a cache by it, and a 0-d array shares as
    its number."""
    wi, wo = directions(400, 7)
    rng = np.random.default_rng(8)
    for name, param in (("CookTorrance", "m"), ("CookTorranceGGX", "m"), ("Principled", "roughness")):
        model = get_model(name)
        varying = {param: rng.uniform(0.1, 0.6, 400)}
        alone = [model.evaluate(wi, wo, varying), model.evaluate(wi, wo, {param: 0.3})]
        with shared_half_vectors():
            shared = [model.evaluate(wi, wo, varying), model.evaluate(wi, wo, {param: np.array(0.3)}),
                      model.evaluate(wi, wo, {param: 0.3})]
        np.testing.assert_array_equal(shared[0], alone[0], err_msg=name)
        np.testing.assert_array_equal(shared[1], alone[1], err_msg=name)
        np.testing.assert_array_equal(shared[2], alone[1], err_msg=name)
