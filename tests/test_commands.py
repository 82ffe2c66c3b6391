"""The commands as a user meets them: option errors, outputs that cannot be lost or mixed,
startup cost, framing, shipped examples by name, help and version (issue 11)."""

import errno
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdflab.cli import main
from brdflab.errors import BRDFLabError
from brdflab.io.atomic import atomic_write
from conftest import DATA, ROOT, needs_shared

ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def one_line_error(capsys, code: int) -> str:
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.fixture
def read_only_folder(tmp_path):
    """A folder no file can be created in (root ignores permission bits: then /sys)."""
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        probe = folder / "probe"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError:
        yield folder
        folder.chmod(0o755)
        return
    folder.chmod(0o755)
    if os.access("/sys", os.F_OK):
        try:
            (Path("/sys") / "brdflab-probe").write_bytes(b"")
        except OSError:
            yield Path("/sys")
            return
    pytest.skip("no read-only folder on this machine")


# --- atomic saves ----------------------------------------------------------------------------

def test_atomic_write_reports_each_bad_target_in_one_line(tmp_path, read_only_folder):
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    cases = {tmp_path / "missing" / "o.bin": "does not exist", blocker / "o.bin": "is a file, not a folder",
             read_only_folder / "o.bin": "read-only", tmp_path: "is a folder"}
    for target, said in cases.items():
        with pytest.raises(BRDFLabError) as e:
            atomic_write(target, b"data")
        assert said in str(e.value) and str(target) in str(e.value) and "\n" not in str(e.value)


def test_a_full_disk_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    target = tmp_path / "o.bin"
    atomic_write(target, b"old")

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(BRDFLabError, match="disk is full"):
        atomic_write(target, b"new")
    assert target.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == ["o.bin"]


def test_a_new_file_gets_the_usual_permissions_and_an_old_one_keeps_its_own(tmp_path):
    umask = os.umask(0o022)
    try:
        atomic_write(tmp_path / "new.bin", b"x")
        (tmp_path / "old.bin").write_bytes(b"x")
        (tmp_path / "old.bin").chmod(0o600)
        atomic_write(tmp_path / "old.bin", b"y")
    finally:
        os.umask(umask)
    assert (tmp_path / "new.bin").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "old.bin").stat().st_mode & 0o777 == 0o600


WRITERS = re.compile(r"open\([^)]*['\"][wax]b?['\"]|\.write_(bytes|text)\(|savefig\((?!buf)|np\.save\((?!buf)"
                     r"|\.to_(csv|parquet)\((?!(index|parquet\b))|os\.(rename|replace)\(|\.write\(str\((?!tmp\))")


def test_every_save_goes_through_the_atomic_helper():
    """No module but brdflab/io/atomic.py writes a file itself (temporary files of tools excepted)."""
    offenders = []
    for path in sorted((ROOT / "brdflab").rglob("*.py")):
        if path.name == "atomic.py":
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if WRITERS.search(line):
                offenders.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not offenders, "\n".join(offenders)


# --- render options --------------------------------------------------------------------------

@pytest.mark.parametrize("argv", [
    ["--samples", "1e9"], ["--samples", "0"], ["--samples", "70000"], ["--sh-order", "0"], ["--sh-order", "17"],
    ["--env-rotation", "nan"], ["--env-rotation", "inf"], ["--exposure", "nan"], ["--exposure", "-inf"],
    ["--size", "0,5"], ["--size=-4,4"], ["--size", "99999,99999"], ["--size", "3"], ["--size", "1.5,2"],
    ["--light", "nan,0,1"], ["--light", "0,0,0"],
], ids=" ".join)
def test_bad_render_options_are_one_line_errors(tmp_path, capsys, argv):
    code = main(["render", "example:lambertian", *argv, "--out", str(tmp_path / "o.png")])
    err = one_line_error(capsys, code)
    assert err.startswith("brdflab render:")
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("argv", [["--size", "-5"], ["--size", "0"], ["--density", "1"], ["--density", "100000"],
                                  ["--max-iterations", "0"]], ids=" ".join)
def test_bad_fit_options_are_one_line_errors(capsys, argv):
    one_line_error(capsys, main(["fit", "example:fig2", "--lobes", "Lambertian", *argv]))


def test_render_into_a_bad_folder_is_a_one_line_error(tmp_path, capsys, read_only_folder):
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    for out in (tmp_path / "missing" / "o.exr", blocker / "o.png", read_only_folder / "o.exr"):
        err = one_line_error(capsys, main(["render", "example:lambertian", "--size", "8,8", "--out", str(out)]))
        assert str(out) in err


def test_eval_fit_export_into_a_bad_folder_fail_before_the_work(tmp_path, capsys, read_only_folder):
    pairs = tmp_path / "pairs.npy"
    np.save(pairs, np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]]))
    for argv in (["eval", "example:fig2", "--pairs", str(pairs), "--out"], ["fit", "example:fig2", "--lobes", "Lambertian", "--out"],
                 ["export", "example:fig2", "--format", "glsl", "--out"]):
        for out in (tmp_path / "missing" / "o", read_only_folder / "o"):
            assert str(out) in one_line_error(capsys, main([*argv, str(out)]))


def test_bench_into_a_bad_folder_is_a_one_line_error(tmp_path, capsys, read_only_folder):
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    for out in (blocker, blocker / "sub", read_only_folder / "bench"):
        one_line_error(capsys, main(["bench", "--quick", "--out", str(out)]))


def _mean_radiance(tmp_path, samples: int) -> np.ndarray:
    from brdflab.lighting.envmap import read_exr

    out = tmp_path / f"s{samples}.exr"
    assert main(["render", "example:fig2", "--mode", "fis", "--view", "reference", "--size", "24,24",
                 "--samples", str(samples), "--out", str(out)]) == 0
    image = read_exr(out)
    return image[image.sum(axis=2) > 0].mean(axis=0)


def test_samples_beyond_the_gl_row_limit_render_the_same_image(tmp_path):
    """16,400 samples exceed one texture row of 16,384: they must give the mean of 1,024
    samples (once every sample read texel 0 and the image came out ~70 % too dark)."""
    few, many = _mean_radiance(tmp_path, 1024), _mean_radiance(tmp_path, 16_400)
    assert np.all(few > 0)
    np.testing.assert_allclose(many, few, rtol=0.02)


def test_sh_order_1_renders_band_zero(tmp_path):
    """Order 1 keeps only the constant band: for a Lambertian sphere under a constant map
    of radiance 1 every pixel is the albedo ρ = π × its scaling factor (0.8 here)."""
    from brdflab.lighting.envmap import read_exr, write_exr

    env = tmp_path / "white.exr"
    write_exr(env, np.ones((16, 32, 3), np.float32))
    material = tmp_path / "m.xml"
    material.write_text((ROOT / "materials" / "lambertian.xml").read_text())
    out = tmp_path / "o.exr"
    assert main(["render", str(material), "--mode", "sh", "--sh-order", "1", "--view", "reference", "--env", str(env),
                 "--size", "16,16", "--out", str(out)]) == 0
    image = read_exr(out)
    inside = image.sum(axis=2) > 0
    from brdflab.io.xmlio import load

    lobe_scale = np.asarray(load(material).material.lobes[0].scale)  # ρ/π per channel
    np.testing.assert_allclose(image[inside].mean(axis=0), np.pi * lobe_scale, rtol=0.03)


def test_three_renders_to_one_exr_never_leave_an_unreadable_file(tmp_path):
    """Three processes render to the same .exr at once, a few rounds; each must succeed and
    the file must always read back as one of their complete images."""
    from brdflab.lighting.envmap import read_exr

    out = tmp_path / "same.exr"
    for round_ in range(2):
        procs = [subprocess.Popen([sys.executable, "-m", "brdflab", "render", "example:fig2", "--view", "reference",
                                   "--light", f"0,{k},1", "--size", "48,48", "--out", str(out)],
                                  cwd=tmp_path, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
                 for k in range(3)]
        for p in procs:
            _, err = p.communicate(timeout=300)
            assert p.returncode == 0, err.decode()
        assert read_exr(out).shape == (48, 48, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["same.exr"]  # no temporary left


def test_concurrent_exr_writers_never_mix(tmp_path):
    """Three processes write distinct noisy images (slow to compress, so the writes overlap)
    to one path 12 times each; every write must succeed and the file must always read back
    as one writer's complete image (values in [k, k + 1) for writer k)."""
    out = tmp_path / "same.exr"
    script = ("import sys, numpy as np\nfrom brdflab.lighting.envmap import write_exr\n"
              "k = int(sys.argv[1])\nrng = np.random.default_rng(k)\nfor _ in range(12):\n"
              "    write_exr(sys.argv[2], (k + rng.random((384, 384, 3))).astype(np.float32))\n")
    procs = [subprocess.Popen([sys.executable, "-c", script, str(k + 1), str(out)], env=ENV, stderr=subprocess.PIPE)
             for k in range(3)]
    from brdflab.lighting.envmap import read_exr

    while any(p.poll() is None for p in procs):
        if out.exists():
            image = read_exr(out)
            k = np.floor(image.min())
            assert k in (1, 2, 3) and image.max() < k + 1
    for p in procs:
        assert p.wait() == 0, p.stderr.read().decode()
    image = read_exr(out)
    assert np.floor(image.min()) in (1, 2, 3) and sorted(p.name for p in tmp_path.iterdir()) == ["same.exr"]


# --- framing -----------------------------------------------------------------------------------

def _orbit_coverage(mesh, width: int, height: int) -> np.ndarray:
    from brdflab.io.xmlio import load
    from brdflab.io.resources import data_dir
    from brdflab.render.context import create_context
    from brdflab.render.object_view import ObjectRenderer, RenderSettings

    renderer = ObjectRenderer(create_context())
    renderer.set_source(load(data_dir("materials") / "lambertian.xml").material)
    renderer.set_mesh(mesh)
    headlight = tuple(float(x) for x in renderer.camera.position)  # lights every visible point
    image = renderer.render(RenderSettings("point", width, height, light=headlight, reference_view=False))
    return image.sum(axis=2) > 0


def _framed_whole(covered: np.ndarray) -> bool:
    border = np.concatenate([covered[0], covered[-1], covered[:, 0], covered[:, -1]])
    return not border.any() and covered.mean() > 0.05


@pytest.mark.parametrize("size", [(64, 64), (96, 32), (32, 96)], ids=lambda s: f"{s[0]}x{s[1]}")
def test_the_default_view_shows_the_whole_sphere(size):
    from brdflab.io.mesh import default_mesh

    assert _framed_whole(_orbit_coverage(default_mesh(), *size))


@needs_shared("meshes", "spot.obj")
@pytest.mark.parametrize("size", [(96, 32), (32, 96)], ids=lambda s: f"{s[0]}x{s[1]}")
def test_the_default_view_shows_the_whole_spot(size):
    from brdflab.io.mesh import load_mesh

    assert _framed_whole(_orbit_coverage(load_mesh(DATA / "meshes" / "spot.obj"), *size))


# --- startup cost ----------------------------------------------------------------------------

HEAVY = {"scipy", "matplotlib", "lxml", "trimesh", "moderngl", "PySide6", "pandas", "OpenEXR", "PIL", "dask"}


def _imported_by(argv: list[str]) -> set[str]:
    script = ("import sys, json\nfrom brdflab.cli import main\ntry:\n    main(json.loads(sys.argv[1]))\n"
              "except SystemExit:\n    pass\nprint(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))\n")
    done = subprocess.run([sys.executable, "-c", script, json.dumps(argv)], env=ENV, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    return set(json.loads(done.stdout.strip().splitlines()[-1]))


def test_help_and_models_import_nothing_heavy():
    assert not _imported_by(["--help"]) & (HEAVY | {"numpy"})
    assert not _imported_by(["models"]) & HEAVY


@needs_shared("merl_slices", "gold-metallic-paint3.slice")
def test_a_slice_fit_does_not_import_scipy():
    argv = ["fit", str(DATA / "merl_slices" / "gold-metallic-paint3.slice"), "--lobes", "Lambertian,BlinnPhong",
            "--no-restarts", "--max-iterations", "3"]
    assert not _imported_by(argv) & {"scipy", "matplotlib", "trimesh", "moderngl", "PySide6", "pandas"}


def test_numpy_sobol_points_are_a_scrambled_sobol_net():
    """The SciPy-free points: the unscrambled set is SciPy's Sobol' set, and the scrambled
    one keeps the (0, m, 2)-net property (one point in every elementary box of area 2^-m)."""
    from scipy.stats import qmc

    from brdflab.geometry.sobol import BITS, _generator_matrices, scrambled_sobol

    m = 10
    digits = (np.arange(2**m)[:, None] >> np.arange(m)) & 1
    plain = np.stack([((digits @ C.T) % 2) @ 0.5 ** np.arange(1, BITS + 1) for C in _generator_matrices(m)], axis=1)
    assert sorted(map(tuple, plain)) == sorted(map(tuple, qmc.Sobol(2, scramble=False).random_base2(m)))
    points = scrambled_sobol(m, seed=7)
    assert not np.array_equal(np.sort(points, axis=0), np.sort(plain, axis=0))
    for a in range(m + 1):
        box = np.floor(points[:, 0] * 2**a).astype(int) * 2 ** (m - a) + np.floor(points[:, 1] * 2 ** (m - a)).astype(int)
        assert np.bincount(box, minlength=2**m).max() == 1, a


def test_numpy_nnls_matches_scipy(rng):
    from scipy.optimize import nnls as scipy_nnls

    from brdflab.fitting.nnls import nnls

    for _ in range(300):
        n = int(rng.integers(1, 7))
        A = rng.normal(size=(n + int(rng.integers(0, 3)), n)) * np.exp(2 * rng.normal(size=n))
        y = rng.normal(size=A.shape[0])
        ours, theirs = nnls(A, y), scipy_nnls(A, y)[0]
        assert np.all(ours >= 0)
        assert np.linalg.norm(A @ ours - y) <= np.linalg.norm(A @ theirs - y) + 1e-9 * (1 + np.linalg.norm(y))


# --- examples, help, version, UTF-8 --------------------------------------------------------------

def test_examples_are_reachable_by_name_from_any_folder(tmp_path):
    listed = subprocess.run([sys.executable, "-m", "brdflab", "examples", "--json"], cwd=tmp_path, env=ENV,
                            capture_output=True, text=True, timeout=60)
    names = {e["name"]: e["file"] for e in json.loads(listed.stdout.splitlines()[-1])["examples"]}
    assert names["example:fig2"] == "fig2_lambertian_lafortune.xml"
    assert sorted(names.values()) == sorted(p.name for p in (ROOT / "materials").glob("*.xml"))
    info = subprocess.run([sys.executable, "-m", "brdflab", "info", "example:fig2", "--json"], cwd=tmp_path, env=ENV,
                          capture_output=True, text=True, timeout=60)
    assert info.returncode == 0 and json.loads(info.stdout.splitlines()[-1])["material"]["type"] == "Analytic"


def test_every_material_argument_takes_an_example_name(tmp_path, capsys):
    pairs = tmp_path / "pairs.npy"
    np.save(pairs, np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]]))
    assert main(["eval", "example:lambertian", "--pairs", str(pairs), "--out", str(tmp_path / "v.npy")]) == 0
    assert main(["export", "example:fig2", "--format", "glsl", "--out", str(tmp_path / "f.glsl")]) == 0
    assert main(["fit", "example:phong", "--lobes", "Lambertian", "--no-restarts", "--max-iterations", "2",
                 "--samples", "grid", "--density", "8", "--init", "example:lambertian"]) == 0
    capsys.readouterr()
    err = one_line_error(capsys, main(["info", "example:no-such-thing"]))
    assert "fig2" in err and "brdflab examples" in err


def test_info_writes_utf8_not_escapes(tmp_path, capsys):
    text = (ROOT / "materials" / "lambertian.xml").read_text()
    name = re.search(r"<Name>(.*?)</Name>", text).group(1)
    path = tmp_path / "ü.xml"
    path.write_text(text.replace(f"<Name>{name}</Name>", "<Name>Weiß – grün</Name>", 1), encoding="utf-8")
    for argv in (["info", str(path)], ["info", str(path), "--json"]):
        assert main(argv) == 0
        out = capsys.readouterr().out
        assert "Weiß – grün" in out and "\\u" not in out


def test_version_and_help_show_defaults_and_examples(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and re.fullmatch(r"brdflab \d+\.\d+\.\d+", capsys.readouterr().out.strip())
    from brdflab.cli import EXAMPLES, build_parser

    commands = build_parser()._subparsers._group_actions[0].choices
    assert set(commands) == set(EXAMPLES)
    for name, parser in commands.items():
        text = parser.format_help()
        assert "example:\n  brdflab " + name in text, name
    render = commands["render"].format_help()
    assert "(default: 64)" in render and "(default: 512,512)" in render and "(default: 0.0)" in render


def test_bench_finds_the_shared_data_or_says_why(tmp_path, monkeypatch):
    from brdflab.study.bench import measured_slice

    monkeypatch.setenv("BRDFLAB_SHARED", str(tmp_path))
    assert measured_slice()[0] is None and "no shared data" in measured_slice()[1]
    (tmp_path / "data").mkdir()
    path, why = measured_slice()
    assert path is None and str(tmp_path / "data" / "merl_slices") in why
    if DATA.is_dir():
        monkeypatch.setenv("BRDFLAB_SHARED", str(DATA.parent))
        assert measured_slice()[0] == DATA / "merl_slices" / "gold-metallic-paint3.slice"
