"""Write the first part of docs/benchmarks.md (up to the batch section) from the raw outputs
in docs/bench/; the sections after the END marker are written by hand from the benchmarks
they name, and are kept as they are.

    brdflab bench --out docs/bench
    python benchmarks/fitting.py --json docs/bench/fitting.json > docs/bench/fitting.log
    python benchmarks/batch.py --json docs/bench/batch.json
    python benchmarks/report.py
"""

from __future__ import annotations

import json
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs"
END = ("<!-- The part above is written by benchmarks/report.py from docs/bench/; "
       "the sections below by hand, from the benchmarks they name. -->")


def fitting_rows(log: str):
    speed, published, multistart = [], [], []
    for line in log.splitlines():
        p = line.split()
        if "samples" in line and " it " in line:
            speed.append((p[0], p[1].replace("+", " + "), p[8], p[4], p[6], p[9]))
        elif "published" in line and "fitted" in line and len(p) >= 7:
            published.append((p[0], p[2], p[4], p[6].strip("("), *(p[10:13:2] if len(p) >= 13 else ("–", "–"))))
        elif " starts " in line and " gap " in line:
            multistart.append((p[0], p[1], p[3], p[8], f"{p[10]} {p[11]}"))
        elif line.strip().startswith("peak"):
            memory = line.strip()
    return speed, published, multistart, memory


def table(header: str, rows) -> str:
    cols = header.count("|") - 1
    out = [header, "|" + "|".join(["---"] * cols) + "|"]
    out += ["| " + " | ".join(str(x) for x in row) + " |" for row in rows]
    return "\n".join(out)


def main() -> None:
    bench = json.loads((DOCS / "bench" / "bench.json").read_text())
    speed, published, multistart, memory = fitting_rows((DOCS / "bench" / "fitting.log").read_text())
    r = bench["render"]
    sh = bench["sh"]
    frames = {(f["order"], f["geometry"]): f["ms"] for f in sh["frames"]}
    better = sum(float(f) < float(p) for _, p, f, *_ in published)
    glossy = {f["samples"]: f for f in r["fis"] if f["material"] == "glossy"}
    fis_ms, fis_err = (lambda n: glossy[n]["ms"]), (lambda n: 100 * glossy[n]["relative_rmse"])
    sh_error = {e["order"]: e["relative_rmse"] for e in sh["errors"]}
    sh_ms, sh_err = (lambda order: frames[(order, "sphere")]), (lambda order: 100 * sh_error[order])
    mesh_ratio = [frames[(order, "mesh")] / frames[(order, "sphere")] for order in sh_error]
    text = f"""# Benchmarks

Every number here was measured on this project's reference machine: 2 cores, 24 GiB, no GPU,
OpenGL from Mesa llvmpipe (OpenGL 4.5), Python 3.11, NumPy 2.4, with nothing else running.
Raw outputs: `docs/bench/`. The sections up to the batch fitting are written by
`python benchmarks/report.py`; the later ones by hand, from the benchmarks they name.

## Lobe evaluation throughput (NumPy, float64, one core)

`brdflab bench --out docs/bench`: 1,000,000 random direction pairs above the surface per
model, best of 3 (also `python benchmarks/model_throughput.py`).

{table("| model | Mpairs/s |", [(m["model"], f"{m['mpairs_per_s']:.1f}") for m in sorted(bench["models"], key=lambda m: -m["mpairs_per_s"])])}

Schwenk's survey ranks models by cost; NumPy agrees in kind: Lafortune and Phong (a dot
product and a power) cost about half of the microfacet models (half vector, Fresnel,
distribution, masking); Strauss, with its Fresnel and shadowing approximations on angles,
is the most expensive.

![Model throughput](bench/model_throughput.png)

## Fitting (Levenberg–Marquardt)

`python benchmarks/fitting.py --json docs/bench/fitting.json` (log: `docs/bench/fitting.log`).

### Speed on full MERL-size tables, load included

Each table is a real 90 × 90 × 180 MERL `.binary` file (33 MB, float64) written from a
measured slice; the time includes reading it; 1,111,428 valid samples above the surface.
BRDFLab (2009) needed 45.2 s and 94.2 s for such fits. Targets: two lobes ≤ 2 s, three ≤ 5 s.

{table("| material | lobes (Linear) | metric | wall time (s) | iterations | error |", speed)}

How: one pass over the samples per iteration accumulates per-channel Gram matrices of the
lobe values at the current parameters and at every finite-difference perturbation; cost,
JᵀJ and Jᵀr (with the scaling factors re-solved by NNLS for each perturbation) follow
exactly from them. Directions are generated per θh row from the table (no per-sample
arrays), a stratified 60,000-sample subset finds the basin first, and trial steps after a
rejection are evaluated on the cost alone.

### Against the published fits (Ngan et al. 2005)

Lambertian + LafortuneIso fitted with the defaults only (`--lobes`: Ngan metric, model-aware
restarts) on each measured slice, against the published parameters on the same data (their
kd is an albedo and enters as kd/π). Errors are over the (ωi, ωo) solid-angle measure with
θi, θo ≤ 80° (the slice expanded over φd); the last two columns recompute both on BRDFLab's
16 θi × 16 θo × 64 φo grid (`grid_error`, an independent route), which agrees within 2 % on
diffuse and glossy materials and misses highlights narrower than its 5° cells.
{better} of {len(published)} fits are better by the reported error.

{table("| material | published | fitted | time (s) | grid: published | grid: fitted |", published)}

### Against a long multi-start search

Lambertian + each model, Ngan metric, on a measured slice: our fit (model-aware restarts)
against the best of 30 fits from random starts inside the bounds.

{table("| material | model | ours | best of 30 | gap |", multistart)}

### Memory

{memory[0].upper() + memory[1:]} (nickel table, Lambertian + LafortuneIso; target: under 3 ×).

## Rendering (llvmpipe, software OpenGL)

`brdflab bench --out docs/bench`. Frame times at {r["size"]} × {r["size"]} in the reference
view; errors are relative RMSE against NumPy quadrature over the texels of the Venice
Sunset map reduced to 128 × 64, measured at {r["error_size"]} × {r["error_size"]}.

### Point light

{table("| material | ms / frame |", [(p["material"], f"{p['ms']:.1f}") for p in r["point"]])}

Point-light renders equal f(wi, wo)·cos θi from NumPy to 1e-3 relative, pixel by pixel.

### Filtered importance sampling

{table("| material | samples | ms / frame | relative RMSE |", [(f["material"], f["samples"], f"{f['ms']:.0f}", f"{100 * f['relative_rmse']:.2f} %") for f in r["fis"]])}

![Speed against accuracy](bench/render_speed_accuracy.png)

### Lobe viewer

{table("| subdivision level | triangles | ms / frame |", [(l["level"], f"{l['triangles']:,}", f"{l['ms']:.1f}") for l in r["lobe_viewer"]])}

A parameter change only rewrites uniforms, so level 5 redraws in under 10 ms.

### Spherical harmonics (Kautz et al. 2002)

BRDF product tables at the default setting (`brdflab/lighting/sh_tables.py`: 128 × 128
texels; both sources here are isotropic, so 2^12 samples per tabulated elevation, turned
about z), against the paper's minutes for analytic models and up to 90 minutes for measured
ones:

{table("| source | order | build time (s) |", [(t["source"], t["order"], f"{t['seconds']:.1f}") for t in sh["tables"]])}

Frame times with per-pixel rotation (view and light both free); the mesh is Spot subdivided
to {next(f["vertices"] for f in sh["frames"] if f["geometry"] == "mesh"):,} vertices (the paper's teapot had about 150,000):

{table("| order | sphere (ms) | mesh (ms) | mesh, fixed light (ms) | mesh, fixed view (ms) | relative RMSE (glossy, n = 20) |", [(e["order"], f"{frames[(e['order'], 'sphere')]:.0f}", f"{frames[(e['order'], 'mesh')]:.0f}", f"{frames.get((e['order'], 'fixed-light'), float('nan')):.0f}", f"{frames.get((e['order'], 'fixed-view'), float('nan')):.0f}", f"{100 * e['relative_rmse']:.2f} %") for e in sh["errors"]])}

On the sphere, SH order 5 ({sh_ms(5):.0f} ms, {sh_err(5):.2f} %) costs {sh_ms(5) / fis_ms(64):.2f}× FIS with 64
samples ({fis_ms(64):.0f} ms, {fis_err(64):.2f} %) and order 8 ({sh_ms(8):.0f} ms, {sh_err(8):.2f} %) {sh_ms(8) / fis_ms(256):.2f}× FIS
with 256 ({fis_ms(256):.0f} ms, {fis_err(256):.2f} %), on the glossy material (see the chart); on the mesh the
frame, with the per-pixel rotation (z-rotations and two tabulated ±90° x-rotations per band)
at every one of its pixels, costs {min(mesh_ratio):.1f}–{max(mesh_ratio):.1f}× the sphere's. The paper's fixed-light mode (lighting rotated into
each vertex's frame once, on the CPU) and fixed-view mode (each vertex's BRDF vector turned
to world once; a lighting change is then one dot product per vertex) remove that rotation;
their frame times include the per-vertex preparation when it is not cached.
"""
    page = DOCS / "benchmarks.md"
    old = page.read_text() if page.exists() else ""
    if old and END not in old:
        raise SystemExit(f"{page}: the marker that ends the generated part is missing; not overwritten")
    by_hand = old.split(END, 1)[1] if old else "\n"
    page.write_text(text + batch_section() + "\n" + END + by_hand)


def batch_section() -> str:
    """Batch fitting on Dask (benchmarks/batch.py), when its numbers exist."""
    path = DOCS / "bench" / "batch.json"
    if not path.exists():
        return ""
    b = json.loads(path.read_text())
    floor = b["tasks"] * b["task_seconds_mean"] / b["workers"]  # the fits' own time, perfectly shared
    return f"""
## Batch fitting (Dask)

`python benchmarks/batch.py --json docs/bench/batch.json`: {b["tasks"]} fits (31 MERL slices × 4
lobe sets), one after another in one process against `brdflab batch`'s LocalCluster of
{b["workers"]} workers, in one run. Load average {b["load_average_before"][0]:.1f} → {b["load_average_after"][0]:.1f}.

| route | seconds | against serial |
|---|---|---|
| one process | {b["serial_s"]:.1f} | 1.00× |
| plain process pool ({b["workers"]}) | {b["plain_pool_s"]:.1f} | {b["plain_pool_speedup"]:.2f}× |
| **batch, cluster running** | **{b["batch_s"]:.1f}** | **{b["speedup"]:.2f}×** |
| batch, cluster start-up included | {b["batch_s"] + b["cluster_startup_s"]:.1f} | {b["speedup_with_startup"]:.2f}× |

Errors equal to the serial ones (max relative difference {b["max_relative_error_difference"]:.1e}); Dask's overhead
{1e3 * b["dask_overhead_per_task_s"]:.1f} ms per task; the fits inside the workers averaged {b["task_seconds_mean"]:.3f} s against
{b["serial_s"] / b["tasks"]:.2f} s serially, so the batch ran within {100 * (b["batch_s"] / floor - 1):.0f} % of the {floor:.1f} s that {b["workers"]} workers
need at least. Before round 8 the batch reached 1.37–1.43×: Dask's nanny starts workers with
`MALLOC_TRIM_THRESHOLD_` set, which made every fit 30 % slower (`docs/batch.md`). Conditions,
earlier runs and the plan for a 64-core cluster: `docs/batch.md`.
"""


if __name__ == "__main__":
    main()
