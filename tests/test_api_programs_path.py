"""The Python API takes an override's ``arch.programs`` (an instruction-cost table) relative to
the working folder, as ``tlm run --set arch.programs=FILE`` does: ``Config.updated``,
``load_config`` of a file, of a scene file and of a mapping (whatever its ``base``), and
``simulate``'s ``arch`` keys. The config's folder ``A`` and the working folder ``B`` each hold
a ``my.yaml``; B's traversal ``record_cycles`` differ, so a table read from the wrong folder
shows in the cycles as well as in the path."""

from __future__ import annotations

import pytest
import yaml

import tlm
from tests.helpers_programs import PACKAGED, tlm_run_reads_the_working_folders_table
from tlm.api import load_config, render_image, simulate
from tlm.errors import InputError
from tlm.experiments.run import programs_for

TINY = {"scene": "cornell", "resolution": [8, 8], "mode": "rcast", "render": {"spp": 1, "light_samples": 1},
        "arch": {"trace": False}}


@pytest.fixture
def tree(tmp_path, monkeypatch):
    """``A/`` (the config's and the scene file's folder, with the packaged table as ``my.yaml``)
    and ``B/`` (the working folder, whose ``my.yaml`` has another traversal record cost)."""
    a, b = tmp_path / "A", tmp_path / "B"
    a.mkdir()
    b.mkdir()
    (a / "my.yaml").write_text(PACKAGED.read_text())
    table = yaml.safe_load(PACKAGED.read_text())
    assert table["traversal"]["record_cycles"] != 999
    table["traversal"]["record_cycles"] = 999
    (b / "my.yaml").write_text(yaml.safe_dump(table, sort_keys=False))
    (a / "run.yaml").write_text(yaml.safe_dump(TINY))
    (a / "scene.yaml").write_text("extends: cornell\n")
    monkeypatch.chdir(b)
    return tmp_path


def _read(cfg) -> str:
    return programs_for(cfg.settings, cfg.base).source


def test_updated_reads_the_working_folders_table(tree):
    cfg = load_config(tree / "A" / "run.yaml")
    assert cfg.base == tree / "A"
    for over in ({"arch.programs": "my.yaml"}, ["arch.programs=my.yaml"], {"arch": {"programs": "my.yaml"}}):
        new = cfg.updated(over)
        assert new.settings.arch.programs == str(tree / "B" / "my.yaml")
        assert _read(new) == str(tree / "B" / "my.yaml")
    assert _read(cfg.updated({"seed": 3})) == str(PACKAGED)  # (other keys: the config's own table)


def test_a_run_of_an_updated_config_records_the_working_folders_table(tree, cache):
    cfg = load_config(tree / "A" / "run.yaml").updated({"arch.programs": "my.yaml"})
    results = tlm.run(cfg, tree / "B" / "out", outputs="images")
    assert results["timing"]["programs"]["source"] == str(tree / "B" / "my.yaml")
    assert results["timing"]["programs"]["record_cycles"]["traversal"] == 999
    resolved = yaml.safe_load((tree / "B" / "out" / "config.resolved.yaml").read_text())
    assert resolved["arch"]["programs"] == str(tree / "B" / "my.yaml")


def test_a_missing_table_names_the_working_folders_path(tree, cache):
    cfg = load_config(tree / "A" / "run.yaml").updated({"arch.programs": "nope.yaml"})
    (tree / "A" / "nope.yaml").write_text(PACKAGED.read_text())  # (the config's folder has one: not read)
    with pytest.raises(InputError, match=r"^" + str(tree / "B" / "nope.yaml") + r": arch\.programs: file not found$"):
        tlm.run(cfg, tree / "B" / "out")
    assert not (tree / "B" / "out").exists()


def test_a_mapping_with_a_base_reads_the_working_folders_table(tree):
    cfg = load_config(TINY, {"arch.programs": "my.yaml"}, base=tree / "A")
    assert cfg.base == tree / "A"
    assert _read(cfg) == str(tree / "B" / "my.yaml")
    # the mapping's own programs start at its base
    own = load_config({**TINY, "arch": {"programs": "my.yaml"}}, {"seed": 1}, base=tree / "A")
    assert _read(own) == str(tree / "A" / "my.yaml")


def test_a_scene_file_with_overrides_reads_the_working_folders_table(tree):
    cfg = load_config(tree / "A" / "scene.yaml", {"arch.programs": "my.yaml"})
    assert cfg.scene_file and cfg.base == tree / "A"
    assert _read(cfg) == str(tree / "B" / "my.yaml")


def test_tlm_run_of_a_scene_file_reads_the_working_folders_table(tree, cache, capsys):
    (tree / "A" / "nope.yaml").write_text(PACKAGED.read_text())  # (the config's folder has one: not read)
    tlm_run_reads_the_working_folders_table(capsys, "../A/scene.yaml", "my.yaml", tree / "B")


def test_simulate_arch_programs_is_relative_to_the_working_folder(tree, cache):
    res = render_image(load_config(tree / "A" / "run.yaml"))
    assert res.base == tree / "A"
    given = simulate(res, {"programs": "my.yaml"})
    assert given.cycles == simulate(res, programs=tree / "B" / "my.yaml").cycles
    assert given.cycles["traversal"] != simulate(res, programs=tree / "A" / "my.yaml").cycles["traversal"]
