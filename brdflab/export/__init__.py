"""Export a material or stored fit in formats other tools read."""

from __future__ import annotations

import os
from pathlib import Path

from brdflab.errors import BRDFLabError

# the renderers' family: the source goes out as Disney's principled parameters (export/principled.py)
PRINCIPLED_FORMATS = ("mitsuba", "mtlx", "gltf")
FORMATS = ("merl", "brdf-explorer", "glsl", *PRINCIPLED_FORMATS)
SUFFIXES = {"merl": "binary", "brdf-explorer": "brdf", "glsl": "glsl", "mitsuba": "xml", "mtlx": "mtlx", "gltf": "gltf"}


def export_source(source, fmt: str, path: str | os.PathLike, origin: Path | None = None, env=None,
                  cancel=None) -> list[str]:
    """Write `source` to `path` in format `fmt` (one of FORMATS), atomically; errors about
    the source name `origin`, the file it came from. Returns what the export could not carry
    (one line each, with the error it costs). `env`: the map of a Mitsuba scene (default: the
    shipped one); `cancel` (an Event) stops a fit on the way out, and nothing is written."""
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
    elif fmt in PRINCIPLED_FORMATS:
        return _export_principled(source, fmt, path, env, cancel)
    else:
        raise BRDFLabError(f"unknown export format {fmt!r}; one of {', '.join(FORMATS)}", path)
    return []


def _export_principled(source, fmt: str, path: Path, env, cancel) -> list[str]:
    from brdflab.export.principled import as_principled

    if fmt == "gltf" and path.suffix.lower() not in (".gltf", ".glb"):
        # the container follows the name (.glb binary, .gltf JSON): another name says neither
        raise BRDFLabError("a glTF export is named .gltf (JSON, buffer embedded) or .glb (binary)", path)
    export = as_principled(source, fmt, cancel)
    if cancel is not None and cancel.is_set():
        raise BRDFLabError("export cancelled: nothing was written", path)
    name = getattr(source, "name", None) or path.stem
    if fmt == "mitsuba":
        from brdflab.export.mitsuba import export_mitsuba
        from brdflab.io.resources import default_environment_path
        from brdflab.lighting.envmap import load_environment

        return export_mitsuba(export, path, env or load_environment(default_environment_path()), name)
    if fmt == "mtlx":
        from brdflab.export.materialx import export_materialx

        return export_materialx(export, path, name)
    from brdflab.export.gltf import export_gltf

    return export_gltf(export, path, name)


def run_export(source, fmt: str, path: str, env, messages, cancel) -> None:
    """An export in a worker process (the window's File → Export): reports ("finished",
    warnings) or ("failed", message) on `messages`, as the window's child jobs do."""
    messages.put(("started", 0))
    try:
        messages.put(("finished", export_source(source, fmt, path, env=env, cancel=cancel)))
    except BRDFLabError as e:
        messages.put(("failed", str(e)))
    except OSError as e:
        messages.put(("failed", f"{path}: cannot write: {e.strerror}"))
