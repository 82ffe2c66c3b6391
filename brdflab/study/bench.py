"""`brdflab bench`: what each speed costs in accuracy, as numbers (JSON) and charts (PNG).

Renders run on whatever OpenGL the machine has (llvmpipe here); errors are relative RMSE
against NumPy quadrature over the environment map's texels in the reference view.
"""

from __future__ import annotations

import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from brdflab.lighting.envmap import load_environment
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.models import all_models
from brdflab.lighting.reference_view import environment_image, relative_rmse, sphere_view
from brdflab.io.resources import data_dir, default_environment_path
from brdflab.study.framework import Progress, measured_slice, pyplot, save_figure, timed
from brdflab.study.framework import quiet as _quiet


def stderr_progress(message: str) -> None:
    """One line per step on stderr, so a long run shows it is alive."""
    print(f"brdflab bench: {message}", file=sys.stderr, flush=True)

BENCH_MATERIALS = {
    "diffuse": lambda: AnalyticMaterial("diffuse", "Linear", 3, [Lobe.create("Lambertian", [0.25, 0.2, 0.15])]),
    "glossy": lambda: AnalyticMaterial("glossy", "Linear", 3, [Lobe.create("Lambertian", [0.05] * 3),
                                                               Lobe.create("BlinnPhong", [0.3] * 3, Exponent=60.0)]),
    "anisotropic": lambda: AnalyticMaterial("anisotropic", "Linear", 3, [Lobe.create("Lambertian", [0.03] * 3),
                                                                         Lobe.create("Ward", [0.6] * 3, ax=0.08, ay=0.3)]),
}


def model_throughput(pairs: int) -> list[dict]:
    rng = np.random.default_rng(0)
    v = rng.normal(size=(2, pairs, 3))
    v[..., 2] = np.abs(v[..., 2])
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    rows = []
    for m in all_models():
        s = timed(lambda: m.evaluate(v[0], v[1]), 3)
        rows.append({"model": m.name, "mpairs_per_s": pairs / s / 1e6})
    return rows


def _scene(quick: bool):
    """A renderer, the shipped map and its 128 × 64 reduction, frame and error sizes."""
    from brdflab.render.context import create_context
    from brdflab.render.object_view import ObjectRenderer

    ctx = create_context()
    env = load_environment(default_environment_path())
    return ctx, ObjectRenderer(ctx), env, env.downsampled(128, 64), (256 if quick else 512), (48 if quick else 96)


def render_numbers(quick: bool, progress: Progress = _quiet) -> dict:
    from brdflab.render.lobe_view import LobeViewer
    from brdflab.render.object_view import RenderSettings

    ctx, renderer, env, small, size, err_size = _scene(quick)
    counts = (16, 64) if quick else (16, 64, 256)
    out = {"renderer": ctx.info.get("GL_RENDERER", ""), "size": size, "error_size": err_size, "point": [], "fis": []}
    inside = sphere_view(err_size, err_size).inside
    for name, make in BENCH_MATERIALS.items():
        progress(f"rendering the {name} material (point light, FIS with {', '.join(map(str, counts))} samples)")
        material = make()
        renderer.set_material(material)
        ms = 1e3 * timed(lambda: renderer.render(RenderSettings("point", size, size)), 3)
        out["point"].append({"material": name, "ms": ms})
        reference = environment_image(material, small, err_size, err_size)
        for n in counts:
            renderer.set_environment(env)
            ms = 1e3 * timed(lambda: renderer.render(RenderSettings("fis", size, size, samples=n)), 1 if n > 64 else 2)
            renderer.set_environment(small)
            err = relative_rmse(renderer.render(RenderSettings("fis", err_size, err_size, samples=n)), reference, inside)
            out["fis"].append({"material": name, "samples": n, "ms": ms, "relative_rmse": err})
    progress("timing the lobe viewer")
    viewer = LobeViewer(ctx)
    viewer.set_original(BENCH_MATERIALS["glossy"]())
    out["lobe_viewer"] = []
    for level in (4, 5, 6, 7):
        viewer.settings.level = level
        ms = 1e3 * timed(lambda: viewer.render(size, size), 3)
        out["lobe_viewer"].append({"level": level, "triangles": viewer.triangle_count(), "ms": ms})
    return out


def big_mesh(min_vertices: int = 150_000):
    """A shipped mesh (Spot) subdivided until it has at least `min_vertices` (the paper used a
    teapot of about 150,000)."""
    import trimesh

    from brdflab.io.mesh import from_arrays, load_mesh

    base = load_mesh(data_dir("resources") / "meshes" / "spot.obj")
    v, f = base.positions.astype(float), base.faces.astype(np.int64)
    while len(v) < min_vertices:
        v, f = trimesh.remesh.subdivide(v, f)
    return from_arrays(v, f, name="spot-subdivided")


def sh_numbers(quick: bool, progress: Progress = _quiet) -> dict:
    from brdflab.sources.measured import read_slice
    from brdflab.render.object_view import RenderSettings
    from brdflab.lighting.sh_tables import brdf_table

    _, renderer, env, small, size, err_size = _scene(quick)
    orders = (3, 5) if quick else (3, 5, 8)
    material = AnalyticMaterial("glossy", "Linear", 3, [Lobe.create("Lambertian", [0.05] * 3),
                                                        Lobe.create("BlinnPhong", [0.3] * 3, Exponent=20.0)])
    out = {"size": size, "tables": [], "frames": [], "errors": [], "skipped": []}
    progress(f"building SH tables of orders {', '.join(map(str, orders))}")
    for order in orders:
        t0 = time.perf_counter()
        brdf_table(material, order)
        out["tables"].append({"source": "analytic (Lambertian + Blinn-Phong)", "order": order, "seconds": time.perf_counter() - t0})
    slice_path, why = measured_slice()
    if slice_path is None:
        out["skipped"].append({"row": "SH tables of a measured material", "why": why})
        progress(f"skipped the measured SH table rows: {why}")
    else:
        progress(f"building SH tables of the measured slice {slice_path.name}")
        table = read_slice(slice_path).to_full()
        for order in orders:
            t0 = time.perf_counter()
            brdf_table(table, order)
            out["tables"].append({"source": "measured (MERL gold-metallic-paint3, proxy-sampled)", "order": order,
                                  "seconds": time.perf_counter() - t0})
    reference = environment_image(material, small, err_size, err_size)
    inside = sphere_view(err_size, err_size).inside
    renderer.set_source(material)
    mesh = big_mesh(50_000 if quick else 150_000)
    for order in orders:
        progress(f"SH order {order}: error and frame times (sphere, {mesh.n_vertices}-vertex mesh, fixed variants)")
        renderer.set_sh_order(order)
        renderer.set_environment(small)
        err = relative_rmse(renderer.render(RenderSettings("sh", err_size, err_size)), reference, inside)
        out["errors"].append({"order": order, "relative_rmse": err})
        renderer.set_environment(env)
        for geometry in ("sphere", "mesh"):
            renderer.set_mesh(None if geometry == "sphere" else mesh)
            ms = 1e3 * timed(lambda: renderer.render(RenderSettings("sh", size, size, reference_view=geometry == "sphere")), 2)
            out["frames"].append({"order": order, "geometry": geometry,
                                  "vertices": 0 if geometry == "sphere" else mesh.n_vertices, "ms": ms})
        for variant in ("fixed-light", "fixed-view"):  # the paper's modes, per vertex on the mesh
            renderer.sh_variant = variant
            ms = 1e3 * timed(lambda: renderer.render(RenderSettings("sh", size, size, reference_view=False)), 2)
            out["frames"].append({"order": order, "geometry": variant, "vertices": mesh.n_vertices, "ms": ms})
        renderer.sh_variant = "dynamic"
        renderer.set_mesh(None)
    return out


def charts(result: dict, out_dir: Path) -> list[str]:
    import matplotlib.ticker

    plt = pyplot()

    files = []
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=110)
    for name in BENCH_MATERIALS:
        rows = [r for r in result["render"]["fis"] if r["material"] == name]
        ax.loglog([r["ms"] for r in rows], [100 * r["relative_rmse"] for r in rows], "o-", label=name)
        for r in rows:
            ax.annotate(f"{r['samples']}", (r["ms"], 100 * r["relative_rmse"]), textcoords="offset points", xytext=(4, 4), fontsize=8)
    sh_result = result.get("sh")
    if sh_result:
        frames = {f["order"]: f["ms"] for f in sh_result["frames"] if f["geometry"] == "sphere"}
        errs = sorted(sh_result["errors"], key=lambda e: e["order"])
        ax.loglog([frames[e["order"]] for e in errs], [100 * e["relative_rmse"] for e in errs], "s--", color="black",
                  label="SH, glossy (Blinn-Phong n=20)")
        for e in errs:
            ax.annotate(f"L={e['order']}", (frames[e["order"]], 100 * e["relative_rmse"]), textcoords="offset points",
                        xytext=(4, -10), fontsize=8)
    ax.axhline(2.0, color="grey", lw=0.8, ls=":")
    ax.set_xlabel(f"milliseconds per frame at {result['render']['size']}² ({result['render']['renderer'].split(' (')[0]})")
    ax.set_ylabel("relative RMSE vs quadrature (%)")
    ax.set_title("Environment lighting: speed against accuracy (FIS labels: samples)")
    ax.legend()
    fig.tight_layout()
    files.append(save_figure(fig, out_dir / "render_speed_accuracy.png"))

    fig, ax = plt.subplots(figsize=(6.4, 4.6), dpi=110)
    rows = sorted(result["models"], key=lambda r: r["mpairs_per_s"])
    bars = ax.barh([r["model"] for r in rows], [r["mpairs_per_s"] for r in rows], color="#4a7bb7")
    for bar, r in zip(bars, rows):
        ax.text(bar.get_width() * 1.03, bar.get_y() + bar.get_height() / 2, f"{r['mpairs_per_s']:.0f}", va="center", fontsize=8)
    ax.set_xscale("log")
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())  # decades only: no crowded labels
    ax.set_xlabel("million direction pairs per second (NumPy, one core)")
    ax.set_title("What each lobe model costs")
    fig.tight_layout()
    files.append(save_figure(fig, out_dir / "model_throughput.png"))
    return files


def run(out_dir: Path, quick: bool = False, progress: Progress = _quiet) -> dict:
    """Measure everything, write the charts and bench.json into `out_dir`; the results."""
    from brdflab.io.atomic import atomic_write

    result = {"machine": {"platform": platform.platform(), "processor": platform.processor() or platform.machine()},
              "quick": quick}
    progress("timing every lobe model (NumPy)")
    result["models"] = model_throughput(100_000 if quick else 1_000_000)
    result["render"] = render_numbers(quick, progress)
    result["sh"] = sh_numbers(quick, progress)
    progress("drawing the charts")
    result["charts"] = charts(result, out_dir)
    atomic_write(out_dir / "bench.json", json.dumps(result, indent=2).encode())
    return result
