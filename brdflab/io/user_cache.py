"""The user's cache folder: work the lab can redo but need not (simulated tables, fits made
on the way out of an export, model files' checks). `BRDFLAB_CACHE` moves it; by default
~/.cache/brdflab.

Entries are written atomically (io/atomic.py), so concurrent processes never read half an
entry; a reader that finds an entry it cannot use recomputes it and writes it again.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
from pathlib import Path

from brdflab.errors import BRDFLabError
from brdflab.io.atomic import atomic_write


def cache_folder(kind: str) -> Path:
    """The folder of one kind of cached work (it may not exist yet)."""
    return Path(os.environ.get("BRDFLAB_CACHE") or Path.home() / ".cache" / "brdflab") / kind


@functools.lru_cache(maxsize=None)
def code_digest(*parts: str) -> str:
    """SHA-256 of the lab's own source that decides a cached result: `parts` are folders (every
    module under them) and modules of the package, as they are on disk, so a changed program
    never returns an old answer (a few hundred kB: milliseconds, once per process)."""
    import brdflab

    root = Path(brdflab.__file__).parent
    h = hashlib.sha256()
    for part in parts:
        where = root / part
        for path in sorted(where.rglob("*.py")) if where.is_dir() else [where]:
            h.update(path.relative_to(root).as_posix().encode())
            h.update(path.read_bytes())
    return h.hexdigest()


def entry_key(described: dict) -> str:
    """The key of an entry: a SHA-256 of what decides it (JSON, keys sorted)."""
    return hashlib.sha256(json.dumps(described, sort_keys=True, default=repr).encode()).hexdigest()


def read_entry(kind: str, key: str) -> dict | None:
    """The entry stored under `key`, or None when there is none or it is not a JSON object
    (a corrupt or foreign file is recomputed, never trusted)."""
    try:
        entry = json.loads((cache_folder(kind) / f"{key}.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return entry if isinstance(entry, dict) else None


def write_entry(kind: str, key: str, entry: dict) -> None:
    """Store `entry` under `key`, atomically; an unwritable cache only costs time."""
    store(cache_folder(kind) / f"{key}.json", json.dumps(entry).encode())


def store(path: Path, data: bytes) -> None:
    """Write a cache file atomically, making its folder; an unwritable cache only costs time."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, data)
    except (OSError, BRDFLabError):
        pass
