"""Review of 1131538 and 04a8f53 (h348): the commands the refusals print run as printed.

1. A sweep folder's ``sweep.yaml`` names its sweep file as ``tlm sweep`` was given it; the command it suggested
   named that file wherever a file of that name was found from here: given in the sweep folder itself, of a sweep
   file named ``sweep.yaml``, the record itself (``tlm sweep sweep.yaml --out .``: refused again, the same line);
   another sweep's file of that name (another project's ``sw.yaml``) would run another sweep into the folder. It
   says ``SWEEP_FILE`` and why, where the file found holds no sweep of the record's ``base``, ``set``, ``grid`` and
   ``zip``; and a record of a piped sweep file (``/dev/fd/63``) is said to be a pipe's, not 'moved since'.
2. A run folder's ``config.resolved.yaml`` in a folder of a name with a space: ``tlm run runs/my run/...
   --out runs/my run-again``, not runnable as printed; the path and the ``--out`` are quoted.
"""

from __future__ import annotations

import shlex
from pathlib import Path

import yaml

from tlm.cli import main

QUIET = ["--no-progress", "--no-report", "--outputs", "images"]


def _record(folder: Path, sweep: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    record = {"tlm": "sweep/1", "sweep": sweep, "description": None, "base_file": "cornell",
              "base": {"scene": "cornell", "mode": "rcast"}, "set": {}, "overrides": ["resolution=[8, 8]"],
              "grid": {"bsp.levels": [5, 7]}, "zip": {},
              "points": [{"point": 0, "hash": "a" * 16, "factors": {"bsp.levels": 5}}]}
    (folder / "sweep.yaml").write_text(yaml.safe_dump(record, sort_keys=False))
    return folder / "sweep.yaml"


def test_a_sweep_records_command_names_no_file_of_its_name_that_holds_another_sweep(tmp_path, cache, capsys,
                                                                                       monkeypatch):
    _record(tmp_path / "runs" / "s", "sweep.yaml")  # (tlm sweep sweep.yaml --out runs/s, in tmp_path)
    monkeypatch.chdir(tmp_path / "runs" / "s")  # (the sweep folder: its sweep.yaml is the record itself)
    assert main(["sweep", "sweep.yaml"]) == 2
    err = capsys.readouterr().err
    # (was: tlm sweep sweep.yaml --out . (its sweep file, as this record names it): the record, refused again)
    assert "tlm sweep SWEEP_FILE --out . --set 'resolution=[8, 8]'" in err, err
    assert "which this record names 'sweep.yaml', here a sweep folder's record, not a sweep file" in err
    assert len(err.splitlines()) == 1
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sweep.yaml").write_text("base: room\ngrid: {bsp.levels: [4, 8]}\n")  # (another sweep's file)
    assert main(["sweep", "runs/s/sweep.yaml"]) == 2
    err = capsys.readouterr().err
    assert "tlm sweep SWEEP_FILE --out runs/s" in err and "here another sweep's file" in err, err  # (was: sweep.yaml)
    (tmp_path / "sweep.yaml").write_text("base: cornell\ngrid: {bsp.levels: [5, 7]}\n")  # (the record's sweep)
    assert main(["sweep", "runs/s/sweep.yaml"]) == 2
    assert "tlm sweep sweep.yaml --out runs/s --set 'resolution=[8, 8]' (its sweep file, as this record names it)" \
        in capsys.readouterr().err


def test_a_sweep_record_of_a_piped_sweep_file_says_so(tmp_path, cache, capsys):
    path = _record(tmp_path / "p", "/dev/fd/63")  # (tlm sweep <(...) --out p)
    assert main(["sweep", str(path)]) == 2
    err = capsys.readouterr().err
    assert "tlm sweep SWEEP_FILE --out" in err and "names '/dev/fd/63', a pipe's, read once" in err, err
    assert "moved since" not in err  # (was: not found from here (moved since?))


def test_a_run_folders_config_in_a_folder_of_a_spaced_name_is_given_a_command_that_runs(tmp_path, cache, capsys,
                                                                                         monkeypatch):
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "runs" / "my run"
    folder.mkdir(parents=True)
    (folder / "config.resolved.yaml").write_text("scene: cornell\nmode: rcast\nresolution: [8, 8]\n")
    assert main(["run", "runs/my run/config.resolved.yaml", *QUIET]) == 2
    err = capsys.readouterr().err
    assert "give --out, say --out 'runs/my run-again' (" in err, err  # (was: --out runs/my run-again)
    assert main(["sweep", "runs/my run/config.resolved.yaml"]) == 2
    err = capsys.readouterr().err
    command = "tlm run 'runs/my run/config.resolved.yaml' --out 'runs/my run-again'"
    assert err.rstrip().endswith(f"run it with {command}"), err  # (was: unquoted, two arguments each)
    assert main([*shlex.split(command)[1:], *QUIET]) == 0  # (it runs, as printed)
    assert (tmp_path / "runs" / "my run-again" / "results.json").is_file()
