"""Charts of the `lighting` study part, drawn from its numbers only: one Pareto chart per
material class (error against frame time, every method a line, the front marked), the FIS
and SH heat maps over glossiness, and the summary table (Markdown) of the cheapest method
under each error target. Captions state where a method breaks, read from the numbers.
"""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import numpy as np

from brdflab.io.atomic import atomic_write
from brdflab.study.framework import pyplot, save_figure
from brdflab.study.tradeoff import cheapest_under, pareto_front

# the heat maps' rows, broad to sharp (the classes of a run that are not here are left out)
GLOSSINESS = ("Lambertian", "Blinn-Phong n=10", "Blinn-Phong n=100", "Blinn-Phong n=1000", "Blinn-Phong n=10000")
MODE_NAMES = {"point": "point light", "fis": "FIS", "sh": "SH", "mis": "MIS", "prefiltered": "prefiltered"}
MODE_STYLES = {"fis": ("o-", "#1f77b4"), "sh": ("s-", "#d62728"), "mis": ("^-", "#2ca02c"),
               "prefiltered": ("D", "#9467bd")}
BREAKS = 0.05  # a method "breaks" on a scene where even its dearest setting stays above 5 %


def method_name(row: dict) -> str:
    name = MODE_NAMES.get(row["mode"], row["mode"])
    return f"{name} {row['setting']}".rstrip()


def floor_of(floors: list[dict], material: str, env: str) -> float:
    """The reference's own resolution on this scene (0 when it was not measured)."""
    return next((f["floor"] for f in floors if f["material"] == material and f["map"] == env), 0.0)


def summary(rows: list[dict], thresholds: list[float], floors: list[dict] = ()) -> list[dict]:
    """Per material and map, the cheapest method reaching each error target (mode None:
    none does). A target the reference cannot resolve (at or below its floor) is not judged:
    `resolved` is False there."""
    out = []
    for material, env in dict.fromkeys((r["material"], r["map"]) for r in rows):
        scene = [r for r in rows if r["material"] == material and r["map"] == env]
        floor = floor_of(floors, material, env)
        for target in thresholds:
            best = cheapest_under(scene, target) if target > floor else None
            out.append({"material": material, "map": env, "target": target, "resolved": target > floor,
                        **({k: best[k] for k in ("mode", "setting", "ms", "error")} if best else
                           {"mode": None, "setting": None, "ms": None, "error": None})})
    return out


def slug(name: str) -> str:
    return re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_")


def draw(numbers: dict, out_dir: Path) -> list[str]:
    files = [pareto_chart(numbers, material, out_dir) for material in numbers["materials"]
             if any(r["material"] == material for r in numbers["rows"])]
    for mode in ("fis", "sh"):
        if mode in numbers["modes"] and len(glossiness_rows(numbers)) >= 2:
            files.append(heat_map(numbers, mode, out_dir))
    files.append(summary_markdown(numbers, out_dir))
    return files


# --- Pareto charts ---------------------------------------------------------------------------
def pareto_chart(numbers: dict, material: str, out_dir: Path) -> str:
    plt = pyplot()
    maps = [m for m in numbers["maps"] if any(r["material"] == material and r["map"] == m["name"]
                                               for r in numbers["rows"])]
    fig, axes = plt.subplots(1, len(maps), figsize=(max(6.4, 4.3 * len(maps) + 0.6), 4.8), dpi=100, squeeze=False)
    tables = [t["seconds"] for t in numbers["sh_tables"] if t["material"] == material]
    for ax, env in zip(axes[0], maps):
        rows = [r for r in numbers["rows"] if r["material"] == material and r["map"] == env["name"]]
        for mode in numbers["modes"]:
            line = [r for r in rows if r["mode"] == mode]
            if not line:
                continue
            if line[0]["error"] is None:  # no environment estimate: a cost line
                ax.axvline(line[0]["ms"], color="grey", ls="--", lw=1.0,
                           label=f"{MODE_NAMES.get(mode, mode)} (exact for one light): cost floor")
                continue
            style, color = MODE_STYLES.get(mode, ("x-", None))
            label = MODE_NAMES.get(mode, mode)
            if mode == "sh" and tables:
                label += f" (+ table build {min(tables):.0f}–{max(tables):.0f} s)"
            ax.loglog([r["ms"] for r in line], [100 * max(r["error"], 1e-5) for r in line], style, color=color,
                      ms=4, lw=1.2, label=label)
            for r in line:
                ax.annotate(r["setting"].split("=")[-1], (r["ms"], 100 * max(r["error"], 1e-5)), fontsize=6.5,
                            textcoords="offset points", xytext=(3, 3), color=color)
        floor = 100 * floor_of(numbers["floors"], material, env["name"])
        if floor > 0:
            ax.axhspan(1e-3, floor, color="grey", alpha=0.18, lw=0,
                       label="below the reference's resolution (not judged)")
        front = pareto_front(rows)
        ax.loglog([r["ms"] for r in front], [100 * max(r["error"], 1e-5) for r in front], "-", color="black",
                  lw=2.2, alpha=0.25, drawstyle="steps-post", label="Pareto front")
        ax.loglog([r["ms"] for r in front], [100 * max(r["error"], 1e-5) for r in front], "o", mfc="none",
                  mec="black", ms=9, mew=1.0)
        for target in numbers["thresholds"]:
            ax.axhline(100 * target, color="grey", lw=0.6, ls=":")
        ax.set_title(f"{env['name']} ({env['character']})", fontsize=9)
        lowest = min([100 * r["error"] for r in rows if r["error"]] + ([floor] if floor > 0 else []), default=1.0)
        ax.set_ylim(bottom=max(lowest / 2, 1e-3))
        ax.set_xlabel(f"ms per frame at {numbers['frame_size']}²")
        ax.grid(True, which="major", lw=0.3, alpha=0.5)
    axes[0][0].set_ylabel("relative RMSE vs quadrature (%)")
    axes[0][0].legend(fontsize=7, loc="lower left")
    renderer = numbers["renderer"].split(" (")[0]
    fig.suptitle(f"{material}: error against frame time ({renderer})\nlabels: samples or SH order; dotted: "
                 f"{', '.join(f'{100 * t:g} %' for t in numbers['thresholds'])} error", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, out_dir / f"lighting_pareto_{slug(material)}.png")


# --- heat maps -------------------------------------------------------------------------------
def glossiness_rows(numbers: dict) -> list[str]:
    return [g for g in GLOSSINESS if g in numbers["materials"] and any(r["material"] == g for r in numbers["rows"])]


def heat_grid(numbers: dict, mode: str, env: str) -> tuple[list[str], list[int], np.ndarray, np.ndarray]:
    """(row names, setting values, error (rows, values), negative pixels) of one mode on one map."""
    names = glossiness_rows(numbers)
    rows = [r for r in numbers["rows"] if r["mode"] == mode and r["map"] == env and r["material"] in names]
    values = sorted({r["value"] for r in rows})
    error = np.full((len(names), len(values)), np.nan)
    negative = np.zeros_like(error)
    for r in rows:
        i, j = names.index(r["material"]), values.index(r["value"])
        error[i, j], negative[i, j] = r["error"], r["negative_pixels"] or 0
    return names, values, error, negative


def heat_map(numbers: dict, mode: str, out_dir: Path) -> str:
    from matplotlib.colors import LogNorm

    plt = pyplot()
    maps = numbers["maps"]
    width = max(7.5, 3.6 * len(maps) + 2.6)
    fig, axes = plt.subplots(1, len(maps), figsize=(width, 4.8), dpi=100, squeeze=False)
    covered = int(round(np.pi / 4 * numbers["error_size"] ** 2))
    image = None
    for k, (ax, env) in enumerate(zip(axes[0], maps)):
        names, values, error, negative = heat_grid(numbers, mode, env["name"])
        image = ax.imshow(np.clip(100 * error, 0.1, 100), cmap="magma_r", norm=LogNorm(0.1, 100), aspect="auto")
        floors = [floor_of(numbers["floors"], n, env["name"]) for n in names]
        for (i, j), e in np.ndenumerate(error):
            if np.isfinite(e):
                text = f"{100 * e:.1f}" + ("*" if e <= floors[i] else "") + (
                    f"\n{int(negative[i, j])} neg" if negative[i, j] else "")
                ax.text(j, i, text, ha="center", va="center", fontsize=6.5, color="white" if e > 0.1 else "black")
        ax.set_xticks(range(len(values)), [str(v) for v in values], fontsize=8)
        ax.set_yticks(range(len(names)), [n.replace("Blinn-Phong ", "BP ") if k == 0 else "" for n in names],
                      fontsize=8)
        ax.set_xlabel("samples" if mode != "sh" else "SH order L")
        ax.set_title(f"{env['name']}", fontsize=9)
    fig.subplots_adjust(bottom=0.36, top=0.84, left=0.12, right=0.88, wspace=0.12)
    bar = fig.colorbar(image, cax=fig.add_axes([0.90, 0.36, 0.015, 0.48]), label="relative RMSE (%)")
    bar.set_ticks([0.1, 1, 10, 100], labels=["0.1", "1", "10", "100"])
    what = ("FIS error (%) over glossiness × samples" if mode != "sh" else
            f"SH error (%) over glossiness × order; neg: pixels clamped from negative (ringing), of ~{covered}")
    fig.suptitle(what, fontsize=10)
    caption = ("* at or below the reference's own resolution (not judged). "
               + (fis_caption(numbers) if mode == "fis" else sh_caption(numbers)))
    fig.text(0.01, 0.02, textwrap.fill(caption, int(width * 17)), fontsize=7.5, va="bottom")
    return save_figure(fig, out_dir / f"lighting_{mode}_heatmap.png")


def _dearest(numbers: dict, mode: str) -> tuple[list[dict], list[dict]]:
    """Each glossiness class's row at the mode's dearest setting, per map: those the
    reference resolves at the BREAKS level, and those it does not."""
    rows = [r for r in numbers["rows"] if r["mode"] == mode and r["material"] in glossiness_rows(numbers)]
    top = max(r["value"] for r in rows)
    dearest = [r for r in rows if r["value"] == top]
    judged = [r for r in dearest if floor_of(numbers["floors"], r["material"], r["map"]) < BREAKS]
    return judged, [r for r in dearest if r not in judged]


def _breaks(numbers: dict, mode: str) -> str:
    """'Breaks (above 5 % at n=1024): …; not judged: …' read from the numbers."""
    judged, unjudged = _dearest(numbers, mode)
    setting = (judged or unjudged)[0]["setting"]
    broken = [r for r in judged if r["error"] > BREAKS]
    where = "; ".join(f"{r['material']} on {r['map']} {100 * r['error']:.0f} %" for r in broken) or "nowhere"
    text = f"Breaks (above {100 * BREAKS:g} % at {setting}): {where}."
    if unjudged:
        text += (" Not judged (the reference itself is uncertain by more than 5 %): "
                 + "; ".join(f"{r['material']} on {r['map']}" for r in unjudged) + ".")
    return text


def fis_caption(numbers: dict) -> str:
    """Where FIS breaks (read from the numbers) and why."""
    return (f"{_breaks(numbers, 'fis')} Why: FIS draws directions from the BRDF alone, so a broad lobe under a "
            "map whose power sits in a few texels (a sun, lamps) rarely draws them and its noise falls only as "
            "1/√n; the mip-level filter that hides that noise blurs small sources and biases low counts.")


def sh_caption(numbers: dict) -> str:
    """Where SH breaks (read from the numbers) and why."""
    ringing = [r for r in numbers["rows"] if r["mode"] == "sh" and r["negative_pixels"]]
    worst = max(ringing, key=lambda r: r["negative_pixels"]) if ringing else None
    ring = (f"Ringing: {len(ringing)} of the runs have negative pixels, most {worst['negative_pixels']} "
            f"({worst['material']}, {worst['setting']}, {worst['map']})." if worst else "No negative pixels.")
    return (f"{_breaks(numbers, 'sh')} {ring} Why: order L keeps frequencies up to about L; a lobe of "
            "exponent n is about 1/√n rad wide and needs L of order √n, so sharp lobes are cut off (blurred), and "
            "a truncated sun or lamp rings: the series goes negative beside it and is clamped to black.")


# --- summary table ---------------------------------------------------------------------------
def summary_markdown(numbers: dict, out_dir: Path) -> str:
    targets = numbers["thresholds"]
    lines = ["# Environment lighting: the cheapest method under each error target", "",
             f"Frame time: reference-view sphere at {numbers['frame_size']}² on {numbers['renderer']} "
             f"(the full-resolution {numbers['timing_map']} map). Error: relative RMSE at "
             f"{numbers['error_size']}² against quadrature, the map reduced to {numbers['reduced'][0]} × "
             f"{numbers['reduced'][1]} for render and reference. 'none' gives the best error reached. "
             "'not judged': the target is within the reference's own resolution (its change when every "
             "texel is split 2 × 2; lobes narrower than a texel fall between texel centres).", "",
             "| material | map | " + " | ".join(f"≤ {100 * t:g} %" for t in targets) + " |",
             "|---|---|" + "---|" * len(targets)]
    by_scene: dict[tuple, dict] = {}
    for s in numbers["summary"]:
        by_scene.setdefault((s["material"], s["map"]), {})[s["target"]] = s
    for (material, env), cells in by_scene.items():
        scene = [r for r in numbers["rows"] if r["material"] == material and r["map"] == env and r["error"] is not None]
        best = min(scene, key=lambda r: r["error"]) if scene else None
        texts = []
        for t in targets:
            c = cells[t]
            if not c.get("resolved", True):
                texts.append(f"not judged (reference ±{100 * floor_of(numbers['floors'], material, env):.2g} %)")
            elif c["mode"]:
                texts.append(f"{method_name(c)}: {c['ms']:.3g} ms ({100 * c['error']:.2g} %)")
            else:
                texts.append(f"none (best {method_name(best)} {100 * best['error']:.2g} %)" if best else "none")
        lines.append(f"| {material} | {env} | " + " | ".join(texts) + " |")
    point = {r["material"]: r["ms"] for r in numbers["rows"] if r["mode"] == "point"}
    if point:
        lines += ["", "Point light (exact for one light, not an environment estimate): the cost floor, "
                  + ", ".join(f"{m} {ms:.3g} ms" for m, ms in point.items()) + "."]
    if numbers["sh_tables"]:
        lines += ["", "SH BRDF table build (once per material and order, not in the frame time):", "",
                  "| material | " + " | ".join(f"L={t['order']}" for t in numbers["sh_tables"]
                                               if t["material"] == numbers["sh_tables"][0]["material"]) + " |",
                  "|---|" + "---|" * sum(t["material"] == numbers["sh_tables"][0]["material"]
                                         for t in numbers["sh_tables"])]
        for material in dict.fromkeys(t["material"] for t in numbers["sh_tables"]):
            lines.append(f"| {material} | " + " | ".join(f"{t['seconds']:.1f} s" for t in numbers["sh_tables"]
                                                        if t["material"] == material) + " |")
    for s in numbers["skipped"]:
        lines.append(f"\nSkipped {s['what']}: {s['why']}.")
    path = out_dir / "lighting_summary.md"
    atomic_write(path, ("\n".join(lines) + "\n").encode())
    return path.name
