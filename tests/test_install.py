"""The product as a user installs it: a wheel in a fresh virtual environment, run from a
folder outside the checkout. Every command must work there, the render and GUI packages
included (a hand-kept package list once left them out of the wheel)."""

import json
import os
import shutil
import site
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
IGNORE = shutil.ignore_patterns(".git", "build", "dist", "*.egg-info", "__pycache__", ".pytest_cache",
                                ".hypothesis", ".venv", "docs", "tests", "benchmarks", "bench-out")


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """A fresh venv holding the wheel; its dependencies come from this interpreter's
    site-packages through a .pth file (that adds their paths without running their .pth
    hooks, so an editable install of the checkout stays invisible)."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    shutil.copytree(ROOT, src, ignore=IGNORE)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation",
                    "-w", str(tmp / "dist"), str(src)], check=True, cwd=tmp)
    shutil.rmtree(src)  # nothing may point back into a checkout
    wheel = next((tmp / "dist").glob("brdflab-*.whl"))
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    purelib = subprocess.run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    deps = [p for p in {*site.getsitepackages(), sysconfig.get_paths()["purelib"]} if Path(p).is_dir()]
    (Path(purelib) / "host_dependencies.pth").write_text("\n".join(deps) + "\n")
    subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--quiet", "--no-deps",
                    "--no-index", str(wheel)], check=True)
    work = tmp / "elsewhere"
    work.mkdir()
    return {"wheel": wheel, "bin": venv / "bin", "work": work}


CLEAN_ENV = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}


def brdflab(installed, *args, check=True):
    proc = subprocess.run([str(installed["bin"] / "brdflab"), *map(str, args)], capture_output=True, text=True,
                          cwd=installed["work"], timeout=600, env=CLEAN_ENV)
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def last_json(proc):
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_wheel_in_a_fresh_venv_runs_every_command(installed):
    names = zipfile.ZipFile(installed["wheel"]).namelist()
    on_disk = {p.parent.relative_to(ROOT).as_posix() for p in (ROOT / "brdflab").rglob("__init__.py")}
    in_wheel = {n.rsplit("/", 1)[0] for n in names if n.endswith("/__init__.py")}
    assert on_disk <= in_wheel, on_disk - in_wheel
    assert {"brdflab/_shaders", "brdflab/_materials", "brdflab/_resources"} <= {n.rsplit("/", 1)[0] for n in names}

    py = installed["bin"] / "python"
    where = subprocess.run([py, "-c", "import brdflab, brdflab.render, brdflab.gui; print(brdflab.__file__)"],
                           capture_output=True, text=True, cwd=installed["work"], check=True, env=CLEAN_ENV).stdout
    assert where.startswith(str(installed["bin"].parent)), where

    models = last_json(brdflab(installed, "models", "--json"))
    assert len(models["models"]) >= 16
    example = subprocess.run([py, "-c", "from brdflab.io.resources import data_dir; "
                              "print(data_dir('materials') / 'fig2_lambertian_lafortune.xml')"],
                             capture_output=True, text=True, check=True, env=CLEAN_ENV).stdout.strip()
    assert last_json(brdflab(installed, "info", example, "--json"))["material"]

    work = installed["work"]
    pairs = np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], [0.6, 0.0, 0.8, -0.6, 0.0, 0.8]])
    np.save(work / "pairs.npy", pairs)
    brdflab(installed, "eval", example, "--pairs", "pairs.npy", "--out", "values.npy")
    assert np.all(np.isfinite(np.load(work / "values.npy"))) and np.load(work / "values.npy").shape == (2, 3)

    fit = last_json(brdflab(installed, "fit", example, "--lobes", "Lambertian,BlinnPhong", "--out", "fit.xml", "--json"))
    assert np.isfinite(fit["error"]) and (work / "fit.xml").is_file()

    for mode in ("point", "fis", "sh"):
        out = brdflab(installed, "render", example, "--mode", mode, "--view", "reference", "--size", "48,48",
                      "--samples", "16", "--sh-order", "3", "--out", f"{mode}.png", "--json")
        assert (work / f"{mode}.png").stat().st_size > 500, out.stderr

    assert last_json(brdflab(installed, "info", "example:fig2", "--json"))["material"]["type"] == "Analytic"

    run = brdflab(installed, "bench", "--quick", "--out", "bench", "--json")
    bench = last_json(run)
    check_bench_outputs(work / "bench", bench)
    progress = [line for line in run.stderr.splitlines() if line.startswith("brdflab bench: ")]
    assert len(progress) >= 6, run.stderr  # a line per step, not minutes of silence
    measured = any("measured" in t["source"] for t in json.loads((work / "bench" / "bench.json").read_text())["sh"]["tables"])
    assert measured or "skipped SH tables of a measured material" in run.stderr  # never dropped silently


def check_bench_outputs(out: Path, payload: dict) -> None:
    """What `bench --quick` promises: numbers for models and renders, and real charts."""
    data = json.loads((out / "bench.json").read_text())
    assert {"models", "render"} <= set(data)
    fis = data["render"]["fis"]
    assert {r["material"] for r in fis} == {"diffuse", "glossy", "anisotropic"}
    for name in ("diffuse", "glossy", "anisotropic"):  # more samples give less error
        rows = sorted((r for r in fis if r["material"] == name), key=lambda r: r["samples"])
        assert rows[-1]["relative_rmse"] < rows[0]["relative_rmse"]
    for chart in payload["files"][1:]:
        assert (out / chart).stat().st_size > 10_000
