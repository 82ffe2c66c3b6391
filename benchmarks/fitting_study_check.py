"""Check rows of the fitting study by routes the study does not take.

    python benchmarks/fitting_study_check.py [--refit] MATERIAL/FAMILY/SIZE ...   # SIZE: 5k, 20k, ..., all
    e.g.  "brass/2×CookTorranceGGX Linear/5k"

For each row of docs/study/fitting: its fitted material rebuilt from the stored parameters
and scored (Ngan) on a sample set built afresh from the slice file, and on BRDFLab's
16 × 16 × 64 grid; with --refit, the same fit run again here (`lm.fit`, the study's options)
and timed by `time.process_time`, its result scored on all samples.
"""

from __future__ import annotations

import os

# one BLAS thread, as in the study's workers (more would add their spinning to process_time)
os.environ.update({"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"})

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from brdflab.fitting.lm import FitOptions, fit  # noqa: E402
from brdflab.fitting.metrics import grid_error, metric_errors  # noqa: E402
from brdflab.fitting.samples import samples_of  # noqa: E402
from brdflab.io.resources import shared_data_dir  # noqa: E402
from brdflab.sources.measured import read_slice  # noqa: E402
from brdflab.study.fit_jobs import FitJob, material_of, start_material  # noqa: E402
from brdflab.study.framework import read_study  # noqa: E402


def parse_key(text: str) -> tuple[str, str, int | None]:
    material, family, size = text.split("/")
    return material, family, None if size == "all" else int(size.rstrip("k")) * 1000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rows", nargs="+")
    parser.add_argument("--refit", action="store_true")
    parser.add_argument("--study", default="docs/study/fitting")
    args = parser.parse_args()
    rows = {(r["material"], r["family"], r["size"]): r
            for r in read_study(Path(args.study))["parts"]["fitting"]["rows"]}
    folder = shared_data_dir() / "merl_slices"
    for text in args.rows:
        row = rows[parse_key(text)]
        source = read_slice(str(folder / f"{row['material']}.slice"))
        full = samples_of(source)
        fitted = material_of(row)
        fresh = metric_errors([fitted], full, "Ngan")[0]
        grid = grid_error(source, fitted, "Ngan")
        line = (f"{text}: row {row['error']:.6g} (fitted {row['error_fitted']:.6g}), fresh {fresh:.6g}, "
                f"grid {grid:.6g}, row CPU s {row['seconds']:.3g}")
        if args.refit:
            samples = full if row["size"] is None else full.subset(row["size"], seed=1)
            job = FitJob("", tuple(row["lobes"].split("+")[1:]), row["combination"], row["size"])
            c0 = time.process_time()
            result = fit(start_material(job), samples, FitOptions(metric="Ngan", restarts=True,
                                                                  coarse_size=60_000, diagnose=False))
            cpu = time.process_time() - c0
            line += f", refit CPU s {cpu:.3g}, refit error {metric_errors([result.material], full, 'Ngan')[0]:.6g}"
        print(line, flush=True)


if __name__ == "__main__":
    main()
