"""A map's prefiltered stack is built once and kept in the user's cache folder: a later process
(here: this one with its memory cache emptied) reads it back instead of building it again
(1.3–2 s, most of a cold Render Auto); a damaged entry is built again and rewritten, and an
unwritable cache folder only costs time."""

import numpy as np
import pytest

from brdflab.lighting import prefilter
from brdflab.lighting.envmap import EnvironmentMap


def a_map(seed: int = 1) -> EnvironmentMap:
    return EnvironmentMap(np.random.default_rng(seed).random((32, 64, 3)).astype(np.float32))


def as_a_new_process():
    prefilter._CACHE.clear()


@pytest.fixture(autouse=True)
def _memory_emptied():
    """Each test starts as a process that has built nothing (the user cache is empty too)."""
    as_a_new_process()
    yield
    as_a_new_process()


def stored(env: EnvironmentMap):
    return prefilter._stack_file(prefilter.map_key(env))


def test_a_stack_built_once_is_read_back_by_a_later_process():
    env = a_map()
    before = prefilter.stack_builds()
    first = prefilter.prefiltered_stack(env)
    assert prefilter.stack_builds() == before + 1 and stored(env).is_file()
    as_a_new_process()
    again = prefilter.prefiltered_stack(EnvironmentMap(env.data.copy()))
    assert prefilter.stack_builds() == before + 1  # read, not built
    np.testing.assert_array_equal(again.layers, first.layers)
    np.testing.assert_array_equal(again.lights, first.lights)
    assert again.key == first.key
    other = a_map(2)
    prefilter.prefiltered_stack(other)  # another map is another entry
    assert prefilter.stack_builds() == before + 2 and stored(other) != stored(env)


@pytest.mark.parametrize("damage", ["garbage", "truncated", "wrong-shape", "not-finite", "empty"])
def test_a_damaged_stack_entry_is_built_again_and_rewritten(damage):
    env = a_map()
    good = prefilter.prefiltered_stack(env)
    path = stored(env)
    if damage == "garbage":
        path.write_bytes(b"not an archive at all")
    elif damage == "truncated":
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    elif damage == "wrong-shape":
        np.savez(path.with_suffix(".tmp.npz"), layers=good.layers[:3], lights=good.lights)
        path.with_suffix(".tmp.npz").replace(path)
    elif damage == "not-finite":
        layers = good.layers.copy()
        layers[0, 0, 0, 0] = np.nan
        np.savez(path.with_suffix(".tmp.npz"), layers=layers, lights=good.lights)
        path.with_suffix(".tmp.npz").replace(path)
    else:
        path.write_bytes(b"")
    as_a_new_process()
    before = prefilter.stack_builds()
    again = prefilter.prefiltered_stack(env)
    assert prefilter.stack_builds() == before + 1  # built again, never trusted
    np.testing.assert_array_equal(again.layers, good.layers)
    as_a_new_process()
    assert prefilter.read_stack(prefilter.map_key(env)) is not None  # and rewritten


def test_an_unwritable_cache_folder_only_costs_time(tmp_path, monkeypatch):
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file where the cache folder would be")
    monkeypatch.setenv("BRDFLAB_CACHE", str(blocker))
    env = a_map(3)
    stack = prefilter.prefiltered_stack(env)
    assert stack.layers.shape[0] == prefilter.STACK_LAYERS
    as_a_new_process()
    before = prefilter.stack_builds()
    prefilter.prefiltered_stack(env)
    assert prefilter.stack_builds() == before + 1
