"""The one registry of lobe models. Importing this module imports every model module."""

from __future__ import annotations

import importlib
import pkgutil

from brdflab.errors import BRDFLabError
from brdflab.models.base import LobeModel

_MODELS: dict[str, LobeModel] = {}


def register(cls: type[LobeModel]) -> type[LobeModel]:
    """Class decorator: add a model (by its XML name) to the registry."""
    if cls.name in _MODELS:
        raise ValueError(f"model {cls.name!r} registered twice")
    _MODELS[cls.name] = cls()
    return cls


def _load_all() -> None:
    from brdflab.models import __path__ as pkg_path

    for info in sorted(pkgutil.iter_modules(pkg_path), key=lambda i: i.name):
        if info.name not in {"base", "registry"}:
            importlib.import_module(f"{__package__}.{info.name}")


def get_model(name: str) -> LobeModel:
    """The model called `name` (its XML name); BRDFLabError if there is none."""
    try:
        return _MODELS[name]
    except KeyError:
        known = ", ".join(sorted(_MODELS))
        raise BRDFLabError(f"unknown lobe model {name!r} (known: {known})") from None


def all_models() -> list[LobeModel]:
    return [ _MODELS[k] for k in sorted(_MODELS) ]


def model_names() -> list[str]:
    return sorted(_MODELS)


_load_all()
