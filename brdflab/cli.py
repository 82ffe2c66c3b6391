"""The command line: `brdflab [gui|models|examples|info|eval|fit|batch|render|simulate|export|bench|study] ...`.

Every command prints one JSON object as the last line of stdout with --json. Bad
input raises BRDFLabError, which becomes a one-line message on stderr and exit
status 2 (never a traceback). Heavy libraries (NumPy, SciPy, OpenGL …) are imported by
the commands that use them, so `brdflab --help` and `brdflab models` start at once.
"""

from __future__ import annotations

import argparse
import codecs
import io
import json
import math
import os
import re
import signal
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

from brdflab.errors import BRDFLabError, shown_path
from brdflab.io.resources import MODELS_ENV


def _emit(args: argparse.Namespace, payload: dict, human: str) -> None:
    if getattr(args, "json", False):
        print(_json_text(payload))
    else:
        print(human)


def _json_text(payload: dict, indent: int | None = None) -> str:
    """`payload` as JSON. A file name that is not UTF-8 reaches Python as lone surrogates
    (PEP 383), which no UTF-8 output can hold: they are written as \\udcXX escapes, so the
    output stays UTF-8 JSON and json.loads then os.fsencode give the name's bytes back."""
    text = json.dumps(payload, indent=indent, default=_json_default, ensure_ascii=False)
    return re.sub("[\ud800-\udfff]", lambda m: f"\\u{ord(m.group()):04x}", text)


def _shown_name(e: UnicodeEncodeError) -> tuple[str, int]:
    """An encoding error handler for stdout: the bytes of a name that is not UTF-8 (lone
    surrogates, PEP 383) as \\xNN, as error messages show names, so the output stays UTF-8."""
    return shown_path(e.object[e.start:e.end]), e.end


def _json_default(o):
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(type(o).__name__)


# --- commands ---------------------------------------------------------------------------

def cmd_models(args: argparse.Namespace) -> int:
    from brdflab.models import all_models

    models = [m.describe() for m in all_models()]
    lines = []
    for m in models:
        ps = ", ".join(f"{p['name']}={p['default']:g} [{p['lower']:g}, {p['upper']:g}]" for p in m["parameters"])
        flags = ("isotropic" if m["isotropic"] else "anisotropic") + (", samplable" if m["samplable"] else "")
        lines.append(f"{m['id']:<24} {flags:<24} {ps}")
        if "file" in m:
            lines.append(f"{'':<24} from {m['format']} file {m['file']} ({m['evaluation']})")
        lines.append(f"{'':<24} prefiltered: {m['prefiltered']['rule']}")
    _emit(args, {"models": models}, "\n".join(lines))
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    from brdflab.lighting.map_info import SEPARATION_DEG, describe_map, is_map_file, summary_line
    from brdflab.sources.files import describe_file

    if is_map_file(Path(args.file)):
        info = describe_map(Path(args.file), args.env_layout)
        lines = [summary_line(info)] + [
            f"  bright spot {k + 1}: luminance {b['luminance']:.4g} at elevation {b['elevation_deg']:.1f}°, "
            f"azimuth {b['azimuth_deg']:.1f}°; {100 * b['share_nearby']:.1f} % of the light within {SEPARATION_DEG:g}° of it"
            for k, b in enumerate(info["map"]["brightest"])]
        _emit(args, info, "\n".join(lines))
        return 0
    info = _json_safe(describe_file(Path(args.file)))
    for w in info.get("warnings", []):
        print(f"{shown_path(args.file)}: warning: {w}", file=sys.stderr)
    _emit(args, info, _json_text(info, indent=2))
    return 0


def cmd_examples(args: argparse.Namespace) -> int:
    from brdflab.io.resources import EXAMPLE_PREFIX, example_names

    examples = [{"name": EXAMPLE_PREFIX + name, "file": path.name, "path": str(path)}
                for name, path in sorted(example_names().items())]
    lines = [f"{e['name']:<28} {e['file']}" for e in examples]
    _emit(args, {"examples": examples}, "\n".join(lines))
    return 0


def _json_safe(value):
    """`value` with every non-finite float as None: Infinity and NaN are not JSON."""
    import numpy as np

    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_json_safe(v) for v in value]
    if isinstance(value, (float, np.floating)) and not np.isfinite(value):
        return None
    return value


def _warner(args: argparse.Namespace):
    """A callback that prints a problem that does not stop the command as one stderr line."""
    return lambda message: print(f"brdflab {args.command}: warning: {message}", file=sys.stderr)


def cmd_eval(args: argparse.Namespace) -> int:
    import numpy as np

    from brdflab.io.atomic import atomic_write, check_writable
    from brdflab.io.pairs import read_pairs
    from brdflab.sources.files import evaluate_in_chunks, load_source

    check_writable(args.out)
    wi, wo = read_pairs(args.pairs)
    source = load_source(Path(args.material), fitting=args.fitting, warn=_warner(args))
    values = evaluate_in_chunks(source, wi, wo)
    out = Path(args.out)
    buf = io.BytesIO()
    np.save(buf, values)
    atomic_write(out, buf.getvalue())
    payload = {"out": str(out), "pairs": int(values.shape[0]), "channels": int(values.shape[1])}
    _emit(args, payload, f"wrote {values.shape[0]} × {values.shape[1]} values to {out}")
    return 0


def _lobe_names(text: str) -> list[str]:
    """A comma-separated lobe list as registry names: a model's name, or a model file's path
    (read, checked and registered)."""
    from brdflab.models.files.library import resolve_lobe

    return [resolve_lobe(s.strip()) for s in text.split(",") if s.strip()]


def _load_model_folders(args: argparse.Namespace) -> None:
    """Register the user's model files: every folder in BRDFLAB_MODELS, then --models DIR.
    The `--models` of fit and batch also names the --auto ladder's models: its folders are
    taken out here, and the names left for --auto. Nothing is imported when no folder is named
    (commands start light)."""
    folders = [Path(d) for d in (getattr(args, "global_model_dirs", None) or [])]
    folders += [Path(d) for d in (getattr(args, "model_dirs", None) or [])]
    names = getattr(args, "models", None)
    if isinstance(names, str):
        entries = [e.strip() for e in names.split(",") if e.strip()]
        folders += [Path(e) for e in entries if Path(e).is_dir()]
        args.models = ",".join(e for e in entries if not Path(e).is_dir()) or None
    if folders or os.environ.get(MODELS_ENV, "").strip():
        from brdflab.models.files.library import env_folders, load_folders

        folders = env_folders() + folders
        warn = _warner(args)
        for model in load_folders(folders, warn=warn):
            for message in model.warnings if args.command == "models" else ():  # not on every command
                warn(message)


def cmd_fit(args: argparse.Namespace) -> int:
    from brdflab.fitting.lm import STOPPED, FitOptions, fit
    from brdflab.io.atomic import check_writable
    from brdflab.fitting.stored import append_fitting, document_for, initial_material
    from brdflab.fitting.image_metric import fit_target
    from brdflab.fitting.samples import MAX_DENSITY, samples_of
    from brdflab.fitting.second_error import describe
    from brdflab.sources.files import load_source
    from brdflab.io.xmlio import check_savable, save

    if not args.time_limit > 0:
        raise BRDFLabError(f"--time-limit {args.time_limit:g}: must be a positive number of seconds")
    if args.out:
        check_writable(args.out)  # a bad --out fails before the fit, not after it
    for option, given in (("--tolerance", args.tolerance is not None), ("--models", args.models)):
        if given and not args.auto:
            raise BRDFLabError(f"{option} applies to --auto")
    if args.mesh and not (args.metric == "image" or (args.auto and args.env)):
        raise BRDFLabError("--mesh applies to --metric image and scene-Auto (the renders are judged on it)")
    if args.auto:
        if args.env or args.metric == "image":
            return _fit_scene_auto(args, Path(args.source))
        return _fit_auto(args, Path(args.source))
    for option, value, kind in (("--size", args.size, "subset"), ("--density", args.density, "grid")):
        if value is not None and args.samples != kind:
            raise BRDFLabError(f"{option} applies to --samples {kind}, not --samples {args.samples}")
    if args.size is not None and args.size < 1:
        raise BRDFLabError(f"--size {args.size}: a subset needs at least 1 sample")
    if args.density is not None and not 2 <= args.density <= MAX_DENSITY:
        raise BRDFLabError(f"--density {args.density}: must be 2..{MAX_DENSITY} bins per half/difference angle")
    source_path = Path(args.source)
    source = load_source(source_path, fitting=args.fitting, warn=_warner(args))
    lobes = _lobe_names(args.lobes) if args.lobes else None
    combination = {"linear": "Linear", "fixed": "Fixed"}[args.combination]
    start = initial_material(lobes, combination, source.n_channels,
                             Path(args.init) if args.init else None, args.init_fitting)
    if args.out:
        check_savable(document_for(source_path, source), args.out, start)  # a name XML cannot hold
    if args.metric == "image" and args.samples != "all":
        raise BRDFLabError(f"--samples {args.samples} applies to sample metrics; --metric image fits renders")
    maps = _image_maps(args)
    samples = fit_target(source, args.metric, {"kind": args.samples, "size": args.size, "density": args.density}, maps,
                         _image_view(args))
    score_on = samples_of(source) if args.samples != "all" else None
    restarts = args.restarts if args.restarts is not None else not args.init  # a stored fit is continued
    options = FitOptions(metric=args.metric, compression=args.compression, max_iterations=args.max_iterations,
                         time_limit=args.time_limit, restarts=restarts)
    if args.init:
        options.coarse_size = 0  # continuing a stored fit: it is already near the optimum of all samples
    t0 = time.perf_counter()
    show = sys.stderr.isatty() and not args.json

    def progress(p):
        if show:
            elapsed = time.perf_counter() - t0
            print(f"\r{p.stage:>6} iteration {p.iteration:4d}  {options.metric} error {p.error:.6g}  {elapsed:6.2f} s",
                  end="", file=sys.stderr, flush=True)

    cancel = threading.Event()

    def interrupted(signum, frame):  # Ctrl-C: stop at the next sample chunk, keep the best so far
        cancel.set()
        signal.signal(signal.SIGINT, signal.default_int_handler)  # a second Ctrl-C stops at once

    previous = signal.signal(signal.SIGINT, interrupted) if threading.current_thread() is threading.main_thread() else None
    try:
        result = fit(start, samples, options, progress=progress, cancel=cancel, score_on=score_on)
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
        if show:
            print(file=sys.stderr)
    # a fit stopped by --time-limit or Ctrl-C ends now, without its second error
    measured = result.status in STOPPED or _measure_second(result, source, samples, maps)
    payload = {**result.as_dict(), "samples": samples.size, "source": str(source_path)}
    if args.out:
        doc = document_for(source_path, source)
        append_fitting(doc, result)
        save(doc, Path(args.out))
        payload["out"] = args.out
    human = (f"{result.metric} error {result.error:.6g} on {result.scored_on} after {result.iterations} iterations "
             f"({result.seconds:.2f} s, {result.status})" + (f"; {describe(result.second)}" if result.second else ""))
    for w in result.warnings:
        print(f"brdflab fit: warning: {w}", file=sys.stderr)
    if result.status == "no-better-than-zero":
        print(f"brdflab fit: warning: {result.message}", file=sys.stderr)
    _emit(args, payload, human)
    if result.status == "cancelled":
        saved = f"; the best parameters so far are saved in {args.out}" if args.out else ""
        print(f"brdflab fit: interrupted{saved}", file=sys.stderr)
        return 130
    return 0 if measured else _interrupted_second(args, "the fit")


def _measure_second(result, source, fitted, maps=None) -> bool:
    """Fill in the number the fit was not judged by (`second_error`: seconds on a full table);
    False where Ctrl-C stopped that: the fit is kept without it, not lost."""
    from brdflab.fitting.second_error import second_error

    try:
        result.second = second_error(result.material, source, fitted, maps)
    except KeyboardInterrupt:
        return False
    return True


def _interrupted_second(args: argparse.Namespace, what: str) -> int:
    saved = f"; {what} is saved in {args.out} without it" if args.out else ""
    print(f"brdflab fit: interrupted while its {'sample' if args.metric == 'image' else 'image'} error was "
          f"measured{saved}", file=sys.stderr)
    return 130


def _image_maps(args: argparse.Namespace) -> list | None:
    """`fit --env MAP ...`: the image metric's maps (None: its default three)."""
    from brdflab.lighting.envmap import load_environment

    if not args.env:
        return None
    if args.metric != "image":
        raise BRDFLabError("--env applies to --metric image (the maps its renders are lit by)")
    return [load_environment(Path(p)) for p in args.env]


def _image_view(args: argparse.Namespace):
    """`fit --mesh FILE`: the image metric's view, the mesh's pixels as `brdflab render --view
    orbit --mesh FILE` draws it (its camera; the view sized so that the mesh covers as many
    pixels as the reference sphere does at the metric's VIEW × VIEW); else the reference view's
    size."""
    from brdflab.fitting.image_metric import VIEW

    if not args.mesh:  # (cmd_fit refused --mesh without the image metric)
        return VIEW
    from brdflab.io.mesh import load_mesh
    from brdflab.render.camera import OrbitCamera
    from brdflab.render.context import create_context
    from brdflab.render.gbuffer import frames_covering

    mesh = load_mesh(args.mesh)
    frames = frames_covering(create_context(), mesh, OrbitCamera())
    if not frames.inside.any():
        raise BRDFLabError(f"{args.mesh}: the mesh covers no pixel of the view")
    return frames


def _fit_auto(args: argparse.Namespace, source_path: Path) -> int:
    """`brdflab fit SOURCE --auto`: the ladder as a table (or JSON); --out stores the pick."""
    from brdflab.fitting.auto import DEFAULT_SPLIT, DEFAULT_TOLERANCE, auto_fit, chosen_fit, validate_tolerance
    from brdflab.fitting.lm import FitOptions
    from brdflab.fitting.samples import samples_of
    from brdflab.fitting.second_error import describe
    from brdflab.fitting.stored import document_for
    from brdflab.io.xmlio import check_savable
    from brdflab.models import get_model
    from brdflab.sources.files import load_source

    tolerance = DEFAULT_TOLERANCE if args.tolerance is None else args.tolerance
    validate_tolerance(tolerance)
    for option, given in (("--init", args.init), ("--samples", args.samples != "all"), ("--density", args.density)):
        if given:
            raise BRDFLabError(f"{option} does not apply to --auto (it fits its own split of the samples)")
    source = load_source(source_path, fitting=args.fitting, warn=_warner(args))
    if args.out:
        check_savable(document_for(source_path, source), args.out)  # a name XML cannot hold, before the ladder
    options = FitOptions(metric=args.metric, compression=args.compression, max_iterations=args.max_iterations,
                         time_limit=args.time_limit, restarts=args.restarts is not False)
    models = _lobe_names(args.models) if args.models else None
    for name in models or []:
        get_model(name)  # an unknown name fails before any fit
    t0 = time.perf_counter()

    def progress(p) -> None:  # a line per screen and full fit: a climb takes minutes, and says so as it goes
        print(f"brdflab fit: auto: {p.describe()} ({time.perf_counter() - t0:.1f} s)", file=sys.stderr, flush=True)

    samples = samples_of(source)
    ladder = auto_fit(samples, tolerance, args.metric, {"linear": "Linear", "fixed": "Fixed"}[args.combination],
                      split=args.size or DEFAULT_SPLIT, models=models, options=options, progress=progress)
    measured = ladder.chosen.result is None or _measure_second(ladder.chosen.result, source, samples)
    chosen = chosen_fit(ladder)
    payload = {**ladder.as_dict(), "source": str(source_path), "fit": chosen.as_dict()}
    _store_pick(args, source_path, source, ladder, payload)
    lines = _ladder_lines(ladder, f"Auto ladder ({ladder.metric}; {ladder.fitted_samples} samples fitted, "
                                  f"{ladder.held_back_samples} held back; tolerance {tolerance:.1%}; the one-lobe "
                                  f"candidates are screened on a quarter of the fitted samples, the held-back error "
                                  f"of that screening in brackets):", "fitted", "held back")
    lines.append(f"its {ladder.metric} error on {chosen.scored_on}: {chosen.error:.6g} ({chosen.status}); "
                 f"{describe(chosen.second)}")
    if args.out:
        lines.append(f"stored the chosen fit in {args.out}")
    _emit(args, payload, "\n".join(lines))
    return 0 if measured else _interrupted_second(args, "the pick")


def _store_pick(args: argparse.Namespace, source_path: Path, source, ladder, payload: dict) -> None:
    """--out: the source's XML with Auto's pick as a new <Fitting> (said in `payload`)."""
    from brdflab.fitting.auto import chosen_fitting
    from brdflab.fitting.stored import document_for
    from brdflab.io.xmlio import save

    if args.out:
        doc = document_for(source_path, source)
        doc.fittings.append(chosen_fitting(ladder))
        save(doc, Path(args.out))
        payload["out"] = args.out


def _ladder_lines(ladder, title: str, first: str, second: str) -> list[str]:
    """An Auto ladder as a table: a row per candidate, the pick marked *, and why."""
    lines = [title, f"{'':2}{'rung':>4}  {'lobes':<48} {'params':>6} {first:>10} {second:>10} {'seconds':>8}"]
    for c in ladder.candidates:
        mark = "*" if c is ladder.chosen else ""
        lobes = "+".join(("Lambertian", *c.lobes))
        errors = (f"{c.error_fitted:>10.5g} {c.error_held_back:>10.5g}" if c.fitted else
                  f"{'screened out (' + format(c.screen_error, '.4g') + ')':>21}" if c.status == "screened out" else
                  f"{c.status or 'not fitted':>21}")
        screened = f"  ({c.screen_error:.4g})" if c.fitted and math.isfinite(c.screen_error) else ""
        lines.append(f"{mark:2}{c.rung:>4}  {lobes:<48} {c.parameters:>6} {errors} {c.seconds:>8.2f}{screened}")
    lines.append(f"chosen (*): {ladder.reason}; {ladder.seconds:.1f} s in all")
    return lines


def _fit_scene_auto(args: argparse.Namespace, source_path: Path) -> int:
    """`brdflab fit SOURCE --auto --env MAP ...` (or `--metric image`): scene-Auto, the fewest
    lobes whose render of the maps is within --tolerance (image error) of the measurement's."""
    from brdflab.fitting.defaults import DEFAULT_METRIC
    from brdflab.fitting.image_metric import SceneImages
    from brdflab.fitting.lm import FitOptions
    from brdflab.fitting.scene_auto import DEFAULT_SCENE_TOLERANCE, scene_auto, validate_scene_tolerance
    from brdflab.fitting.second_error import describe
    from brdflab.fitting.stored import document_for
    from brdflab.io.xmlio import check_savable
    from brdflab.models import get_model
    from brdflab.sources.files import load_source

    tolerance = DEFAULT_SCENE_TOLERANCE if args.tolerance is None else args.tolerance
    validate_scene_tolerance(tolerance)
    if args.metric not in ("image", DEFAULT_METRIC):
        raise BRDFLabError(f"--metric {args.metric}: scene-Auto (--auto --env) judges by the image metric")
    for option, given in (("--init", args.init), ("--samples", args.samples != "all"), ("--density", args.density),
                          ("--size", args.size), ("--compression", args.compression != "none")):
        if given:
            raise BRDFLabError(f"{option} does not apply to scene-Auto (it fits the scene's renders)")
    args.metric = "image"
    maps = _image_maps(args)
    source = load_source(source_path, fitting=args.fitting, warn=_warner(args))
    if args.out:
        check_savable(document_for(source_path, source), args.out)
    models = _lobe_names(args.models) if args.models else None
    for name in models or []:
        get_model(name)
    t0 = time.perf_counter()
    view = _image_view(args)
    scene = SceneImages.of_source(source, maps, view)
    seen = scene.seen if not args.mesh or Path(args.mesh).name == args.mesh else f"{scene.seen} ({args.mesh})"
    print(f"brdflab fit: auto: the scene: {scene.size} pixels of {seen} under {', '.join(q.name for q in scene.quadratures)} "
          f"({time.perf_counter() - t0:.1f} s)", file=sys.stderr, flush=True)

    def progress(p) -> None:
        print(f"brdflab fit: auto: {p.describe()} ({time.perf_counter() - t0:.1f} s)", file=sys.stderr, flush=True)

    options = FitOptions(metric="image", max_iterations=args.max_iterations, time_limit=args.time_limit,
                         restarts=args.restarts is not False)
    ladder = scene_auto(scene, tolerance, {"linear": "Linear", "fixed": "Fixed"}[args.combination], models=models,
                        options=options, progress=progress)
    chosen = ladder.chosen.result
    measured = _measure_second(chosen, source, scene)
    payload = {**ladder.as_dict(), "maps": [q.name for q in scene.quadratures], "mesh": args.mesh,
               "source": str(source_path),
               "fit": chosen.as_dict()}
    _store_pick(args, source_path, source, ladder, payload)
    lines = _ladder_lines(ladder, f"Scene-Auto ladder (image error of {scene.seen} under "
                                  f"{', '.join(q.name for q in scene.quadratures)}; tolerance {tolerance:.1%}; the "
                                  f"one-lobe candidates are screened on a sixteenth of the pixels, their image error "
                                  f"in brackets):", "fitted", "image")
    lines.append(f"its image error {chosen.error:.6g} ({chosen.status}); {describe(chosen.second)}")
    if args.out:
        lines.append(f"stored the chosen fit in {args.out}")
    _emit(args, payload, "\n".join(lines))
    return 0 if measured else _interrupted_second(args, "the pick")


def cmd_batch(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from brdflab.batch.runner import BatchSettings, run_batch

    if args.tolerance is not None and not args.auto:
        raise BRDFLabError("--tolerance applies to --auto")
    lobe_sets = [tuple(_lobe_names(spec)) for spec in args.lobes]
    models = tuple(_lobe_names(args.models)) if args.models else ()
    tolerance = {} if args.tolerance is None else {"auto_tolerance": args.tolerance}
    settings = BatchSettings(sources=[Path(s) for s in args.sources], lobe_sets=lobe_sets, out=Path(args.out),
                             metric=args.metric, combination={"linear": "Linear", "fixed": "Fixed"}[args.combination],
                             max_iterations=args.max_iterations, scheduler=args.scheduler, workers=args.workers,
                             auto=args.auto, auto_models=models, **tolerance)
    summary = run_batch(settings)
    human = (f"{summary.tasks} tasks: {summary.ran} fitted ({summary.failed} failed), {summary.skipped} already done, "
             f"{summary.seconds:.1f} s; wrote {args.out}/{{{','.join(summary.files)}}} and {args.out}/fits/")
    _emit(args, {"out": args.out, **asdict(summary)}, human)
    return 0


def _vector(text: str, n: int, what: str) -> tuple[float, ...]:
    try:
        values = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise BRDFLabError(f"{what} {text!r}: expected {n} comma-separated numbers") from None
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise BRDFLabError(f"{what} {text!r}: expected {n} finite comma-separated numbers")
    return values


def _resolve_auto(args: argparse.Namespace, source, renderer):
    """--mode auto: pick the lighting from the material and the map (lighting/auto.py) and
    put the pick into args (mode, samples, SH order), so the render is that setting's."""
    from brdflab.lighting.auto import choose_lighting

    if args.sh_shadows or args.sh_variant != "dynamic" or args.env_rotation:
        raise BRDFLabError("--mode auto predicts the reference view's unshadowed, unturned lighting: "
                           "drop --sh-shadows, --sh-variant and --env-rotation, or pick a mode")
    choice = choose_lighting(source, renderer.environment, args.tolerance, proxy=renderer.material)
    args.mode = choice.mode
    if choice.mode in ("fis", "mis"):
        args.samples = choice.setting
    if choice.mode == "sh":
        args.sh_order = choice.setting
    return choice


def _prefiltered_check(args: argparse.Namespace, source, renderer) -> tuple[dict, str] | None:
    """--mode prefiltered: the split sum's predicted error for this material and map
    (lighting/auto.prefiltered_check), a warning on stderr where it exceeds the bound the mode
    is trusted within; None when the map is turned (the prediction is for the unturned map)."""
    from brdflab.lighting.auto import PREFILTERED_BOUND, prefiltered_check

    if args.env_rotation:
        return None
    error = prefiltered_check(source, renderer.environment, proxy=renderer.material)
    line = (f"prefiltered: predicted {100 * error:.1f} % off pixel by pixel (reference view; "
            f"trusted within {100 * PREFILTERED_BOUND:g} %)")
    if error > PREFILTERED_BOUND:
        print(f"brdflab render: warning: the split sum cannot hold this material under this map: predicted "
              f"{100 * error:.1f} % off pixel by pixel (a narrow lobe under a small bright source, or lobes "
              "stretched at grazing views); --mode mis or --mode auto", file=sys.stderr)
    return {"predicted_error": error, "bound": PREFILTERED_BOUND, "trusted": error <= PREFILTERED_BOUND}, line


def _sh_table(args: argparse.Namespace):
    """--sh-table as the renderer takes it: a TableSetting, or AutoTable(--sh-table-tolerance)."""
    from brdflab.lighting.sh_table_auto import AutoTable

    if args.sh_table != "auto":
        return args.sh_table
    if not 0.0 < args.sh_table_tolerance < 1.0:
        raise BRDFLabError(f"--sh-table-tolerance {args.sh_table_tolerance:g} must be between 0 and 1")
    return AutoTable(args.sh_table_tolerance)


def _sh_table_used(renderer) -> tuple[dict, str]:
    """The table the SH render used, for the JSON and one human line (Auto: its pick and why)."""
    from brdflab.lighting.sh_table_auto import AutoTable, known_choice

    source = renderer.source if renderer.source is not None else renderer.material
    if isinstance(renderer.sh_table, AutoTable):
        choice = known_choice(source, renderer.sh_order, renderer.sh_table)
        return {"auto": True, **choice.as_dict()}, f"SH table: auto picked {choice.label}"
    setting = renderer.sh_table.of(source)
    return ({"auto": False, "size": setting.size, "samples_log2": setting.samples_log2},
            f"SH table: {setting.text}")


def _check_map_options(args: argparse.Namespace) -> None:
    """The map's options in point mode are a mistake, not a no-op: the point light ignores the map,
    so a user who typed --env and forgot --mode would get an image lit by something else."""
    if args.mode != "point":
        return
    given = [name for name, value, default in (("--env", args.env, None), ("--env-back", args.env_back, None),
                                               ("--env-layout", args.env_layout, "auto"),
                                               ("--env-rotation", args.env_rotation, 0.0))
             if value != default]
    if given:
        raise BRDFLabError(f"{', '.join(given)}: only the map modes (mis, prefiltered, sh, fis, auto) use a map; "
                           "--mode point lights with --light alone: add --mode MODE or drop the map")


def cmd_render(args: argparse.Namespace) -> int:
    from brdflab.lighting.envmap import load_environment, write_exr
    from brdflab.io.mesh import default_mesh, load_mesh
    from brdflab.render.context import create_context
    from brdflab.render.object_view import ObjectRenderer, RenderSettings
    from brdflab.io.resources import default_environment_path
    from brdflab.sources.files import load_source
    from brdflab.lighting.tonemap import write_png
    from brdflab.io.atomic import check_writable

    out = Path(args.out)
    if out.suffix.lower() not in (".exr", ".png"):
        raise BRDFLabError("the output must be .exr (linear) or .png (tone-mapped)", out)
    check_writable(out)  # a bad --out fails before the render, not after it
    _check_map_options(args)
    width, height = args.size
    light = _vector(args.light, 3, "--light")
    if math.hypot(*light) < 1e-12:
        raise BRDFLabError("--light must not be the zero vector")
    source = load_source(Path(args.material), fitting=args.fitting, warn=_warner(args))
    ctx = create_context()
    renderer = ObjectRenderer(ctx)
    try:
        renderer.set_source(source)
    except BRDFLabError as e:  # what the renderer cannot draw (e.g. too many lobes), named by file
        raise BRDFLabError(str(e), args.material) from None
    if args.view != "reference":
        renderer.set_mesh(default_mesh() if args.mesh == "sphere" else load_mesh(args.mesh))
    if args.mode in ("fis", "sh", "prefiltered", "mis", "auto"):
        env_path = Path(args.env) if args.env else default_environment_path()
        if args.env_back and not args.env:
            raise BRDFLabError("--env-back names the back half of the dual-paraboloid pair given by --env")
        renderer.set_environment(load_environment(env_path, args.env_layout, args.env_back))
    auto = _resolve_auto(args, source, renderer) if args.mode == "auto" else None
    prefiltered = _prefiltered_check(args, source, renderer) if args.mode == "prefiltered" else None
    settings = RenderSettings(mode=args.mode, width=width, height=height, samples=args.samples, light=light,
                              env_rotation=args.env_rotation, reference_view=args.view == "reference",
                              mis_control=args.mis_control == "on")
    if args.mode == "sh":
        renderer.set_sh_order(args.sh_order, None if args.sh_window == "none" else args.sh_window)
        renderer.sh_shadows = args.sh_shadows
        renderer.sh_variant = args.sh_variant
        if args.sh_table is not None:
            renderer.set_sh_table(_sh_table(args))
    renderer.render(RenderSettings(**{**settings.__dict__, "width": 8, "height": 8, "samples": 1}))  # compile
    t0 = time.perf_counter()
    image = renderer.render(settings)
    seconds = time.perf_counter() - t0
    if out.suffix.lower() == ".exr":
        write_exr(out, image)
    else:
        write_png(out, image, exposure=args.exposure)
    if args.mode == "sh" and renderer.clamped_pixels:
        print(f"brdflab render: warning: {renderer.clamped_pixels} pixels had negative radiance from SH ringing "
              "and were clamped to 0 (try --sh-window hanning)", file=sys.stderr)
    payload = {
        "out": str(out), "seconds": seconds, "frame_ms": seconds * 1e3,
        "clamped_pixels": renderer.clamped_pixels if args.mode == "sh" else 0,
        "settings": {"mode": args.mode, "view": args.view, "mesh": args.mesh if args.view != "reference" else "sphere",
                     "size": [width, height], "samples": args.samples, "light": light, "sh_order": args.sh_order,
                     "env": args.env, "renderer": ctx.info.get("GL_RENDERER", "")},
    }
    if renderer.environment is not None:  # the map as read: a probe's layout, and the lat-long size it became
        payload["settings"]["env_layout"] = renderer.environment.layout
        payload["settings"]["env_size"] = list(renderer.env_size)
    human = f"wrote {out} ({width}×{height}, {args.mode}, {seconds * 1e3:.1f} ms)"
    if auto is not None:
        payload["auto"] = auto.as_dict()
        human = "\n".join(auto.reasons + [human])
    if prefiltered is not None:
        payload["prefiltered"], line = prefiltered
        human = "\n".join([line, human])
    if args.mode == "mis":
        weight = renderer.control_weight() if settings.mis_control else 0.0
        payload["settings"]["mis_control"] = {"on": settings.mis_control, "weight": weight}
        human = "\n".join([f"MIS control: {'weight ' + format(weight, '.2f') if settings.mis_control else 'off'}", human])
    if args.mode == "sh":
        payload["settings"]["sh_table"], line = _sh_table_used(renderer)
        human = "\n".join([line, human])
    _emit(args, payload, human)
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from brdflab.io.atomic import ensure_folder
    from brdflab.study.bench import run, stderr_progress

    out = ensure_folder(args.out)  # before minutes of measuring
    result = run(out, quick=args.quick, progress=stderr_progress)
    for row in result["sh"]["skipped"]:
        print(f"brdflab bench: warning: skipped {row['row']}: {row['why']}", file=sys.stderr)
    fis = result["render"]["fis"]
    lines = [f"{r['material']:<12} {r['samples']:>4} samples {r['ms']:8.1f} ms  {100 * r['relative_rmse']:6.2f} %" for r in fis]
    _emit(args, {"out": str(out), "files": ["bench.json", *result["charts"]], "render": result["render"]},
          "\n".join(lines + [f"wrote {out}/bench.json and {', '.join(result['charts'])}"]))
    return 0


def cmd_study(args: argparse.Namespace) -> int:
    from brdflab.io.atomic import ensure_folder
    from brdflab.study.framework import StudyContext, run_study, stderr_progress

    out = ensure_folder(args.out)  # before minutes of measuring
    deadline = None if args.stop_after is None else time.monotonic() + 60.0 * args.stop_after
    context = StudyContext(quick=args.quick, progress=stderr_progress, fresh=args.fresh,
                           cancelled=lambda: deadline is not None and time.monotonic() > deadline)
    result = run_study(out, context, args.part or None)
    files = [f for charts in result.charts.values() for f in charts]
    lines = [f"{name:<12} {result.seconds[name]:7.1f} s  {', '.join(charts)}" for name, charts in result.charts.items()]
    _emit(args, {"out": str(out), "files": ["study.json", *files], "seconds": result.seconds, "charts": result.charts},
          "\n".join(lines + [f"wrote {out}/study.json and {len(files)} charts"]))
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    from brdflab.io.xmlio import BRDFDocument, save
    from brdflab.simulation.material import SimulationSpec, reference_of, simulated_material
    from brdflab.simulation.registry import KINDS, get_kind

    if args.list:
        kinds = [k.describe() for k in KINDS.values()]
        lines = []
        for k in kinds:
            lines.append(f"{k['kind']} ({k['library']}{'' if k['available'] else ', not installed'}): {k['doc']}")
            for p in k["parameters"]:
                rng = " | ".join(p["choices"]) if "choices" in p else f"[{p['lower']:g}, {p['upper']:g}]"
                lines.append(f"    {p['name']:<14} {str(p['default']):<8} {rng:<22} {p['unit']:<5} {p['doc']}")
        _emit(args, {"kinds": kinds}, "\n".join(lines))
        return 0
    if not args.kind or not args.out:
        raise BRDFLabError("simulate needs a KIND and --out FILE.xml (or --list)")
    given = {}
    for item in args.set or []:
        name, sep, value = item.partition("=")
        if not sep:
            raise BRDFLabError(f"--set {item!r}: expected NAME=VALUE")
        given[name.strip()] = value.strip()
    kind = get_kind(args.kind)
    spec = SimulationSpec(kind.name, kind.complete(given), args.seed, args.samples, args.resolution, args.name or "")
    out = Path(args.out)
    show = sys.stderr.isatty() and not args.json

    def progress(fraction: float, message: str) -> None:
        if show:
            print(f"\r{message} ({100 * fraction:3.0f} %)", end="", file=sys.stderr, flush=True)

    material = simulated_material(spec, progress)
    if show:
        print(file=sys.stderr)
    save(BRDFDocument(reference_of(spec)), out)
    payload = {"out": str(out), "seconds": material.seconds, **material.describe()}
    _emit(args, payload, f"wrote {out} ({spec.kind}, {spec.resolution}³ table in {material.seconds:.2f} s)")
    return 0


def cmd_gui(args: argparse.Namespace) -> int:
    problem = display_problem(os.environ)
    if problem:
        raise BRDFLabError(problem)
    from brdflab.gui.app import run

    return run(getattr(args, "file", None))


def display_problem(env) -> str | None:
    """Why the GUI cannot open a window here (Qt itself would abort with signal 6), or None."""
    platform = env.get("QT_QPA_PLATFORM", "")
    if platform and not platform.startswith(("xcb", "wayland")):
        return None  # offscreen, vnc, eglfs …: Qt needs no display server
    if env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"):
        return None
    return ("no display to open the window on: run it as `xvfb-run -a brdflab`, "
            "or set DISPLAY to an X server")


def cmd_export(args: argparse.Namespace) -> int:
    from brdflab.export import PRINCIPLED_FORMATS, check_destination, export_source, stored_principled
    from brdflab.sources.files import load_source

    out = Path(args.out)
    check_destination(args.format, out, Path(args.source))  # before the source is read (a simulation, a table)
    warn = _warner(args)
    source = load_source(Path(args.source), fitting=args.fitting, warn=warn)
    if args.fitting is None and args.format in PRINCIPLED_FORMATS:
        stored = stored_principled(Path(args.source), source)
        if stored is not None:
            warn(f"{args.source} stores a Principled fit (--fitting {stored}), which exports exactly: this export "
                 "fits the material itself to Principled again")
    env = None
    if args.env_back and not args.env:
        raise BRDFLabError("--env-back names the back half of the dual-paraboloid pair given by --env")
    if args.env:
        from brdflab.lighting.envmap import load_environment

        env = load_environment(Path(args.env), args.env_layout, args.env_back)
    try:
        warnings = export_source(source, args.format, out, origin=Path(args.source), env=env)
    except OSError as e:
        raise BRDFLabError(f"cannot write: {e.strerror}", out) from None
    if env is not None and args.format != "mitsuba":
        warn(f"--env is for a Mitsuba scene's map: a {args.format} export has none")
    for line in warnings:
        warn(line)
    _emit(args, {"out": str(out), "format": args.format, "warnings": warnings}, f"wrote {args.format} export to {out}")
    return 0


# --- parser ------------------------------------------------------------------------------

ENV_LAYOUTS = ["auto", "latlong", "angular", "dual-paraboloid"]  # lighting/probes.py LAYOUTS, kept here so --help imports no NumPy
MAX_RENDER_SAMPLES = 65_536  # FIS samples per pixel: minutes per frame on a software rasteriser beyond this

EXAMPLES = {
    "gui": "brdflab gui example:fig2\n  xvfb-run -a brdflab gui measured/chrome.binary",
    "models": "brdflab models\n  brdflab models --json | python3 -m json.tool",
    "examples": "brdflab examples\n  brdflab info example:fig2",
    "info": "brdflab info example:fig2\n  brdflab info gold.slice --json",
    "eval": "brdflab eval example:fig2 --pairs pairs.npy --out values.npy\n"
            "  brdflab eval fits.xml --fitting 0 --pairs pairs.npy --out values.npy",
    "fit": "brdflab fit gold-metallic-paint3.slice --lobes Lambertian,CookTorrance --out gold.xml\n"
           "  brdflab fit gold.xml --init gold.xml --out gold.xml --json",
    "batch": "brdflab batch slices/ --lobes Lambertian,BlinnPhong --lobes Lambertian,CookTorrance --out results/\n"
             "  brdflab batch slices/ --auto --out results/",
    "render": "brdflab render example:fig2 --mode fis --samples 256 --out fig2.png\n"
              "  brdflab render gold.xml --fitting 0 --mode sh --view reference --out gold.exr",
    "simulate": "brdflab simulate --list\n  brdflab simulate <KIND> --set NAME=VALUE --out simulated.xml",
    "export": "brdflab export example:fig2 --format glsl --out fig2.glsl\n"
              "  brdflab export gold.slice --format merl --out gold.binary",
    "bench": "brdflab bench --quick --out bench-out/",
    "study": "brdflab study --quick --out study-out/\n  brdflab study --part viewer --out docs/study",
}


def _add(sub, name: str, help: str, **kwargs) -> argparse.ArgumentParser:
    """A sub-command whose help ends with an example or two."""
    return sub.add_parser(name, help=help, description=kwargs.pop("description", help[0].upper() + help[1:] + "."),
                          epilog="example:\n  " + EXAMPLES[name], **kwargs)


def build_parser() -> argparse.ArgumentParser:
    from brdflab import __version__
    from brdflab.cli_options import Parser, finite_float, image_size, int_in, material_path, sh_table
    from brdflab.fitting.defaults import DEFAULT_METRIC, DEFAULTS_WHY

    parser = Parser(prog="brdflab", description="A laboratory for reflectance. Without a command it opens "
                    "the GUI. Material arguments take a file or `example:NAME` (see `brdflab examples`).",
                    epilog="examples:\n  brdflab info example:fig2\n  brdflab render example:fig2 --out fig2.png\n"
                           "  brdflab COMMAND --help")
    parser.add_argument("--version", action="version", version=f"brdflab {__version__}")
    parser.add_argument("--models", action="append", dest="global_model_dirs", metavar="DIR",
                        help="a folder of model files (.brdf, BRDFLab model descriptors) to use beside the "
                             "built-in models (repeatable; BRDFLAB_MODELS lists more)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = _add(sub, "gui", "open the desktop application")
    p.add_argument("file", nargs="?", type=material_path, help="an XML material or measured data file")
    p.set_defaults(func=cmd_gui)

    p = _add(sub, "models", "list every lobe model")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(func=cmd_models)

    p = _add(sub, "examples", "list the shipped example materials (use them as example:NAME)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(func=cmd_examples)

    p = _add(sub, "info", "what a material or data file holds")
    p.add_argument("file", type=material_path, help="XML material, measured data, a model file (.brdf, model descriptor: one lobe at its defaults), an environment map (.hdr, .exr) or example:NAME")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.add_argument("--env-layout", choices=ENV_LAYOUTS, default="auto",
                   help="how to read an environment map (auto: a square disk is an angular probe, a NAME-front/-back pair dual-paraboloid)")
    p.set_defaults(func=cmd_info)

    p = _add(sub, "eval", "evaluate a material at direction pairs")
    p.add_argument("material", type=material_path, help="XML material, measured data, a model file (.brdf, model descriptor: one lobe at its defaults) or example:NAME")
    p.add_argument("--pairs", required=True, help="(N, 6) .npy array [wi | wo] in the local frame")
    p.add_argument("--out", required=True, help="(N, C) .npy output")
    p.add_argument("--fitting", type=int_in(0, 1_000_000), default=None, help="evaluate the K-th stored fit (0-based)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(func=cmd_eval)

    p = _add(sub, "fit", "fit analytic lobes to a source with Levenberg–Marquardt",
             description="Fit analytic lobes to a source with Levenberg–Marquardt. Every source "
             "(table, slice, raw samples, analytic grid) is fitted and scored over the same "
             "solid-angle measure of (ωi, ωo) pairs. " + DEFAULTS_WHY)
    p.add_argument("source", type=material_path,
                   help="measured data file, XML material (or example:NAME), or XML with fits (see --fitting)")
    which = p.add_mutually_exclusive_group()
    which.add_argument("--lobes", help="comma-separated lobe models or model files, e.g. Lambertian,LafortuneIso or Lambertian,mine.brdf")
    which.add_argument("--auto", action="store_true",
                       help="climb a ladder of candidates (Lambertian, + one lobe of each model, two, three) "
                            "and keep the cheapest that more lobes no longer improve by more than --tolerance "
                            "on held-back samples; with --env MAP or --metric image (scene-Auto): the fewest "
                            "lobes whose render is within --tolerance image error; prints the ladder")
    p.add_argument("--tolerance", type=float, default=None,
                   help="with --auto: the relative held-back error gain a rung must beat (default 0.05); "
                        "scene-Auto: the image error to reach (default 0.02)")
    p.add_argument("--models", help="with --auto: the lobe models the ladder tries, comma-separated names or model "
                                    "files (default: all); a folder in the list adds its model files, as --models DIR "
                                    "does on other commands")
    p.add_argument("--combination", choices=["linear", "fixed"], default="linear", help="how lobes combine")
    p.add_argument("--metric", default=DEFAULT_METRIC,
                   help="Ngan, L2, cosL2 (over BRDF samples) or image (renders of the reference view under "
                        "three maps, or --env, cube-root toned)")
    p.add_argument("--env", action="append", default=[],
                   help="with --metric image: a map the renders are lit by (repeat for several; default: "
                        "three synthetic maps, a sky with a sun, a room with a window, a studio)")
    p.add_argument("--mesh", help="with --metric image (and scene-Auto): judge the renders on this mesh (OBJ, PLY, "
                                  "STL, OFF, GLB, glTF) as `brdflab render --view orbit --mesh FILE` shows it, "
                                  "instead of the reference sphere")
    p.add_argument("--compression", default="none", choices=["none", "cbrt", "log"], help="of the values fitted")
    p.add_argument("--init", type=material_path, help="XML file whose last fitting (or material) is the initial guess")
    p.add_argument("--init-fitting", type=int_in(0, 1_000_000), default=None, help="use this stored fitting of --init")
    p.add_argument("--fitting", type=int_in(0, 1_000_000), default=None, help="fit the K-th stored fit of SOURCE")
    p.add_argument("--samples", choices=["all", "subset", "grid"], default="all", help="which samples to fit")
    p.add_argument("--size", type=int_in(1, 100_000_000), default=None,
                   help="samples in a subset (default: 50,000); with --auto, samples fitted and as many "
                        "held back (default: 20,000)")
    p.add_argument("--density", type=int_in(2, 90), default=None,
                   help="bins per angle of a grid (2..90; default: 45 for tables, 32 for analytic sources)")
    p.add_argument("--restarts", action=argparse.BooleanOptionalAction, default=None,
                   help="also start from each model's own guesses and keep the best (default: on, "
                        "off when continuing an --init fit)")
    p.add_argument("--max-iterations", type=int_in(1, 1_000_000), default=200, help="Levenberg–Marquardt iterations")
    p.add_argument("--time-limit", type=float, default=float("inf"),
                   help="seconds (> 0); the fit stops within one sample chunk and keeps the best so far "
                        "(with --auto: a limit for each candidate's fit, screens included)")
    p.add_argument("--out", help="write the source's XML with the new <Fitting> here")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(func=cmd_fit)

    p = _add(sub, "batch", "fit lobe sets to many sources on a Dask cluster (resumable)")
    p.add_argument("sources", nargs="+", help="measured data or XML files, or folders of them")
    p.add_argument("--lobes", action="append", default=[],
                   help="a lobe set, e.g. Lambertian,BlinnPhong; repeat for several")
    p.add_argument("--auto", action="store_true",
                   help="also one task per source that climbs Auto's ladder (as fit --auto) and keeps its pick; "
                        "its row's error is the pick's on all samples")
    p.add_argument("--tolerance", type=float, default=None,
                   help="with --auto: the relative held-back error gain a rung must beat (default 0.05)")
    p.add_argument("--models", help="with --auto: the lobe models the ladder tries, comma-separated names or model "
                                    "files (default: all); a folder in the list adds its model files, as --models DIR "
                                    "does on other commands")
    p.add_argument("--metric", default=DEFAULT_METRIC, help="L2, cosL2 or Ngan (as for fit)")
    p.add_argument("--combination", choices=["linear", "fixed"], default="linear", help="how lobes combine")
    p.add_argument("--max-iterations", type=int, default=200, help="Levenberg–Marquardt iterations")
    p.add_argument("--out", required=True, help="folder for the results table, the charts and fits/*.xml")
    p.add_argument("--scheduler", help="address of an existing Dask scheduler, e.g. tcp://host:8786")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes of the local cluster (default: one per core)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(func=cmd_batch)

    p = _add(sub, "render", "offscreen render of a material")
    p.add_argument("material", type=material_path, help="XML material, measured data file, a model file (.brdf, model descriptor: one lobe at its defaults) or example:NAME")
    p.add_argument("--mode", choices=["point", "fis", "sh", "prefiltered", "mis", "auto"], default="point",
                   help="point light, filtered importance sampling of --env, spherical harmonics, "
                        "prefiltered lighting (the split sum), mis: the BRDF's and the map's importance "
                        "sampling combined (half the samples each), or auto: the cheapest of these "
                        "predicted within --tolerance for this material and map")
    p.add_argument("--tolerance", type=finite_float, default=0.02,
                   help="--mode auto: the relative error (reference view, over the view and per pixel) to stay within (default 0.02)")
    p.add_argument("--view", choices=["reference", "orbit"], default="orbit",
                   help="reference: the benchmarks' orthographic unit sphere; orbit: a perspective view of --mesh")
    p.add_argument("--mesh", default="sphere", help="sphere or a mesh file (OBJ, PLY, STL, OFF, GLB)")
    p.add_argument("--env", help="environment map (.hdr or .exr); default: the shipped CC0 map")
    p.add_argument("--env-layout", choices=ENV_LAYOUTS, default="auto",
                   help="light-probe layout of --env; auto: a square image with a disk is an angular map, a "
                        "square NAME-front or NAME-back beside its other half a dual-paraboloid pair")
    p.add_argument("--env-back", help="the back half of a dual-paraboloid pair whose front half is --env (default: "
                                      "the file named like --env with front and back swapped)")
    p.add_argument("--env-rotation", type=finite_float, default=0.0, help="degrees about +Y")
    p.add_argument("--light", default="0,0,1", help="direction towards the light, X,Y,Z (world)")
    p.add_argument("--samples", type=int_in(1, MAX_RENDER_SAMPLES), default=64,
                   help=f"FIS and MIS samples per pixel (1..{MAX_RENDER_SAMPLES})")
    p.add_argument("--mis-control", choices=["on", "off"], default="on",
                   help="--mode mis: the prefiltered image as a control variate, unbiased, its weight chosen for the "
                        "material and map (default on; off: plain MIS)")
    p.add_argument("--sh-order", type=int_in(1, 16, name="SH order"), default=5, help="bands of the SH mode (order² coefficients), 1..16")
    p.add_argument("--sh-window", choices=["none", "hanning", "lanczos"], default="none", help="against ringing")
    p.add_argument("--sh-table", type=sh_table, default=None, metavar="auto|SIZExLOG2",
                   help="the SH mode's BRDF table: SIZE² texels and 2^LOG2 samples per integral (e.g. 64x10), "
                        "or auto: the cheapest within --sh-table-tolerance (default: 128 texels, 2^12 samples per "
                        "elevation for isotropic sources, 2^8 per texel for anisotropic ones)")
    p.add_argument("--sh-table-tolerance", type=finite_float, default=0.01,
                   help="--sh-table auto: the table's relative RMS error over views to stay within")
    p.add_argument("--sh-shadows", action="store_true", help="self-shadowing by precomputed transfer (meshes)")
    p.add_argument("--sh-variant", choices=["dynamic", "fixed-light", "fixed-view"], default="dynamic",
                   help="per-pixel rotation, or the paper's per-vertex precomputation for a fixed light or view")
    p.add_argument("--size", type=image_size, default="512,512", help="W,H in pixels (1..8192 each)")
    p.add_argument("--exposure", type=finite_float, default=0.0, help="stops, for .png output")
    p.add_argument("--fitting", type=int_in(0, 1_000_000), default=None, help="render the K-th stored fit")
    p.add_argument("--out", required=True, help=".exr (linear radiance) or .png (tone-mapped)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(func=cmd_render)

    p = _add(sub, "simulate", "write a simulated material (SCATMECH or ray-bounce microgeometry)")
    p.add_argument("kind", nargs="?", help="a simulated kind (see --list)")
    p.add_argument("--list", action="store_true", help="list every simulated kind with its parameters")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="a parameter value (repeatable)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the ray-bounce simulator")
    p.add_argument("--samples", type=int, default=200_000, help="rays per incident angle (ray-bounce kinds)")
    p.add_argument("--resolution", type=int, default=32, help="R of the R×R×R half/difference table")
    p.add_argument("--name", help="the material's name (default: the kind)")
    p.add_argument("--out", help="the XML material to write")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(func=cmd_simulate)

    p = _add(sub, "export", "write a material or stored fit for other tools")
    p.add_argument("source", type=material_path, help="XML material, measured data file, a model file (.brdf, model descriptor: one lobe at its defaults) or example:NAME")
    p.add_argument("--format", choices=["merl", "brdf-explorer", "glsl", "mitsuba", "mtlx", "gltf"], required=True,
                   help="merl: a MERL .binary table (any source, tabulated); brdf-explorer: a Disney BRDF Explorer .brdf; "
                        "glsl: a GLSL function with the parameters baked in; mitsuba: a Mitsuba 3 scene (the reference "
                        "view) with a principled BSDF; mtlx: MaterialX standard_surface and open_pbr_surface; gltf: a "
                        "glTF 2.0 sphere with a metallic-roughness material (.glb: binary). The last three take a "
                        "Principled material as it is and fit anything else to Principled on the way out, saying the error")
    p.add_argument("--env", help="mitsuba: the scene's environment map (default: the shipped map), written "
                                  "beside the scene as lat-long OpenEXR")
    p.add_argument("--env-layout", choices=ENV_LAYOUTS, default="auto",
                   help="the layout of --env")
    p.add_argument("--env-back", help="the back half of a dual-paraboloid pair whose front half is --env")
    p.add_argument("--fitting", type=int_in(0, 1_000_000), default=None, help="export the K-th stored fit")
    p.add_argument("--out", required=True, help="the file to write")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(func=cmd_export)

    p = _add(sub, "bench", "speed/accuracy charts (PNG) and numbers (JSON)")
    p.add_argument("--quick", action="store_true", help="smaller sizes, fewer sample counts")
    p.add_argument("--out", required=True, help="folder for bench.json and the charts (created if missing)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(func=cmd_bench)

    p = _add(sub, "study", "measure speed against accuracy for every method; charts (PNG) and study.json")
    p.add_argument("--quick", action="store_true", help="small sizes and test matrices (minutes, as CI runs it)")
    p.add_argument("--part", action="append", metavar="PART",
                   help="run only this part (repeatable; default: all; an unknown name lists the parts)")
    p.add_argument("--out", required=True, help="folder for study.json and the charts (created if missing); "
                   "fits measured by an earlier run into it are kept, and only the missing ones fitted")
    p.add_argument("--fresh", action="store_true", help="measure every fit again, whatever OUT holds")
    p.add_argument("--stop-after", type=int_in(0, 100_000, "a number of minutes"), metavar="MINUTES",
                   help="start no new measurement after MINUTES and draw the charts from what is done "
                        "(run again into OUT to go on)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(func=cmd_study)
    for name, command in sub.choices.items():
        if name not in ("fit", "batch"):  # theirs also names --auto's models (folders count there too)
            command.add_argument("--models", action="append", dest="model_dirs", metavar="DIR",
                                 help="a folder of model files (.brdf, BRDFLab model descriptors) to use "
                                      "beside the built-in models (repeatable; BRDFLAB_MODELS lists more)")
    return parser


class _Terminated(BaseException):
    """SIGTERM, raised in the main thread so that `finally` blocks stop worker processes and
    clusters (by default the process would die at once and leave its workers running)."""


@contextmanager
def _terminate_cleanly(command: str):
    """While a command runs, SIGTERM raises `_Terminated`. Not for the GUI, whose event loop
    runs no Python between events (the default action stops it at once)."""
    if command == "gui" or threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum, frame):
        raise _Terminated

    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv: list[str] | None = None) -> int:
    from brdflab.cli_options import UsageError

    if argv is None and hasattr(sys.stdout, "reconfigure"):
        # JSON and names print as UTF-8 whatever the locale; a name that is not UTF-8 as errors show it
        codecs.register_error("brdflab-shown", _shown_name)
        sys.stdout.reconfigure(encoding="utf-8", errors="brdflab-shown")
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            args = parser.parse_args(["gui"])
    except UsageError as e:
        print(e, file=sys.stderr)
        return 2
    try:
        with _terminate_cleanly(args.command):
            _load_model_folders(args)
            return args.func(args)
    except BRDFLabError as e:
        print(f"brdflab {args.command}: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"brdflab {args.command}: interrupted", file=sys.stderr)
        return 130
    except _Terminated:
        print(f"brdflab {args.command}: terminated", file=sys.stderr)
        return 128 + signal.SIGTERM
    except BrokenPipeError:  # `brdflab models | head`: the reader left; say nothing more
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # the exit flush must not fail again
        return 141  # 128 + SIGPIPE, what a shell reports for a writer whose reader left


if __name__ == "__main__":
    sys.exit(main())
