"""Export a material or stored fit in formats other tools read."""

from __future__ import annotations

import os
from pathlib import Path

from brdflab.errors import BRDFLabError

FORMATS = ("merl", "brdf-explorer", "glsl")


def export_source(source, fmt: str, path: str | os.PathLike, origin: Path | None = None) -> None:
    """Write `source` to `path` in format `fmt` (one of FORMATS), atomically; errors about
    the source name `origin`, the file it came from."""
    from brdflab.io.atomic import atomic_write

    path = Path(path)
    if fmt == "merl":
        from brdflab.export.merl import export_merl

        export_merl(source, path)
    elif fmt in ("glsl", "brdf-explorer"):
        from brdflab.export.brdf_explorer import brdf_explorer_file
        from brdflab.export.glsl import glsl_function
        from brdflab.material.analytic import AnalyticMaterial

        if not isinstance(source, AnalyticMaterial):
            raise BRDFLabError(f"{fmt} export needs an analytic material or a stored fit (--fitting K)", origin or path)
        text = glsl_function(source) if fmt == "glsl" else brdf_explorer_file(source)
        atomic_write(path, text.encode())
    else:
        raise BRDFLabError(f"unknown export format {fmt!r}; one of {', '.join(FORMATS)}", path)
