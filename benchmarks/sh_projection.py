"""Projecting a lat-long map onto spherical harmonics: the separable sum against the sum over
every texel's Gauss points that it stands for (and that `project_environment` computed before).

    python benchmarks/sh_projection.py [--json docs/bench/sh_projection.json]

Maps: the default map as the lab reads it (1,024 × 512) and a 2,000 × 1,000 map (what a
1,000-texel light probe becomes); orders 3, 8 and 16. Both routes run in one process, one after
the other; the largest relative difference of their coefficients is printed beside the times.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from brdflab.io.resources import default_environment_path
from brdflab.lighting import sh
from brdflab.lighting.envmap import EnvironmentMap, load_environment, uv_to_direction

ORDERS = (3, 8, 16)


def gauss_point_sum(env: EnvironmentMap, order: int, rows: int = 16) -> np.ndarray:
    """Every texel's 2 × 2 Gauss points in cos θ and φ, the basis at their directions."""
    h, w = env.height, env.width
    g = (np.array([-1.0, 1.0]) / math.sqrt(3.0) + 1.0) / 2.0
    out = np.zeros((order * order, env.data.shape[2]))
    for r0 in range(0, h, rows):
        r = np.arange(r0, min(h, r0 + rows))
        z0, z1 = np.cos(math.pi * r / h), np.cos(math.pi * (r + 1) / h)
        weight = (0.5 * np.abs(z0 - z1))[:, None] * (math.pi / w)
        for gy in g:
            v = np.arccos(z0 + gy * (z1 - z0)) / math.pi
            for gx in g:
                d = uv_to_direction(((np.arange(w) + gx) / w)[None, :], v[:, None])
                out += np.einsum("rwn,rwc->nc", sh.basis(order, d) * weight[..., None], env.data[r].astype(float))
    return out


def timed(run) -> tuple[float, np.ndarray]:
    t0 = time.perf_counter()
    value = run()
    return time.perf_counter() - t0, value


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json")
    args = ap.parse_args()
    maps = {"default map": load_environment(default_environment_path()),
            "2,000 × 1,000": EnvironmentMap(np.random.default_rng(0).random((1000, 2000, 3)).astype(np.float32))}
    rows = []
    for name, env in maps.items():
        for order in ORDERS:
            sh.project_environment(EnvironmentMap(np.ones((2, 4, 3), np.float32)), order)  # the frame change, cached
            direct_s, direct = timed(lambda: gauss_point_sum(env, order))
            separable_s, separable = timed(lambda: sh.project_environment(env, order))
            difference = float(np.abs(separable - direct).max() / np.abs(direct).max())
            rows.append({"map": name, "size": [env.width, env.height], "order": order, "gauss_points_s": direct_s,
                         "separable_s": separable_s, "ratio": direct_s / separable_s, "difference": difference})
            print(f"{name:<14} order {order:2d}: every Gauss point {direct_s:6.2f} s, separable {separable_s:5.3f} s "
                  f"({direct_s / separable_s:5.1f}×), coefficients differ by {difference:.1e}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows}, indent=1))


if __name__ == "__main__":
    main()
