"""`python -m brdflab.render.model_probe FILE SHA256 NAME`: compile a model file's GLSL and evaluate
it on probe pairs at its defaults; print {"problem": null | "one line", "undefined": null | "one
line"} as JSON (undefined: where its values are NaN, a warning).

Run by `model_eval.check` in a child process with a CPU-time limit: GLSL that never finishes
takes this process with it, not the lab.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from brdflab.errors import BRDFLabError

SLOW_CPU_SECONDS = 2.0  # CPU time for PROBE_PAIRS pairs (the same on a loaded machine); corpus models take ms
AGREE = 1e-3  # a formula and its GLSL twin agree this closely (float32 GLSL); the corpora: 2e-5


def problem(model) -> tuple[str | None, str | None]:
    """What is wrong with the model's values at its defaults on the probe pairs (or None), and
    where they are undefined (or None)."""
    from brdflab.models.files.library import PROBE_PAIRS, probe_pairs, undefined_where, values_problem

    wi, wo = probe_pairs(PROBE_PAIRS)
    p = model.defaults()
    model._gl_values(wi[:8], wo[:8], p)  # compiles the program
    t0 = time.process_time()  # this process's CPU time, llvmpipe's threads included: not the machine's load
    values = model._gl_values(wi, wo, p)
    seconds = time.process_time() - t0
    if seconds > SLOW_CPU_SECONDS:
        return (f"evaluating its GLSL at {PROBE_PAIRS:,} direction pairs took {seconds:.1f} s of CPU time (a lobe "
                "takes milliseconds): too slow to render or fit"), None
    found = values_problem(values, wi, wo, "its GLSL")
    if found:
        return found, None
    undefined = undefined_where(values, wi, wo, "its GLSL")
    if model.formula is not None:
        cpu = model.formula_values(wi, wo, p)
        gpu = values[:, 0]
        big = np.isfinite(cpu) & (np.abs(gpu) > 1e-6)
        rel = np.abs(cpu[big] - gpu[big]) / np.abs(gpu[big])
        if rel.size and rel.max() > AGREE:
            k = np.flatnonzero(big)[int(np.argmax(rel))]
            return (f"its <Equation> and <Equation_GLSL> disagree by up to {rel.max():.2%} (e.g. {cpu[k]:.4g} "
                    f"against {gpu[k]:.4g} at wi = {np.round(wi[k], 3).tolist()}, wo = {np.round(wo[k], 3).tolist()}): "
                    "fits would use one and renders the other"), None
    return None, undefined


def main(argv: list[str]) -> int:
    """argv: the file, its sha256 and its registry name, as the parent read them."""
    from brdflab.models.files.library import rebuild

    undefined = None
    try:
        found, undefined = problem(rebuild(*argv[:3]))  # refused if the file changed since the parent read it
    except BRDFLabError as e:
        found = str(e).split(": ", 1)[1] if str(e).startswith(argv[0]) else str(e)
    print(json.dumps({"problem": found, "undefined": undefined}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
