"""Analytic stand-ins that importance-sample sources which have no sampler of their own."""

from __future__ import annotations

import weakref

from brdflab.material.analytic import AnalyticMaterial

# Cook–Torrance m floor of the proxy: lobes fitted to a mirror-like table come out far
# narrower (m ≈ 0.003) than the table's peak, and samples of the other lobes landing near
# the mirror direction then weigh f/pdf wildly (dark discs with bright rims, one per sample).
MIN_ROUGHNESS = 0.05


# one proxy per measured source object while it lives: the window sets its source again on
# every view-control change, and a refit each time cost ~0.7 s on the GUI thread
# (by id: sources are unhashable dataclasses; an entry goes when its source does)
_PROXIES: dict[int, AnalyticMaterial] = {}
_TABLES: dict[int, object] = {}
_SAMPLERS: dict[int, object] = {}


def _once_per_source(cache: dict, source, make):
    """make(source), kept in `cache` while `source` lives."""
    key = id(source)
    if key not in cache:
        cache[key] = make(source)
        weakref.finalize(source, cache.pop, key, None)
    return cache[key]


def render_table(source):
    """The table a measured source is drawn (and its proxy fitted) from: the source itself
    when it is a table, else its tabulation, made once per source object."""
    from brdflab.sources.measured import MeasuredTable, tabulate

    if isinstance(source, MeasuredTable):
        return source
    return _once_per_source(_TABLES, source, lambda s: tabulate(s, phi_d_samples=1))


def proxy_lobes(source) -> AnalyticMaterial:
    """A Lambertian + two Cook–Torrance fit (Ngan metric, a stratified subset): the
    distribution that importance-samples a measured source (a sharp and a broad lobe,
    so that glossy tails get samples too). Analytic materials are their own proxy;
    a measured source's proxy is fitted once per source object (a copy is returned)."""
    if isinstance(source, AnalyticMaterial):
        return source
    return _once_per_source(_PROXIES, source, _fit_proxy).copy()


def _fit_proxy(source) -> AnalyticMaterial:
    from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
    from brdflab.fitting.samples import samples_of

    table = render_table(source)
    start = material_from_lobes(["Lambertian", "CookTorrance", "CookTorrance"], "Linear", table.n_channels)
    start.lobes[1].params["m"], start.lobes[2].params["m"] = 0.05, 0.35
    result = fit(start, samples_of(table, "subset", size=20_000),
                 FitOptions(metric="Ngan", coarse_size=0, max_iterations=60, restarts=False,
                            diagnose=False))
    for lobe in result.material.lobes:  # a lobe the fit switched off still deserves samples
        lobe.scale = [max(s, 1e-6) for s in lobe.scale]
        if "m" in lobe.params:
            lobe.params["m"] = max(lobe.params["m"], MIN_ROUGHNESS)
    return result.material


class _ChannelMean:
    """A measured table as the one-valued lobe the tabulated sampler tabulates: the mean of
    its channels (so that no channel's highlight goes without samples)."""

    def __init__(self, table) -> None:
        self.table = table

    def evaluate(self, wi, wo, params):
        return self.table.evaluate(wi, wo).mean(axis=-1)

    @staticmethod
    def is_isotropic(params) -> bool:
        return True


def measured_sampler(source):
    """The tables that importance-sample a measured source in the renderers' FIS and MIS: the
    generic tabulated sampler (`models.files.sampler`) built from the source's own values, its
    half vectors tabulated per view up to 89°, so its density follows f cos θi at every view.
    The proxy lobes' fixed mixture did not: at grazing views a paint's Fresnel-brightened
    highlight carried up to 140× the proxy's density (FIS under a small sun 11–17 % off at
    4,096 samples). Made once per source object; the tables are built on first use."""
    from brdflab.models.files.sampler import TabulatedSampler

    return _once_per_source(_SAMPLERS, source, lambda s: TabulatedSampler(_ChannelMean(render_table(s)), {}))
