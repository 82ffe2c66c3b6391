"""Choosing an environment map's layout and the halves of a dual-paraboloid pair in the
window: the Open dialog takes one map or both halves of a pair, and the object view's
"map layout" asks for a missing back half."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import QFileDialog, QWidget

from brdflab.errors import BRDFLabError
from brdflab.lighting.probes import pair_path

MAP_FILTER = "HDR maps (*.hdr *.exr)"
LAYOUT_TIP = ("How the map's texels cover the sphere. auto: a square image holding a disk with a dark surround "
              "is an angular light probe, a square NAME-front / NAME-back beside its other half a dual-paraboloid "
              "pair, anything else lat-long. To open a pair, select both halves in Open environment.")


def front_and_back(names: list[str]) -> tuple[Path, Path | None]:
    """The map (or front half) and back half chosen in the Open dialog: one file, or the two
    halves of a pair (told apart by the words front / back in their names, else in the order given)."""
    paths = [Path(n) for n in names]
    if len(paths) == 1:
        return paths[0], None
    if len(paths) != 2:
        raise BRDFLabError(f"choose one map or the two halves of a dual-paraboloid pair, not {len(paths)} files")
    named = pair_path(paths[0])
    if named is not None and paths[1] in named:
        return named
    if "back" in paths[0].stem.lower() and "back" not in paths[1].stem.lower():
        return paths[1], paths[0]
    return paths[0], paths[1]


def ask_back_half(parent: QWidget, front: Path) -> Path | None:
    """The back half of the pair whose front is `front`, chosen by the user; None when a
    file named like it with front and back swapped holds it (the loader finds it) or when
    the user cancels (`front` holds both halves side by side)."""
    if pair_path(front) is not None:
        return None
    name, _ = QFileDialog.getOpenFileName(parent, f"Back half of the pair whose front is {front.name} "
                                          "(cancel: it holds both halves side by side)", str(front.parent), MAP_FILTER)
    return Path(name) if name else None
