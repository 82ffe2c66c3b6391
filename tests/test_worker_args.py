"""Large arrays reach worker processes through shared memory (gui/background.py)."""

import multiprocessing
import pickle
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import shared_memory

import numpy as np
import pytest

from brdflab.gui.background import SHARED_BYTES, Packed, submit


def _checksum(table, small, label):
    return float(table.sum()), small.tolist(), label, table.flags.writeable


def test_large_arrays_travel_by_name_and_arrive_whole():
    table = np.random.default_rng(0).random((90, 90, 180, 3))[:, ::2]  # 17 MB, not contiguous
    small = np.arange(5)
    packed = Packed((table, small, "brass"))
    try:
        assert len(packed.payload) < 4096  # the table is not in the pickle …
        assert len(packed.segments) == 1 and packed.segments[0].size >= table.nbytes  # … but in shared memory
        back = pickle.loads(packed.payload)
        np.testing.assert_array_equal(back[0], table)
        np.testing.assert_array_equal(back[1], small)
        assert back[2] == "brass" and back[0].flags.writeable
    finally:
        name = packed.segments[0].name
        packed.release()
        packed.release()  # twice is harmless (a job's end and a window's close may both)
    with pytest.raises(FileNotFoundError):
        shared_memory.SharedMemory(name=name)


def test_a_worker_process_gets_the_same_arrays():
    table = np.linspace(0.0, 1.0, SHARED_BYTES // 8 + 1000)
    with ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn")) as pool:
        total, small, label, writeable = submit(pool, _checksum, table, np.arange(3), "x").result(timeout=120)
    assert total == pytest.approx(float(table.sum()), rel=1e-12)
    assert small == [0, 1, 2] and label == "x" and writeable


def test_without_room_in_shared_memory_arrays_go_through_the_pipe(monkeypatch):
    import os

    class Full:
        f_bavail, f_frsize = 10, 4096

    monkeypatch.setattr(os, "statvfs", lambda path: Full())
    table = np.ones(SHARED_BYTES)
    packed = Packed((table,))
    assert packed.segments == [] and len(packed.payload) > table.nbytes
    np.testing.assert_array_equal(pickle.loads(packed.payload)[0], table)
