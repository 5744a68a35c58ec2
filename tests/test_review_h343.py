"""Review of 74102f8 (h343): what the new lines on running again say is runnable, and true.

1. A sweep folder's ``sweep.yaml`` names its sweep file as ``tlm sweep`` was given it (``sweep: sw.yaml``, from the
   folder it ran in): given from another folder, the record's advice was ``tlm sweep sw.yaml --out ...``, a file
   not found from there (so too an absolute path, the project moved since). It now says ``SWEEP_FILE`` and which
   path the record names, where that is not found here.
2. A run folder's ``config.resolved.yaml`` given to ``tlm sweep`` (or a study's command) was asked for ``--out``
   (which it did not need: with it, the sweep refused it as a run config), and the ``tlm run`` command that
   refusal gave was itself refused (no ``--out``). It is refused as a run config first, with a ``tlm run ...
   --out runs/a-again`` that runs.
3. The moved project's hint (``--set scene=PATH``) was said where the missing absolute path was the user's own
   ``--set scene=...``, not the run folder's: it is said only for the path the file names.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.scenes.loader import load_scene

SCENE = ("geometry: [{shape: plane, params: {size: [4, 4]}}]\n"
         "materials: {g: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\ndefault_material: g\n"
         "lights: [{type: point, position: [0, 3, -2], power: [40, 40, 40]}]\n"
         "camera: {eye: [0, 1, -5], target: [0, 0, 0], vfov: 40}\nresolution: [8, 8]\n")
QUIET = ["--no-progress", "--no-report", "--outputs", "images"]


def _record(folder: Path, sweep: str) -> Path:
    folder.mkdir(parents=True)
    record = {"tlm": "sweep/1", "sweep": sweep, "description": None, "base_file": "exp.yaml",
              "base": {"scene": "s.yaml", "mode": "rcast"}, "set": {}, "overrides": ["resolution=[8, 8]"],
              "grid": {"bsp.levels": [5, 7]}, "zip": None,
              "points": [{"point": 0, "hash": "a" * 16, "factors": {"bsp.levels": 5}}]}
    (folder / "sweep.yaml").write_text(yaml.safe_dump(record, sort_keys=False))
    return folder / "sweep.yaml"


def test_a_sweep_records_relative_sweep_file_not_found_from_here_is_no_command(tmp_path, cache, capsys,
                                                                                monkeypatch):
    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "sw.yaml").write_text("base: exp.yaml\ngrid: {bsp.levels: [5, 7]}\n")
    _record(tmp_path / "p" / "runs" / "sw", "sw.yaml")  # (tlm sweep sw.yaml, run in p/)
    monkeypatch.chdir(tmp_path)  # (another folder: sw.yaml is not there)
    assert main(["sweep", "p/runs/sw/sweep.yaml"]) == 2
    err = capsys.readouterr().err
    assert "tlm sweep SWEEP_FILE --out p/runs/sw --set 'resolution=[8, 8]'" in err, err  # (was: tlm sweep sw.yaml)
    assert "which this record names 'sw.yaml'" in err and "not found from here" in err and len(err.splitlines()) == 1
    monkeypatch.chdir(tmp_path / "p")  # (the folder it ran in: the command as it is)
    assert main(["sweep", "runs/sw/sweep.yaml"]) == 2
    assert "tlm sweep sw.yaml --out runs/sw --set 'resolution=[8, 8]' (its sweep file" in capsys.readouterr().err
    _record(tmp_path / "moved", "/nowhere/p/sw.yaml")  # (an absolute path, the project moved since)
    assert main(["sweep", str(tmp_path / "moved" / "sweep.yaml")]) == 2
    err = capsys.readouterr().err
    assert "tlm sweep SWEEP_FILE --out" in err and "names '/nowhere/p/sw.yaml', not found from here (moved" in err


def test_a_run_folders_config_given_to_tlm_sweep_says_the_tlm_run_command_that_runs(tmp_path, cache, capsys,
                                                                                      monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("s.yaml").write_text(SCENE)
    assert main(["run", "s.yaml", "--out", "runs/a", *QUIET]) == 0
    capsys.readouterr()
    for command in ("sweep", "error-vs-cost"):
        assert main([command, "runs/a/config.resolved.yaml"]) == 2
        err = capsys.readouterr().err
        assert "give --out" not in err, err  # (was: give --out, then, with it, a run config, not a sweep file)
        assert "a run config (it has scene:)" in err and len(err.splitlines()) == 1
        assert err.rstrip().endswith("run it with tlm run runs/a/config.resolved.yaml --out runs/a-again"), err
    assert main(["run", "runs/a/config.resolved.yaml", "--out", "runs/a-again", *QUIET]) == 0  # (it runs)
    assert (tmp_path / "runs" / "a-again" / "results.json").is_file()


def test_the_moved_project_hint_is_for_the_files_own_scene_not_a_set_scene(tmp_path, cache, capsys):
    resolved = tmp_path / "r" / "config.resolved.yaml"
    resolved.parent.mkdir()
    resolved.write_text(yaml.safe_dump({"scene": "/nowhere/old/s.yaml", "mode": "rcast"}))
    assert main(["run", str(resolved), "--out", str(tmp_path / "b"), *QUIET, "--set", "scene=/nowhere/mine.yaml"]) == 2
    err = capsys.readouterr().err
    assert "'/nowhere/mine.yaml' not found" in err and "--set scene=PATH" not in err, err  # (was: the hint)
    assert main(["run", str(resolved), "--out", str(tmp_path / "b"), *QUIET, "--set", "mode=rcast"]) == 2
    err = capsys.readouterr().err  # (the file's own path, with another --set: the hint stays)
    assert "'/nowhere/old/s.yaml' not found" in err and "--set scene=PATH" in err and len(err.splitlines()) == 1
    with pytest.raises(InputError) as e:
        load_scene("/nowhere/mine.yaml", None, None, f"{resolved}, with --set")
    assert "--set scene" not in str(e.value)
    assert not (tmp_path / "b").exists()
