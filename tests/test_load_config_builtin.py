"""``tlm.load_config`` takes a built-in experiment's name as ``tlm run`` does (tlm/api.py,
:func:`tlm.api.experiment_path`): from any folder, a path that exists winning over the
name, and a path that does not exist refused with the command line's error, not replaced
by the built-in experiment of its file name."""

from __future__ import annotations

import pytest

import tlm
from tlm import api
from tlm.cli import main


def test_a_built_in_experiment_by_name_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # (no configs/ here)
    packaged = api.configs_dir() / "cornell_pmap.yaml"
    cfg = tlm.load_config("cornell_pmap", {"resolution": [16, 16]})
    by_path = tlm.load_config(str(packaged), {"resolution": [16, 16]})
    assert cfg.settings == by_path.settings and cfg.mode == "pmap" and cfg.resolution == (16, 16)
    assert cfg.source == str(packaged) and cfg.base == packaged.parent
    assert cfg.overrides == ("resolution=[16, 16]",)

    (tmp_path / "cornell_pmap").write_text("scene: cornell\nmode: rcast\n")  # a file of that name here wins
    own = tlm.load_config("cornell_pmap")
    assert own.mode == "rcast" and own.source == "cornell_pmap" and own.base == tmp_path


def test_a_missing_path_gets_the_command_lines_error_not_the_built_in(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    for ref in ("configs/cornell.yaml", "cornell.yaml"):
        with pytest.raises(tlm.InputError, match=r"not found here; the built-in experiment of that name: "
                                                 r"tlm run cornell \('tlm config export'"):
            tlm.load_config(ref)
        assert main(["run", ref]) == 2
        assert "not found here; the built-in experiment of that name: tlm run cornell" in capsys.readouterr().err
    with pytest.raises(tlm.InputError, match=r"^cornel: neither a file nor a built-in experiment .*did you mean "
                                             r"'cornell'\?"):
        tlm.load_config("cornel")
    with pytest.raises(tlm.InputError, match=r"examples/mesh_on_floor is a built-in scene, not an experiment"):
        tlm.load_config("examples/mesh_on_floor")
    with pytest.raises(tlm.InputError, match=r"an empty name names no experiment file"):
        tlm.load_config("")
