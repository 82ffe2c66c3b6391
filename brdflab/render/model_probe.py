"""`python -m brdflab.render.model_probe FILE NAME`: compile a model file's GLSL and evaluate
it on probe pairs at its defaults; print {"problem": null | "one line"} as JSON.

Run by `model_eval.check` in a child process with a time limit: GLSL that never finishes
takes this process with it, not the lab.
"""

from __future__ import annotations

import json
import sys

import numpy as np

from brdflab.errors import BRDFLabError


def problem(model) -> str | None:
    """What is wrong with the model's values at its defaults on the probe pairs, or None."""
    from brdflab.models.files.library import PROBE_PAIRS, probe_pairs

    wi, wo = probe_pairs(PROBE_PAIRS)
    p = model.defaults()
    values = model._gl_values(wi, wo, p)
    bad = ~np.isfinite(values).all(axis=-1)
    if bad.mean() > 0.01:
        k = int(np.argmax(bad))
        return (f"its GLSL gives NaN or infinity at {bad.mean():.0%} of probe pairs at its defaults "
                f"(e.g. wi = {np.round(wi[k], 3).tolist()}, wo = {np.round(wo[k], 3).tolist()})")
    neg = (values < -1e-6 * np.nanmax(np.abs(values), initial=1.0)).any(axis=-1) & ~bad
    if neg.any():
        k = int(np.argmax(neg))
        return (f"its GLSL gives negative values at its defaults (e.g. {float(values[k].min()):.3g} at wi = "
                f"{np.round(wi[k], 3).tolist()}, wo = {np.round(wo[k], 3).tolist()}): a BRDF is never negative")
    return None


def main(argv: list[str]) -> int:
    from brdflab.models.files import read_model_file

    try:
        model = read_model_file(argv[0], argv[1] if len(argv) > 1 else None)
        found = problem(model)
    except BRDFLabError as e:
        found = str(e).split(": ", 1)[1] if str(e).startswith(argv[0]) else str(e)
    print(json.dumps({"problem": found}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
