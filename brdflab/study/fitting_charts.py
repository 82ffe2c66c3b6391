"""Charts and summaries of the `fitting` study part, from its rows only.

Errors are pooled over materials relative to each material's best core fit (the families
fitted on every material, on the core sample set), so a material with a large error (a metal)
and one with a small error (a fabric) weigh the same.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

from brdflab.study.framework import pyplot, save_figure
from brdflab.study.pareto import enough_point, gain, pareto_front

PAGE = 12  # material panels per chart file
ENOUGH = 0.05  # "stops paying": within 5 % of the best error found
TIME_LABELS = {"cpu": "fit time (CPU s, one thread)", "wall": "fit wall time (s)"}
MARKERS = {(0, "Linear"): "D", (0, "Fixed"): "d", (1, "Linear"): "o", (1, "Fixed"): "s",
           (2, "Linear"): "^", (2, "Fixed"): "v"}

LESSON = ("Two GGX lobes over a Lambertian, Linear, fitted on a 5–20 k-sample subset is where more stops paying "
          "on most MERL materials (one GGX lobe, the best single lobe, leaves a median 31 % more error at a third "
          "of the time); a second lobe pays for the microfacet, Lafortune, Kurt, Ashikhmin–Shirley and "
          "Ward–Dürer models, the Fixed combination about 2 % at most, and subsets of 5–200 k samples lose a "
          "median well under 0.1 % against all samples (docs/study.md).")


def with_relative_error(rows: list[dict]) -> list[dict]:
    """Rows with `relative` = error / the material's best core error (its best error
    when no core fit finished)."""
    reference: dict[str, float] = {}
    for r in rows:
        if r["core"]:
            reference[r["material"]] = min(reference.get(r["material"], np.inf), r["error"])
    for r in rows:
        reference.setdefault(r["material"], min(x["error"] for x in rows if x["material"] == r["material"]))
    return [{**r, "relative": r["error"] / max(reference[r["material"]], 1e-300)} for r in rows]


def family_summary(rows: list[dict], size: int | None) -> list[dict]:
    """Per family, over the materials it was fitted on with `size` samples (None: all):
    the median and the range of the relative error and of the time."""
    groups = defaultdict(list)
    for r in with_relative_error(rows):
        if r["size"] == size:
            groups[(r["family"], r["model"], r["lobes_count"], r["combination"])].append(r)
    out = []
    for (family, model, lobes, combination), rs in groups.items():
        rel = np.array([r["relative"] for r in rs])
        sec = np.array([r["seconds"] for r in rs])
        out.append({"family": family, "model": model, "lobes": lobes, "combination": combination,
                    "materials": len(rs), "parameters": rs[0]["parameters"],
                    "relative_median": float(np.median(rel)), "relative_min": float(rel.min()),
                    "relative_max": float(rel.max()), "seconds_median": float(np.median(sec)),
                    "seconds_min": float(sec.min()), "seconds_max": float(sec.max())})
    return sorted(out, key=lambda f: f["seconds_median"])


def subset_effect(rows: list[dict]) -> list[dict]:
    """Per subset size: the error on all samples of the fit on the subset over that of the
    same family's fit on all samples (same material), and the time ratio."""
    full = {(r["material"], r["family"]): r for r in rows if r["size"] is None}
    ratios = defaultdict(list)
    for r in rows:
        ref = full.get((r["material"], r["family"]))
        if r["size"] is not None and ref is not None and ref["error"] > 0:
            ratios[r["size"]].append((r["error"] / ref["error"], r["seconds"] / max(ref["seconds"], 1e-9),
                                      f"{r['family']} on {r['material']}"))
    out = []
    for size in sorted(ratios):
        e, t = (np.array([x[k] for x in ratios[size]]) for k in (0, 1))
        out.append({"size": size, "pairs": int(e.size), "worst": ratios[size][int(np.argmax(e))][2],
                    "error_ratio_median": float(np.median(e)),
                    "error_ratio_p90": float(np.percentile(e, 90)), "error_ratio_max": float(e.max()),
                    "time_ratio_median": float(np.median(t)), "time_ratio_p10": float(np.percentile(t, 10)),
                    "time_ratio_p90": float(np.percentile(t, 90))})
    return out


def richer_gains(rows: list[dict]) -> list[dict]:
    """Per model: what a second lobe (2 vs 1, Linear) and the Fixed combination (vs
    Linear, one lobe) buy in error on all samples and cost in time — medians over the
    pairs fitted on the same material and the same sample set."""
    fits = {(r["material"], r["size"], r["model"], r["lobes_count"], r["combination"]): r for r in rows}
    out = []
    for model in sorted({r["model"] for r in rows if r["lobes_count"] > 0}):
        entry = {"model": model}
        for what, richer in (("second_lobe", (2, "Linear")), ("fixed", (1, "Fixed"))):
            pairs = [(fits[(m, size, model, 1, "Linear")], r) for (m, size, mo, n, c), r in fits.items()
                     if mo == model and (n, c) == richer and (m, size, model, 1, "Linear") in fits]
            if pairs:
                gains = [gain(a["error"], b["error"]) for a, b in pairs]
                entry[what] = {"pairs": len(pairs), "gain_median": float(np.median(gains)),
                               "gain_max": float(max(gains)),
                               "time_factor_median": float(np.median([b["seconds"] / max(a["seconds"], 1e-9)
                                                                      for a, b in pairs]))}
        out.append(entry)
    return out


def material_fronts(rows: list[dict]) -> dict[str, dict]:
    """Per material: its Pareto front (cheapest to best) and where more stops paying."""
    out = {}
    for material in dict.fromkeys(r["material"] for r in rows):
        rs = [r for r in rows if r["material"] == material]
        cost, error = [r["seconds"] for r in rs], [r["error"] for r in rs]
        front = pareto_front(cost, error)
        enough = enough_point(cost, error, ENOUGH)
        out[material] = {"front": [_describe(rs[i]) for i in front], "enough": _describe(rs[enough]),
                         "best_error": float(min(error)), "fits": len(rs)}
    return out


def _describe(r: dict) -> dict:
    size = "all" if r["size"] is None else f"{r['size'] // 1000}k"
    return {"family": r["family"], "samples": size, "seconds": r["seconds"], "error": r["error"]}


def _colors(models) -> dict[str, tuple]:
    """Distinct colours for up to 18 models: tab10, then Dark2."""
    plt = pyplot()
    palette = [plt.get_cmap("tab10")(k) for k in range(10)] + [plt.get_cmap("Dark2")(k) for k in range(8)]
    return {m: palette[k % len(palette)] for k, m in enumerate(sorted(models))}


def _scatter(ax, rows, colors, size_scale=1.0) -> None:
    for r in rows:
        marker = MARKERS[(r["lobes_count"], r["combination"])]
        color = colors[r["model"]]
        filled = r["size"] is None
        ax.plot(r["seconds"], r["error"], marker, ms=5 * size_scale, mec=color, mfc=color if filled else "none",
                alpha=0.9, lw=0)


def _front_line(ax, xs, ys) -> None:
    """The front as a staircase: a point buys its error from its time on."""
    ax.step(xs, ys, where="post", color="black", lw=1.0, alpha=0.8)


def _legend(fig, colors, ncol: int = 8) -> None:
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], ls="", marker="o", color=c, label=m) for m, c in colors.items()]
    handles += [Line2D([], [], ls="", marker=mk, color="k", mfc="none" if n == 0 else "k",
                       label={0: "Lambertian only", 1: "1 lobe", 2: "2 lobes"}[n] + f", {c}")
                for (n, c), mk in MARKERS.items()]
    handles += [Line2D([], [], ls="", marker="o", color="grey", mfc="none", label="hollow: fitted on a subset"),
                Line2D([], [], color="black", label="Pareto front"),
                Line2D([], [], ls="", marker="*", color="red", ms=12, label=f"enough: within {ENOUGH:.0%} of best")]
    fig.legend(handles=handles, loc="lower center", ncol=ncol, fontsize=7, frameon=False)


def draw_materials(rows: list[dict], out_dir: Path, fronts: dict, time_label: str) -> list[str]:
    plt = pyplot()
    colors = _colors({r["model"] for r in rows})
    materials = list(fronts)
    files = []
    for page in range(0, len(materials), PAGE):
        names = materials[page:page + PAGE]
        cols = min(4, len(names))
        nrows = -(-len(names) // cols)
        fig, axes = plt.subplots(nrows, cols, figsize=(4.0 * cols, 3.3 * nrows + 1.2), dpi=100, squeeze=False)
        for ax in axes.ravel()[len(names):]:
            ax.axis("off")
        for ax, material in zip(axes.ravel(), names):
            rs = [r for r in rows if r["material"] == material]
            _scatter(ax, rs, colors)
            front = fronts[material]["front"]
            _front_line(ax, [f["seconds"] for f in front], [f["error"] for f in front])
            e = fronts[material]["enough"]
            ax.plot(e["seconds"], e["error"], "*", color="red", ms=13, mec="black", mew=0.5)
            ax.annotate(f"{e['family']} ({e['samples']})", (e["seconds"], e["error"]), fontsize=7,
                        textcoords="offset points", xytext=(5, 6), color="darkred")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_title(f"{material} ({len(rs)} fits)", fontsize=9)
            ax.tick_params(labelsize=7)
            ax.grid(True, which="both", alpha=0.2)
        for ax in axes[-1]:
            ax.set_xlabel(time_label, fontsize=8)
        for ax in axes[:, 0]:
            ax.set_ylabel("Ngan error on all samples", fontsize=8)
        fig.suptitle("Fitting: error on all samples against fit time, per material", fontsize=11)
        _legend(fig, colors, ncol=2 * cols + 1)
        legend_rows = -(-(len(colors) + len(MARKERS) + 3) // (2 * cols + 1))
        fig.tight_layout(rect=(0, (0.2 * legend_rows + 0.1) / fig.get_figheight(), 1, 0.97))
        files.append(save_figure(fig, out_dir / f"fitting_pareto_materials_{page // PAGE + 1}.png"))
    return files


def draw_pooled(rows: list[dict], out_dir: Path, summary: list[dict], subsets: list[dict], gains: list[dict],
                time_label: str, core_size: int | None) -> str:
    plt = pyplot()
    colors = _colors({r["model"] for r in rows})
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(17, 5.8), dpi=100, gridspec_kw={"width_ratios": [1.6, 1, 1.2]})
    everywhere = max(f["materials"] for f in summary)
    pooled = [f for f in summary if f["materials"] == everywhere]  # the core: every material
    for f in summary:
        x, y = f["seconds_median"], f["relative_median"]
        mk = MARKERS[(f["lobes"], f["combination"])]
        if f["materials"] == everywhere:
            a.errorbar(x, y, xerr=[[x - f["seconds_min"]], [f["seconds_max"] - x]],
                       yerr=[[y - f["relative_min"]], [f["relative_max"] - y]], fmt=mk, color=colors[f["model"]],
                       ms=7, elinewidth=0.7, alpha=0.9, capsize=0)
        else:  # one material only: no median to speak of
            a.plot(x, y, mk, color=colors[f["model"]], mfc="none", ms=5, alpha=0.5)
    cost, err = [f["seconds_median"] for f in pooled], [f["relative_median"] for f in pooled]
    front = pareto_front(cost, err)
    _front_line(a, [cost[i] for i in front], [err[i] for i in front])
    for k, i in enumerate(front):
        a.annotate(pooled[i]["family"], (cost[i], err[i]), fontsize=7, textcoords="offset points",
                   xytext=(4, -10 if k % 2 else 4))
    e = enough_point(cost, err, ENOUGH)
    a.plot(cost[e], err[e], "*", color="red", ms=15, mec="black", mew=0.5)
    a.set_xscale("log")
    a.set_yscale("log")
    fitted = "all samples" if core_size is None else f"{core_size:,} samples"
    a.set_xlabel(f"{time_label}, fitted on {fitted}: median, bar = range over materials")
    a.set_ylabel("error on all samples / the material's best core error")
    a.set_title(f"Pooled: filled = on all {everywhere} materials (median, range), front over these;\n"
                "hollow = fewer materials (the model's sampled slice)", fontsize=9)
    a.grid(True, which="both", alpha=0.2)

    sizes = [s["size"] for s in subsets]
    if sizes:
        pct = lambda key: [100 * (s[key] - 1) for s in subsets]  # noqa: E731
        b.plot(sizes, pct("error_ratio_median"), "o-", color="tab:blue", label="error: median")
        b.plot(sizes, pct("error_ratio_p90"), "o--", color="tab:blue", alpha=0.6, label="error: 90th percentile")
        b.axhline(1.0, color="grey", ls=":", lw=0.8)
        b.set_ylim(-0.05, max(1.2, 1.3 * max(pct("error_ratio_p90"))))
        worst = max(subsets, key=lambda s: s["error_ratio_max"])
        b.annotate(f"worst: +{100 * (worst['error_ratio_max'] - 1):.1f} % at {worst['size'] // 1000}k\n"
                   f"({worst['worst']})", (0.03, 0.80), xycoords="axes fraction", fontsize=7)
        b.set_xscale("log")
        b.set_xticks(sizes, [f"{s // 1000}k" for s in sizes])
        b.minorticks_off()
        b.set_xlabel("samples fitted (stratified subset)")
        b.set_ylabel("error on all samples vs the all-sample fit (% more)", color="tab:blue")
        twin = b.twinx()
        twin.plot(sizes, [s["time_ratio_median"] for s in subsets], "s-", color="tab:orange", label="time: median")
        twin.fill_between(sizes, [s["time_ratio_p10"] for s in subsets], [s["time_ratio_p90"] for s in subsets],
                          color="tab:orange", alpha=0.15)
        twin.set_ylabel("fit time / all-sample fit time (median, 10–90 %)", color="tab:orange")
        twin.set_ylim(0, max(1.05, 1.1 * max(s["time_ratio_p90"] for s in subsets)))
        b.legend(fontsize=7, loc="upper right")
        b.set_title(f"Fitting on a subset ({min(s['pairs'] for s in subsets)}–{max(s['pairs'] for s in subsets)} "
                    "fits per size)", fontsize=10)

    models = [g["model"] for g in gains if "second_lobe" in g or "fixed" in g]
    y = np.arange(len(models))
    for k, (what, color, label) in enumerate((("second_lobe", "tab:green", "second lobe (2 vs 1, Linear)"),
                                              ("fixed", "tab:purple", "Fixed vs Linear (1 lobe)"))):
        vals = [100 * g[what]["gain_median"] if what in g else 0.0 for g in gains if g["model"] in models]
        bars = c.barh(y + (k - 0.5) * 0.38, vals, height=0.38, color=color, label=label)
        for bar, g in zip(bars, [g for g in gains if g["model"] in models]):
            if what in g:
                c.annotate(f"×{g[what]['time_factor_median']:.1f} t", (max(bar.get_width(), 0), bar.get_y()),
                           fontsize=6, textcoords="offset points", xytext=(2, 0))
    c.axvline(100 * ENOUGH, color="red", ls=":", lw=1, label=f"{ENOUGH:.0%}: below, it stops paying")
    c.set_yticks(y, models, fontsize=7)
    c.set_xlabel("median error reduction (%), same material and samples; label: time factor")
    c.set_title("What more lobes or parameters buy\n(median over the materials and sample sets fitted both ways)",
                fontsize=9)
    c.legend(fontsize=7, loc="lower right")
    c.grid(True, axis="x", alpha=0.2)
    _legend(fig, colors)
    fig.tight_layout(rect=(0, 0.12, 1, 1))
    return save_figure(fig, out_dir / "fitting_pareto_pooled.png")


def summarise(rows: list[dict], core_size: int | None) -> dict:
    """Everything the charts and docs read, computed from the rows; families are pooled
    at the core fits' sample set (the one every material has)."""
    if not rows:
        return {"fronts": {}, "families": [], "subsets": [], "gains": []}
    return {"fronts": material_fronts(rows), "families": family_summary(rows, core_size),
            "subsets": subset_effect(rows), "gains": richer_gains(rows)}


def draw(numbers: dict, out_dir: Path) -> list[str]:
    """Per-material Pareto charts (pages of 12) and the pooled chart."""
    rows = numbers["rows"]
    if not rows:
        return []
    label = TIME_LABELS[numbers["clock"]]
    files = draw_materials(rows, out_dir, numbers["fronts"], label)
    files.append(draw_pooled(rows, out_dir, numbers["families"], numbers["subsets"], numbers["gains"], label,
                             numbers["core_size"]))
    return files
