"""Study part `lighting-classes`: each lighting mode's error pixel by pixel against its cost,
per class of map, held-out maps marked (issue 36 goal 5).

The maps are the synthetic ones (`lighting.synthetic_maps`: sky, sun, interior, night, studio;
a third of them held out of every tuning, drawn dashed). Every mode the renderer has renders
the reference view, scored against the subdivided texel quadrature
(`reference_view.refined_environment_image`, an independent route) by the RMS of each pixel's
relative error in luminance (`pixel_relative_rmse`: what a user sees). A setting's frame is
timed once per material (a frame's cost does not depend on the map). Materials: a Lambertian,
GGX m = 0.3 (a rough lobe prefiltered lighting should hold) and GGX m = 0.1 (a narrow one),
F0 = 1; the context's material alone when the study is scoped to a scene.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

from brdflab.study.framework import Part, StudyContext, pyplot, register, save_figure

SETTINGS = (("prefiltered", None), *(("sh", order) for order in (2, 4, 8)),
            *((mode, n) for mode in ("fis", "mis") for n in (16, 64, 256, 1024)))
QUICK_SETTINGS = (("prefiltered", None), ("sh", 2), ("sh", 4), ("fis", 16), ("fis", 64), ("mis", 16), ("mis", 64))
COLOURS = {"prefiltered": "tab:green", "sh": "tab:purple", "fis": "tab:blue", "mis": "tab:red"}
GOAL = 0.02  # issue 36: 2 % per pixel


def _lobe(model: str, **params: float):
    from brdflab.material.analytic import AnalyticMaterial, Lobe

    return AnalyticMaterial(model, "Linear", 3, [Lobe.create(model, [0.5] * 3, **params)])


MATERIALS = {"Lambertian": lambda: _lobe("Lambertian"),
             "GGX m=0.3": lambda: _lobe("CookTorranceGGX", m=0.3, F0=1.0),
             "GGX m=0.1": lambda: _lobe("CookTorranceGGX", m=0.1, F0=1.0)}
QUICK_MATERIALS = ("GGX m=0.3",)


def label(mode: str, setting: int | None) -> str:
    return mode if setting is None else f"{mode} {setting}"


def maps(quick: bool) -> list:
    """The catalogue's maps; quick: one tuning and one held-out map of each class that has both."""
    from brdflab.lighting.synthetic_maps import CLASSES, catalogue

    specs = catalogue()
    if not quick:
        return specs
    chosen = []
    for kind in CLASSES:
        for held_out in (False, True):
            chosen += [s for s in specs if s.kind == kind and s.held_out == held_out][:1]
    return chosen


def materials(context: StudyContext) -> dict:
    chosen = context.source if context.source is not None else context.material
    if chosen is not None:
        return {"current material": lambda: chosen}
    names = QUICK_MATERIALS if context.quick else tuple(MATERIALS)
    return {name: MATERIALS[name] for name in names}


def measure(context: StudyContext) -> dict:
    size, frame, map_size = (16, 32, (64, 32)) if context.quick else (32, 64, (128, 64))
    return measure_maps(materials(context), maps(context.quick), QUICK_SETTINGS if context.quick else SETTINGS,
                        size, frame, map_size, context)


def measure_maps(chosen: dict, specs: list, settings, size: int, frame: int, map_size: tuple[int, int],
                 context: StudyContext) -> dict:
    """Errors of `settings` per material (name → maker) and synthetic map, and their frame times."""
    from brdflab.lighting.reference_view import pixel_relative_rmse, refined_environment_image, sphere_view
    from brdflab.render.context import create_context
    from brdflab.render.object_view import ObjectRenderer, RenderSettings
    from brdflab.study.lighting import build_sh_table, frame_ms

    renderer = ObjectRenderer(create_context())
    inside = sphere_view(size, size).inside
    built = [(spec, spec.build(*map_size)) for spec in specs]
    numbers = {"size": size, "map_size": list(map_size), "frame": frame, "goal": GOAL,
               "renderer": renderer.ctx.info.get("GL_RENDERER", ""), "materials": {}}
    for name, make in chosen.items():
        if context.cancelled():
            break
        source = make()
        renderer.set_source(source)
        renderer.set_environment(built[0][1])
        context.progress(f"lighting-classes: {name}, frame times")
        ms = {}
        for mode, setting in settings:
            if mode == "sh":
                build_sh_table(source, setting)
                renderer.set_sh_order(setting)
            samples = setting if mode in ("fis", "mis") else 1
            ms[label(mode, setting)] = frame_ms(renderer, RenderSettings(mode, frame, frame, samples=samples))
        rows = []
        for spec, env in built:
            if context.cancelled():
                break
            context.progress(f"lighting-classes: {name}, {spec.name}")
            renderer.set_environment(env)
            reference = refined_environment_image(source, env, size, size)
            errors = {}
            for mode, setting in settings:
                if mode == "sh":
                    renderer.set_sh_order(setting)
                samples = setting if mode in ("fis", "mis") else 1
                image = renderer.render(RenderSettings(mode, size, size, samples=samples))
                errors[label(mode, setting)] = pixel_relative_rmse(image, reference, inside)
            rows.append({"map": spec.name, "class": spec.kind, "held_out": spec.held_out, "errors": errors})
        numbers["materials"][name] = {"frame_ms": ms, "rows": rows}
    return numbers


def within_goal(numbers: dict) -> list[str]:
    """Per material, in words: on how many maps (held-out ones apart) some setting of ≤ 64
    samples per pixel reaches the goal, and the cheapest setting that does on every map."""
    words = []
    for name, entry in numbers["materials"].items():
        rows = entry["rows"]
        if not rows:
            continue
        cheap = [k for k in entry["frame_ms"] if len(k.split()) == 1 or k.split()[0] == "sh" or int(k.split()[1]) <= 64]
        met = [r for r in rows if min(r["errors"][k] for k in cheap) <= numbers["goal"]]
        held = [r for r in rows if r["held_out"]]
        everywhere = [k for k in sorted(entry["frame_ms"], key=entry["frame_ms"].get)
                      if all(r["errors"][k] <= numbers["goal"] for r in rows)]
        words.append(f"{name}: ≤ 64 samples within {100 * numbers['goal']:.0f} % on {len(met)} of {len(rows)} maps "
                     f"({sum(r in met for r in held)} of {len(held)} held out); within it everywhere: "
                     + (f"{everywhere[0]} ({entry['frame_ms'][everywhere[0]]:.1f} ms)" if everywhere else "no setting"))
    return words


def draw(numbers: dict, out_dir: Path) -> list[str]:
    from matplotlib.ticker import FuncFormatter, NullFormatter

    from brdflab.lighting.synthetic_maps import CLASSES

    plt = pyplot()
    names = list(numbers["materials"])
    if not names:
        return []
    fig, axes = plt.subplots(len(names), len(CLASSES), figsize=(3.2 * len(CLASSES), 2.8 * len(names) + 1.2),
                             sharex=True, sharey=True, squeeze=False, constrained_layout=True)
    for i, name in enumerate(names):
        entry = numbers["materials"][name]
        for j, kind in enumerate(CLASSES):
            ax = axes[i][j]
            for row in (r for r in entry["rows"] if r["class"] == kind):
                for mode, colour in COLOURS.items():
                    keys = [k for k in row["errors"] if k.split()[0] == mode]
                    ax.plot([entry["frame_ms"][k] for k in keys], [max(100 * row["errors"][k], 1e-3) for k in keys],
                            "--" if row["held_out"] else "-", marker="o", ms=4 if row["held_out"] else 3, lw=1,
                            color=colour, alpha=0.8, mfc="none" if row["held_out"] else colour)
            ax.axhline(100 * numbers["goal"], color="k", lw=0.6, ls=":")
            ax.set_xscale("log")
            ax.set_yscale("log")
            for axis in (ax.xaxis, ax.yaxis):
                axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
                axis.set_minor_formatter(NullFormatter())
            ax.set_title(f"{name} · {kind}", fontsize=9)
            if i == len(names) - 1:
                ax.set_xlabel(f"ms per {numbers['frame']}² frame", fontsize=8)
            if j == 0:
                ax.set_ylabel("error per pixel (%)", fontsize=8)
            ax.tick_params(labelsize=7)
    handles = [plt.Line2D([], [], color=c, marker="o", ms=3, lw=1, label=m) for m, c in COLOURS.items()]
    handles += [plt.Line2D([], [], color="grey", lw=1, ls="--", marker="o", ms=4, mfc="none", label="held-out map"),
                plt.Line2D([], [], color="k", lw=0.6, ls=":", label=f"{100 * numbers['goal']:.0f} % goal")]
    caption = ("Per pixel: the RMS of each pixel's relative error in luminance against the subdivided texel "
               f"quadrature, reference view at {numbers['size']}², maps at {numbers['map_size'][0]} × "
               f"{numbers['map_size'][1]}; along a line a mode's settings (SH orders, samples per pixel). "
               + " ".join(f"{w}." for w in within_goal(numbers)))
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8,
               title=textwrap.fill(caption, 190), title_fontsize=8)
    return [save_figure(fig, out_dir / "lighting_classes.png")]


register(Part("lighting-classes", "environment lighting per map class: error per pixel against frame time, "
                                  "held-out maps marked", measure, draw,
              lesson="A method tuned on some maps must hold on the next user's: per class of map (sky, sun, "
                     "interior, night, studio), each mode's error per pixel against its cost, the held-out maps "
                     "dashed."))
