"""Study part `lighting`: environment lighting, error against frame time, for every lighting
mode the object view has, per material class, on real environment maps.

Error: relative RMSE of the reference-view sphere against NumPy quadrature over the map's
texels (`reference_view.environment_image`; for a lobe narrower than the texels, with the
texels near each mirror direction subdivided: `quadrature_reference`), the map
area-averaged to 128 × 64 for both the render and the reference. Frame time: one frame of the reference view with the full
map, on whatever OpenGL this machine has, once per material and setting (the map's content
does not change the work per pixel; SH frames read only order² lighting coefficients). The
reference's own resolution is measured too (`reference_floor`): targets within it are not
judged. The sweep is driven by `object_view.MODES` through `MODE_SWEEPS`, one row of
settings per mode; a mode without a row is an error, so no method the renderer gains goes
unmeasured. The charts are drawn by `lighting_charts`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.io.resources import data_dir, shared_data_dir
from brdflab.lighting.envmap import EnvironmentMap, load_environment
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.study.framework import Part, StudyContext, measured_slice, register, timed
from brdflab.study.lighting_charts import draw, summary

THRESHOLDS = (0.01, 0.02, 0.05)  # error targets of the summary table
REDUCED = (128, 64)  # the map the error is measured with (render and reference alike)
FLOOR_SIZE = 16  # image size of the reference's own resolution check (cheap; an estimate)
SHORT_FRAME_S = 0.2  # frames shorter than this are timed three times (best kept)


@dataclass(frozen=True)
class Sweep:
    """The settings a lighting mode is measured at (full and quick run). `error`: whether
    its image under an environment is an estimate of that lighting at all."""

    full: tuple[dict, ...]
    quick: tuple[dict, ...]
    error: bool = True


def _samples(*counts: int) -> tuple[dict, ...]:
    return tuple({"samples": n} for n in counts)


def _orders(*orders: int) -> tuple[dict, ...]:
    return tuple({"order": n} for n in orders)


MODE_SWEEPS: dict[str, Sweep] = {
    # exact for one point light, not an environment estimate: the floor of the cost
    "point": Sweep(({},), ({},), error=False),
    "fis": Sweep(_samples(4, 16, 64, 256, 1024), _samples(4, 16, 64)),
    "sh": Sweep(_orders(2, 3, 4, 6, 8, 12), _orders(2, 4)),
    "prefiltered": Sweep(({},), ({},)),
    "mis": Sweep(_samples(4, 16, 64, 256, 1024), _samples(4, 16, 64)),
}


def sweeps(quick: bool, modes: tuple[str, ...] | None = None) -> dict[str, tuple[dict, ...]]:
    """The settings of every lighting mode (default: the renderer's MODES, read now)."""
    if modes is None:
        from brdflab.render import object_view

        modes = object_view.MODES
    missing = [m for m in modes if m not in MODE_SWEEPS]
    if missing:
        raise BRDFLabError(f"lighting mode {', '.join(missing)} has no settings in the lighting study's "
                           "MODE_SWEEPS (brdflab/study/lighting.py): add a row so that it is measured")
    return {m: (MODE_SWEEPS[m].quick if quick else MODE_SWEEPS[m].full) for m in modes}


def setting_label(setting: dict) -> str:
    """'n=64' (samples), 'L=5' (SH order) or '' (a mode without settings)."""
    if "samples" in setting:
        return f"n={setting['samples']}"
    if "order" in setting:
        return f"L={setting['order']}"
    return ""


# --- the test matrix -------------------------------------------------------------------------
def _lobe(model: str, **params: float) -> Callable[[], AnalyticMaterial]:
    return lambda: AnalyticMaterial(model, "Linear", 3, [Lobe.create(model, [0.5] * 3, **params)])


MATERIAL_CLASSES: dict[str, Callable[[], AnalyticMaterial]] = {
    "Lambertian": _lobe("Lambertian"),
    "Blinn-Phong n=10": _lobe("BlinnPhong", Exponent=10.0),
    "Blinn-Phong n=100": _lobe("BlinnPhong", Exponent=100.0),
    "Blinn-Phong n=1000": _lobe("BlinnPhong", Exponent=1000.0),
    "Blinn-Phong n=10000": _lobe("BlinnPhong", Exponent=10000.0),
    "Cook-Torrance m=0.5": _lobe("CookTorrance", m=0.5),
    "Cook-Torrance m=0.2": _lobe("CookTorrance", m=0.2),
    "Cook-Torrance m=0.05": _lobe("CookTorrance", m=0.05),
    "Ward ax=0.05 ay=0.3 (anisotropic)": _lobe("Ward", ax=0.05, ay=0.3),
}
QUICK_CLASSES = ("Lambertian", "Blinn-Phong n=100", "Blinn-Phong n=1000")
MEASURED_CLASS = "MERL gold-metallic-paint3 (measured slice)"

# (file, where it lives, what makes it hard); the first is the map frames are timed with
MAPS = (("quarry_01_1k.hdr", "shared", "sun: a small, very bright source"),
        ("royal_esplanade_1k.hdr", "shared", "night: street lamps"),
        ("venice_sunset_1k.hdr", "shipped", "sunset: a soft, broad sky"))
QUICK_MAPS = MAPS[:1]


def material_classes(quick: bool, skipped: list[dict]) -> dict[str, Callable[[], object]]:
    """The material classes of the run; the measured one only with the shared data."""
    names = QUICK_CLASSES if quick else tuple(MATERIAL_CLASSES)
    classes: dict[str, Callable[[], object]] = {n: MATERIAL_CLASSES[n] for n in names}
    if not quick:
        path, why = measured_slice()
        if path is None:
            skipped.append({"what": MEASURED_CLASS, "why": why})
        else:
            from brdflab.sources.measured import read_slice

            classes[MEASURED_CLASS] = lambda: read_slice(path)
    return classes


def study_maps(quick: bool, skipped: list[dict]) -> list[tuple[str, str, EnvironmentMap]]:
    """(name, what makes it hard, map) of the run; without the shared data, the shipped map."""
    chosen, shared = (QUICK_MAPS if quick else MAPS), shared_data_dir()
    maps = []
    for file, where, character in chosen:
        folder = data_dir("resources") / "envmaps" if where == "shipped" else (shared / "envmaps" if shared else None)
        if folder is None or not (folder / file).is_file():
            skipped.append({"what": file, "why": "no shared data: set BRDFLAB_SHARED, or put shared/data next "
                                                "to the checkout" if folder is None else f"not found: {folder / file}"})
            continue
        maps.append((Path(file).stem, character, load_environment(folder / file)))
    if not maps:
        file, _, character = MAPS[-1]
        maps.append((Path(file).stem, character, load_environment(data_dir("resources") / "envmaps" / file)))
    return maps


def reduced(env: EnvironmentMap) -> EnvironmentMap:
    """The map area-averaged to 128 × 64 (or the largest sizes below that divide it evenly)."""
    small = env.downsampled_within(*REDUCED)
    if small.width < 16 or small.height < 8:
        raise BRDFLabError(f"the {env.width}×{env.height} map cannot be reduced evenly for the lighting study "
                           "(its sides have no divisors of at least 16 × 8)", env.path)
    return small


# --- measuring -------------------------------------------------------------------------------
def split_texels(small: EnvironmentMap) -> EnvironmentMap:
    """The same map with every texel split 2 × 2 (the same radiance, four times the quadrature points)."""
    return EnvironmentMap(np.repeat(np.repeat(small.data, 2, axis=0), 2, axis=1), small.name, small.path)


def reference_floor(source, small: EnvironmentMap) -> float:
    """How far the quadrature reference can be trusted: its relative change when every texel
    of the reduced map is split 2 × 2 (the same radiance, four times the quadrature points).
    Lobes narrower than a texel fall between texel centres: errors below this are not resolved."""
    from brdflab.lighting.reference_view import environment_image, relative_rmse, sphere_view

    split = split_texels(small)
    coarse = environment_image(source, small, FLOOR_SIZE, FLOOR_SIZE)
    fine = environment_image(source, split, FLOOR_SIZE, FLOOR_SIZE)
    return relative_rmse(coarse, fine, sphere_view(FLOOR_SIZE, FLOOR_SIZE).inside)


def refined_floor(source, small: EnvironmentMap) -> float:
    """The same check for `refined_environment_image`: its relative change when every texel
    of the map is split 2 × 2 and the near ones then subdivided a quarter as finely (parts
    twice as large where the lobe is, texel centres four times as many elsewhere: an
    estimate of both halves' error, conservative for the first)."""
    from brdflab.lighting.reference_view import SUBDIVISION, refined_environment_image, relative_rmse, sphere_view

    split = split_texels(small)
    fine = refined_environment_image(source, small, FLOOR_SIZE, FLOOR_SIZE)
    other = refined_environment_image(source, split, FLOOR_SIZE, FLOOR_SIZE, subdivision=SUBDIVISION // 4)
    return relative_rmse(fine, other, sphere_view(FLOOR_SIZE, FLOOR_SIZE).inside)


def quadrature_reference(source, small: EnvironmentMap, size: int,
                         resolve: float | None = None) -> tuple[np.ndarray, float, str]:
    """The reference image (size²), its floor and its kind: `refined_environment_image`
    (the texels near each mirror direction subdivided), or, given `resolve`, texel centres
    where their own floor is within it. The study always subdivides: the texel-centre floor,
    probed at 16², said 0.11 % for Cook–Torrance m = 0.2 under the sunset where the two
    references differ by 1.0 % at 48²."""
    from brdflab.lighting.reference_view import environment_image, refined_environment_image

    if resolve is not None and (floor := reference_floor(source, small)) <= resolve:
        return environment_image(source, small, size, size), floor, "texel centres"
    return refined_environment_image(source, small, size, size), refined_floor(source, small), "subdivided"


def frame_ms(renderer, settings) -> float:
    """Milliseconds per frame: a tiny frame first (compiles the program, builds the mode's
    resources), then one frame; a short one is timed again and the best kept."""
    renderer.render(replace(settings, width=8, height=8))
    t0 = time.perf_counter()
    renderer.render(settings)
    first = time.perf_counter() - t0
    return 1e3 * (first if first >= SHORT_FRAME_S else min(first, timed(lambda: renderer.render(settings), 2)))


def build_sh_table(source, order: int) -> float:
    """Seconds to build the SH BRDF table of this order; the table is left where the
    renderer finds it, so the frames below draw with the table that was timed."""
    from brdflab.lighting.sh_tables import brdf_table, remember_table

    t0 = time.perf_counter()
    table = brdf_table(source, order)
    seconds = time.perf_counter() - t0
    remember_table(source, order, table)
    return seconds


@dataclass
class Scene:
    """The GPU side of the run: `frames` holds the full map frames are timed with,
    `errors` the reduced map being measured."""

    frames: object
    errors: object
    renderer_name: str
    frame_size: int
    error_size: int


def measure(context: StudyContext) -> dict:
    from brdflab.lighting.reference_view import sphere_view
    from brdflab.render.context import create_context
    from brdflab.render.object_view import ObjectRenderer

    skipped: list[dict] = []
    modes = sweeps(context.quick)
    scoped = context.source if context.source is not None else context.material
    if scoped is not None and context.environment is not None:
        classes = {"current material": lambda: scoped}
        env = context.environment
        maps = [(env.name, "the current map", env)]
    else:
        classes, maps = material_classes(context.quick, skipped), study_maps(context.quick, skipped)
    ctx = create_context()
    scene = Scene(ObjectRenderer(ctx), ObjectRenderer(ctx), ctx.info.get("GL_RENDERER", ""),
                  128 if context.quick else 256, 32 if context.quick else 64)
    scene.frames.set_environment(maps[0][2])
    small = {name: reduced(env) for name, _, env in maps}
    inside = sphere_view(scene.error_size, scene.error_size).inside
    numbers = {"renderer": scene.renderer_name, "frame_size": scene.frame_size, "error_size": scene.error_size,
               "reduced": list(next(iter(small.values())).data.shape[1::-1]), "timing_map": maps[0][0],
               "thresholds": list(THRESHOLDS), "modes": list(modes), "skipped": skipped,
               "maps": [{"name": n, "character": c, "size": [e.width, e.height]} for n, c, e in maps],
               "materials": list(classes), "rows": [], "sh_tables": [], "floors": []}
    for material, make in classes.items():
        source = make()
        scene.frames.set_source(source)
        scene.errors.set_source(source)
        references = {}
        for name, _, _ in maps:
            if context.cancelled():
                return finish(numbers)
            context.progress(f"lighting: {material} on {name}: quadrature reference ({scene.error_size}²)")
            references[name], floor, kind = quadrature_reference(source, small[name], scene.error_size)
            numbers["floors"].append({"material": material, "map": name, "floor": floor, "reference": kind})
        for mode, settings in modes.items():
            for setting in settings:
                if context.cancelled():
                    return finish(numbers)
                context.progress(f"lighting: {material}: {mode} {setting_label(setting)}".rstrip())
                measure_setting(scene, numbers, material, source, mode, setting, maps, small, references, inside)
    return finish(numbers)


def measure_setting(scene: Scene, numbers: dict, material: str, source, mode: str, setting: dict,
                    maps: list, small: dict, references: dict, inside) -> None:
    """One setting of one mode on one material: its frame time and its error on every map."""
    from brdflab.lighting.reference_view import relative_rmse
    from brdflab.render.object_view import RenderSettings

    if "order" in setting:
        numbers["sh_tables"].append({"material": material, "order": setting["order"],
                                     "seconds": build_sh_table(source, setting["order"])})
        scene.errors.set_sh_order(setting["order"])
    samples = setting.get("samples", 1)
    # an SH frame reads order² lighting coefficients, never the map's texels: it is timed
    # with the reduced map's coefficients (projecting the full map costs up to 13 s a time)
    timer = scene.errors if mode == "sh" else scene.frames
    if mode == "sh":
        timer.set_environment(small[maps[0][0]])
    ms = frame_ms(timer, RenderSettings(mode, scene.frame_size, scene.frame_size, samples=samples))
    for name, _, _ in maps:
        row = {"material": material, "map": name, "mode": mode, "setting": setting_label(setting),
               "value": setting.get("samples", setting.get("order")), "ms": ms, "error": None,
               "negative_pixels": None}
        if MODE_SWEEPS[mode].error:
            scene.errors.set_environment(small[name])
            image = scene.errors.render(RenderSettings(mode, scene.error_size, scene.error_size, samples=samples))
            row["error"] = relative_rmse(image, references[name], inside)
            if mode == "sh":
                row["negative_pixels"] = scene.errors.clamped_pixels
        numbers["rows"].append(row)


def finish(numbers: dict) -> dict:
    """The numbers with their summary: the cheapest method under each error target."""
    numbers["summary"] = summary(numbers["rows"], numbers["thresholds"], numbers["floors"])
    return numbers


register(Part("lighting", "environment lighting: error against frame time for every mode, material and map",
              measure, draw,
              lesson="Each lighting method is cheapest somewhere: the charts show where, per material "
                     "class and map, and where each one breaks."))
