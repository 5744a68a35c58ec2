"""A sweep file's ``base:`` names a run config as ``tlm run`` takes one, relative to the sweep
file: a file there wins; else a name without ``.yaml`` or ``/`` is the built-in run config of
that name (``base: cornell``, from a sweep file in any folder). A path that does not exist is
not replaced by the built-in config of its file name, and a name that is neither says where
the built-in ones are listed and how one is copied out (exit status 2, nothing written)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import tlm.builtin
from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.sweep_file import load_sweep

SET = {"resolution": [8, 8], "mode": "rcast", "arch.trace": False, "render.spp": 1, "render.light_samples": 1}


def _sweep(folder: Path, base, grid=None) -> Path:
    path = folder / "mine.yaml"
    path.write_text(yaml.safe_dump({"base": base, "set": SET, "grid": grid or {"arch.fifo_depth": [1, 2]}},
                                   sort_keys=False))
    return path


def test_a_built_in_name_is_the_packaged_run_config(elsewhere):
    sweep = load_sweep(_sweep(elsewhere, "cornell"))
    packaged = yaml.safe_load((tlm.builtin.configs_dir() / "cornell.yaml").read_text())
    assert sweep.base == packaged and sweep.base_file == "cornell"
    assert [p.config["scene"] for p in sweep.points] == ["cornell", "cornell"]
    assert sweep.points[0].config["render"]["reflect_depth"] == packaged["render"]["reflect_depth"]
    # relative paths start at the sweep file's folder (the built-in config names its scene by name)
    assert sweep.folder == elsewhere.resolve()
    (elsewhere / "mine_programs.yaml").write_bytes(
        (Path(tlm.__file__).parent / "arch" / "programs.yaml").read_bytes())
    sweep = load_sweep(_sweep(elsewhere, "cornell", {"arch.programs": ["mine_programs.yaml"]}))
    # (absolute where the sweep file is read: one file on any worker and in config.resolved.yaml)
    assert sweep.points[0].config["arch"]["programs"] == str((elsewhere / "mine_programs.yaml").resolve())


def test_a_path_that_exists_wins_and_a_folder_does_not_hide_the_built_in(elsewhere):
    (elsewhere / "cornell").write_text(yaml.safe_dump({"scene": "cornell-box", "mode": "rcast"}))
    sweep = load_sweep(_sweep(elsewhere, "cornell"))
    assert sweep.base == {"scene": "cornell-box", "mode": "rcast"} and sweep.points[0].config["scene"] == "cornell-box"
    (elsewhere / "cornell").unlink()
    (elsewhere / "cornell").mkdir()
    assert load_sweep(_sweep(elsewhere, "cornell")).base["scene"] == "cornell"


@pytest.mark.parametrize("base, said", [
    ("cornell.yaml", r"mine\.yaml: base: 'cornell\.yaml': file not found \(relative to the sweep file\); the "
                     r"built-in experiment of that name: base: cornell \('tlm config export cornell FILE\.yaml'"),
    ("configs/cornell.yaml", r"mine\.yaml: base: 'configs/cornell\.yaml': file not found .*: base: cornell "),
    ("cornel", r"mine\.yaml: base: 'cornel': neither a file \(relative to the sweep file\) nor a built-in "
               r"experiment \('tlm config list -l' lists them; 'tlm config export NAME FILE\.yaml' .*'cornell'"),
    ("nowhere.yaml", r"mine\.yaml: base: 'nowhere\.yaml': file not found \(relative to the sweep file\); a built-in "
                     r"experiment is named without \.yaml .*'tlm config list -l'.*'tlm config export NAME FILE\.yaml'"),
    ("sweep_fifo", r"mine\.yaml: base: 'sweep_fifo' is an experiment of 'tlm sweep', not a run config"),
])
def test_a_base_that_names_no_run_config_says_where_they_are(elsewhere, base, said):
    with pytest.raises(InputError, match=said):
        load_sweep(_sweep(elsewhere, base))


def test_the_command_line_runs_a_built_in_base_and_refuses_a_missing_file(elsewhere, cache, capsys):
    path = _sweep(elsewhere, "cornell", {"arch.fifo_depth": [4]})
    assert main(["sweep", str(path), "--out", "out", "--jobs", "1", "--no-progress", "--no-report"]) == 0
    marker = yaml.safe_load((elsewhere / "out" / "sweep.yaml").read_text())
    assert marker["base_file"] == "cornell" and marker["base"]["scene"] == "cornell"
    assert (elsewhere / "out" / "sweep.csv").read_text().count("\n") == 2  # the header and the point
    capsys.readouterr()
    path = _sweep(elsewhere, "cornell.yaml")
    assert main(["sweep", str(path), "--out", "out2", "--jobs", "1", "--no-progress", "--no-report"]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and "base: 'cornell.yaml': file not found" in err[0] and "base: cornell " in err[0], err
    assert not (elsewhere / "out2").exists()
