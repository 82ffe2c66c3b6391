"""The user's model files: where they are looked for, and how they join the registry.

Model folders, in this order: the folder chosen in the GUI's settings, every folder in
`BRDFLAB_MODELS` (a path list, `:`-separated as PATH is), and `--models DIR` on the command
line. Every `.brdf` and BRDFLab descriptor `.xml` in them is read, checked (its GLSL
compiled and evaluated on probe pairs in a child process with a time limit; its formula
evaluated) and registered beside the built-ins. A bad file in a folder is reported in one
line and skipped; a bad file named on its own (a lobe, a material argument, "Add model from
file…") is an error. A model is registered whole or not at all.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.io.bounded import kind_problem, outside_problem
from brdflab.io.resources import MODELS_ENV
from brdflab.models.files import (DESCRIPTOR_ROOT, SUFFIXES, is_model_file, read_model_bytes, read_model_file,
                                  root_element)
from brdflab.models.files.limits import MAX_MODEL_BYTES
from brdflab.models.files.model import FileModel
from brdflab.models.registry import (DuplicateModelName, add_file_model, file_models, find_file_model, model_names,
                                     registry_name)

MAX_FILES_PER_FOLDER = 1000
PROBE_PAIRS = 4096

Warn = Callable[[str], None]


def env_folders() -> list[Path]:
    return [Path(p) for p in os.environ.get(MODELS_ENV, "").split(os.pathsep) if p.strip()]


def model_files(folder: Path) -> list[Path]:
    """The model files in a folder (not its subfolders), by name."""
    if not folder.is_dir():
        raise BRDFLabError("no such model folder", folder)
    found = sorted(p for p in folder.iterdir() if p.suffix.lower() in SUFFIXES and p.is_file())
    if len(found) > MAX_FILES_PER_FOLDER:
        raise BRDFLabError(f"{len(found):,} model files (at most {MAX_FILES_PER_FOLDER:,} a folder)", folder)
    return [p for p in found if p.suffix.lower() == ".brdf" or is_descriptor(p)]


def is_descriptor(path: Path) -> bool:
    """Whether a file's root element is BRDFLab's <AnalyticBRDFModel> (a model, not a material),
    whatever comments (a licence) come before it; read a block at a time, at most a model file's
    size limit."""
    head = b""
    try:
        with open(path, "rb") as f:
            while len(head) < MAX_MODEL_BYTES:
                block = f.read(min(max(len(head), 4096), MAX_MODEL_BYTES - len(head)))
                if not block:
                    break
                head += block
                name = root_element(head)
                if name is not None:
                    return name == DESCRIPTOR_ROOT
    except OSError:
        return False
    return False


def check_model(model: FileModel) -> None:
    """Refuse a model whose values are unusable: its formula is undefined (NaN) at most probe
    pairs or negative at its defaults, or its GLSL does not compile, runs away, or is undefined
    or negative (child process). Where it is undefined at fewer, the model says so
    (`FileModel.undefined`, one warning)."""
    if model.formula is not None:
        wi, wo = probe_pairs(PROBE_PAIRS)
        values = model.formula_values(wi, wo, model.defaults())[:, None]
        problem = values_problem(values, wi, wo, "its <Equation>")
        if problem:
            raise BRDFLabError(problem, model.origin.path)
        model.note_undefined(undefined_where(values, wi, wo, "its <Equation>"))
    from brdflab.models.files.backend import glsl_evaluator

    glsl_evaluator().check(model)


UNDEFINED_SHARE = 0.5  # a model undefined at more of the probe pairs than this is no usable lobe


def values_problem(values: np.ndarray, wi: np.ndarray, wo: np.ndarray, what: str) -> str | None:
    """What is wrong with a model's values (N, channels) at probe pairs at its defaults: NaN or
    infinity at more than UNDEFINED_SHARE of them, or any negative value; None if nothing."""
    bad = ~np.isfinite(values).all(axis=-1)
    if bad.mean() > UNDEFINED_SHARE:
        k = int(np.argmax(bad))
        return (f"{what} gives NaN or infinity at {bad.mean():.0%} of probe pairs at its defaults "
                f"(e.g. wi = {np.round(wi[k], 3).tolist()}, wo = {np.round(wo[k], 3).tolist()})")
    finite = np.where(np.isfinite(values), values, 0.0)
    neg = (finite < -1e-6 * np.abs(finite).max(initial=1.0)).any(axis=-1)
    if neg.any():
        k = int(np.argmax(neg))
        return (f"{what} gives negative values at its defaults (e.g. {float(finite[k].min()):.3g} at wi = "
                f"{np.round(wi[k], 3).tolist()}, wo = {np.round(wo[k], 3).tolist()}): a BRDF is never negative")
    return None


def undefined_where(values: np.ndarray, wi: np.ndarray, wo: np.ndarray, what: str) -> str | None:
    """Where a usable model is undefined (NaN or infinite even as a limit) at its defaults:
    the share of probe pairs, the range of θi and θo there, and an example; None if nowhere."""
    bad = ~np.isfinite(values).all(axis=-1)
    if not bad.any():
        return None
    k = int(np.argmax(bad))
    ti, to = (np.degrees(np.arccos(np.clip(w[bad, 2], -1.0, 1.0))) for w in (wi, wo))
    return (f"{what} is undefined (NaN or infinity, taken as 0) at {bad.mean():.1%} of probe pairs at its "
            f"defaults, with θi {ti.min():.0f}–{ti.max():.0f}° and θo {to.min():.0f}–{to.max():.0f}° there "
            f"(e.g. wi = {np.round(wi[k], 3).tolist()}, wo = {np.round(wo[k], 3).tolist()})")


def probe_pairs(n: int, seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """n pairs of directions strictly above the surface (cos θ ≥ 0.02), reproducible."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(0.02, 1.0, (2, n))
    phi = rng.uniform(0.0, 2.0 * np.pi, (2, n))
    s = np.sqrt(1.0 - z * z)
    w = np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=-1)
    return w[0], w[1]


def load_model_file(path: str | Path, check: bool = True) -> FileModel:
    """Read, check and register one model file; the registered model (an identical file
    already registered is that model). BRDFLabError, naming the file, if it is unusable."""
    return register(read_model(Path(path)), check)


def read_model(path: Path) -> FileModel:
    """The model a file defines, read (not checked): the registered one if this file,
    unchanged, is registered already (no second parse or check)."""
    data = read_model_bytes(path)
    sha256 = hashlib.sha256(data).hexdigest()
    for m in file_models():
        if m.origin.path == path.resolve() and m.origin.sha256 == sha256:
            return m
    return read_model_file(path, data=data)


def register(model: FileModel, check: bool = True) -> FileModel:
    """Check a model read from a file (unless registered already) and register it."""
    if check and model not in file_models():
        check_model(model)
    return add_file_model(model)


def load_folders(folders: Iterable[Path], warn: Warn | None = None) -> list[FileModel]:
    """Register every model file in these folders. A file that cannot be used is reported
    through `warn` (one line) and skipped; so are files that define one model name (all of
    them: which one a material meant cannot be known), in one line naming them."""
    read: list[FileModel] = []
    for folder in folders:
        for path in model_files(Path(folder)):
            _skipping(warn, lambda: read.append(read_model(path)))
    by_name: dict[str, dict[str, FileModel]] = {}
    for model in read:
        by_name.setdefault(registry_name(model), {}).setdefault(model.origin.sha256, model)
    loaded = []
    for name, versions in by_name.items():
        if len(versions) > 1:
            message = (f"{len(versions)} model files define the model {name!r} "
                       f"({', '.join(str(m.origin.path) for m in versions.values())}): all are skipped; rename all "
                       "but one (a model's name must be unique)")
            if warn is None:
                raise DuplicateModelName(message)
            warn(message)
            continue
        _skipping(warn, lambda: loaded.append(register(next(iter(versions.values())))))
    return loaded


def _skipping(warn: Warn | None, work: Callable[[], object]) -> None:
    """Run `work`; a BRDFLabError is told to `warn` (one line) and skipped, or raised without one."""
    try:
        work()
    except BRDFLabError as e:
        if warn is None:
            raise
        warn(str(e))


def resolve_lobe(text: str) -> str:
    """A lobe argument as a registry name: a model's name, or the path of a model file
    (loaded, checked and registered)."""
    if is_model_file(text) and text not in model_names():
        if not Path(text).exists():
            raise BRDFLabError("no such model file", text)
        return load_model_file(Path(text)).name
    return text


class MissingModelFile(BRDFLabError):
    """A material names a file model that cannot be found (the GUI offers to locate it)."""

    def __init__(self, message: str, path=None, model_name: str = "", recorded: str | None = None) -> None:
        super().__init__(message, path)
        self.model_name = model_name
        self.recorded = recorded


def resolve_reference(model_name: str, path_text: str | None, sha256: str | None, base_dir: Path | None) -> FileModel:
    """The file model a material's lobe names: by its recorded path (relative to the
    material's folder) where `reference_problem` allows it, else a registered model of that
    name and checksum. BRDFLabError that says why not: the file is missing (MissingModelFile,
    with how to supply it), is not a regular file, or is refused by the folder policy."""
    refused = None
    if path_text:
        p = Path(path_text)
        candidate = p if p.is_absolute() or base_dir is None else base_dir / p
        if os.path.exists(candidate):  # False, not an error, for a name too long for the system
            refused = reference_problem(candidate, base_dir or Path("."), sha256)
            if refused is None:
                model = load_model_file(candidate)
                if model.xml_name != model_name:
                    raise BRDFLabError(f"the model file defines {model.xml_name!r}, not {model_name!r}", candidate)
                return model
    found = find_file_model(model_name, sha256) or find_file_model(model_name)
    if found is not None:
        return found  # the reader warns when its checksum is not the one recorded
    if refused is not None:
        raise BRDFLabError(refused, candidate)
    where = f" from {path_text}" if path_text else ""
    raise MissingModelFile(f"the lobe model {model_name!r}{where} is not available: its model file is missing "
                           f"(put it back, or add its folder with --models DIR or {MODELS_ENV})",
                           model_name=model_name, recorded=path_text)


def reference_problem(path: Path, folder: Path, sha256: str | None) -> str | None:
    """Why a model file that a material names, and that is there, may not be opened, or None:
    not a regular file, or refused by the folder policy (`outside_problem`). One exception: a
    model file elsewhere, by its name and root element, whose reference the lab saved (a
    sha256 is recorded) and that was edited since is used, and the reader says it changed:
    `fit --lobes models/x.brdf --out saved/fit.xml`, then an edit of x.brdf."""
    kind = kind_problem(os.stat(path).st_mode)
    if kind:
        return kind
    problem = outside_problem(path, folder, sha256, MAX_MODEL_BYTES, "model file")
    if problem and sha256 and is_model_path(Path(path).resolve()):
        return None  # edited since the save: used, and the reader says so
    return problem


def is_model_path(path: Path) -> bool:
    """Whether a file is a model rather than a material or data: a `.brdf`, or a regular `.xml`
    file whose root element is <AnalyticBRDFModel>."""
    suffix = path.suffix.lower()
    return suffix == ".brdf" or (suffix == ".xml" and path.is_file() and is_descriptor(path))


def rebuild(path: str, sha256: str, name: str) -> FileModel:
    """A file model in another process (a fit's worker): read again from its file, which
    must still be the one the parent read."""
    for m in file_models():
        if m.origin.sha256 == sha256 and m.name == name:
            return m
    model = read_model_file(Path(path), name)
    if model.origin.sha256 != sha256:
        raise BRDFLabError("the model file changed while the lab was using it", path)
    return add_file_model(model)
