"""A simulated material: what reproduces it (`SimulationSpec`) and the source built from its
cached half/difference table (`SimulatedMaterial`)."""

from __future__ import annotations

import hashlib
import io
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Callable

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.io.user_cache import cache_folder, store
from brdflab.io.numbers import ascii_integer
from brdflab.simulation import microgeometry, scatmech
from brdflab.simulation.registry import get_kind
from brdflab.simulation.table import HalfDiffTable, node_directions

TABLE_VERSION = 1  # bump when a change to the simulators changes their tables
Progress = Callable[[float, str], None]


@dataclass
class SimulationSpec:
    """Everything that reproduces a simulated material: kind, every parameter, the seed and
    ray count (ray-bounce kinds) and the table resolution R (R³ half/difference nodes)."""

    kind: str
    params: dict = field(default_factory=dict)
    seed: int = 0
    samples: int = 200_000
    resolution: int = 32
    name: str = ""

    def __post_init__(self) -> None:
        self.params = get_kind(self.kind).complete(self.params)
        if not 4 <= self.resolution <= 128:
            raise BRDFLabError(f"resolution {self.resolution} is outside 4..128")
        if not 1000 <= self.samples <= 50_000_000:
            raise BRDFLabError(f"samples {self.samples} is outside 1000..50000000")
        if not 0 <= self.seed < 2**63:
            raise BRDFLabError(f"seed {self.seed} must be a non-negative integer")
        self.name = self.name or self.kind

    @property
    def library(self) -> str:
        return get_kind(self.kind).library

    def key(self) -> str:
        """The cache key: a hash of everything the table depends on."""
        stored = {"kind": self.kind, "params": self.params, "resolution": self.resolution, "v": TABLE_VERSION}
        if get_kind(self.kind).uses_rays:
            stored.update(seed=self.seed, samples=self.samples)
        return hashlib.sha256(json.dumps(stored, sort_keys=True).encode()).hexdigest()[:24]

    def describe(self) -> dict:
        out = {"library": self.library, "model": self.kind, "parameters": dict(self.params), "resolution": self.resolution}
        if get_kind(self.kind).uses_rays:
            out.update(seed=self.seed, samples=self.samples)
        return out


class SimulatedMaterial:
    """A source (`evaluate`, `n_channels`, `isotropic`, `describe`) backed by a table."""

    kind = "Simulated"
    isotropic = True

    def __init__(self, spec: SimulationSpec, table: HalfDiffTable, seconds: float = 0.0) -> None:
        self.spec = spec
        self.table = table
        self.seconds = seconds
        self.name = spec.name
        self.source_type = spec.library

    @property
    def n_channels(self) -> int:
        return self.table.n_channels

    def evaluate(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        return self.table.evaluate(wi, wo)

    def describe(self) -> dict:
        r = self.spec.resolution
        return {"type": self.source_type, "name": self.name, "channels": self.n_channels, **self.spec.describe(),
                "max_value": [float(v) for v in self.table.values.reshape(self.n_channels, -1).max(axis=1)],
                "domain": f"isotropic; a {r}×{r}×{r} half/difference table (θh, θd, φd), trilinear between nodes"}


# --------------------------------------------------------------------------------------
# building tables

def cache_dir() -> Path:
    return cache_folder("simulated")


def _jobs(spec: SimulationSpec, workers: int):
    """(function, args) pieces of work, independent of how many workers run them."""
    if get_kind(spec.kind).uses_rays:
        n = len(microgeometry.incident_angles(spec.resolution))
        return [(microgeometry.simulate_incidence, (spec.kind, spec.params, spec.seed, spec.samples, spec.resolution, k))
                for k in range(n)]
    scatmech.require(spec.kind)
    wi, wo = node_directions(spec.resolution)
    chunks = np.array_split(np.arange(wi.shape[0]), max(8, 4 * workers))
    return [(scatmech.evaluate_chunk, (spec.kind, spec.params, wi[c], wo[c])) for c in chunks]


def _assemble(spec: SimulationSpec, pieces: list) -> HalfDiffTable:
    r = spec.resolution
    if get_kind(spec.kind).uses_rays:
        return microgeometry.table_from_histograms(np.stack(pieces), r)
    values = np.concatenate(pieces).T.reshape(-1, r, r, r)
    return HalfDiffTable(values.astype(np.float32))


def compute_table(spec: SimulationSpec, progress: Progress | None = None, workers: int | None = None) -> HalfDiffTable:
    """Run the simulation over `workers` processes (default: every core)."""
    workers = workers or os.cpu_count() or 1
    jobs = _jobs(spec, workers)
    pieces: list = [None] * len(jobs)
    done = 0
    if workers == 1:
        for i, (fn, args) in enumerate(jobs):
            pieces[i] = fn(*args)
            done += 1
            if progress:
                progress(done / len(jobs), f"{spec.kind}: {done}/{len(jobs)}")
        return _assemble(spec, pieces)
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("fork")) as pool:
        futures = {pool.submit(fn, *args): i for i, (fn, args) in enumerate(jobs)}
        for fut in as_completed(futures):
            pieces[futures[fut]] = fut.result()
            done += 1
            if progress:
                progress(done / len(jobs), f"{spec.kind}: {done}/{len(jobs)}")
    return _assemble(spec, pieces)


def load_table(spec: SimulationSpec, progress: Progress | None = None, workers: int | None = None) -> tuple[HalfDiffTable, float]:
    """The spec's table from the cache, or computed and cached; and the seconds it took."""
    path = cache_dir() / f"{spec.kind}-{spec.key()}.npy"
    if path.is_file():
        try:
            values = np.load(path, allow_pickle=False)
            if values.shape[1:] == (spec.resolution,) * 3:
                return HalfDiffTable(values), 0.0
        except (OSError, ValueError):
            pass  # a damaged cache entry is recomputed
    t0 = time.perf_counter()
    table = compute_table(spec, progress, workers)
    seconds = time.perf_counter() - t0
    buf = io.BytesIO()
    np.save(buf, table.values)
    store(path, buf.getvalue())
    return table, seconds


def simulated_material(spec: SimulationSpec, progress: Progress | None = None, workers: int | None = None) -> SimulatedMaterial:
    table, seconds = load_table(spec, progress, workers)
    return SimulatedMaterial(spec, table, seconds)


# --------------------------------------------------------------------------------------
# files

def reference_of(spec: SimulationSpec):
    """The <Material> element's content that reproduces `spec`."""
    from brdflab.io.xmlio import SimulatedReference

    settings = {"resolution": str(spec.resolution)}
    if get_kind(spec.kind).uses_rays:
        settings.update(seed=str(spec.seed), samples=str(spec.samples))
    return SimulatedReference(spec.library, spec.name, spec.kind, {k: str(v) for k, v in spec.params.items()}, settings)


def _integer(settings: dict, name: str, default: int) -> int:
    text = settings.get(name)
    if text is None:
        return default
    try:
        return ascii_integer(text)
    except ValueError as e:
        raise BRDFLabError(f"<Simulation {name}> is {e}") from None


def spec_of(ref) -> SimulationSpec:
    """The spec a stored simulated material describes (BRDFLabError if it is not valid)."""
    kind = get_kind(ref.model)
    if kind.library != ref.type:
        raise BRDFLabError(f"the simulated kind {ref.model} belongs to {kind.library}, the file says <Type>{ref.type}")
    return SimulationSpec(ref.model, kind.complete(ref.parameters), _integer(ref.settings, "seed", 0),
                          _integer(ref.settings, "samples", 200_000), _integer(ref.settings, "resolution", 32), ref.name)


def open_simulated(ref, path: Path | None = None, progress: Progress | None = None) -> SimulatedMaterial:
    """The source a stored simulated material stands for (computed, or from the cache)."""
    try:
        spec = spec_of(ref)
        return simulated_material(spec, progress)
    except BRDFLabError as e:
        raise (e if e.path or path is None else BRDFLabError(str(e), path)) from None


def describe_stored(ref, path: Path | None = None) -> dict:
    """What `brdflab info` says about a stored simulated material, without simulating it."""
    try:
        spec = spec_of(ref)
    except BRDFLabError as e:
        raise (e if e.path or path is None else BRDFLabError(str(e), path)) from None
    cached = (cache_dir() / f"{spec.kind}-{spec.key()}.npy").is_file()
    return {"type": spec.library, "name": spec.name, **spec.describe(), "channels": 3,
            "available": get_kind(spec.kind).available, "cached": cached}
