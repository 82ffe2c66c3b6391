"""Check rows of the fitting study by routes the study does not take.

    python benchmarks/fitting_study_check.py [--refit] MATERIAL/FAMILY/SIZE ...   # SIZE: 5k, 20k, ..., all
    e.g.  "brass/2×CookTorranceGGX Linear/5k"

For each row of docs/study/fitting: its fitted material rebuilt from the stored parameters
and scored (Ngan) on a sample set built afresh from the slice file, and on BRDFLab's
16 × 16 × 64 grid; with --refit, the study's job for that row (`fit_jobs.run_job`: its
options, subset and CPU clock) run again here, its result scored on all samples.
"""

from __future__ import annotations

import os

from brdflab.study.workers import ONE_THREAD  # imports no NumPy

# one BLAS thread, as in the study's workers (more would add their spinning to process_time)
os.environ.update(ONE_THREAD)

import argparse  # noqa: E402
from pathlib import Path  # noqa: E402

from brdflab.fitting.metrics import grid_error, metric_errors  # noqa: E402
from brdflab.fitting.samples import samples_of  # noqa: E402
from brdflab.io.resources import shared_data_dir  # noqa: E402
from brdflab.sources.measured import read_slice  # noqa: E402
from brdflab.study.fit_jobs import FitJob, material_of, run_job  # noqa: E402
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
        path = folder / f"{row['material']}.slice"
        source = read_slice(str(path))
        full = samples_of(source)
        fitted = material_of(row)
        fresh = metric_errors([fitted], full, "Ngan")[0]
        grid = grid_error(source, fitted, "Ngan")
        line = (f"{text}: row {row['error']:.6g} (fitted {row['error_fitted']:.6g}), fresh {fresh:.6g}, "
                f"grid {grid:.6g}, row CPU s {row['seconds']:.3g}")
        if args.refit:  # the study's own job, run again in this process
            job = FitJob(str(path), tuple(row["lobes"].split("+")[1:]), row["combination"], row["size"])
            again = run_job(job)
            line += f", refit CPU s {again['seconds']:.3g}, refit error {again['error']:.6g}"
        print(line, flush=True)


if __name__ == "__main__":
    main()
