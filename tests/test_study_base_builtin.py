"""A study file's ``base:`` names a run config as a sweep file's does, by one function
(tlm.builtin.read_base): a file relative to the study file, else a name without ``.yaml``
or ``/`` is the built-in run config of that name (``base: cornell``, from a study file in
any folder). ``tlm granularity`` is the study whose ``base:`` may be a string; the others
(thesis, error-vs-cost, extreme) take a mapping (tests/test_study.py)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import tlm.builtin
from tlm.cli import main
from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.experiments.granularity import load_granularity


def _study(folder: Path, base) -> Path:
    path = folder / "g.yaml"
    path.write_text(yaml.safe_dump({"base": base, "packet_sizes": [4, 1]}, sort_keys=False))
    return path


def test_a_built_in_name_is_the_packaged_run_config(elsewhere):
    from tlm.experiments.study import read_study_base

    cfg, sizes, folder = load_granularity(_study(elsewhere, "cornell"))
    packaged = yaml.safe_load((tlm.builtin.configs_dir() / "cornell.yaml").read_text())
    assert cfg == config_from_dict(packaged) and sizes == [1, 4]
    # the built-in config names its scene by name: relative paths start at the study file's folder
    assert folder == elsewhere.resolve()
    raw, base, source, folder = read_study_base(_study(elsewhere, "cornell"), ("packet_sizes",))
    assert raw["packet_sizes"] == [4, 1] and folder == elsewhere.resolve()
    assert base == packaged and source == str(tlm.builtin.configs_dir() / "cornell.yaml")
    # a file of that name wins (its paths start at its folder), as for a sweep's base
    (elsewhere / "cornell").write_text(yaml.safe_dump({"scene": "ring", "mode": "rcast"}))
    cfg, _, folder = load_granularity(_study(elsewhere, "cornell"))
    assert cfg.scene == "ring" and folder == elsewhere.resolve()
    (elsewhere / "runs").mkdir()
    (elsewhere / "runs" / "run.yaml").write_text(yaml.safe_dump({"scene": "ring", "mode": "rcast"}))
    assert load_granularity(_study(elsewhere, "runs/run.yaml"))[2] == (elsewhere / "runs").resolve()


@pytest.mark.parametrize("base, said", [
    ("cornel", r"g\.yaml: base: 'cornel': neither a file \(relative to the study file\) nor a built-in "
               r"experiment \('tlm config list -l' lists them; .*\(did you mean 'cornell'\?\)"),
    ("cornell.yaml", r"g\.yaml: base: 'cornell\.yaml': file not found \(relative to the study file\); the "
                     r"built-in experiment of that name: base: cornell "),
    ("tlm_granularity", r"g\.yaml: base: 'tlm_granularity' is an experiment of 'tlm granularity', not a run config"),
])
def test_a_base_that_names_no_run_config_says_so(elsewhere, base, said):
    with pytest.raises(InputError, match=said):
        load_granularity(_study(elsewhere, base))


def test_the_command_line_refuses_a_misspelt_name_in_one_line(elsewhere, cache, capsys):
    path = _study(elsewhere, "cornel")
    assert main(["granularity", str(path), "--out", "out"]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and "base: 'cornel': neither a file" in err[0] and "did you mean 'cornell'?" in err[0], err
    assert not (elsewhere / "out").exists()

