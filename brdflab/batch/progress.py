"""A one-line progress bar on a terminal: tasks done, failures, elapsed and remaining time."""

from __future__ import annotations

import sys
import time
from typing import TextIO


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


class Progress:
    """Redraws in place at most ten times a second, and only when the stream is a terminal."""

    def __init__(self, total: int, stream: TextIO | None = None, width: int = 30) -> None:
        self.total, self.width = total, width
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty()
        self.done = self.failed = 0
        self.t0 = time.perf_counter()
        self._drawn = 0.0

    def line(self) -> str:
        elapsed = time.perf_counter() - self.t0
        fraction = self.done / self.total if self.total else 1.0
        bar = "#" * int(fraction * self.width)
        eta = elapsed / self.done * (self.total - self.done) if self.done else float("nan")
        eta_text = _clock(eta) if self.done else "?"
        return (f"[{bar:<{self.width}}] {self.done}/{self.total} done, {self.failed} failed, "
                f"{_clock(elapsed)} elapsed, {eta_text} left")

    def update(self, done: int, failed: int) -> None:
        self.done += done
        self.failed += failed
        now = time.perf_counter()
        if self.enabled and (now - self._drawn > 0.1 or self.done == self.total):
            self._drawn = now
            print("\r" + self.line(), end="", file=self.stream, flush=True)

    def close(self) -> None:
        if self.enabled:
            print("\r" + self.line(), file=self.stream, flush=True)
