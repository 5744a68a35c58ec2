"""The experiments of configs/ are built in (shipped as tlm/_configs): a command that takes an
experiment file takes a built-in experiment's name instead, 'tlm config list|export' lists and
copies them, 'tlm plots' finds them outside a checkout; 'tlm calibrate' leaves an installed
copy's table alone; an exported scene keeps its meshes' notices; 'tlm scene list' leaves out
the scenes of bad input on purpose."""

from __future__ import annotations

import json
import shlex
import shutil
import tomllib
from pathlib import Path

import pytest
import yaml

import tlm.api
import tlm.api_studies
import tlm.arch.costs as costs
import tlm.builtin
import tlm.scenes.export as export
from tests.helpers_packaged import installed_configs, one_error
from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.extreme import load_cases
from tlm.experiments.sweep_file import load_sweep
from tlm.scenes.loader import load_scene, resolve_scene_path

REPO = Path(__file__).resolve().parents[1]
CONFIGS = REPO / "configs"
TINY = ["--set", "resolution=[16,16]", "--mode", "rcast", "--no-progress", "--no-report"]


_one_error = one_error


@pytest.fixture
def packaged(tmp_path, monkeypatch):
    """The built-in experiments as an installed copy has them: a copy of configs/ in a
    package folder of its own (tlm/_configs), and a working folder without configs/."""
    return installed_configs(tmp_path, monkeypatch)


# ---------------------------------------------------------------- names and paths


def test_the_experiments_ship_in_the_wheel():
    """pyproject's wheel maps configs/ to tlm/_configs, where configs_dir looks first."""
    project = tomllib.loads((REPO / "pyproject.toml").read_text())
    assert project["tool"]["hatch"]["build"]["targets"]["wheel"]["force-include"]["configs"] == "tlm/_configs"
    assert tlm.builtin.configs_dir() == CONFIGS  # (a checkout: no tlm/_configs)
    assert {"cornell", "cornell_pmap", "thesis", "extreme", "sweep_fifo"} <= set(tlm.builtin.list_experiments())


def test_a_name_is_the_built_in_experiment_and_a_path_that_exists_wins(packaged):
    assert tlm.builtin.experiment_path("cornell_pmap") == packaged / "cornell_pmap.yaml"
    assert tlm.builtin.experiment_path("cornell") == packaged / "cornell.yaml"  # (the experiment: scene cornell)
    Path("cornell").write_text("scene: ring\n")  # a file of that name here: it is the one run
    assert tlm.builtin.experiment_path("cornell") == Path("cornell")
    assert tlm.builtin.experiment_path(str(CONFIGS / "cornell.yaml")) == CONFIGS / "cornell.yaml"


def test_in_the_checkout_a_path_is_taken_as_given(monkeypatch):
    monkeypatch.chdir(REPO)
    assert tlm.builtin.experiment_path("configs/cornell.yaml") == Path("configs/cornell.yaml")


def test_a_missing_path_of_a_built_in_name_is_not_replaced_by_it(packaged, capsys):
    assert main(["run", "configs/cornell.yaml", *TINY]) == 2
    assert _one_error(capsys) == ("tlm: error: configs/cornell.yaml: not found here; the built-in experiment of "
                                  "that name: tlm run cornell ('tlm config export' copies it out to edit)")
    assert main(["thesis", "configs/thesis.yaml"]) == 2
    assert "the built-in experiment of that name: tlm thesis thesis" in _one_error(capsys)
    assert not Path("runs").exists()


def test_an_unknown_name_lists_the_built_in_ones(packaged, capsys):
    assert main(["run", "cornell_pmp", *TINY]) == 2
    line = _one_error(capsys)
    assert line.startswith("tlm: error: cornell_pmp: neither a file nor a built-in experiment (built-in: ")
    assert "cornell_pmap, design_space" in line and "(did you mean 'cornell_pmap'?)" in line
    assert main(["extreme", "nothing.yaml"]) == 2
    assert _one_error(capsys) == "tlm: error: nothing.yaml: file not found"


def test_a_built_in_scene_name_is_not_an_experiment(packaged, capsys):
    assert main(["run", "thesis/ring", *TINY]) == 2
    line = _one_error(capsys)
    assert "thesis/ring is a built-in scene, not an experiment" in line and "scene: thesis/ring" in line
    assert "tlm run ring" not in line  # (not the experiment ring: another scene)


def test_run_by_name_equals_the_run_of_the_checkouts_file(packaged, tmp_path, capsys):
    """`tlm run cornell` from an empty folder runs the packaged copy (the same bytes as
    configs/cornell.yaml) into runs/cornell, with the results of the checkout's file."""
    assert main(["run", "cornell", *TINY]) == 0
    err = capsys.readouterr().err
    assert f"tlm: cornell: the built-in experiment {packaged / 'cornell.yaml'}" in err
    assert main(["run", str(CONFIGS / "cornell.yaml"), *TINY, "--out", str(tmp_path / "checkout")]) == 0
    ours = json.loads(Path("runs/cornell/results.json").read_text())
    theirs = json.loads((tmp_path / "checkout" / "results.json").read_text())
    assert ours["config"] == str(packaged / "cornell.yaml")
    for key in ("scene", "work", "cycles", "fps", "image"):
        assert ours[key] == theirs[key], key
    assert ((tmp_path / "checkout" / "images" / "composite.png").read_bytes()
            == Path("runs/cornell/images/composite.png").read_bytes())


def test_relative_paths_of_a_packaged_experiment_stay_in_the_package(packaged):
    """A sweep's `base: cornell.yaml` is the packaged one; the extreme cases' scenes are
    built-in names, found from any folder."""
    sweep = load_sweep(tlm.builtin.experiment_path("sweep_fifo"))
    assert sweep.folder == packaged and sweep.base_file == "cornell.yaml"
    _, cases, _ = load_cases(tlm.builtin.experiment_path("extreme"))
    scenes = [c["config"]["scene"] for c in cases if "scene" in c["config"]]
    assert "extreme/cornell_ior10" in scenes and "extreme/bad_scale_zero" in scenes
    for scene in scenes:
        resolve_scene_path(scene, packaged)


def test_plots_takes_the_built_in_experiments_where_there_is_no_configs_folder(packaged, monkeypatch):
    seen = []
    monkeypatch.setattr(tlm.api, "plots", lambda configs, runs, out, only, **kw: seen.append(configs) or Path("p"))
    assert main(["plots", "--only", "thesis"]) == 0
    Path("configs").mkdir()
    assert main(["plots", "--only", "thesis"]) == 0
    assert main(["plots", "--only", "thesis", "--configs", "mine"]) == 0
    assert seen == [str(packaged), "configs", "mine"]


# ---------------------------------------------------------------- tlm config list | export


def test_config_list(packaged, capsys):
    assert main(["config", "list"]) == 0
    assert capsys.readouterr().out.split() == tlm.builtin.list_experiments()
    assert main(["config", "list", "-l"]) == 0
    lines = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()}
    assert " tlm sweep sweep_fifo " in lines["sweep_fifo"] and "FIFO depth x packet size" in lines["sweep_fifo"]
    assert " tlm run cornell_pmap " in lines["cornell_pmap"]
    assert " tlm thesis thesis " in lines["thesis"] and " tlm extreme extreme " in lines["extreme"]


def test_config_export_copies_the_bytes_and_a_sweeps_base(packaged, capsys):
    assert main(["config", "export", "cornell_pmap", "mine.yaml"]) == 0
    assert "wrote mine.yaml (a copy of the built-in experiment cornell_pmap)" in capsys.readouterr().out
    assert Path("mine.yaml").read_bytes() == (CONFIGS / "cornell_pmap.yaml").read_bytes()
    assert tlm.builtin.export_experiment("sweep_fifo", "fifo.yaml") == [Path("fifo.yaml"), Path("cornell.yaml")]
    assert Path("cornell.yaml").read_bytes() == (CONFIGS / "cornell.yaml").read_bytes()
    assert load_sweep(Path("fifo.yaml")).folder == Path.cwd().resolve()
    Path("mine.yaml").write_text("scene: ring\n")  # edited since: not overwritten
    assert main(["config", "export", "cornell_pmap", "mine.yaml"]) == 2
    assert "mine.yaml: exists with other contents" in _one_error(capsys)
    assert Path("mine.yaml").read_text() == "scene: ring\n"
    for name, file, what in (("nothing", "x.yaml", "is not a built-in experiment"), ("cornell", "x.txt", ".yaml"),
                             ("cornell", "no/x.yaml", "does not exist")):
        with pytest.raises(InputError, match=what):
            tlm.builtin.export_experiment(name, file)


# ---------------------------------------------------------------- tlm calibrate on an installed copy


def test_an_installed_package_is_told_from_a_checkout(tmp_path):
    assert tlm.api.in_checkout(REPO / "tlm")
    (tmp_path / "src" / "tlm").mkdir(parents=True)
    (tmp_path / "src" / "pyproject.toml").write_text("")
    assert tlm.api.in_checkout(tmp_path / "src" / "tlm")
    (tmp_path / "bare" / "tlm").mkdir(parents=True)
    assert not tlm.api.in_checkout(tmp_path / "bare" / "tlm")
    site = tmp_path / "venv" / "lib" / "python3.11" / "site-packages"
    (site / "tlm").mkdir(parents=True)
    (site / "pyproject.toml").write_text("")  # (a stray file beside it does not make it a checkout)
    assert not tlm.api.in_checkout(site / "tlm")


@pytest.fixture
def installed(tmp_path, monkeypatch):
    """tlm as an installed copy: its package folder in a site-packages folder, holding the
    packaged table (a copy: the real one is out of reach)."""
    package = tmp_path / "venv" / "lib" / "site-packages" / "tlm"
    table = package / "arch" / "programs.yaml"
    table.parent.mkdir(parents=True)
    shutil.copy(costs.DEFAULT_PATH, table)
    monkeypatch.setattr(tlm.api_studies, "_package_dir", lambda: package)  # (where write_calibration is)
    monkeypatch.setattr(costs, "DEFAULT_PATH", table)
    return table


# what the refusal of an installed copy's table asks for, the same from the command line and from
# Python (each way by its whole command or call: no bare flag renamed to an argument, "with target"),
# naming the study given (h357; STUDY where write_calibration is not given it)
def installed_ways(study: str) -> str:
    return (f"name another table (tlm calibrate --write FILE {study}, or tlm.write_calibration's target=), "
            f"or fit and print only (tlm calibrate --dry-run {study}, or tlm.calibrate alone)")


def test_write_calibration_leaves_an_installed_table_alone(installed, tmp_path):
    before = installed.read_bytes()
    programs = costs.load_programs(installed)
    with pytest.raises(InputError, match=r"not written: the table is inside the installed tlm package ") as e:
        tlm.api.write_calibration(programs, {"cells": {}})
    assert str(e.value).endswith(installed_ways("STUDY"))
    assert installed.read_bytes() == before and not list(installed.parent.glob("*.tmp"))


def test_calibrate_on_an_installed_copy_is_refused_before_the_fit(installed, tmp_path, monkeypatch, capsys):
    def fit(*args, **kw):
        raise RuntimeError("the fit ran")

    monkeypatch.setattr(tlm.api, "calibrate", fit)
    before = installed.read_bytes()
    assert main(["calibrate", str(CONFIGS / "thesis.yaml")]) == 2
    line = _one_error(capsys)
    assert line.startswith(f"tlm: error: {installed}: not written: the table is inside the installed tlm package")
    assert line.endswith(installed_ways(shlex.quote(str(CONFIGS / "thesis.yaml"))))
    assert installed.read_bytes() == before
    for more in (["--dry-run"], ["--write", str(tmp_path / "mine.yaml")]):  # these reach the fit
        assert main(["calibrate", str(CONFIGS / "thesis.yaml"), *more]) == 1
        assert "the fit ran" in capsys.readouterr().err


# ---------------------------------------------------------------- notices in exported scenes

NOTICE = "Notice of the mesh CornellBox-Original.obj (its COPYRIGHT-cornellbox.txt), to keep with every copy:"
CC_BY = "Attribution 3.0 Unported (CC BY 3.0) License"


def test_an_exported_cornell_box_carries_its_attribution(tmp_path):
    scene = load_scene("cornell-box")
    told = export.notices(scene)
    assert told[0] == NOTICE and f"  {CC_BY}" in told
    assert "  Created by Guedis Cardenas and Morgan McGuire at Williams College, 2011" in told
    export.export_triangles(scene, tmp_path / "b.obj")
    export.export_triangles(scene, tmp_path / "b.ply")
    export.export_triangles(scene, tmp_path / "s.yaml")
    for file in ("b.obj", "b.mtl", "s.yaml", "s.obj", "s.mtl"):
        lines = (tmp_path / file).read_text().splitlines()
        assert f"# {NOTICE}" in lines and f"#   {CC_BY}" in lines, file
    head = (tmp_path / "b.ply").read_bytes().split(b"end_header")[0].decode()
    assert f"comment {NOTICE}\n" in head and f"comment   {CC_BY}\n" in head
    (tmp_path / "p.yaml").write_text("extends: cornell-box\ngeometry: {mesh: b.ply}\ndefault_material: grey\n"
                                     "materials: {grey: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n")
    from_ply = load_scene(str(tmp_path / "p.yaml"))  # the PLY still reads back, and passes its notice on
    assert from_ply.n_triangles == scene.n_triangles and export.notices(from_ply) == told
    again = load_scene(str(tmp_path / "s.yaml"))  # the export's own scene file: the notice passed on
    assert export.notices(again) == told
    export.export_triangles(again, tmp_path / "again.obj")
    assert f"#   {CC_BY}" in (tmp_path / "again.obj").read_text().splitlines()


def test_a_scene_of_no_licensed_mesh_gets_no_notice(tmp_path):
    assert export.notices(load_scene("cornell")) == []
    export.export_triangles(load_scene("cornell"), tmp_path / "c.obj")
    assert "Notice" not in (tmp_path / "c.obj").read_text()


# ---------------------------------------------------------------- tlm scene list


def test_scene_list_leaves_out_the_scenes_of_bad_input_on_purpose(capsys):
    assert main(["scene", "list"]) == 0
    out, err = capsys.readouterr()
    names = out.split()
    assert "extreme/cornell_ior10" in names and not [n for n in names if n.startswith("extreme/bad_")]
    assert err.strip() == ("tlm: scene list: 2 scenes of bad input on purpose (tests of tlm's error messages: "
                           "extreme/bad_extends_itself, extreme/bad_scale_zero) left out; --all lists them")
    assert main(["scene", "list", "--all"]) == 0
    out, err = capsys.readouterr()
    assert {"extreme/bad_extends_itself", "extreme/bad_scale_zero"} <= set(out.split()) and err == ""


def test_a_description_of_comment_lines_is_its_whole_first_sentence():
    assert tlm.api.scene_description("extreme/cornell_ior10") == (
        "The Cornell box with a glass sphere of IOR 10: almost every internal ray is totally reflected; the frame "
        "must stay finite.")
    assert tlm.api.scene_description("extreme/cornell_dark") == (
        "The Cornell box with its one light at zero power: a black frame, no photons to trace.")


def test_the_extreme_cases_name_no_path_into_the_checkout():
    text = (CONFIGS / "extreme.yaml").read_text()
    assert "../" not in text
    assert yaml.safe_load(text)["cases"]
