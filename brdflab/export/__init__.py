"""Export a material or stored fit in formats other tools read."""

from __future__ import annotations

import os
from pathlib import Path

from brdflab.errors import BRDFLabError, shown_path
from brdflab.io.atomic import atomic_write, check_writable

# the renderers' family: the source goes out as Disney's principled parameters (export/principled.py)
PRINCIPLED_FORMATS = ("mitsuba", "mtlx", "gltf")
FORMATS = ("merl", "brdf-explorer", "glsl", *PRINCIPLED_FORMATS)
# the names a format's file may have (what reads it goes by the name), and the line that says so
NAMES = {
    "merl": ((".binary",), "a MERL export is named .binary (the name MERL's readers take)"),
    "brdf-explorer": ((".brdf",), "a BRDF Explorer export is named .brdf (the files BRDF Explorer opens)"),
    "glsl": ((".glsl",), "a GLSL export is named .glsl"),
    "mitsuba": ((".xml",), "a Mitsuba export is named .xml (the scene; its map goes beside it as NAME_env.exr)"),
    "mtlx": ((".mtlx",), "a MaterialX export is named .mtlx"),
    # the container follows the name (.glb binary, .gltf JSON): another name says neither
    "gltf": ((".gltf", ".glb"), "a glTF export is named .gltf (JSON, buffer embedded) or .glb (binary)"),
}
SUFFIXES = {fmt: suffixes[0][1:] for fmt, (suffixes, _) in NAMES.items()}  # the default of each


def check_destination(fmt: str, path: Path, origin: Path | None = None) -> None:
    """Refuse in one line, before any work, an export that no reader would open or that would
    lose a file: a name that does not say the format, the source itself (`origin`, also through
    a link or another spelling of its path), a folder that cannot take the file, a Mitsuba map
    that would replace a file other than the map of the scene being replaced."""
    if fmt not in NAMES:
        raise BRDFLabError(f"unknown export format {fmt!r}; one of {', '.join(FORMATS)}", path)
    suffixes, rule = NAMES[fmt]
    if path.suffix.lower() not in suffixes:
        raise BRDFLabError(rule, path)
    if origin is not None and _same_file(path, origin):
        raise BRDFLabError("it is the file being exported: an export never replaces its source (choose another "
                           "--out)", path)
    for kind, named in files_read_by(origin):
        if _same_file(path, named):
            raise BRDFLabError(f"it is the {kind} that the material being exported reads: an export never replaces "
                               "what its source reads (choose another --out)", path)
    check_writable(path)
    if fmt == "mitsuba":
        from brdflab.export.mitsuba import check_map_destination

        check_map_destination(path)


def stored_principled(origin: Path, source) -> int | None:
    """The index of the first stored fit of the XML material `origin` that is exactly one
    Principled lobe, when `source` itself is not one; else None."""
    from brdflab.export.principled import exact_principled

    if exact_principled(source) is not None or origin.suffix.lower() != ".xml":
        return None
    from brdflab.io.xmlio import load

    for k, fitting in enumerate(load(origin).fittings):
        if exact_principled(fitting.material) is not None:
            return k
    return None


def files_read_by(origin: Path | None) -> list[tuple[str, Path]]:
    """The files an XML material reads besides itself: its measured data and the model files
    of its lobes and stored fits, as (what it is, path); none for anything else."""
    if origin is None or origin.suffix.lower() != ".xml" or not origin.is_file():
        return []
    from brdflab.io.xmlio import MeasuredReference, load
    from brdflab.material.analytic import AnalyticMaterial

    try:
        doc = load(origin)
    except BRDFLabError:
        return []  # what cannot be read is refused, in its own words, when the export reads it
    read = [("measured data file", doc.material.path)] if isinstance(doc.material, MeasuredReference) else []
    materials = [doc.material, *(f.material for f in doc.fittings)]
    for material in materials:
        if isinstance(material, AnalyticMaterial):
            read += [("model file", lobe.model.origin.path) for lobe in material.lobes
                     if getattr(lobe.model, "origin", None) is not None]
    return read


def _same_file(a: Path, b: Path) -> bool:
    """Whether two paths name one file (links followed); a path with nothing there is no file."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def export_source(source, fmt: str, path: str | os.PathLike, origin: Path | None = None, env=None,
                  cancel=None) -> list[str]:
    """Write `source` to `path` in format `fmt` (one of FORMATS), atomically; errors about
    the source name `origin`, the file it came from. Returns what the export could not carry
    (one line each, with the error it costs). `env`: the map of a Mitsuba scene (default: the
    shipped one); `cancel` (an Event) stops a fit on the way out, and nothing is written.
    The destination is checked first (`check_destination`)."""
    path = Path(path)
    check_destination(fmt, path, origin)
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
        return _export_principled(source, fmt, path, origin, env, cancel)
    return []


def export_name(source, path: Path, origin: Path | None) -> str:
    """What an exported material is called: the source's own name; a fit's (every fit is
    FIT_NAME, which says nothing) is the stem of the file it came from, else of the export."""
    from brdflab.fitting.lm import FIT_NAME

    name = getattr(source, "name", None)
    return name if name and name != FIT_NAME else shown_path((origin or path).stem)  # a label: text, whatever the name


def _export_principled(source, fmt: str, path: Path, origin: Path | None, env, cancel) -> list[str]:
    from brdflab.export.principled import as_principled

    export = as_principled(source, fmt, cancel)
    if cancel is not None and cancel.is_set():
        raise BRDFLabError("export cancelled: nothing was written", path)
    if export.fitted_now and fmt != "mtlx":
        from brdflab.export.materialx import materialx_losses

        materialx_losses(export)  # weighed (and cached) while the fit is made: a later export in any format reads them
    name = export_name(source, path, origin)
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


def run_export(source, fmt: str, path: str, env, origin: Path | None, messages, cancel) -> None:
    """An export in a worker process (the window's File → Export; `origin`: the document's
    file): reports ("finished", warnings) or ("failed", message) on `messages`, as the
    window's child jobs do."""
    messages.put(("started", 0))
    try:
        messages.put(("finished", export_source(source, fmt, path, origin=origin, env=env, cancel=cancel)))
    except BRDFLabError as e:
        messages.put(("failed", str(e)))
    except OSError as e:
        messages.put(("failed", f"{path}: cannot write: {e.strerror}"))
