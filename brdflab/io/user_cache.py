"""The user's cache folder: work the lab can redo but need not (simulated tables, fits made
on the way out of an export). `BRDFLAB_CACHE` moves it; by default ~/.cache/brdflab.

Entries are written atomically (io/atomic.py), so concurrent processes never read half an
entry; a reader that finds an entry it cannot use recomputes it and writes it again.
"""

from __future__ import annotations

import os
from pathlib import Path


def cache_folder(kind: str) -> Path:
    """The folder of one kind of cached work (it may not exist yet)."""
    return Path(os.environ.get("BRDFLAB_CACHE") or Path.home() / ".cache" / "brdflab") / kind
