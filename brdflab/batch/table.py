"""The results table of a batch: one row per (source, lobe set, options), kept as CSV and
Parquet in the output folder and rewritten atomically whenever results arrive. Batches that
share an output folder take turns (a lock), and each save first takes in the rows the
others saved, so that no run's rows are lost."""

from __future__ import annotations

import io
from pathlib import Path

import pandas as pd

from brdflab.batch.tasks import stored_key
from brdflab.errors import BRDFLabError
from brdflab.io.atomic import atomic_write

COLUMNS = ["source", "material", "lobes", "combination", "metric", "error", "image_error", "parameters", "seconds",
           "iterations", "evaluations", "status", "message", "worker", "pid", "sha256", "options", "key"]
ADDED_LATER = {"image_error"}  # a table saved before it has no such column: read as unknown (NaN)
TEXT_COLUMNS = ["source", "material", "lobes", "combination", "metric", "parameters", "status", "message", "worker",
                "sha256", "options", "key"]
CSV_NAME, PARQUET_NAME = "results.csv", "results.parquet"


class ResultsTable:
    """Rows by pair key; a new row for a key replaces the old one."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.rows: dict[str, dict] = {}
        self.changed: set[str] = set()  # keys this process updated: they win over the saved rows

    @classmethod
    def load(cls, folder: Path) -> "ResultsTable":
        """The table a previous run left in `folder` (the CSV is the record), or an empty one."""
        table = cls(folder)
        table.rows = _saved_rows(folder)
        return table

    def is_done(self, key: str, sha256: str) -> bool:
        """A pair with a result for the same file content (failed rows are retried)."""
        row = self.rows.get(key)
        return row is not None and row["status"] != "failed" and row["sha256"] == sha256 and sha256 != ""

    def update(self, rows: list[dict]) -> None:
        for row in rows:
            self.rows[row["key"]] = {c: row.get(c) for c in COLUMNS}
            self.changed.add(row["key"])

    def merge_saved(self) -> None:
        """Take in the rows another batch saved in the folder since (call under `folder_lock`)."""
        self.rows = {**_saved_rows(self.folder), **{k: self.rows[k] for k in self.changed}}

    def frame(self) -> pd.DataFrame:
        frame = pd.DataFrame(list(self.rows.values()), columns=COLUMNS)
        return frame.sort_values(["material", "source", "lobes", "options"], kind="stable").reset_index(drop=True)

    def save(self) -> None:
        """Parquet first, then the CSV (the record a rerun reads): each through a temp file and a
        rename (call under `folder_lock`, after `merge_saved`)."""
        frame = self.frame()
        parquet = io.BytesIO()
        frame.to_parquet(parquet, index=False)
        atomic_write(self.folder / PARQUET_NAME, parquet.getvalue())  # BRDFLabError names the file
        atomic_write(self.folder / CSV_NAME, frame.to_csv(index=False).encode())


def _saved_rows(folder: Path) -> dict[str, dict]:
    """The rows of the table saved in `folder` (the CSV is the record), by key; none if there is none."""
    path = folder / CSV_NAME
    if not path.exists():
        return {}
    try:
        frame = pd.read_csv(path, dtype={c: str for c in TEXT_COLUMNS}, keep_default_na=False)
        missing = set(COLUMNS) - set(frame.columns) - ADDED_LATER
        if missing:
            raise ValueError(f"missing columns {', '.join(sorted(missing))}")
        for column in ("error", *ADDED_LATER):
            frame[column] = pd.to_numeric(frame[column], errors="coerce") if column in frame else float("nan")
    except (ValueError, pd.errors.ParserError, UnicodeDecodeError) as e:
        raise BRDFLabError(f"not a batch results table: {e}", path) from None
    rows = frame[COLUMNS].to_dict("records")
    for row in rows:
        row["key"] = stored_key(row["key"])
    return {row["key"]: row for row in rows}
