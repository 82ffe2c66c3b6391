"""The object view's Auto lighting: the core's choice (lighting/auto.py) made in a worker
process for the window, and described in one line (the Object view options) and in full
(its tooltip). Qt-free, so the worker process that runs `choose_job` never loads Qt."""

from __future__ import annotations

from html import escape

from brdflab.lighting.auto import Candidate, LightingChoice, choose_lighting

# what the prediction is made for (lighting/auto.py); the object view's mesh and camera approximate it
PREDICTED_FOR = ("the reference view (a sphere seen under the unturned map), without SH self-shadowing, "
                 "the dynamic SH variant")


def choose_job(job: tuple) -> tuple[int, LightingChoice]:
    """(token, source, map, tolerance, proxy) → (token, the choice) — run in a worker process.
    `proxy`: the lobes the renderer samples a measured source with (its own fit), as the CLI passes."""
    token, source, env, tolerance, proxy = job
    return token, choose_lighting(source, env, tolerance, proxy=proxy)


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
