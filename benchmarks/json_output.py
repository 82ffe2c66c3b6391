"""The command line of a benchmark that measures once and may write its numbers as JSON."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path


def measure_and_write(measure: Callable[[], dict], doc: str) -> None:
    """Parse `--json PATH` (the description: the first line of `doc`), run `measure()` and write
    its result there if asked."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--json")
    args = ap.parse_args()
    result = measure()
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
