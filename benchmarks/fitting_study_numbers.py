"""The numbers docs/study.md, the README and docs/benchmarks.md quote from the fitting study,
recomputed from its stored rows (not from the summaries the study wrote beside them).

    python benchmarks/fitting_study_numbers.py [DIR]     # DIR: docs/study/fitting by default

Prints: coverage (fits, CPU s, which slices are measured whole); per material the cheapest
fit within 5 % of its best error (the charts' red star), and what the Fixed twin of two GGX
lobes gives where it is the star; the 20 k pooled view of two and one GGX lobes; one GGX
lobe against the other single lobes; what a second lobe and the Fixed combination buy; what
subsets cost; fit times.
"""

from __future__ import annotations

import sys
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.study.fitting import FULL
from brdflab.study.framework import read_study


def size_name(size) -> str:
    return "all" if size is None else f"{size // 1000}k"


def star(rows: list[dict], best: float) -> dict:
    """The cheapest fit within 5 % of the lowest error `best` (ties: the lower error)."""
    good = [r for r in rows if r["error"] <= 1.05 * best]
    return min(good, key=lambda r: (r["seconds"], r["error"]))


def full_matrix(folder: Path) -> dict:
    """The fitting part of the study in `folder`, or an error where it is not (part of) the
    full matrix: the numbers below compare its families at 20 k and at every size."""
    numbers = read_study(folder).get("parts", {}).get("fitting")
    if numbers is None:
        raise BRDFLabError(f"{folder}: no fitting study here (brdflab study --part fitting --out {folder})")
    matrix = (numbers["core_size"], numbers["sizes"], numbers["fixed_sizes"], numbers["per_model"],
              numbers["every_family_core"])
    if matrix != (FULL.core_size, list(FULL.sizes), list(FULL.fixed_sizes), FULL.per_model, FULL.every_family_core):
        raise BRDFLabError(f"{folder}: these numbers are the full matrix's (every family at 5 k to all samples), "
                           "and this study fitted a smaller one (--quick or scoped)")
    return numbers


def main(folder: Path) -> None:
    numbers = full_matrix(folder)
    rows = numbers["rows"]  # the fits that ended with an error; those that could not run are in "failed"
    per_slice = numbers["fits_planned"] // len(numbers["materials"])
    by_material = defaultdict(list)
    for r in rows:
        by_material[r["material"]].append(r)
    best = {m: min(r["error"] for r in rs) for m, rs in by_material.items()}
    whole = sorted(m for m, rs in by_material.items() if len(rs) == per_slice)
    print(f"fits {len(rows)}, CPU s {sum(r['seconds'] for r in rows):,.0f}, "
          f"failed {len(numbers['failed'])}, "
          f"worse than zero {sum(r['error'] >= r['zero_error'] for r in rows)}")
    print(f"whole slices ({len(whole)}): {', '.join(whole)}")
    partial = {m: len(rs) for m, rs in by_material.items() if len(numbers["families"]) < len(rs) < per_slice}
    print(f"partial slices: {partial}")
    cost = [sum(r["seconds"] for r in by_material[m]) for m in whole]
    if cost:
        print(f"CPU s per whole slice: {min(cost):,.0f}-{max(cost):,.0f}, mean {np.mean(cost):,.0f}")

    print("\n== the star (cheapest within 5 % of the best) per material")
    stars = {m: star(rs, best[m]) for m, rs in by_material.items()}
    by_key = {(r["material"], r["size"], r["family"]): r for r in rows}
    print(Counter(s["family"] for s in stars.values()).most_common())
    for m in whole:
        s = stars[m]
        print(f"  {m}: {s['family']} {size_name(s['size'])} {s['seconds']:.2f} s, +{100 * (s['error'] / best[m] - 1):.1f} %")
    sizes = Counter(size_name(stars[m]["size"]) for m in whole)
    print(f"  stars' sample sets on whole slices: {dict(sizes)}")
    others = defaultdict(list)
    for m, s in sorted(stars.items()):
        if not s["family"].startswith("2×CookTorranceGGX"):
            others[s["family"]].append(m)
    print(f"  stars on other families: {dict(others)}")
    twin = [(s, by_key[(m, s["size"], "2×CookTorranceGGX Linear")]) for m, s in stars.items()
            if s["family"] == "2×CookTorranceGGX Fixed"]
    if twin:
        e = np.array([a["error"] / b["error"] for a, b in twin])
        t = np.array([a["seconds"] / b["seconds"] for a, b in twin])
        print(f"  where 2×GGX Fixed is the star ({len(twin)}): error / 2×GGX Linear's on the same samples "
              f"median {np.median(e):.2f} ({e.min():.2f}-{e.max():.2f}), time x{t.min():.1f}-{t.max():.1f}")

    print("\n== pooled at 20 k (relative to each material's best 20 k fit)")
    core = [r for r in rows if r["size"] == 20_000]
    best20 = {m: min(r["error"] for r in core if r["material"] == m) for m in by_material}
    fam = defaultdict(list)
    for r in core:
        fam[r["family"]].append(r)
    for name in ("2×CookTorranceGGX Linear", "2×CookTorranceGGX Fixed", "1×CookTorranceGGX Linear"):
        rel = np.array([r["error"] / best20[r["material"]] for r in fam[name]])
        sec = np.array([r["seconds"] for r in fam[name]])
        print(f"  {name}: relative median {np.median(rel):.3f} ({rel.min():.2f}-{rel.max():.2f}), "
              f"CPU s median {np.median(sec):.2f} ({sec.min():.2f}-{sec.max():.2f}), n={len(rel)}")
    best_family = Counter(min((r for r in core if r["material"] == m), key=lambda r: r["error"])["family"]
                          for m in by_material)
    print(f"  best family at 20 k: {best_family.most_common(4)}")
    single = Counter(min((r for r in core if r["material"] == m and r["lobes_count"] == 1
                          and r["combination"] == "Linear"), key=lambda r: r["error"])["model"] for m in by_material)
    print(f"  best single Linear lobe at 20 k: {single.most_common(4)}")

    print("\n== one GGX lobe (Linear) against other single lobes at 20 k, same material: median error ratio")
    for other in ("1×CookTorrance Linear", "1×LafortuneIso Linear", "Lambertian Linear"):
        ratio = [r["error"] / by_key[(r["material"], r["size"], other)]["error"] for r in core
                 if r["family"] == "1×CookTorranceGGX Linear"]
        print(f"  against {other}: {np.median(ratio):.2f} ({len(ratio)} pairs)")
    alone = [m for m, s in stars.items() if s["family"].startswith("1×")]
    near = [m for m, rs in by_material.items()
            if any(r["family"] == "1×CookTorranceGGX Linear" and r["error"] <= 1.05 * best[m] for r in rs)]
    print(f"  one lobe is the star on {alone}; 1×GGX Linear within 5 % of the best on {near}")

    print("\n== what a second lobe (2 vs 1, Linear) and Fixed (vs Linear, 1 lobe) buy: median gain, pairs, time x")
    for model in sorted({r["model"] for r in rows if r["lobes_count"] > 0}):
        line, one = [], f"1×{model} Linear"
        for what, other in (("second lobe", f"2×{model} Linear"), ("Fixed", f"1×{model} Fixed")):
            pairs = [(by_key[(m, s, one)], r) for (m, s, f), r in by_key.items()
                     if f == other and (m, s, one) in by_key]
            g = [1 - b["error"] / a["error"] for a, b in pairs]
            t = [b["seconds"] / a["seconds"] for a, b in pairs]
            line.append(f"{what} {100 * np.median(g):+.1f} % (max {100 * max(g):.0f} %, {len(g)} pairs, "
                        f"{np.median(t):.1f}x)")
        print(f"  {model}: " + "; ".join(line))

    print("\n== subsets against the same family on all samples, same material")
    full = {(r["material"], r["family"]): r for r in rows if r["size"] is None}
    for size in (5_000, 20_000, 50_000, 200_000):
        pairs = [(r, full[(r["material"], r["family"])]) for r in rows
                 if r["size"] == size and (r["material"], r["family"]) in full]
        e = np.array([a["error"] / b["error"] - 1 for a, b in pairs])
        t = np.array([a["seconds"] / b["seconds"] for a, b in pairs])
        worst = pairs[int(np.argmax(e))][0]
        print(f"  {size_name(size)}: {len(e)} pairs, median +{100 * np.median(e):.4f} %, "
              f"p90 {100 * np.percentile(e, 90):.3f} %, time x{np.median(t):.2f}; "
              f"worst +{100 * e.max():.0f} % ({worst['family']} on {worst['material']})")

    print("\n== fit times, CPU s min / median / max")
    for size in (None, 5_000, 20_000):
        for n, c in ((1, "Linear"), (2, "Linear"), (1, "Fixed"), (2, "Fixed")):
            sec = np.array([r["seconds"] for r in rows if r["size"] == size and r["lobes_count"] == n
                            and r["combination"] == c])
            print(f"  {size_name(size)} {n} lobe(s) {c}: {sec.min():.2f} / {np.median(sec):.2f} / "
                  f"{sec.max():.1f} (n={sec.size})")


if __name__ == "__main__":
    try:
        main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/study/fitting"))
    except BRDFLabError as e:
        print(f"fitting_study_numbers: {e}", file=sys.stderr)
        sys.exit(2)
