"""Where a relative ``arch.programs`` (an instruction-cost table) is read from: relative to
the file that writes it (a run config, a sweep file, a base config), and on the command line
(``--set arch.programs=FILE``) relative to the working folder, as any path given there, for
a built-in config too. A table that is not there stops with the path that was tried.

Every folder here holds a table of the same name with other bytes, so a table read from the
wrong folder shows."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest
import yaml

from tests.helpers_programs import PACKAGED, tlm_run_reads_the_working_folders_table
from tlm.api import load_config
from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.experiments.granularity import load_granularity
from tlm.experiments.run import programs_for
from tlm.experiments.sweep_file import load_sweep

TINY = {"resolution": [8, 8], "mode": "rcast", "render": {"spp": 1, "light_samples": 1}}


def _table(folder: Path, name: str = "t.yaml") -> Path:
    """A copy of the packaged table, its bytes marked by its folder."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(PACKAGED.read_text() + f"# the copy in {folder.name}\n")
    return path


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def tree(tmp_path, monkeypatch):
    """``cwd/`` (the working folder), ``configs/`` and ``study/``, each with its own ``t.yaml``."""
    for name in ("cwd", "configs", "study"):
        _table(tmp_path / name)
    monkeypatch.chdir(tmp_path / "cwd")
    return tmp_path


def test_a_config_file_reads_the_table_beside_it(tree):
    (tree / "configs" / "run.yaml").write_text(yaml.safe_dump({**TINY, "arch": {"programs": "t.yaml"}}))
    for more in ([], ["seed=3"]):  # (other --set keys leave the file's own path as the file wrote it)
        cfg = load_config(str(tree / "configs" / "run.yaml"), more)
        assert cfg.settings.arch.programs == str(tree / "configs" / "t.yaml")  # (absolute: runs again anywhere)
        assert programs_for(cfg.settings, cfg.base).source == str(tree / "configs" / "t.yaml")


@pytest.mark.parametrize("config", ["cornell", "../configs/run.yaml"])
@pytest.mark.parametrize("given", ["arch.programs=t.yaml", "arch={programs: t.yaml}"])
def test_a_table_given_on_the_command_line_is_relative_to_the_working_folder(tree, config, given):
    (tree / "configs" / "run.yaml").write_text(yaml.safe_dump(TINY))
    cfg = load_config(config, [given])
    assert cfg.settings.arch.programs == str(tree / "cwd" / "t.yaml")
    assert programs_for(cfg.settings, cfg.base).source == str(tree / "cwd" / "t.yaml")
    # an absolute path, and null (the packaged table), stay as given
    absolute = str(tree / "study" / "t.yaml")
    assert load_config(config, [given.replace("t.yaml", absolute)]).settings.arch.programs == absolute
    assert load_config(config, [given.replace("t.yaml", "null")]).settings.arch.programs is None


def test_tlm_run_of_a_built_in_config_reads_the_working_folders_table(tree, cache, capsys):
    tlm_run_reads_the_working_folders_table(capsys, "cornell", "t.yaml", tree / "cwd")


def _sweep(tree: Path, body: dict) -> Path:
    (tree / "configs" / "base.yaml").write_text(yaml.safe_dump({**TINY, "arch": {"trace": False}}))
    path = tree / "study" / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": "../configs/base.yaml", **body}, sort_keys=False))
    return path


@pytest.mark.parametrize("body", [
    {"grid": {"arch.programs": ["t.yaml"]}},
    {"set": {"arch.programs": "t.yaml"}, "grid": {"seed": [0]}},
    {"zip": {"arch": [{"programs": "t.yaml", "trace": False}]}},
])
def test_a_sweep_files_table_is_beside_the_sweep_file_whatever_folder_its_base_is_in(tree, body):
    sweep = load_sweep(_sweep(tree, body))
    assert sweep.folder == (tree / "configs").resolve()  # (the base file's paths start at its folder)
    point = sweep.points[0]
    assert point.config["arch"]["programs"] == str(tree / "study" / "t.yaml")  # (absolute: on any worker)
    table = programs_for(config_from_dict(point.config), sweep.folder)
    assert _digest(Path(table.source)) == _digest(tree / "study" / "t.yaml")
    if "grid" in body and "arch.programs" in body["grid"]:
        assert point.factors == {"arch.programs": "t.yaml"}  # (the label as the sweep file writes it)


def test_a_sweep_files_missing_table_names_the_path_tried(tree):
    with pytest.raises(InputError, match=r"sweep\.yaml \(point 0\): .*/study/nope\.yaml: arch\.programs: "
                                         r"file not found"):
        load_sweep(_sweep(tree, {"grid": {"arch.programs": ["nope.yaml"]}}))


def test_a_base_files_own_table_is_beside_the_base_file(tree):
    (tree / "configs" / "base.yaml").write_text(yaml.safe_dump({**TINY, "arch": {"programs": "t.yaml"}}))
    (tree / "study" / "sweep.yaml").write_text(yaml.safe_dump({"base": "../configs/base.yaml",
                                                               "grid": {"arch.fifo_depth": [1, 2]}}))
    sweep = load_sweep(tree / "study" / "sweep.yaml")
    assert [p.config["arch"]["programs"] for p in sweep.points] == [str(tree / "configs" / "t.yaml")] * 2
    assert programs_for(config_from_dict(sweep.points[0].config), sweep.folder).source == str(
        tree / "configs" / "t.yaml")
    (tree / "study" / "g.yaml").write_text(yaml.safe_dump({"base": "../configs/base.yaml", "packet_sizes": [1]}))
    cfg, _, folder = load_granularity(tree / "study" / "g.yaml")
    assert programs_for(cfg, folder).source == str(tree / "configs" / "t.yaml")
