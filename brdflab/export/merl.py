"""Export any BRDF source as a MERL `.binary` table, so MERL-capable renderers can use it."""

from __future__ import annotations

import os

from brdflab.errors import BRDFLabError
from brdflab.sources.measured import MeasuredTable, tabulate, write_merl_binary


def export_merl(source, path: str | os.PathLike) -> MeasuredTable:
    """Tabulate `source` on MERL's (θh, θd, φd) bins and write it atomically to `path`.

    A grey (1-channel) source is repeated into RGB, since MERL files always hold three.
    """
    table = source if isinstance(source, MeasuredTable) else tabulate(source, name="exported")
    if table.n_channels == 1:
        table = MeasuredTable(table.values.repeat(3, axis=0), table.valid, table.name, table.source_type)
    elif table.n_channels != 3:
        raise BRDFLabError(f"MERL export needs 1 or 3 channels, the source has {table.n_channels}", path)
    write_merl_binary(table, path)
    return table
