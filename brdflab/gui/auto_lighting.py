"""The object view's Auto lighting: the core's choice (lighting/auto.py) made in a worker
process for the window, and described in one line (the Object view options) and in full
(its tooltip); and for a hand-picked prefiltered mode, the split sum's predicted error.
Qt-free, so the worker process that runs the jobs never loads Qt."""

from __future__ import annotations

from html import escape

from brdflab.lighting.auto import PREFILTERED_BOUND, Candidate, LightingChoice, choose_lighting, prefiltered_check

# what the prediction is made for (lighting/auto.py); the object view's mesh and camera approximate it
PREDICTED_FOR = ("the reference view (a sphere seen under the unturned map), without SH self-shadowing, "
                 "the dynamic SH variant")


def choose_job(job: tuple) -> tuple[int, LightingChoice]:
    """(token, source, map, tolerance, proxy) → (token, the choice) — run in a worker process.
    `proxy`: the lobes the renderer samples a measured source with (its own fit), as the CLI passes."""
    token, source, env, tolerance, proxy = job
    return token, choose_lighting(source, env, tolerance, proxy=proxy)


def prefiltered_job(job: tuple) -> tuple[int, float]:
    """(token, source, map, proxy) → (token, the prefiltered mode's predicted error) — run in a
    worker process (a second or two: the view pilot's converged pixels)."""
    token, source, env, proxy = job
    return token, prefiltered_check(source, env, proxy=proxy)


def prefiltered_note(error: float) -> tuple[str, bool]:
    """The line under the lighting choice for the prefiltered mode, and whether it warns."""
    if error <= PREFILTERED_BOUND:
        return (f"prefiltered: predicted {100 * error:.1f} % off pixel by pixel "
                f"(trusted within {100 * PREFILTERED_BOUND:g} %)"), False
    return (f"prefiltered: predicted {100 * error:.1f} % off pixel by pixel: the split sum cannot hold this "
            "material under this map (a narrow lobe under a small bright source, or lobes stretched at "
            "grazing views); choose mis or auto"), True


def chosen(choice: LightingChoice) -> Candidate:
    """The candidate the choice picked."""
    return next(c for c in choice.candidates if (c.mode, c.setting) == (choice.mode, choice.setting))


def summary(choice: LightingChoice) -> str:
    """'auto → fis n=64, predicted 1.6 % (≤ 2 %)'; when nothing is predicted within the
    tolerance, says so and that the best predicted is drawn."""
    head = f"auto → {chosen(choice).label}, predicted {100 * choice.predicted_error:.1f} %"
    if choice.within:
        return f"{head} (≤ {100 * choice.tolerance:g} %)"
    return f"{head}: nothing is predicted within {100 * choice.tolerance:g} %, drawing the best predicted"


def details(choice: LightingChoice) -> str:
    """Every reason, then every candidate weighed (cheapest first) with its predicted error and
    modelled frame cost (FRAME_COST_MS: only their order matters), the pick in bold — rich
    text, for the label's tooltip."""
    pick, bold = chosen(choice), ' style="font-weight: bold"'
    rows = "".join(f"<tr{bold if c is pick else ''}><td>{escape(c.label)}</td>"
                   f"<td align=right>{100 * c.predicted_error:.2f} %</td><td align=right>{c.cost_ms:.1f} ms</td></tr>"
                   for c in choice.candidates)
    return ("<br>".join(escape(r) for r in choice.reasons) + f"<br><i>predicted for {escape(PREDICTED_FOR)}</i>"
            "<table cellspacing=0 cellpadding=2><tr><th align=left>candidate</th><th>predicted</th>"
            f"<th>frame cost (model)</th></tr>{rows}</table>")
