"""Scene-Auto (issue 34 goal 4): the fewest lobes whose render of the scene is within a visible
tolerance of the measurement's, with progress, on the command line and in the core."""

import json
import os
import subprocess
import sys

import pytest

from brdflab.errors import BRDFLabError
from brdflab.fitting.image_metric import SceneImages
from brdflab.fitting.scene_auto import scene_auto
from brdflab.lighting.envmap import write_exr
from brdflab.lighting.synthetic_maps import spec
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.models import get_model
from conftest import ROOT

SMALL = {"view": 12, "dim_width": 16, "fine_width": 64}
MODELS = ["BlinnPhong", "Ward", "CookTorranceGGX"]


def material(*specs) -> AnalyticMaterial:
    return AnalyticMaterial("m", "Linear", 3, [Lobe(get_model(m), dict(p), list(s)) for m, p, s in specs])


def scene_of(source) -> SceneImages:
    return SceneImages.of_source(source, [spec(n).build(128, 64) for n in ("sun-mid-large", "room-one-window")],
                                 **SMALL)


GLOSSY = material(("Lambertian", {}, (0.2, 0.15, 0.1)), ("Ward", {"ax": 0.2, "ay": 0.2}, (0.3, 0.3, 0.3)))


def test_a_diffuse_source_stops_at_the_lambertian():
    ladder = scene_auto(scene_of(material(("Lambertian", {}, (0.4, 0.3, 0.2)))), models=MODELS)
    assert ladder.chosen.lobes == () and len(ladder.candidates) == 1 and ladder.chosen.error_held_back < 1e-6
    assert "Lambertian alone is within 2.0%" in ladder.reason


def test_a_glossy_source_gets_one_lobe_within_the_tolerance_and_progress_says_so():
    heard = []
    ladder = scene_auto(scene_of(GLOSSY), models=MODELS, progress=heard.append)
    assert len(ladder.chosen.lobes) == 1 and ladder.chosen.error_held_back <= 0.02, ladder.reason
    assert "renders the scene within 2.0%" in ladder.reason
    assert not any(len(c.lobes) > 1 for c in ladder.candidates)  # nothing climbed past the rung that is enough
    # every screen and full fit was heard, with its image error and the best so far
    assert heard and all(p.measure == "image" for p in heard)
    assert {p.stage for p in heard} == {"screened", "fitted"}
    assert "image" in heard[-1].describe() and "best so far" in heard[-1].describe()
    # of the candidates within the tolerance, the fewest parameters
    within = [c for c in ladder.candidates if c.fitted and c.error_held_back <= 0.02]
    assert ladder.chosen.parameters == min(c.parameters for c in within)


def test_an_unreachable_tolerance_climbs_and_says_how_far_it_got():
    ladder = scene_auto(scene_of(GLOSSY), tolerance=1e-9, models=["BlinnPhong"], max_lobes=2)
    assert "no candidate is within" in ladder.reason
    assert ladder.chosen.error_held_back == min(c.error_held_back for c in ladder.candidates if c.fitted)


@pytest.mark.parametrize("tolerance", [0.0, -0.1, 1.0, float("nan")])
def test_a_bad_tolerance_is_refused(tolerance):
    with pytest.raises(BRDFLabError, match="tolerance"):
        scene_auto(scene_of(GLOSSY), tolerance=tolerance)


def _cli(*args, cwd):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "brdflab", *args], capture_output=True, text=True, cwd=cwd,
                          env=env, timeout=600)


def test_cli_scene_auto_under_the_users_map_prints_progress_and_stores_the_pick(tmp_path):
    env = tmp_path / "sky.exr"
    write_exr(env, spec("sun-mid-large").build(128, 64).data)
    out = tmp_path / "pick.xml"
    run = _cli("fit", "example:ward", "--auto", "--env", str(env), "--models", "BlinnPhong,Ward", "--out", str(out),
               "--json", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    payload = json.loads(run.stdout.splitlines()[-1])
    assert payload["metric"] == "image" and payload["maps"] == ["sky"] and payload["tolerance"] == 0.02
    chosen = payload["candidates"][payload["chosen"]]
    assert chosen["lobes"] == ["Ward"] and chosen["error_held_back"] <= 0.02  # the source is a Ward
    assert "sampleError" in payload["fit"]
    lines = run.stderr.splitlines()
    assert lines[0].startswith("brdflab fit: auto: the scene:") and "under sky" in lines[0]
    assert any("rung 1" in l and "image" in l and "best so far" in l for l in lines[1:])
    info = _cli("info", str(out), "--json", cwd=tmp_path)
    fittings = json.loads(info.stdout.splitlines()[-1])["fittings"]
    assert fittings[-1]["statistics"]["metric"] == "image" and fittings[-1]["statistics"]["autoTolerance"] == 0.02


def test_cli_scene_auto_on_a_mesh_judges_the_meshs_pixels(tmp_path):
    """`--mesh`: the scene is the mesh as `render --view orbit` shows it, covering about as many
    pixels as the reference sphere (812); the pick is judged there and the payload names it."""
    env = tmp_path / "sky.exr"
    write_exr(env, spec("sun-mid-large").build(128, 64).data)
    mesh = ROOT / "resources" / "meshes" / "spot.obj"
    run = _cli("fit", "example:ward", "--auto", "--env", str(env), "--mesh", str(mesh), "--models", "BlinnPhong,Ward",
               "--json", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    payload = json.loads(run.stdout.splitlines()[-1])
    assert payload["mesh"] == str(mesh) and payload["maps"] == ["sky"] and payload["seen"] == "spot.obj"
    chosen = payload["candidates"][payload["chosen"]]
    assert chosen["lobes"] == ["Ward"] and chosen["error_held_back"] <= 0.02
    human = _cli("fit", "example:ward", "--auto", "--env", str(env), "--mesh", str(mesh), "--models", "Ward",
                 cwd=tmp_path)
    assert "Scene-Auto ladder (image error of spot.obj under sky" in human.stdout, human.stdout
    scene_line = run.stderr.splitlines()[0]
    assert "pixels of spot.obj" in scene_line, scene_line
    pixels = int(scene_line.split("the scene: ")[1].split()[0])
    assert 0.85 * 812 <= pixels <= 1.3 * 812


@pytest.mark.parametrize("args, says", [
    (["--env", "missing.exr"], "missing.exr"),
    (["--metric", "image", "--mesh", "missing.obj"], "missing.obj"),
    (["--metric", "image", "--mesh", "."], "not a regular file: a directory"),
    (["--mesh", str(ROOT / "resources" / "meshes" / "spot.obj")], "--mesh applies to --metric image"),
    (["--metric", "image", "--tolerance", "0"], "--tolerance 0"),
    (["--metric", "image", "--samples", "subset"], "--samples"),
])
def test_cli_bad_scene_auto_options_exit_2_with_one_line(tmp_path, args, says):
    run = _cli("fit", "example:ward", "--auto", *args, cwd=tmp_path)
    assert run.returncode == 2 and says in run.stderr and len(run.stderr.strip().splitlines()) == 1, run.stderr


def test_sample_auto_refuses_the_image_metric_in_one_line():
    from brdflab.fitting.auto import auto_fit
    from brdflab.fitting.samples import samples_of

    with pytest.raises(BRDFLabError, match="held-back samples: it takes a sample metric"):
        auto_fit(samples_of(GLOSSY), metric="image")
