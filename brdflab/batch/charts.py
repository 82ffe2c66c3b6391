"""Charts of a batch: the error of every material under every lobe set, materials sorted
(as Ngan et al. 2005, Fig. 7), and each fit's error against its time."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from brdflab.io.atomic import atomic_write


def _save(fig, path: Path) -> None:
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    atomic_write(path, buf.getvalue())


def error_per_material(frame: pd.DataFrame, metric: str, path: Path) -> Path | None:
    """One line per lobe set over the materials, sorted by their median error over the lobe sets."""
    from matplotlib.figure import Figure

    ok = frame[(frame["status"] != "failed") & (frame["metric"] == metric)]
    if ok.empty:
        return None
    grid = ok.pivot_table(index="material", columns="lobes", values="error", aggfunc="min")
    grid = grid.loc[grid.median(axis=1).sort_values().index]
    fig = Figure(figsize=(max(6.0, 0.28 * len(grid) + 2.5), 4.8), layout="constrained")
    ax = fig.add_subplot()
    x = np.arange(len(grid))
    for lobes in grid.columns:
        ax.plot(x, grid[lobes].to_numpy(), marker="o", markersize=3.5, linewidth=1.2, label=lobes)
    ax.set_yscale("log")
    ax.set_xticks(x, grid.index, rotation=90, fontsize=7)
    ax.set_ylabel(f"{metric} error on all samples (log)")
    ax.set_title(f"Fit error per material and lobe set ({len(grid)} materials, sorted by median error)")
    ax.grid(True, which="both", axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    _save(fig, path)
    return path


def error_against_time(frame: pd.DataFrame, metric: str, path: Path) -> Path | None:
    """Each fit as a point: seconds on x, error on y (both log), one colour per lobe set."""
    from matplotlib.figure import Figure

    ok = frame[(frame["status"] != "failed") & (frame["metric"] == metric)]
    if ok.empty:
        return None
    fig = Figure(figsize=(6.4, 4.8), layout="constrained")
    ax = fig.add_subplot()
    for lobes, group in ok.groupby("lobes", sort=True):
        ax.scatter(group["seconds"], group["error"], s=14, alpha=0.8, label=f"{lobes} (median {group['seconds'].median():.2f} s)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("fit time per task (s, log)")
    ax.set_ylabel(f"{metric} error on all samples (log)")
    ax.set_title(f"Error against fit time ({len(ok)} fits)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    _save(fig, path)
    return path


def write_charts(frame: pd.DataFrame, metric: str, folder: Path) -> list[Path]:
    charts = [error_per_material(frame, metric, folder / "error_per_material.png"),
              error_against_time(frame, metric, folder / "error_vs_time.png")]
    return [c for c in charts if c is not None]
