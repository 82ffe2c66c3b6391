"""A material that names one model of a 100-file `--models` folder, evaluated as a user runs it
(issue 35, goal 5: once the folder has been seen, ≤ 2× the time with a one-file folder).

    python benchmarks/model_folders.py [--files 100] [--json docs/bench/model_folders.json]

Two folders: one BRDF Explorer file (ward.brdf, as `m001.brdf`), and `--files` files of the
same model, each made distinct (another comment line, so another content and sha256) and named
`m001` … Each command is `brdflab eval MATERIAL --models FOLDER --pairs P --out V` in a new
process from another folder, first with an empty user cache (every file probed in a child
process) and then three times with the cache it left (the best is kept).
Times are wall-clock, measured in one run; the ratios are what the goal is about.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

import numpy as np
from export_cache import timed  # a command as a user runs it, wall seconds (same folder)

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("BRDFLAB_SHARED", ROOT.parent / "shared")) / "data"
WARD = DATA / "models" / "brdf_explorer" / "ward.brdf"


def folder_of(path: Path, files: int) -> Path:
    path.mkdir()
    text = WARD.read_text()
    for k in range(1, files + 1):
        (path / f"m{k:03d}.brdf").write_text(text.replace("analytic\n", f"analytic\n# copy {k}\n", 1))
    return path


def material_naming(model_file: Path, out: Path) -> None:
    """A Lambertian + one lobe of the file's model, saved as a material (it records the file)."""
    from brdflab.io.xmlio import BRDFDocument, save
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.models.files.library import load_model_file

    model = load_model_file(model_file)
    save(BRDFDocument(AnalyticMaterial("one file model", "Linear", 3, [Lobe.create("Lambertian", [0.2] * 3),
                                                                         Lobe.create(model.name, [0.5] * 3)])), out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--files", type=int, default=100)
    ap.add_argument("--json", default=str(ROOT / "docs" / "bench" / "model_folders.json"))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        one, many = folder_of(tmp / "one", 1), folder_of(tmp / "many", args.files)
        material = tmp / "material.xml"
        material_naming(one / "m001.brdf", material)
        rng = np.random.default_rng(3)
        w = rng.normal(size=(2, 1000, 3))
        w[..., 2] = np.abs(w[..., 2])
        w /= np.linalg.norm(w, axis=-1, keepdims=True)
        np.save(tmp / "pairs.npy", np.concatenate([w[0], w[1]], axis=1))
        elsewhere = tmp / "cwd"
        elsewhere.mkdir()
        rows = {}
        for name, folder in (("one file", one), (f"{args.files} files", many)):
            env = {**os.environ, "BRDFLAB_CACHE": str(tmp / f"cache-{folder.name}")}
            command = [str(a) for a in ("eval", material, "--models", folder, "--pairs", tmp / "pairs.npy", "--out",
                                        tmp / "v.npy")]
            cold = timed(command, elsewhere, env)
            warm = min(timed(command, elsewhere, env) for _ in range(3))
            rows[name] = {"first_s": round(cold, 3), "seen_s": round(warm, 3)}
            print(f"{name:>10}: first {cold:6.2f} s, once seen {warm:6.2f} s", flush=True)
    many_row = rows[f"{args.files} files"]
    result = {"files": args.files, "rows": rows,
              "seen_ratio_many_to_one": round(many_row["seen_s"] / rows["one file"]["seen_s"], 2),
              "first_ratio_many_to_one": round(many_row["first_s"] / rows["one file"]["first_s"], 2),
              "load_average": os.getloadavg(), "cpu_count": os.cpu_count()}
    print(json.dumps(result, indent=2))
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
