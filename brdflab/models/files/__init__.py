"""Models read from files: BRDFLab's model descriptors (`.xml`) and BRDF Explorer's `.brdf`.

`read_model_file(path)` builds a `FileModel`; `brdflab.models.registry.add_file_model`
puts it beside the built-ins, and `library` finds the user's model folders.
"""

from __future__ import annotations

import re
from pathlib import Path

from brdflab.errors import BRDFLabError
from brdflab.io.bounded import read_bounded
from brdflab.models.files.limits import MAX_MODEL_BYTES
from brdflab.models.files.model import FileModel, Origin

SUFFIXES = (".brdf", ".xml")


def is_model_file(text: str) -> bool:
    """Whether a command-line argument names a model file (by its suffix)."""
    return Path(text).suffix.lower() in SUFFIXES


# what may stand before an XML document's root element: a BOM, space, the declaration and other
# processing instructions, comments (a licence), a DOCTYPE (with an internal subset)
_PROLOG = re.compile(rb"(?:\xef\xbb\xbf)?(?:\s+|<\?.*?\?>|<!--.*?-->|<!DOCTYPE(?:[^\[\]>]|\[[^\]]*\])*>)*", re.S)
_ROOT = re.compile(rb"<([A-Za-z_][\w.:-]*)")
DESCRIPTOR_ROOT = "AnalyticBRDFModel"


def root_element(head: bytes) -> str | None:
    """The name of an XML document's root element, if `head` (its first bytes) reaches it."""
    m = _ROOT.match(head, _PROLOG.match(head).end())
    return m.group(1).decode("ascii") if m else None


def read_model_bytes(path: str | Path) -> bytes:
    """A model file's bytes, refused in one line if it is not a regular file or too large."""
    return read_bounded(Path(path), MAX_MODEL_BYTES, "a model file")


def read_model_file(path: str | Path, name: str | None = None, data: bytes | None = None) -> FileModel:
    """The model a file defines (from `data` when its bytes are read already), by its
    format; BRDFLabError (one line naming the file)."""
    from brdflab.models.files import brdf_explorer, descriptor

    path = Path(path)
    data = read_model_bytes(path) if data is None else data
    if path.suffix.lower() == ".brdf":
        return brdf_explorer.read(path, data, name)
    if path.suffix.lower() == ".xml" or root_element(data) == DESCRIPTOR_ROOT:
        return descriptor.read(path, data, name)
    raise BRDFLabError("not a model file (a BRDF Explorer .brdf or a BRDFLab model descriptor .xml)", path)


__all__ = ["FileModel", "Origin", "SUFFIXES", "is_model_file", "read_model_bytes", "read_model_file"]
