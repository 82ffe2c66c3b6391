"""`brdflab batch`: fits on Dask worker processes equal the fits run alone, a rerun skips
done work, a killed worker loses no result, and a bad file becomes a failed row."""

import json
import logging
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from brdflab.batch.runner import BatchSettings, run_batch
from brdflab.batch.tasks import restore_malloc_reuse
from brdflab.cli import main
from brdflab.fitting.auto import auto_fit
from brdflab.fitting.lm import FitOptions, fit, material_from_lobes
from brdflab.fitting.metrics import metric_error
from brdflab.fitting.second_error import image_error
from brdflab.fitting.samples import samples_of
from brdflab.io.xmlio import load
from brdflab.sources.files import load_source
from brdflab.sources.measured import read_slice
from conftest import DATA, ROOT, needs_shared

distributed = pytest.importorskip("distributed")
SLICES = DATA / "merl_slices"
pytestmark = needs_shared("merl_slices")


def copy_slices(folder: Path, names) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        shutil.copy(SLICES / f"{name}.slice", folder / f"{name}.slice")
    return folder


def batch_cli(cwd: Path, *argv) -> subprocess.CompletedProcess:
    """The command as a user runs it: another folder, the worktree's code."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "brdflab", "batch", *argv, "--json"], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def summary_of(proc) -> dict:
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def cluster():
    """One LocalCluster of two single-threaded worker processes, shared by the tests that
    use an existing cluster (`--scheduler`): Dask's defaults, as on a cluster the lab did not
    start. Its nanny writes its pre-spawn variables into this process's environment; they
    are taken back out so that later tests' processes do not inherit them."""
    saved = dict(os.environ)
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                       silence_logs=logging.CRITICAL)
    client = distributed.Client(cluster)
    yield cluster, client
    client.close()
    cluster.close()
    os.environ.clear()
    os.environ.update(saved)


def test_local_cluster_batch_equals_fits_alone_and_bad_file_is_a_failed_row(tmp_path):
    data = copy_slices(tmp_path / "data", ["pvc", "nickel"])
    (data / "broken.slice").write_bytes(b"\0" * 5000)
    (data / "notes.md").write_text("not a source")  # not a data file: ignored
    proc = batch_cli(tmp_path, "data", "--lobes", "Lambertian,BlinnPhong", "--lobes", "Lambertian,Ward",
                     "--metric", "L2", "--out", "results", "--workers", "2")
    summary = summary_of(proc)
    assert summary["tasks"] == 6 and summary["ran"] == 6 and summary["failed"] == 2 and summary["workers"] == 2
    assert "dashboard http" in proc.stderr

    table = pd.read_csv(tmp_path / "results" / "results.csv")
    assert len(table) == 6
    bad = table[table["material"] == "broken"]
    assert list(bad["status"]) == ["failed", "failed"]
    assert all(m.endswith("broken.slice: truncated: 5000 bytes, a slice is 97200") for m in bad["message"])
    ok = table[table["status"] != "failed"]
    assert ok["worker"].str.startswith("tcp://").all() and ok["pid"].nunique() >= 1
    for row in ok.itertuples():
        alone = fit(material_from_lobes(row.lobes.split(","), "Linear", 3), samples_of(read_slice(data / f"{row.material}.slice")),
                    FitOptions(metric="L2"))
        assert row.error == pytest.approx(alone.error, rel=1e-6), row
        # its image error beside it, the same as the image metric gives the fit (issue 34 goal 2)
        assert row.image_error == pytest.approx(image_error(alone.material, read_slice(data / f"{row.material}.slice")),
                                                rel=1e-6), row
    assert bad["image_error"].isna().all()
    parquet = pd.read_parquet(tmp_path / "results" / "results.parquet")
    assert sorted(parquet["error"].dropna()) == pytest.approx(sorted(ok["error"]))

    # the XML of a source holds every fit of it, and a stored fit reproduces its error on the slice
    doc = load(tmp_path / "results" / "fits" / "pvc.xml")
    assert [f.statistics["batch_key"] for f in doc.fittings] == list(table[table["material"] == "pvc"]["key"])
    stored = load_source(tmp_path / "results" / "fits" / "pvc.xml", fitting=1)
    samples = samples_of(load_source(tmp_path / "results" / "fits" / "pvc.xml"))
    row = ok[(ok["material"] == "pvc") & (ok["lobes"] == "Lambertian,Ward")].iloc[0]
    assert metric_error(stored, samples, "L2") == pytest.approx(row.error, rel=1e-6)
    assert not (tmp_path / "results" / "fits" / "broken.xml").exists()
    for chart in ("error_per_material.png", "error_vs_time.png"):
        assert (tmp_path / "results" / chart).read_bytes()[:4] == b"\x89PNG"


def test_rerun_skips_done_work_and_redoes_changed_files(tmp_path, cluster):
    _, client = cluster
    address = client.scheduler.address
    data = copy_slices(tmp_path / "data", ["pvc", "brass"])
    args = ("data", "--lobes", "Lambertian,BlinnPhong", "--out", "out", "--scheduler", address)
    first = summary_of(batch_cli(tmp_path, *args))
    assert (first["ran"], first["skipped"], first["failed"]) == (2, 0, 0)
    csv_before = (tmp_path / "out" / "results.csv").read_bytes()

    again = summary_of(batch_cli(tmp_path, *args))
    assert (again["ran"], again["skipped"]) == (0, 2)
    assert (tmp_path / "out" / "results.csv").read_bytes() == csv_before

    # a folder written before keys had their prefix (the bare digest, in the table and the XML):
    # its pairs are still done, and no second row or fit is added beside the old ones
    for path in [tmp_path / "out" / "results.csv", *(tmp_path / "out" / "fits").glob("*.xml")]:
        path.write_text(path.read_text().replace("pair-", ""))
    (tmp_path / "out" / "results.parquet").unlink()
    old = summary_of(batch_cli(tmp_path, *args))
    assert (old["ran"], old["skipped"]) == (0, 2)
    assert len(pd.read_csv(tmp_path / "out" / "results.csv")) == 2

    shutil.copy(SLICES / "nickel.slice", data / "brass.slice")  # new content under the same name
    third = summary_of(batch_cli(tmp_path, *args, "--lobes", "Lambertian,Ward"))
    assert (third["ran"], third["skipped"]) == (3, 1)  # brass twice (changed, new set), pvc with the new set
    table = pd.read_csv(tmp_path / "out" / "results.csv")
    assert len(table) == 4
    brass = table[table["material"] == "brass"]
    nickel_alone = fit(material_from_lobes(["Lambertian", "BlinnPhong"], "Linear", 3),
                       samples_of(read_slice(SLICES / "nickel.slice")), FitOptions())
    assert brass[brass["lobes"] == "Lambertian,BlinnPhong"]["error"].iloc[0] == pytest.approx(nickel_alone.error, rel=1e-6)
    assert len(load(tmp_path / "out" / "fits" / "brass.xml").fittings) == 2  # replaced, not appended


def test_killed_worker_loses_no_result(tmp_path, cluster):
    _, client = cluster
    data = copy_slices(tmp_path / "data", ["pvc", "brass", "nickel"])
    killed: dict = {}

    def kill_a_busy_worker():
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not killed:
            busy = {w: keys for w, keys in client.processing().items() if keys}
            if busy:
                worker, keys = next(iter(busy.items()))
                time.sleep(0.2)  # well inside a fit of this lobe set
                running = set(client.processing().get(worker, ())) & set(keys)
                if running:
                    pid = client.run(os.getpid, workers=[worker])[worker]
                    os.kill(pid, signal.SIGKILL)
                    killed.update(pid=pid, keys=running)
            time.sleep(0.05)

    killer = threading.Thread(target=kill_a_busy_worker)
    killer.start()
    summary = run_batch(BatchSettings([data], [("Lambertian", "LafortuneIso"), ("Lambertian", "BlinnPhong")],
                                      tmp_path / "out", scheduler=client.scheduler.address))
    killer.join()
    assert killed, "no worker was busy long enough to be killed"
    assert (summary.ran, summary.failed) == (6, 0)
    table = pd.read_csv(tmp_path / "out" / "results.csv")
    assert len(table) == 6 and (table["status"] != "failed").all()
    rerun = table[[f"fit-{k}-{s[:8]}" in killed["keys"] for k, s in zip(table["key"], table["sha256"])]]
    assert len(rerun) >= 1 and (rerun["pid"] != killed["pid"]).all()  # the lost task ran again elsewhere
    assert all(len(load(tmp_path / "out" / "fits" / f"{m}.xml").fittings) == 2 for m in ("pvc", "brass", "nickel"))
    assert not list((tmp_path / "out").rglob("*.tmp"))


@pytest.mark.parametrize("argv, message", [
    (["--lobes", "Lambertian,NoSuchLobe"], "NoSuchLobe"),
    (["--lobes", "Lambertian", "--metric", "L7"], "unknown metric"),
    (["--lobes", "Lambertian", "--workers", "0"], "--workers must be at least 1"),
    ([], "name at least one lobe set (--lobes A,B,...) or --auto"),
    (["--lobes", "Lambertian", "--models", "Ward"], "--models applies to --auto"),
    (["--auto", "--models", "Ward,NoSuchLobe"], "NoSuchLobe"),
    (["--auto", "--tolerance", "1.5"], "--tolerance 1.5"),
])
def test_bad_options_fail_in_one_line_before_any_cluster(tmp_path, capsys, argv, message):
    copy_slices(tmp_path / "data", ["pvc"])
    code = main(["batch", str(tmp_path / "data"), *argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1


def test_missing_source_and_out_file_are_one_line_errors(tmp_path, capsys):
    assert main(["batch", str(tmp_path / "nothing"), "--lobes", "Lambertian", "--out", str(tmp_path / "o")]) == 2
    assert "nothing: no such file or folder" in capsys.readouterr().err
    (tmp_path / "o").write_text("a file")
    copy_slices(tmp_path / "data", ["pvc"])
    assert main(["batch", str(tmp_path / "data"), "--lobes", "Lambertian", "--out", str(tmp_path / "o")]) == 2
    assert "--out must be a folder" in capsys.readouterr().err


def test_the_labs_cluster_starts_workers_without_malloc_trim(tmp_path):
    """Dask's nanny starts workers with MALLOC_TRIM_THRESHOLD_ set, which turns off glibc's
    adaptive mmap threshold and makes a fit about 30 % slower (docs/batch.md): the cluster
    that `brdflab batch` starts leaves it unset (checked in a fresh process, as the CLI runs)."""
    code = ("import os\nfrom distributed import Client\nfrom brdflab.batch.runner import local_cluster\n"
            "if __name__ == '__main__':\n    cluster = local_cluster(1)\n    client = Client(cluster)\n"
            "    print(list(client.run(lambda: os.environ.get('MALLOC_TRIM_THRESHOLD_', 'unset')).values()))\n"
            "    print(os.environ.get('MALLOC_TRIM_THRESHOLD_', 'unset'))\n    client.close(); cluster.close()\n")
    (tmp_path / "probe.py").write_text(code)
    env = {k: v for k, v in os.environ.items() if k != "MALLOC_TRIM_THRESHOLD_"}
    proc = subprocess.run([sys.executable, "probe.py"], cwd=tmp_path, env={**env, "PYTHONPATH": str(ROOT)},
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split("\n")[:2] == ["['unset']", "unset"]  # the workers, and the process that started them


def test_workers_of_another_cluster_get_freed_memory_reused(cluster, monkeypatch):
    """On a cluster with Dask's defaults the task raises glibc's thresholds back (once per
    process); a process started without the variable is left alone."""
    _, client = cluster
    assert set(client.run(lambda: os.environ.get("MALLOC_TRIM_THRESHOLD_")).values()) == {"65536"}
    assert all(client.run(restore_malloc_reuse).values())
    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    assert restore_malloc_reuse.__wrapped__() is False


def test_auto_is_one_more_task_per_source_scored_on_all_samples(tmp_path, cluster):
    """`--auto`: per source, Auto's ladder (as `brdflab fit --auto`) as a task of its own; its
    row names the pick, and its error is the pick's on every sample of the source."""
    _, client = cluster
    data = copy_slices(tmp_path / "data", ["pvc"])
    settings = BatchSettings([data], [("Lambertian", "Ward")], tmp_path / "out", metric="Ngan", auto=True,
                             auto_models=("BlinnPhong", "Ward"), scheduler=client.scheduler.address)
    summary = run_batch(settings, stream=open(os.devnull, "w"))
    assert (summary.tasks, summary.ran, summary.failed) == (2, 2, 0)
    table = pd.read_csv(tmp_path / "out" / "results.csv")
    auto = table[table["lobes"] == "auto"].iloc[0]
    samples = samples_of(read_slice(data / "pvc.slice"))
    ladder = auto_fit(samples, 0.05, "Ngan", "Linear", models=["BlinnPhong", "Ward"])  # the same ladder, alone
    assert auto["message"].startswith(f"Auto picked {'+'.join(('Lambertian', *ladder.chosen.lobes))}: ")
    assert json.loads(auto["options"])["auto"] == {"models": "BlinnPhong,Ward", "split": 20000, "tolerance": 0.05}
    doc = load(tmp_path / "out" / "fits" / "pvc.xml")
    k = [f.statistics["batch_key"] for f in doc.fittings].index(auto["key"])
    stored = load_source(tmp_path / "out" / "fits" / "pvc.xml", fitting=k)
    assert metric_error(stored, samples, "Ngan") == pytest.approx(auto["error"], rel=1e-6)  # all samples, reread
    again = run_batch(settings, stream=open(os.devnull, "w"))
    assert (again.ran, again.skipped) == (0, 2)


def test_two_batches_into_one_folder_keep_each_others_rows(tmp_path):
    """Two batches run into one --out, each started before the other saved: every save takes
    the folder's lock and takes in the rows the other saved (the later save kept only its own
    rows, so a run ended with half of them)."""
    from types import SimpleNamespace

    from brdflab.batch.runner import Recorder
    from brdflab.batch.table import COLUMNS, ResultsTable

    def outcome(key: str):
        row = {c: "" for c in COLUMNS} | {"key": key, "source": key, "material": key, "lobes": "Lambertian",
                                           "status": "converged", "error": 0.5}
        return SimpleNamespace(row=row, fitting=None, source_type=None)

    tasks = [SimpleNamespace(source=s, sha256="0" * 64) for s in ("a", "b")]
    first, second = Recorder(tmp_path, tasks, print), Recorder(tmp_path, tasks, print)
    first.add([outcome("pair-a")])
    second.add([outcome("pair-b")])
    first.flush()
    second.flush()
    first.add([outcome("pair-a")])  # a later result of the first batch keeps the second's row too
    first.flush()
    assert sorted(ResultsTable.load(tmp_path).rows) == ["pair-a", "pair-b"]
    assert len(pd.read_csv(tmp_path / "results.csv")) == 2


def test_a_table_saved_before_the_image_error_column_still_loads(tmp_path):
    from brdflab.batch.table import COLUMNS, ResultsTable

    old = [c for c in COLUMNS if c != "image_error"]
    row = {c: "" for c in old} | {"key": "k1", "error": "0.25", "pid": "1", "seconds": "1", "iterations": "3",
                                  "evaluations": "4", "status": "converged"}
    pd.DataFrame([row], columns=old).to_csv(tmp_path / "results.csv", index=False)
    table = ResultsTable.load(tmp_path)  # its key, from before keys had their prefix, is read as today's
    assert table.rows["pair-k1"]["error"] == 0.25 and np.isnan(table.rows["pair-k1"]["image_error"])


def test_a_stored_fit_is_found_again_whatever_its_key_digests_to(tmp_path):
    """A pair's key is a digest; one made of digits and an 'e' (this source's, before keys were
    prefixed: 69395966538766031e18) was read back from <FitStatistics> as a number, so a rerun
    did not find the fit it had stored. Every key must come back as the text it was."""
    from brdflab.batch.store import KEY, FitStore
    from brdflab.batch.tasks import FitTask
    from brdflab.io.xmlio import Fitting

    source = str(tmp_path / "m24941.slice")
    task = FitTask("/data/m24941.slice", "0" * 64, ("Lambertian",), "Linear", {})
    material = material_from_lobes(["Lambertian"], "Linear", 3)
    store = FitStore(tmp_path, [source])
    store.add(task.key, source, Fitting(material, error=0.5), "MERLSlice")
    store.write(source, [{"key": task.key, "status": "done"}], "0" * 64)
    again = FitStore(tmp_path, [source])
    again.load_existing(warn=pytest.fail)
    assert list(again.fittings) == [task.key]
    assert [f.statistics[KEY] for f in load(tmp_path / "m24941.xml").fittings] == [task.key]
