"""Hostile input, as a user meets it: the real CLI in a subprocess, per-case time and memory limits.

The corpus is built here, in a temporary folder (sparse files cost no disk). Each case runs under
20 s of CPU and 1.5 GB of address space (and a wall-clock limit for cases that would block without
computing, like a FIFO), so the limits hold on a loaded machine as on an idle one. Every refused case
must exit 2 with exactly one line on stderr that names the file and the problem, without a
traceback, a warning text or a line of any file it read; valid-but-large files must finish
with status 0 and print only strict JSON.
"""

from __future__ import annotations

import hashlib
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
FIG2 = ROOT / "materials" / "fig2_lambertian_lafortune.xml"
TIME_LIMIT_S = 20  # CPU seconds per case (RLIMIT_CPU): the same budget on an idle or a loaded machine
HANG_LIMIT_S = 180  # wall-clock seconds, for cases that would block without using CPU (a FIFO)
MEMORY_LIMIT = 1536 << 20
SPARSE = 20 << 30

LAMBERT = "<Lobe><Model>Lambertian</Model><Type>Isotropic</Type><Parameters/></Lobe>"


def material(body: str, n_channels: str = "3", n_lobes: int | str = 1, combination: str = "Linear") -> str:
    return (f"<?xml version='1.0' encoding='UTF-8'?>\n<BRDF>\n<Material>\n<Name>hostile</Name>\n<Type>Analytic</Type>\n"
            f"<LobeCombination>{combination}</LobeCombination>\n"
            f'<Parameters nChannels="{n_channels}" nLobes="{n_lobes}">\n{body}\n</Parameters>\n</Material>\n</BRDF>\n')


def linear_lobe(scales: str = 'channel0="0.1" channel1="0.1" channel2="0.1"') -> str:
    return f"<ScalingFactors {scales}/>\n{LAMBERT}"


def measured(data: str, type_: str, checksum: str | None = None) -> str:
    check = f'<Checksum algorithm="sha256">{checksum}</Checksum>' if checksum else ""
    return (f"<?xml version='1.0' encoding='UTF-8'?>\n<BRDF>\n<Material>\n<Name>{data}</Name>\n"
            f"<Type>{type_}</Type>\n{check}\n</Material>\n</BRDF>\n")


def slice_bytes(value: float) -> bytes:
    return np.full((90, 90, 3), value, "<f4").tobytes()


def write_merl(path: Path, special: float) -> None:
    """A valid MERL table (constant 0.5 after scaling) with one raw entry replaced by `special`."""
    raw = np.full(3 * 90 * 90 * 180, 750.0, "<f8")
    raw[12345] = special
    with open(path, "wb") as f:
        f.write(np.array([90, 90, 180], "<i4").tobytes())
        raw.tofile(f)


def sparse(path: Path, head: bytes = b"") -> None:
    with open(path, "wb") as f:
        f.write(head)
        f.truncate(SPARSE)


def build_corpus(d: Path) -> None:
    w = lambda name, text: (d / name).write_text(text, encoding="utf-8")  # noqa: E731
    for n in ("1000000000", "-3", "0"):
        w(f"channels_{n}.xml", material(linear_lobe(), n_channels=n))
    w("nlobes_huge.xml", material(linear_lobe(), n_lobes="1000000000"))
    w("lobes_20000.xml", material("\n".join(
        linear_lobe(f'channel0="{1e-5 * (1 + k % 7)}" channel1="1e-5" channel2="2e-5"') for k in range(20_000)),
        n_lobes=20_000))
    w("unknown_1e6.xml", material(linear_lobe()).replace("</BRDF>", "<U/>" * 1_000_000 + "</BRDF>"))
    w("unknown_3e6.xml", material(linear_lobe()).replace("</BRDF>", "<U/>" * 3_000_000 + "</BRDF>"))
    w("deep.xml", material(linear_lobe()).replace("</BRDF>", "<U>" * 100_000 + "</U>" * 100_000 + "</BRDF>"))
    w("many_attributes.xml", material(linear_lobe(" ".join(f'a{k}="1"' for k in range(100_000)))))
    w("many_parameters.xml", material(linear_lobe().replace("<Parameters/>", "<Parameters "
                                      + " ".join(f'p{k}="1"' for k in range(100_000)) + "/>")))
    fit = material(linear_lobe()).split("<Material>", 1)[1].split("</Material>", 1)[0]
    w("infinite_statistics.xml", material(linear_lobe()).replace("</BRDF>", (
        f'<Fitting error="0.1"><Material>{fit}</Material><FitStatistics seconds="inf" iterations="nan"/></Fitting>'
        "</BRDF>")))
    w("negative_scale.xml", material(linear_lobe('channel0="-50" channel1="0.1" channel2="0.1"')))
    w("huge_scale.xml", material(linear_lobe('channel0="1e308" channel1="0.1" channel2="0.1"')))
    fixed = '<Lobe channel="0"><Model>Lambertian</Model><Type>Isotropic</Type><Parameters value="0.2"/></Lobe>'
    w("fixed_missing.xml", material(fixed, combination="Fixed"))
    w("long_attribute.xml", material(linear_lobe(f'channel0="{"A" * 100_000}" channel1="0.1" channel2="0.1"')))
    # measured data: sparse 20 GB files, special files, overflowing values
    sparse(d / "big.binary", np.array([90, 90, 180], "<i4").tobytes())
    sparse(d / "big.slice")
    sparse(d / "big.xml", b"<?xml version='1.0'?>\n<BRDF>")
    (d / "dev_zero.binary").symlink_to("/dev/zero")
    (d / "dev_zero.xml").symlink_to("/dev/zero")
    os.mkfifo(d / "fifo.slice")
    os.mkfifo(d / "fifo.xml")
    os.mkfifo(d / "fifo.obj")
    os.mkfifo(d / "fifo.hdr")
    (d / "dir.binary").mkdir()
    w("names_fifo.xml", measured("fifo.slice", "BivariateSlice"))
    write_merl(d / "merl_1e308.binary", 1e308)
    write_merl(d / "merl_minus_1e308.binary", -1e308)  # negative: an unmeasured sample, a valid file
    (d / "slice_3e38.slice").write_bytes(slice_bytes(3e38))
    (d / "ok.slice").write_bytes(slice_bytes(0.05))
    sha = hashlib.sha256(slice_bytes(0.05)).hexdigest()
    w("checksum_ok.xml", measured("ok.slice", "BivariateSlice", sha))
    w("checksum_bad.xml", measured("ok.slice", "BivariateSlice", "0" * 64))
    w("names_passwd.xml", measured("/etc/passwd", "RawSamples"))
    # meshes
    tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n"
    w("huge_coords.obj", tri.replace("v 1 0 0", "v 1e308 0 0").replace("v 0 1 0", "v -1e308 1e308 0"))
    w("inf_coords.obj", tri.replace("v 1 0 0", "v 1e309 0 0"))
    (d / "latin1.obj").write_bytes("# modèle exporté — café\n".encode("latin-1", errors="replace") + tri.encode())
    # pair files
    rng = np.random.default_rng(0)
    v = rng.normal(size=(100, 6))
    v[:, 2] = np.abs(v[:, 2])
    v[:, 5] = np.abs(v[:, 5])
    np.save(d / "pairs.npy", v)
    np.savez(d / "pairs.npz", pairs=v)
    (d / "pairs_empty.npy").write_bytes(b"")
    header = b"\x93NUMPY\x01\x00"
    text = b"{'descr': '<f8', 'fortran_order': False, 'shape': (1000000000000, 6), }"
    text += b" " * (63 - len(text) % 64) + b"\n"
    (d / "pairs_huge_header.npy").write_bytes(header + len(text).to_bytes(2, "little") + text + b"\0" * 480)
    sparse(d / "pairs_sparse.npy", header + len(text).to_bytes(2, "little") + text.replace(b"1000000000000", b"447392424"))
    np.save(d / "pairs_objects.npy", np.array([[None] * 6], dtype=object), allow_pickle=True)
    # a Python path that hides charset_normalizer, as in an environment where it is not installed
    (d / "no_charset").mkdir()
    (d / "no_charset" / "charset_normalizer.py").write_text("raise ImportError('not installed')\n")
    (d / "no_charset" / "chardet.py").write_text("raise ImportError('not installed')\n")


@dataclass
class Case:
    """One command line over the corpus and what it must do."""

    argv: list[str]
    status: int = 2
    words: tuple[str, ...] = ()  # the problem, as the one stderr line must say it (lower case)
    names: str | None = None  # the file the error line must name (default: the first argument)
    read: tuple[str, ...] = ()  # text files the command reads: none of their lines may be echoed
    hide_charset: bool = False

    @property
    def named(self) -> str:
        return self.names if self.names is not None else self.argv[1]


def E(*argv: str) -> list[str]:  # eval with a valid pair file
    return ["eval", *argv, "--pairs", "pairs.npy", "--out", "out.npy"]


def R(material: str, *more: str) -> list[str]:  # a tiny, cheap render
    return ["render", material, "--size", "8,8", "--samples", "1", "--out", "out.png", *more]


FIT = ("--lobes", "Lambertian", "--max-iterations", "3")

CASES: dict[str, Case] = {
    # a declared channel count far beyond any material: refused at parse time, everywhere
    "channels-1e9-info": Case(["info", "channels_1000000000.xml"], words=("nchannels",)),
    "channels-1e9-eval": Case(E("channels_1000000000.xml"), words=("nchannels",)),
    "channels-1e9-fit": Case(["fit", "channels_1000000000.xml", *FIT], words=("nchannels",)),
    "channels-1e9-render": Case(R("channels_1000000000.xml"), words=("nchannels",)),
    "channels-negative": Case(["info", "channels_-3.xml"], words=("nchannels",)),
    "channels-zero": Case(["info", "channels_0.xml"], words=("nchannels",)),
    "lobes-declared-1e9": Case(["info", "nlobes_huge.xml"], words=("nlobes",)),
    # valid but large: fast, energy check capped and said so, warnings summarised
    "lobes-20000": Case(["info", "lobes_20000.xml", "--json"], status=0, words=("energy check",)),
    "lobes-20000-render": Case(R("lobes_20000.xml"), words=("20,000 lobes",)),
    "unknown-1e6": Case(["info", "unknown_1e6.xml", "--json"], status=0, words=("999,990 more",)),
    "unknown-3e6": Case(["info", "unknown_3e6.xml"], words=("3,000,011 elements",)),
    "xml-deep": Case(["info", "deep.xml"], words=("depth",)),
    "xml-many-attributes": Case(["info", "many_attributes.xml"], words=("100,000 attributes",)),
    "xml-many-parameters": Case(["info", "many_parameters.xml"], words=("100,000 attributes",)),
    "xml-infinite-statistics": Case(["info", "infinite_statistics.xml", "--json"], status=0),
    # files far larger than declared, special files: refused before reading
    "merl-sparse-20GB": Case(["info", "big.binary"], words=("21474836480 bytes",)),
    "merl-sparse-20GB-eval": Case(E("big.binary"), words=("21474836480 bytes",)),
    "slice-sparse-20GB": Case(["info", "big.slice"], words=("21474836480 bytes",)),
    "xml-sparse-20GB": Case(["info", "big.xml"], words=("21474836480 bytes",)),
    "merl-dev-zero": Case(["info", "dev_zero.binary"], words=("not a regular file", "character device")),
    "merl-dev-zero-fit": Case(["fit", "dev_zero.binary", *FIT], words=("not a regular file",)),
    "xml-dev-zero": Case(["info", "dev_zero.xml"], words=("not a regular file",)),
    "slice-fifo": Case(["info", "fifo.slice"], words=("not a regular file", "fifo")),
    "xml-fifo": Case(["info", "fifo.xml"], words=("not a regular file", "fifo")),
    "xml-names-fifo": Case(E("names_fifo.xml"), words=("not a regular file",), names="fifo.slice"),
    "merl-directory": Case(["info", "dir.binary"], words=("not a regular file", "directory")),
    # numbers that overflow: one line, no RuntimeWarning, never Infinity in JSON
    "merl-1e308": Case(["info", "merl_1e308.binary", "--json"], words=("1e+308",)),
    "merl-1e308-fit": Case(["fit", "merl_1e308.binary", *FIT], words=("1e+308",)),
    "merl-minus-1e308": Case(["info", "merl_minus_1e308.binary", "--json"], status=0),
    "slice-3e38": Case(["info", "slice_3e38.slice", "--json"], words=("3e+38",)),
    "slice-3e38-fit": Case(["fit", "slice_3e38.slice", *FIT], words=("3e+38",)),
    "slice-3e38-render": Case(R("slice_3e38.slice"), words=("3e+38",)),
    "mesh-1e308": Case(R(str(FIG2), "--mesh", "huge_coords.obj"), status=0),  # large, but a mesh
    "mesh-1e309": Case(R(str(FIG2), "--mesh", "inf_coords.obj"), names="inf_coords.obj", words=("nan or inf",),
                       read=("inf_coords.obj",)),
    "envmap-fifo": Case(R(str(FIG2), "--mode", "fis", "--env", "fifo.hdr"), names="fifo.hdr",
                        words=("not a regular file",)),
    "mesh-fifo": Case(R(str(FIG2), "--mesh", "fifo.obj"), names="fifo.obj", words=("not a regular file",)),
    # impossible materials
    "negative-scale": Case(["info", "negative_scale.xml"], words=("negative",)),
    "huge-scale": Case(["info", "huge_scale.xml", "--json"], words=("scaling factor",)),
    "fixed-missing-channels": Case(["info", "fixed_missing.xml"], words=("channel 1",)),
    "fixed-missing-channels-render": Case(R("fixed_missing.xml"), words=("channel 1",)),
    "long-attribute": Case(["info", "long_attribute.xml"], words=("not a number",), read=("long_attribute.xml",)),
    # a Latin-1 comment in an OBJ, with no charset detector installed
    "mesh-latin1": Case(R(str(FIG2), "--mesh", "latin1.obj"), status=0, hide_charset=True),
    # a measured file that no longer matches its checksum: every command says so
    "checksum-info": Case(["info", "checksum_bad.xml"], status=0, words=("checksum",), names="ok.slice"),
    "checksum-eval": Case(E("checksum_bad.xml"), status=0, words=("checksum",), names="ok.slice"),
    "checksum-fit": Case(["fit", "checksum_bad.xml", *FIT], status=0, words=("checksum",), names="ok.slice"),
    "checksum-render": Case(R("checksum_bad.xml"), status=0, words=("checksum",), names="ok.slice"),
    "checksum-good-eval": Case(E("checksum_ok.xml"), status=0),
    # a material that names somebody else's file: its lines are never echoed
    "names-passwd": Case(E("names_passwd.xml"), names="/etc/passwd", read=("/etc/passwd",)),
    # bad options and pair files
    "fit-size-negative": Case(["fit", "ok.slice", *FIT, "--samples", "subset", "--size", "-5"], words=("--size",),
                              names=""),
    "fit-density-huge": Case(["fit", "ok.slice", *FIT, "--samples", "grid", "--density", "100000"],
                             words=("--density",), names=""),
    "fit-density-zero": Case(["fit", "ok.slice", *FIT, "--samples", "grid", "--density", "0"], words=("--density",),
                             names=""),
    "fit-density-one": Case(["fit", str(FIG2), *FIT, "--samples", "grid", "--density", "1"], words=("--density",),
                            names=""),
    "pairs-npz": Case(["eval", str(FIG2), "--pairs", "pairs.npz", "--out", "o.npy"], names="pairs.npz"),
    "pairs-empty": Case(["eval", str(FIG2), "--pairs", "pairs_empty.npy", "--out", "o.npy"], names="pairs_empty.npy",
                        words=("empty",)),
    "pairs-huge-header": Case(["eval", str(FIG2), "--pairs", "pairs_huge_header.npy", "--out", "o.npy"],
                              names="pairs_huge_header.npy", words=("bytes",)),
    "pairs-sparse-20GB": Case(["eval", str(FIG2), "--pairs", "pairs_sparse.npy", "--out", "o.npy"],
                              names="pairs_sparse.npy", words=("pairs",)),
    "pairs-objects": Case(["eval", str(FIG2), "--pairs", "pairs_objects.npy", "--out", "o.npy"],
                          names="pairs_objects.npy"),
}


def _limits() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))
    resource.setrlimit(resource.RLIMIT_CPU, (TIME_LIMIT_S, TIME_LIMIT_S + 1))


def run_case(folder: Path, case: Case) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    if case.hide_charset:
        env["PYTHONPATH"] = os.pathsep.join([str(folder / "no_charset"), str(ROOT)])
    try:
        r = subprocess.run([sys.executable, "-m", "brdflab", *case.argv], cwd=folder, env=env,
                           capture_output=True, text=True, timeout=HANG_LIMIT_S, preexec_fn=_limits)
    except subprocess.TimeoutExpired as e:
        return subprocess.CompletedProcess(e.cmd, -1, "", f"TIMEOUT: blocked for {HANG_LIMIT_S} s")
    if r.returncode == -signal.SIGXCPU:
        return subprocess.CompletedProcess(r.args, -1, r.stdout, f"TIMEOUT: over {TIME_LIMIT_S} s of CPU")
    return r


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """Every case's result, run two at a time (each its own process with its own limits)."""
    folder = tmp_path_factory.mktemp("hostile")
    build_corpus(folder)
    with ThreadPoolExecutor(max_workers=2) as pool:
        done = dict(zip(CASES, pool.map(lambda c: run_case(folder, c), CASES.values())))
    yield folder, done
    shutil.rmtree(folder, ignore_errors=True)


def _strict_json(text: str):
    def refuse(name):
        raise ValueError(f"{name} is not JSON")
    return json.loads(text, parse_constant=refuse)


def _echoed_lines(stderr: str, folder: Path, files: tuple[str, ...]) -> list[str]:
    echoed = []
    for name in files:
        for line in (folder / name).read_text("latin-1").splitlines():
            piece = line.strip()[:16]
            if len(piece) >= 10 and piece in stderr:
                echoed.append(line)
    return echoed


@pytest.mark.parametrize("name", list(CASES))
def test_hostile_case(results, name):
    folder, done = results
    case, r = CASES[name], done[name]
    where = f"{' '.join(case.argv)}\nstatus {r.returncode}\nstderr: {r.stderr[-2000:]}"
    assert not r.stderr.startswith("TIMEOUT"), where
    assert r.returncode == case.status, where
    assert "Traceback" not in r.stderr and "Warning:" not in r.stderr and "RuntimeWarning" not in r.stderr, where
    lines = r.stderr.splitlines()
    assert all(len(line) < 400 for line in lines), where
    if case.status == 2:
        assert len(lines) == 1, where
        assert case.named in lines[0], where
    elif case.words:
        assert 1 <= len(lines) <= 12, where
        assert any(case.named in line for line in lines), where
    else:
        assert lines == [], where
    for word in case.words:
        assert word in r.stderr.lower(), where
    assert not _echoed_lines(r.stderr, folder, case.read), where
    if "--json" in case.argv and r.returncode == 0:
        _strict_json(r.stdout.strip().splitlines()[-1])


def test_large_files_report_what_was_capped(results):
    """The 20,000-lobe file is described whole but its energy check says it was capped; the
    10⁶ unknown elements are summarised in the JSON as in the warning lines."""
    _, done = results
    lobes = _strict_json(done["lobes-20000"].stdout.strip().splitlines()[-1])
    assert len(lobes["material"]["lobes"]) == 20_000
    assert lobes["energy"]["checked"] is False and "20,000 lobes" in lobes["energy"]["reason"]
    unknown = _strict_json(done["unknown-1e6"].stdout.strip().splitlines()[-1])
    assert len(unknown["warnings"]) <= 11 and unknown["warnings"][-1].endswith("and 999,990 more")
    assert len(done["unknown-1e6"].stderr.splitlines()) == len(unknown["warnings"])


def test_checksum_matches_are_silent_and_mismatches_named(results):
    folder, done = results
    assert done["checksum-good-eval"].stderr == ""
    assert np.load(folder / "out.npy").shape == (100, 3)
    for name in ("checksum-eval", "checksum-fit", "checksum-render", "checksum-info"):
        assert "warning" in done[name].stderr and "sha256" in done[name].stderr, done[name].stderr


def test_energy_budget_checks_what_fits_and_names_what_it_skipped(monkeypatch):
    """In process (cheap): with a budget of one anisotropic lobe, the material is checked and
    its two-lobe fit is reported as not checked, with a warning saying how many were skipped."""
    from brdflab.io import xmlio
    from brdflab.material.albedo import check_cost
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.sources import files

    ward = AnalyticMaterial("w", "Linear", 3, [Lobe.create("Ward", [0.1] * 3, ax=0.2, ay=0.3)])
    fit = AnalyticMaterial("f", "Linear", 3, ward.lobes * 2)
    doc = xmlio.BRDFDocument(ward, [xmlio.Fitting(fit, 0.1)])
    monkeypatch.setattr(files, "ENERGY_CHECK_BUDGET", check_cost(ward))
    monkeypatch.setattr(files, "load", lambda path: doc)
    monkeypatch.setattr(files, "is_xml", lambda path: True)
    info = files.describe_file(Path(__file__))
    assert info["energy"]["checked"] and info["energy"]["conserves_energy"]
    assert info["fittings"][0]["energy"]["checked"] is False
    assert "2 lobes" in info["fittings"][0]["energy"]["reason"]
    assert info["warnings"] == ['energy check skipped for 1 of 2 materials (more lobes than the check covers '
                                'in one file; see "energy")']


def test_negative_reflectance_never_conserves():
    """A material built in memory with a negative scale (files refuse one) is flagged, not
    reported as conserving with albedo −15.7; the albedo is checked against the closed form
    of a Lambertian lobe (scale · π)."""
    import math

    from brdflab.material.albedo import energy_check
    from brdflab.material.analytic import AnalyticMaterial, Lobe

    lobe = Lobe.create("Lambertian", [0.1])
    lobe.scale = [-5.0]
    report = energy_check(AnalyticMaterial("n", "Linear", 1, [lobe]))
    assert report.min_albedo[0] == pytest.approx(-5.0 * math.pi, rel=1e-3)
    assert not report.conserves and report.as_dict()["conserves_energy"] is False


def test_the_lab_never_writes_a_fixed_material_its_reader_refuses(tmp_path):
    """The reader refuses a Fixed material with a channel that has no lobe; the workspace says
    so on save instead of writing one, and adding channels gives them the last channel's lobes."""
    from brdflab.errors import BRDFLabError
    from brdflab.io.xmlio import BRDFDocument, load
    from brdflab.workspace import Workspace, with_channels, with_lobe_removed

    fixed = load(ROOT / "materials" / "fig5_fixed_per_channel.xml").material
    grown = Workspace(BRDFDocument(with_channels(fixed, 4)))
    grown.save(tmp_path / "grown.xml")
    back = load(tmp_path / "grown.xml").material
    assert back.n_channels == 4 and back.channels_without_lobes() == []
    assert [l.params for l in back.lobes if l.channel == 3] == [l.params for l in fixed.lobes if l.channel == 2]
    emptied = Workspace(BRDFDocument(with_lobe_removed(with_lobe_removed(fixed, 2), 2)))  # channel 1's lobes
    with pytest.raises(BRDFLabError, match="channel 1"):
        emptied.save(tmp_path / "emptied.xml")
    assert not (tmp_path / "emptied.xml").exists()
