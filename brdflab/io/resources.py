"""Where the shipped data lives: shaders/, materials/ and resources/.

In a source checkout they sit beside the package; an installed package carries them
as the sub-packages brdflab._shaders, brdflab._materials and brdflab._resources
(pyproject.toml maps the folders there).
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

from brdflab.errors import BRDFLabError

MODELS_ENV = "BRDFLAB_MODELS"  # the user's model folders, a path list (models/files/library.py)

_FOLDERS = {"shaders": "brdflab._shaders", "materials": "brdflab._materials", "resources": "brdflab._resources"}


def checkout_root() -> Path | None:
    """The source checkout this package runs from, or None when it is installed."""
    root = Path(__file__).resolve().parents[2]
    return root if (root / "pyproject.toml").is_file() and (root / "shaders").is_dir() else None


def shared_data_dir() -> Path | None:
    """The developers' real measured data (`<shared>/data`): $BRDFLAB_SHARED, else `../shared`
    next to the checkout; None when neither exists (a user's machine)."""
    if os.environ.get("BRDFLAB_SHARED"):
        shared = Path(os.environ["BRDFLAB_SHARED"])
    else:
        root = checkout_root()
        if root is None:
            return None
        shared = root.parent / "shared"
    data = shared / "data"
    return data if data.is_dir() else None


def data_dir(kind: str) -> Path:
    """The folder of shipped `kind` data ('shaders', 'materials' or 'resources')."""
    checkout = Path(__file__).resolve().parents[2] / kind
    if checkout.is_dir():
        return checkout
    spec = importlib.util.find_spec(_FOLDERS[kind])
    if spec is None or not spec.submodule_search_locations:
        raise FileNotFoundError(f"brdflab's {kind} folder is not installed")
    return Path(next(iter(spec.submodule_search_locations)))


def default_environment_path() -> Path:
    """The shipped CC0 map every view and command uses unless told otherwise."""
    return data_dir("resources") / "envmaps" / "venice_sunset_1k.hdr"


def shader_path(name: str) -> Path:
    return data_dir("shaders") / name


def example_materials() -> list[Path]:
    return sorted(data_dir("materials").glob("*.xml"))


EXAMPLE_PREFIX = "example:"


def example_names() -> dict[str, Path]:
    """Each shipped example material by its short name: the file's stem, or the stem's first
    word where that names one file alone (`fig2` for fig2_lambertian_lafortune.xml)."""
    paths = example_materials()
    first_words = [p.stem.split("_")[0] for p in paths]
    return {(word if first_words.count(word) == 1 else p.stem): p for word, p in zip(first_words, paths)}


def resolve_material(text: str) -> Path:
    """A material argument as a path: `example:NAME` names a shipped example (by its short
    name or its file's stem), anything else is a path."""
    if not text.startswith(EXAMPLE_PREFIX):
        return Path(text)
    name = text[len(EXAMPLE_PREFIX):]
    names = example_names()
    if name in names:
        return names[name]
    by_stem = {p.stem: p for p in names.values()}
    if name in by_stem:
        return by_stem[name]
    raise BRDFLabError(f"no shipped example named {name!r}; one of: {', '.join(sorted(names))} "
                       "(`brdflab examples` lists them)")
