"""The synthetic maps at a glance: a contact sheet and the table of docs/maps.md.

    python benchmarks/synthetic_maps.py [--out docs]

Each map tone-mapped by its own mean radiance (× 2, then clipped), so a sun or lamp shows as
white and the rest of the map as it is; the table gives what `brdflab info MAP` says.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from brdflab.lighting.map_info import map_summary
from brdflab.lighting.synthetic_maps import CATALOGUE

ROOT = Path(__file__).resolve().parents[1]


def contact_sheet(path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = 3
    rows = -(-len(CATALOGUE) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(3.2 * columns, 1.9 * rows), dpi=100)
    for ax, m in zip(axes.ravel(), CATALOGUE):
        data = m.build().data
        shown = np.clip(data / (2.0 * data.mean()), 0.0, 1.0) ** (1 / 2.2)
        ax.imshow(shown)
        ax.set_title(f"{m.name} ({m.kind}{', held out' if m.held_out else ''})", fontsize=8,
                     color="firebrick" if m.held_out else "black")
    for ax in axes.ravel():
        ax.set_axis_off()
    fig.tight_layout()
    fig.savefig(path)


def table() -> str:
    lines = ["| map | class | held out | mean radiance | dynamic range | light from the brightest 0.1 % |",
             "|---|---|---|---|---|---|"]
    for m in CATALOGUE:
        s = map_summary(m.build())
        lines.append(f"| {m.name} | {m.kind} | {'yes' if m.held_out else ''} | {s['mean_radiance']:.3g} | "
                     f"{s['dynamic_range']:.2g} | {100 * s['small_source_share']:.1f} % |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs"))
    out = Path(parser.parse_args().out)
    contact_sheet(out / "images" / "synthetic_maps.png")
    print(table())


if __name__ == "__main__":
    main()
