"""Each lighting mode's error pixel by pixel against its cost, per class of map (issue 36 goal 5).

    python benchmarks/lighting_map_classes.py [--json docs/bench/lighting_map_classes.json]
                                              [--chart docs/images/lighting_map_classes.png]
                                              [--materials "GGX m=0.3" ...] [--settings "fis 64" ...]

Three materials (a Lambertian; GGX m = 0.3, a rough lobe the prefiltered mode should hold;
GGX m = 0.1, a narrow one), F0 = 1, under the fifteen synthetic maps (`lighting.synthetic_maps`:
sky, sun, interior, night, studio; a third held out, drawn dashed), maps at 128 × 64. Every
mode the renderer has — prefiltered, SH at orders 2, 4 and 8, FIS and MIS at 16, 64, 256 and
1,024 samples — renders the reference view at 32², scored against the subdivided texel
quadrature (`reference_view.refined_environment_image`) by the RMS of each pixel's relative
error in luminance (`pixel_relative_rmse`: what a user sees); each setting's 64² frame is timed
once per material (llvmpipe; a frame's cost does not depend on the map). The chart: one panel per
material × map class, error against frame time, one line per mode and map.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from brdflab.lighting.reference_view import pixel_relative_rmse, refined_environment_image, sphere_view
from brdflab.lighting.synthetic_maps import CLASSES, catalogue
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.render.context import create_context
from brdflab.render.object_view import ObjectRenderer, RenderSettings
from brdflab.study.lighting import build_sh_table, frame_ms

SIZE = 32
FRAME = 64
MAP_SIZE = (128, 64)
SETTINGS = [("prefiltered", None), *(("sh", L) for L in (2, 4, 8)),
            *((mode, n) for mode in ("fis", "mis") for n in (16, 64, 256, 1024))]
COLOURS = {"prefiltered": "tab:green", "sh": "tab:purple", "fis": "tab:blue", "mis": "tab:red"}


def lobe(model: str, **params: float) -> AnalyticMaterial:
    return AnalyticMaterial(model, "Linear", 3, [Lobe.create(model, [0.5] * 3, **params)])


MATERIALS = {"Lambertian": lambda: lobe("Lambertian"), "GGX m=0.3": lambda: lobe("CookTorranceGGX", m=0.3, F0=1.0),
             "GGX m=0.1": lambda: lobe("CookTorranceGGX", m=0.1, F0=1.0)}


def label(mode: str, setting: int | None) -> str:
    return mode if setting is None else f"{mode} {setting}"


def measure() -> dict:
    renderer = ObjectRenderer(create_context())
    inside = sphere_view(SIZE, SIZE).inside
    maps = [(spec, spec.build(*MAP_SIZE)) for spec in catalogue()]
    out = {"size": SIZE, "map_size": MAP_SIZE, "frame": FRAME, "materials": {}}
    for name, make in MATERIALS.items():
        material = make()
        renderer.set_source(material)
        renderer.set_environment(maps[0][1])
        ms = {}
        for mode, setting in SETTINGS:
            if mode == "sh":
                build_sh_table(material, setting)
                renderer.set_sh_order(setting)
            samples = setting if mode in ("fis", "mis") else 1
            ms[label(mode, setting)] = frame_ms(renderer, RenderSettings(mode, FRAME, FRAME, samples=samples))
        rows = []
        for spec, env in maps:
            renderer.set_environment(env)
            reference = refined_environment_image(material, env, SIZE, SIZE)
            errors = {}
            for mode, setting in SETTINGS:
                if mode == "sh":
                    renderer.set_sh_order(setting)
                samples = setting if mode in ("fis", "mis") else 1
                image = renderer.render(RenderSettings(mode, SIZE, SIZE, samples=samples))
                errors[label(mode, setting)] = pixel_relative_rmse(image, reference, inside)
            rows.append({"map": spec.name, "class": spec.kind, "held_out": spec.held_out, "errors": errors})
            best = min((e, k) for k, e in errors.items())
            print(f"{name:<11} {spec.name:<22}{'*' if spec.held_out else ' '} "
                  + "  ".join(f"{k} {100 * e:.1f}" for k, e in errors.items()) + f"   best {best[1]}", flush=True)
        out["materials"][name] = {"frame_ms": ms, "rows": rows}
    return out


def chart(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    materials = list(result["materials"])
    fig, axes = plt.subplots(len(materials), len(CLASSES), figsize=(3.2 * len(CLASSES), 2.8 * len(materials)),
                             sharex=True, sharey=True, constrained_layout=True)
    for i, name in enumerate(materials):
        ms = result["materials"][name]["frame_ms"]
        for j, kind in enumerate(CLASSES):
            ax = axes[i][j]
            for row in (r for r in result["materials"][name]["rows"] if r["class"] == kind):
                style = "--" if row["held_out"] else "-"
                for mode in COLOURS:
                    keys = [k for k in row["errors"] if k.split()[0] == mode]
                    x = [ms[k] for k in keys]
                    y = [max(100 * row["errors"][k], 1e-3) for k in keys]
                    ax.plot(x, y, style, marker="o", ms=3, lw=1, color=COLOURS[mode], alpha=0.8)
            ax.axhline(2.0, color="k", lw=0.6, ls=":")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_title(f"{name} · {kind}", fontsize=9)
            if i == len(materials) - 1:
                ax.set_xlabel(f"frame ms ({FRAME}², llvmpipe)", fontsize=8)
            if j == 0:
                ax.set_ylabel("error per pixel (%)", fontsize=8)
            ax.tick_params(labelsize=7)
    handles = [plt.Line2D([], [], color=c, marker="o", ms=3, lw=1, label=m) for m, c in COLOURS.items()]
    handles += [plt.Line2D([], [], color="grey", lw=1, ls="--", label="held-out map"),
                plt.Line2D([], [], color="k", lw=0.6, ls=":", label="2 %")]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8)
    fig.savefig(path, dpi=100)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json")
    ap.add_argument("--chart")
    ap.add_argument("--materials", nargs="+", choices=list(MATERIALS), help="only these materials")
    ap.add_argument("--settings", nargs="+", help='only these settings ("prefiltered", "sh 4", "fis 64", …)')
    args = ap.parse_args()
    for name in [k for k in MATERIALS if args.materials and k not in args.materials]:
        del MATERIALS[name]
    if args.settings:
        SETTINGS[:] = [s for s in SETTINGS if label(*s) in args.settings]
    result = measure()
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    if args.chart:
        chart(result, Path(args.chart))


if __name__ == "__main__":
    main()
