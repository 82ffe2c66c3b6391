"""Where the shipped data lives: shaders/, materials/ and resources/.

In a source checkout they sit beside the package; an installed package carries them
as the sub-packages brdflab._shaders, brdflab._materials and brdflab._resources
(pyproject.toml maps the folders there).
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

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


def shader_path(name: str) -> Path:
    return data_dir("shaders") / name


def example_materials() -> list[Path]:
    return sorted(data_dir("materials").glob("*.xml"))
