"""What an installed copy (tlm from a wheel, no checkout) tells its user to run, and the paths its report shows
(found by the probe h353):

- ``tlm calibrate``'s refusal of the packaged table named ``tlm calibrate --write FILE`` and ``tlm calibrate
  --dry-run``, which argparse refuses (no study): it names the study given, quoted, and each command runs;
- the built-in experiments' comments named ``tlm reference configs/cornell_pmap.yaml`` and a bare ``tlm
  calibrate configs/thesis.yaml`` (refused outside a checkout): each command in an exported copy's comments
  names the copy or a built-in experiment, and ``tlm calibrate`` says ``--write FILE``;
- the help of the commands that take an experiment file led with ``configs/NAME.yaml`` (a checkout's
  alone): the built-in name comes first;
- the report showed an installed copy's built-in files by their site-packages paths (the extreme cases'
  ``.../tlm/_configs/extreme.yaml``, the Provenance tables' ``from`` and a study's line): by their place in
  the repository, ``configs/extreme.yaml``, ``scenes/cornell.yaml``.
"""

from __future__ import annotations

import html
import re
import shlex
import shutil
from pathlib import Path

import pytest

import tlm.api
import tlm.api_studies
import tlm.builtin
from tlm.arch import costs
from tlm.cli import EXPERIMENT_ARGS, main
from tlm.errors import InputError
from tlm.report.collect import Inputs, Study
from tlm.report.extreme import extreme_section
from tlm.report.names import shown_paths
from tlm.report.provenance import _lights_table, _materials_table, provenance_section
from tlm.scenes.loader import scenes_dir

REPO = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------- D2: tlm calibrate's refusal on an installed copy


@pytest.fixture
def installed(tmp_path, monkeypatch):
    """tlm as an installed copy (its package folder in a site-packages folder, holding a copy of the
    packaged table), and a fit that only says it ran."""
    package = tmp_path / "venv" / "lib" / "site-packages" / "tlm"
    table = package / "arch" / "programs.yaml"
    table.parent.mkdir(parents=True)
    shutil.copy(costs.DEFAULT_PATH, table)
    monkeypatch.setattr(tlm.api_studies, "_package_dir", lambda: package)
    monkeypatch.setattr(costs, "DEFAULT_PATH", table)

    def fit(*args, **kw):
        raise RuntimeError("the fit ran")

    monkeypatch.setattr(tlm.api, "calibrate", fit)
    return table


def _ways(line: str) -> list[str]:
    """The ``tlm calibrate`` commands a refusal names."""
    return re.findall(r"\((tlm calibrate .*?), or tlm\.", line)


@pytest.mark.parametrize("given", ["thesis", "studies of mine/th.yaml"])
def test_the_refusal_names_the_study_given_and_its_commands_run(given, installed, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    if given != "thesis":
        (tmp_path / "studies of mine").mkdir()
        shutil.copy(REPO / "configs" / "thesis.yaml", tmp_path / given)
    assert main(["calibrate", given]) == 2
    line = capsys.readouterr().err.strip()
    assert "not written: the table is inside the installed tlm package" in line
    ways = _ways(line)
    quoted = shlex.quote(given)
    assert ways == [f"tlm calibrate --write FILE {quoted}", f"tlm calibrate --dry-run {quoted}"], line
    for way in ways:  # (as a user types them: argparse takes each, and the fit runs)
        words = ["mine.yaml" if w == "FILE" else w for w in shlex.split(way)]
        assert main(words[1:]) == 1, way
        assert "the fit ran" in capsys.readouterr().err, way


def test_the_refusal_from_python_keeps_the_commands_whole_for_a_long_path(installed, tmp_path):
    study = tmp_path / ("a folder of a rather long name, " * 3).strip(", ") / "th.yaml"
    study.parent.mkdir()
    shutil.copy(REPO / "configs" / "thesis.yaml", study)
    with pytest.raises(InputError) as e:
        tlm.api.calibration_table(study)
    assert _ways(str(e.value)) == [f"tlm calibrate --write FILE {shlex.quote(str(study))}",
                                   f"tlm calibrate --dry-run {shlex.quote(str(study))}"], str(e.value)
    with pytest.raises(InputError) as e:  # (not given the study: said as STUDY)
        tlm.api.write_calibration(costs.load_programs(installed), {"cells": {}})
    assert _ways(str(e.value)) == ["tlm calibrate --write FILE STUDY", "tlm calibrate --dry-run STUDY"]


# ---------------------------------------------------------------- D3: the built-in experiments' comments


def test_the_commands_in_an_exported_copys_comments_name_files_that_are_there(tmp_path):
    names = tlm.builtin.list_experiments()
    seen = 0
    for name in names:
        source = tlm.builtin.configs_dir() / f"{name}.yaml"
        text = tlm.builtin.exported_text(source, name, Path("copy.yaml")).decode()
        for line in text.splitlines():
            comment = line.partition("#")[2]
            for command, arg, rest in re.findall(r"\btlm ([a-z-]+) ([^\s'`)]+)([^'`)]*)", comment):
                if command not in EXPERIMENT_ARGS:
                    continue
                seen += 1
                assert arg == "copy.yaml" or arg in names, (name, line)  # (the copy, or a built-in one)
                if command == "calibrate":  # (outside a checkout a bare one is refused)
                    assert "--write FILE" in rest, (name, line)
    assert seen >= 10


# ---------------------------------------------------------------- D4: the commands' help


@pytest.mark.parametrize(("command", "name"), [("sweep", "sweep_fifo"), ("thesis", "thesis"),
                                               ("granularity", "tlm_granularity"), ("extreme", "extreme"),
                                               ("calibrate", "thesis"), ("error-vs-cost", "error_vs_cost")])
def test_the_help_names_the_built_in_experiment_before_its_file(command, name, capsys):
    assert main([command, "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert f"built-in experiment's name: {name} " in text, text
    assert text.index(f"name: {name} ") < text.index(f"configs/{name}.yaml"), text
    assert "e.g. configs/" not in text


# ---------------------------------------------------------------- D5: the report's paths


@pytest.fixture
def packaged(tmp_path, monkeypatch):
    """The built-in experiments where an installed copy has them (site-packages/tlm/_configs), and a
    current folder that holds neither them nor the scenes."""
    folder = tmp_path / "venv" / "lib" / "site-packages" / "tlm" / "_configs"
    folder.mkdir(parents=True)
    shutil.copy(REPO / "configs" / "extreme.yaml", folder / "extreme.yaml")
    monkeypatch.setattr(tlm.builtin, "configs_dir", lambda: folder)
    (tmp_path / "here").mkdir()
    monkeypatch.chdir(tmp_path / "here")
    return folder


def test_the_extreme_cases_show_a_built_in_experiment_by_its_place(packaged, tmp_path):
    measured = f"{packaged / 'extreme.yaml'} (bad-resolution-zero): resolution: [0, 32] must be positive"
    assert shown_paths(measured) == "configs/extreme.yaml (bad-resolution-zero): resolution: [0, 32] must be positive"
    row = {"category": "bad input", "case": "bad-resolution-zero", "expect": "refused", "measured": measured,
           "passed": True, "seconds": 0.1}
    text = html.unescape(extreme_section(Inputs([], studies=[Study("extreme", tmp_path / "ext", [row])]),
                                         tmp_path).html)
    assert "<td class=\"l\">configs/extreme.yaml (bad-resolution-zero): resolution" in text
    assert str(packaged) not in text


def test_the_provenance_shows_built_in_files_by_their_place(packaged, tmp_path):
    scenes = scenes_dir()
    mats = {"white": {"kind": "lambertian", "triangles": 2, "albedo": [0.7, 0.7, 0.7],
                      "from": f"{scenes / 'thesis' / '..' / 'room.yaml'}: materials.white"},
            "floor": {"kind": "lambertian", "triangles": 2, "albedo": [0.5, 0.5, 0.5],
                      "from": f"{scenes / 'meshes' / 'CornellBox-Original.mtl'}:12"}}
    table = html.unescape(_materials_table(mats))
    assert "<td class=\"l\">scenes/room.yaml: materials.white</td>" in table, table
    assert "<td class=\"l\">scenes/meshes/CornellBox-Original.mtl:12</td>" in table, table
    lights = [{"type": "point", "power": [1.0, 1.0, 1.0], "position": [0.0, 1.0, 0.0],
               "from": f"{scenes / 'thesis' / 'room.yaml'}: lights[0]"}]
    table = html.unescape(_lights_table(lights, mats))
    assert "<td class=\"l\">scenes/thesis/room.yaml: lights[0]</td>" in table, table
    prov = {"study": str(packaged / "extreme.yaml"), "git_revision": None, "versions": {"python": "3.11"},
            "host_seconds": 9.5}
    sec = provenance_section(Inputs([], studies=[Study("extreme", Path("r/ext"), [], {"provenance": prov})]),
                             tmp_path)
    assert "<p>extreme folder r/ext: study configs/extreme.yaml, git " in sec.html, sec.html
    assert str(packaged) not in sec.html
    mine = tmp_path / "mine.yaml"  # (a file of the user's, outside the current folder: as it was)
    assert shown_paths(f"{mine}: materials.white") == f"{mine}: materials.white"
