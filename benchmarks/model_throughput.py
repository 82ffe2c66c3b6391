"""Evaluation throughput of every lobe model, in million direction pairs per second.

    python benchmarks/model_throughput.py [--pairs N] [--repeat R] [--json OUT]

Schwenk's survey asks what each model costs; this answers it in numbers for the
NumPy path (single process, float64, N random pairs above the surface).
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np

from brdflab.models import all_models


def random_pairs(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(2, n, 3))
    v[..., 2] = np.abs(v[..., 2])
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    return v[0], v[1]


def measure(n: int, repeat: int) -> list[dict]:
    wi, wo = random_pairs(n)
    rows = []
    for model in all_models():
        model.evaluate(wi[:1000], wo[:1000])  # warm-up
        best = min(_timed(model, wi, wo) for _ in range(repeat))
        rows.append({"model": model.name, "seconds": best, "mpairs_per_s": n / best / 1e6})
    return rows


def _timed(model, wi, wo) -> float:
    t0 = time.perf_counter()
    model.evaluate(wi, wo)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--json", help="also write the numbers here")
    args = ap.parse_args()
    rows = measure(args.pairs, args.repeat)
    print(f"{'model':<26}{'Mpairs/s':>10}{'ms / 1M':>10}")
    for r in sorted(rows, key=lambda r: -r["mpairs_per_s"]):
        print(f"{r['model']:<26}{r['mpairs_per_s']:>10.2f}{r['seconds'] * 1e3 * 1e6 / args.pairs:>10.1f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"machine": platform.platform(), "pairs": args.pairs, "rows": rows}, f, indent=2)


if __name__ == "__main__":
    main()
