"""The Qt binding must keep Python's reference counts. PySide6 6.12.0 on Python 3.11 drops a
reference to None on every call of a method that returns nothing (`update()`, `setText()`,
`processEvents()` …), so the window aborted with "none_dealloc" after seconds of use.
pyproject.toml pins below it; this test catches a binding that does it again."""

import sys

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QLabel

CALLS = 3000


def _none_refs_lost(call) -> int:
    before = sys.getrefcount(None)
    for _ in range(CALLS):
        call()
    return before - sys.getrefcount(None)


def test_void_methods_keep_none_alive(qapp):
    label, timer = QLabel(), QTimer()
    for name, call in (("update", label.update), ("setText", lambda: label.setText("x")), ("stop", timer.stop),
                       ("processEvents", qapp.processEvents)):
        lost = _none_refs_lost(call)
        assert lost < CALLS // 10, f"{name}(): {lost} references to None lost in {CALLS} calls (a broken Qt binding)"
