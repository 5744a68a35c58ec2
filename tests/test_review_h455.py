"""h455, a review of h451 (the shadowed built-in scene warning only for the scene used; the unknown-scene hint).

What it left: a ``--set scene=cornell`` that a thesis study, a sweep's scene factor or an extreme case's own
scene refuses was warned of before the error (a scene no cell would use); an extreme study whose every case
gives its own scene warned of its base's; overrides given as an iterator were read by the new check and then
lost (the scene, and every other key they set, silently not set); the hint said ``scene=./myroom.yaml`` to
``tlm scene show myroom`` (whose argument is the path itself), and ``scene_description``'s own error had none;
a run config of the scene's name written as a flow mapping (``{scene: ring}``) or with quoted keys was taken
for a scene file (warned of, and named by the hint).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tlm import storage
from tlm.cli import main
from tlm.config_paths import builtin_scenes_dir
from tlm.errors import InputError

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [4, 4]}
SHADOWED = "is the built-in scene of that name"


@pytest.fixture(autouse=True)
def _fresh_said(monkeypatch):
    """Nothing said yet (an earlier test's warning would keep this one's unsaid: said once)."""
    monkeypatch.setattr(storage, "SAID", set())


@pytest.fixture
def here(elsewhere):
    """The working folder, with scene files cornell.yaml (shadowed by the built-in cornell) and other.yaml."""
    for name in ("cornell.yaml", "other.yaml"):
        shutil.copy(builtin_scenes_dir() / "ring.yaml", elsewhere / name)
    return elsewhere


def _err_lines(capsys) -> list[str]:
    return capsys.readouterr().err.strip().splitlines()


def test_a_thesis_set_scene_is_refused_without_a_warning_first(here, capsys):
    (here / "th.yaml").write_text("scenes: [ring]\nmodes: [rcast]\nbase: {resolution: [4, 4]}\n")
    assert main(["thesis", "th.yaml", "--set", "scene=cornell", "--out", "o"]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and "scene is set by the study's scenes" in err[0], err


def test_a_sweeps_set_scene_beside_a_scene_factor_is_refused_without_a_warning_first(here, capsys):
    from tlm.experiments.sweep_file import load_sweep

    (here / "sw.yaml").write_text(f"base: {json.dumps(BASE)}\ngrid: {{scene: [ring, room]}}\n")
    with pytest.raises(InputError, match="is a factor of the sweep"):
        load_sweep(here / "sw.yaml", ["scene=cornell"])
    assert _err_lines(capsys) == []


def _cases(here: Path, scenes: list[str | None]) -> Path:
    cases = [{"name": f"c{i}", "category": "c", "expect": "e",
              "config": {"seed": 1, **({"scene": s} if s else {})}, "checks": ["finite"]} for i, s in enumerate(scenes)]
    (here / "x.yaml").write_text(f"base: {json.dumps(BASE)}\ncases: {json.dumps(cases)}\n")
    return here / "x.yaml"


def test_an_extreme_study_whose_cases_give_their_scenes_says_nothing_of_the_base_or_a_refused_set(here, capsys):
    from tlm.experiments.extreme import load_cases

    load_cases(_cases(here, ["ring", "room"]))  # (every case its own scene: the base's cornell runs in none)
    assert _err_lines(capsys) == []
    with pytest.raises(InputError, match="set by the case 'c1'"):
        load_cases(_cases(here, [None, "room"]), ("scene=cornell",))  # (refused: no warning before)
    assert _err_lines(capsys) == []
    load_cases(_cases(here, [None, "room"]))  # (case c0 runs the base's cornell: said)
    assert [line for line in _err_lines(capsys) if SHADOWED in line] == [
        "tlm: warning: scene 'cornell' is the built-in scene of that name, not the file cornell.yaml: to run the "
        "file, give it as a path, scene=./cornell.yaml"]


def _granularity(here: Path, sets) -> str:
    from tlm.experiments.granularity import load_granularity

    (here / "g.yaml").write_text(f"base: {json.dumps(BASE)}\npacket_sizes: [1, 4]\n")
    return load_granularity(here / "g.yaml", sets)[0].scene


def _extreme(here: Path, sets) -> str:
    from tlm.experiments.extreme import load_cases

    return load_cases(_cases(here, [None]), sets)[0]["scene"]


def _error_vs_cost(here: Path, sets) -> str:
    from tlm.experiments.error_cost import load_experiment

    (here / "e.yaml").write_text(f"base: {json.dumps({**BASE, 'mode': 'pmap'})}\npoints: [{{photons.count: [1000]}}]\n")
    return load_experiment(here / "e.yaml", sets)[0]["scene"]


def _config(here: Path, sets) -> str:
    from tlm.config import load_config

    (here / "run.yaml").write_text("scene: cornell\nmode: rcast\n")
    return load_config(here / "run.yaml", sets)[0].scene


@pytest.mark.parametrize("load", [_granularity, _extreme, _error_vs_cost, _config])
def test_overrides_given_as_an_iterator_are_applied(here, load):
    assert load(here, iter(["scene=./other.yaml"])) == str(here / "other.yaml")
    assert load(here, (s for s in ["scene=./other.yaml"])) == str(here / "other.yaml")


def test_a_scene_name_given_by_itself_is_told_the_files_path_alone(elsewhere, capsys):
    import tlm

    shutil.copy(builtin_scenes_dir() / "ring.yaml", elsewhere / "myroom.yaml")
    tail = "; a scene file of that name lies at myroom.yaml: give it as a path, ./myroom.yaml"
    assert main(["scene", "show", "myroom"]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and err[0].endswith(tail), err
    with pytest.raises(InputError) as e:
        tlm.load_scene("myroom")
    assert str(e.value).endswith(tail)
    with pytest.raises(InputError) as e:  # (scene_description describes the built-in scenes alone)
        tlm.scene_description("myroom")
    assert str(e.value).endswith("; a scene file of that name lies at myroom.yaml, which scene_description does not "
                                 "describe (the built-in scenes alone): load_scene('./myroom.yaml') reads it")


@pytest.mark.parametrize("text", ["{scene: ring, mode: rcast}\n", '"scene": ring\n"mode": rcast\n'])
def test_a_run_config_of_the_scenes_name_written_otherwise_is_no_scene_file(elsewhere, tmp_path, capsys, text):
    (elsewhere / "room.yaml").write_text(text)  # (a run config: its keys in a flow mapping, or quoted)
    (elsewhere / "myroom.yaml").write_text(text)
    (elsewhere / "run.yaml").write_text("scene: room\nmode: rcast\nresolution: [4, 4]\n")
    assert main(["run", "run.yaml", "--out", str(tmp_path / "o"), "--no-report"]) == 0
    assert SHADOWED not in capsys.readouterr().err
    assert main(["run", "run.yaml", "--set", "scene=myroom", "--out", str(tmp_path / "p"), "--no-report"]) == 2
    assert "lies at" not in capsys.readouterr().err
