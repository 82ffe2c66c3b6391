"""Scene-Auto: the fewest lobes whose render of the user's scene is within a visible tolerance
of the measurement's (issue 34, goal 4).

Auto (auto.py) climbs until more lobes stop paying on held-back samples, and takes Lambertian
+ 3 lobes on almost every material: the samples reward every lobe. A user sees a scene; this
climbs the same ladder (the Lambertian alone, + one lobe of each model, + a second, …; the
first rung screened on a sixteenth of the pixels) but judges every candidate by its image error
(image_metric.py) in the scene, the user's maps, and stops at the first rung where a candidate
is within the tolerance: of those, the one with the fewest parameters (then the lowest error).
Within a rung, candidates are fitted cheapest first, and none with more parameters than one
already within the tolerance is fitted. When no rung gets there, the best candidate found is
kept and the reason says how far it is.

The default tolerance, 2 %, is about one just-noticeable difference: the error is of cube-root
toned values, and at mid-grey (L* ≈ 50) a 2 % change of ∛Y is ΔL* ≈ 1.3.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Callable

from brdflab.errors import BRDFLabError
from brdflab.fitting.auto import (MAX_LOBES, SCREENED_RUNGS, AutoProgress, Cancel, Candidate, Ladder, _Cancelled,
                                  _candidate, _Climb, _fit_fully, _label, _screen, mark_cancelled,
                                  validate_models)
from brdflab.fitting.image_metric import SceneImages
from brdflab.fitting.lm import FitOptions
from brdflab.models import model_names

DEFAULT_SCENE_TOLERANCE = 0.02
SCREEN_SHARE = 16  # the first rung is screened on every fourth pixel's row and column


def validate_scene_tolerance(tolerance: float) -> None:
    if not (math.isfinite(tolerance) and 0.0 < tolerance < 1.0):
        raise BRDFLabError(f"--tolerance {tolerance:g}: scene-Auto needs an image error in (0, 1), e.g. 0.02")


def _pick(within: list[Candidate]) -> Candidate:
    fewest = min(c.parameters for c in within)
    return min((c for c in within if c.parameters == fewest), key=lambda c: (c.error_held_back, c.lobes))


def scene_auto(scene: SceneImages, tolerance: float = DEFAULT_SCENE_TOLERANCE, combination: str = "Linear",
               models: list[str] | None = None, max_lobes: int = MAX_LOBES, options: FitOptions | None = None,
               progress: Callable[[AutoProgress], None] | None = None, cancel: Cancel | None = None) -> Ladder:
    """Climb until a candidate's image error in `scene` is within `tolerance` (see the module
    doc); the Ladder's `error_held_back` of every candidate is its image error in the scene."""
    validate_scene_tolerance(tolerance)
    validate_models(models or [])
    t0, c0 = time.perf_counter(), time.process_time()
    options = replace(options or FitOptions(), metric="image", compression="none", diagnose=False)
    options.validate()
    names = [m for m in (models or model_names()) if m != "Lambertian"]
    channels = scene.n_channels
    climb = _Climb(progress, cancel, max_lobes if names else 0, len(names), exhaustive=False, measure="image")
    lambertian = _candidate(0, (), combination, channels)
    done, chosen, rung = [lambertian], lambertian, []
    try:
        _fit_fully(lambertian, None, scene, scene, combination, options, climb)
        reason = f"the Lambertian alone is within {tolerance:.1%} (image error {lambertian.error_held_back:.4g})"
        base = lambertian
        for rung_index in range(1, max_lobes + 1):
            if chosen.error_held_back <= tolerance or not names:
                break
            rung = sorted((_candidate(rung_index, (*base.lobes, m), combination, channels) for m in names),
                          key=lambda c: (c.parameters, c.evaluation_ns, c.lobes))
            full = _screen(rung, base, scene, scene, combination, options, tolerance, climb, SCREEN_SHARE, 0) \
                if rung_index <= SCREENED_RUNGS else rung
            climb.screened(len(full))
            fitted: list[Candidate] = []
            for c in full:
                if any(f.error_held_back <= tolerance and f.parameters < c.parameters for f in fitted):
                    c.status = "not needed"  # a cheaper candidate of this rung is already within
                    continue
                _fit_fully(c, base, scene, scene, combination, options, climb)
                fitted.append(c)
            done += rung
            rung = []
            within = [c for c in fitted if c.error_held_back <= tolerance]
            best = min(fitted, key=lambda c: c.error_held_back)
            if within:
                chosen = _pick(within)
                reason = (f"rung {rung_index}: {_label(chosen)} renders the scene within {tolerance:.1%} "
                          f"(image error {chosen.error_held_back:.4g}) with the fewest parameters")
                break
            if best.error_held_back >= chosen.error_held_back:
                reason = (f"no candidate is within {tolerance:.1%}; rung {rung_index} does not improve on "
                          f"{_label(chosen)} (image error {chosen.error_held_back:.4g}), which is kept")
                break
            chosen = base = best
            reason = (f"no candidate is within {tolerance:.1%} after {rung_index} lobe(s) on the Lambertian; the "
                      f"best, {_label(chosen)}, renders the scene with image error {chosen.error_held_back:.4g}")
    except _Cancelled as stop:
        mark_cancelled(stop, rung, done)
        fully = [c for c in done if c.fitted]
        chosen = min(fully, key=lambda c: (c.error_held_back > tolerance, c.parameters if c.error_held_back
                                           <= tolerance else 0, c.error_held_back)) if fully else lambertian
        reason = f"cancelled; of the candidates fully fitted, {_label(chosen)} is kept"
    error = chosen.error_held_back if chosen.result is not None else math.nan
    return Ladder(done, chosen, reason, tolerance, "image", scene.size, 0, time.perf_counter() - t0,
                  time.process_time() - c0, error, scene.size, seen=scene.seen)
