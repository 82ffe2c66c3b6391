"""Model files are probed once per content (issue 35, goal 5): the GLSL check's verdict is kept
in the user's cache, so a command that names a model folder it has seen starts no probe child;
a corrupt entry, an edited file or a concurrent process never gives a wrong answer."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from test_model_files_bad import brdf

GOOD = brdf(params="float k 0 1 .5", line="return vec3(k) / 3.14159265;")
BAD = brdf(params="float k 0 1 .5", line="return vec3(k) * missing;")
UNDEFINED = brdf(params="float k 0 1 .5", line="return vec3(k / (L.x - 0.25));")  # negative or infinite at many pairs


@pytest.fixture
def probes(monkeypatch):
    """The names of the models each load probed in a child process."""
    from brdflab.render import model_eval

    calls: list[str] = []
    real = model_eval.probe_in_child
    monkeypatch.setattr(model_eval, "probe_in_child", lambda model: calls.append(model.name) or real(model))
    return calls


def load_as_a_new_process(folder):
    """Register the folder's models as a fresh process would: nothing registered or checked in memory."""
    from brdflab.models.files import backend
    from brdflab.models.files.library import load_folders
    from brdflab.models.registry import _MODELS

    for name in [n for n, m in _MODELS.items() if getattr(m, "origin", None) is not None]:
        del _MODELS[name]
    backend.glsl_evaluator()._checked.clear()
    warnings: list[str] = []
    loaded = load_folders([folder], warn=warnings.append)
    return {m.name for m in loaded}, warnings


def entries():
    from brdflab.io.user_cache import cache_folder

    return sorted((cache_folder("model_checks")).glob("*.json"))


def test_a_folder_seen_once_is_not_probed_again(tmp_path, probes):
    folder = tmp_path / "models"
    folder.mkdir()
    (folder / "good.brdf").write_text(GOOD)
    (folder / "bad.brdf").write_text(BAD)
    first = load_as_a_new_process(folder)
    assert sorted(probes) == ["bad", "good"] and len(entries()) == 2
    assert first[0] == {"good"} and len(first[1]) == 1 and "bad.brdf" in first[1][0] and "missing" in first[1][0]

    probes.clear()
    assert load_as_a_new_process(folder) == first and probes == []  # the same answer, no child

    (folder / "good.brdf").write_text(GOOD.replace("3.14159265", "3.2"))  # edited: another content
    assert load_as_a_new_process(folder)[0] == {"good"} and probes == ["good"]

    moved = tmp_path / "elsewhere"
    folder.rename(moved)
    probes.clear()
    _, warnings = load_as_a_new_process(moved)
    assert probes == [] and str(moved / "bad.brdf") in warnings[0]  # the verdict names the file where it is now


def test_where_a_model_is_undefined_comes_back_from_the_cache(tmp_path, probes):
    folder = tmp_path / "models"
    folder.mkdir()
    (folder / "pole.brdf").write_text(UNDEFINED)
    first = load_as_a_new_process(folder)
    from brdflab.models import get_model

    said = get_model("pole").undefined if first[0] else first[1][0]
    probes.clear()
    again = load_as_a_new_process(folder)
    assert probes == [] and again[0] == first[0]
    assert (get_model("pole").undefined if again[0] else again[1][0]) == said


@pytest.mark.parametrize("damage", [b"", b"\x00\xff not json", b"[1, 2]", b'{"problem": 3, "undefined": null}',
                                    b'{"problem": null}'])
def test_a_damaged_entry_is_probed_again_and_rewritten(tmp_path, probes, damage):
    folder = tmp_path / "models"
    folder.mkdir()
    (folder / "bad.brdf").write_text(BAD)
    (folder / "good.brdf").write_text(GOOD)
    first = load_as_a_new_process(folder)
    for entry in entries():
        entry.write_bytes(damage)
    probes.clear()
    assert load_as_a_new_process(folder) == first and sorted(probes) == ["bad", "good"]
    for entry in entries():
        assert set(json.loads(entry.read_text())) == {"problem", "undefined"}


def test_processes_that_check_one_folder_at_once_agree(tmp_path):
    folder = tmp_path / "models"
    folder.mkdir()
    for k in range(4):
        (folder / f"m{k}.brdf").write_text(GOOD.replace("3.14159265", f"3.{k + 1}"))
    (folder / "bad.brdf").write_text(BAD)
    command = [sys.executable, "-m", "brdflab", "models", "--json", "--models", str(folder)]
    children = [subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                 env=dict(os.environ)) for _ in range(3)]
    answers = [child.communicate(timeout=600) + (child.returncode,) for child in children]
    names = []
    for out, err, code in answers:
        assert code == 0, err
        names.append(sorted(m["id"] for m in json.loads(out.splitlines()[-1])["models"] if m.get("file")))
        assert "bad.brdf" in err and "missing" in err
    assert names[0] == names[1] == names[2] == ["m0", "m1", "m2", "m3"]
    assert len(entries()) == 5 and all(set(json.loads(e.read_text())) == {"problem", "undefined"} for e in entries())
