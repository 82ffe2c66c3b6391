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
        if info.name not in {"base", "registry", "files"}:
            importlib.import_module(f"{__package__}.{info.name}")


class DuplicateModelName(BRDFLabError):
    """Two model files define one model name (never skipped like another bad file)."""


def is_builtin(model: LobeModel) -> bool:
    return model.origin is None


def add_file_model(model: LobeModel) -> LobeModel:
    """Put a model read from a file into the registry, beside the built-ins, and return the
    registered one.

    The same file again (same checksum) is the model already there; the same file path with
    new contents replaces it (an edited file). Two different files defining one model name
    are refused, naming both. A file model named like a built-in (BRDFLab's own Ward.xml)
    is kept beside it as "NAME [FILE]", so `Ward` stays the built-in."""
    name = model.name = registry_name(model)
    held = _MODELS.get(name)
    if held is not None:
        if held.origin.sha256 == model.origin.sha256:
            return held
        if held.origin.path != model.origin.path:
            raise DuplicateModelName(f"two model files define the model {model.xml_name!r}: {held.origin.path} and "
                               f"{model.origin.path} (rename one: a model's name must be unique)")
    _MODELS[name] = model
    return model


def registry_name(model: LobeModel) -> str:
    """The name a file model is registered under: its own, or "NAME [FILE]" where a built-in
    has its name."""
    held = _MODELS.get(model.name)
    return f"{model.name} [{model.origin.path.name}]" if held is not None and is_builtin(held) else model.name


def file_models() -> list[LobeModel]:
    return [m for m in all_models() if not is_builtin(m)]


def find_file_model(model_name: str, sha256: str | None = None) -> LobeModel | None:
    """A registered file model by the name a material gives it (and its checksum, if known)."""
    hits = [m for m in file_models() if m.xml_name == model_name]
    if sha256:
        exact = [m for m in hits if m.origin.sha256 == sha256]
        return exact[0] if exact else None
    return hits[0] if len(hits) == 1 else None


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
