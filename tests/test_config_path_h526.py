"""h526: results.json's config path, found again from another folder, and ``-`` for a config argument.

(1) ``config`` is the config file as typed (``../exp/a.yaml``), of a working folder results.json does not
record; ``config_file`` is its absolute path (null for a config read once: a pipe, ``/dev/stdin``), and the
``tlm reference`` command results.json records (``error.command``) names the config and a ``--set scene=``
file by their absolute paths, so that it runs from any folder. (2) ``-`` is no standard input (a file named
``-`` would make it mean either): refused with a line that says to give ``/dev/stdin``."""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from tlm.cli import main

ROOT = Path(__file__).resolve().parents[1]
needs_dev_fd = pytest.mark.skipif(not os.path.isdir("/dev/fd"), reason="no /dev/fd here")
TINY = ["--set", "resolution=[16,16]", "--set", "photons.count=2000"]


# ------------------------------------------------------------------ 1: the config path of a run folder


@pytest.mark.slow
def test_a_relative_configs_run_folder_names_it_and_its_reference_command_from_any_folder(tmp_path, cache,
                                                                                           monkeypatch, capsys):
    from tlm import api

    (tmp_path / "exp").mkdir()
    (tmp_path / "exp" / "a.yaml").write_text("scene: cornell\nmode: pmap\n")
    work, other = tmp_path / "wd", tmp_path / "other"
    work.mkdir()
    other.mkdir()
    (work / "my.yaml").write_text(f"extends: {ROOT / 'scenes' / 'cornell.yaml'}\n")  # (a scene file of the folder)
    monkeypatch.chdir(work)
    assert main(["run", "../exp/a.yaml", *TINY, "--set", "scene=my.yaml", "--no-reference", "--out", "o",
                 "--no-progress", "--no-report"]) == 0
    printed = next(x for x in capsys.readouterr().out.splitlines() if "pmap error" in x)
    assert "compute it with: tlm reference ../exp/a.yaml" in printed  # (said here, as typed: as before)
    results = json.loads((work / "o" / "results.json").read_text())
    assert results["config"] == "../exp/a.yaml"  # (as typed: kept)
    assert results["config_file"] == str((tmp_path / "exp" / "a.yaml").resolve())  # (was: no such key)
    monkeypatch.chdir(other)  # (a script reading the run folder later, elsewhere)
    words = shlex.split(results["error"]["command"])
    assert words[:3] == ["tlm", "reference", results["config_file"]]  # (was ../exp/a.yaml: not found from here)
    sets = [w for i, w in enumerate(words) if i and words[i - 1] == "--set"]
    assert f"scene={work / 'my.yaml'}" in sets  # (was scene=my.yaml: not found from here)
    cfg = api.load_config(words[2], sets)  # (what `tlm reference` reads of it, from this folder)
    assert Path(str(cfg.scene)).resolve() == (work / "my.yaml").resolve() and cfg.resolution == (16, 16)


def test_config_file_is_absolute_for_a_file_and_null_where_none_is_found_again(tmp_path, monkeypatch, piped):
    from tlm.config_read import config_file

    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "c.yaml").write_text("scene: cornell\n")
    (tmp_path / "link.yaml").symlink_to(tmp_path / "d" / "c.yaml")
    monkeypatch.chdir(tmp_path / "d")
    assert config_file("c.yaml") == str((tmp_path / "d" / "c.yaml").resolve())
    assert config_file("../link.yaml") == str((tmp_path / "d" / "c.yaml").resolve())  # (its relative paths' folder)
    assert [config_file(x) for x in (None, "", "(dict)", "missing.yaml", ".")] == [None] * 5
    if os.path.isdir("/dev/fd"):
        assert config_file(piped(b"scene: cornell\n")) is None  # (a pipe: read once, no file to find again)


def test_rerun_sets_makes_a_relative_file_absolute_and_leaves_the_rest(tmp_path, monkeypatch):
    from tlm.config_read import rerun_sets

    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.yaml").write_text("extends: x.yaml\n")
    (tmp_path / "t.yaml").write_text("")
    got = rerun_sets(["scene=s.yaml", "scene='s.yaml'", "arch.programs=t.yaml", "scene=cornell", "seed=1",
                      "resolution=[16,16]", "scene=gone.yaml", "arch.programs=/abs/t.yaml", "no equals"])
    assert got == [f"scene={tmp_path / 's.yaml'}", f"scene={tmp_path / 's.yaml'}",
                   f"arch.programs={tmp_path / 't.yaml'}", "scene=cornell", "seed=1", "resolution=[16,16]",
                   "scene=gone.yaml", "arch.programs=/abs/t.yaml", "no equals"]


@needs_dev_fd
def test_a_config_from_dev_stdin_records_no_config_file(tmp_path, cache):
    """A config given as /dev/stdin (a pipe): config says so, config_file is null, the command names the copy."""
    out = tmp_path / "o"
    done = subprocess.run([sys.executable, "-m", "tlm", "run", "/dev/stdin", "--mode", "pmap", *TINY,
                           "--no-reference", "--out", str(out), "--no-progress", "--no-report"],
                          input=(ROOT / "configs" / "cornell.yaml").read_bytes(), capture_output=True,
                          cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 0, done.stderr.decode()
    results = json.loads((out / "results.json").read_text())
    assert (results["config"], results["config_file"]) == ("/dev/stdin", None)
    assert results["error"]["command"] == f"tlm reference {out.absolute() / 'config.resolved.yaml'}"


# ------------------------------------------------------------------ 2: `-`


@pytest.mark.parametrize("command", ["run", "sweep", "reference", "thesis", "calibrate"])
@pytest.mark.parametrize("file_named_dash", [False, True])
def test_a_dash_is_refused_with_a_line_naming_dev_stdin(tmp_path, monkeypatch, capsys, command, file_named_dash):
    monkeypatch.chdir(tmp_path)
    if file_named_dash:  # (a file of that name: it would be read in place of the input the user meant)
        (tmp_path / "-").write_text("scene: cornell\nresolution: [8, 8]\n")
    assert main([command, "-", "--no-progress"] if command != "calibrate" else [command, "-"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tlm: error: -: not the standard input here: give /dev/stdin (tlm "
                                               f"{command} /dev/stdin"), err
    assert err[0].endswith("or ./- for a file named -")
    assert not (tmp_path / "runs").exists()


def test_dot_slash_dash_names_a_file_named_dash(tmp_path, monkeypatch):
    from tlm import api

    monkeypatch.chdir(tmp_path)
    (tmp_path / "-").write_text("scene: cornell\n")
    assert api.experiment_path("./-") == Path("-")
    with api.argument_names.flags_kept(), pytest.raises(api.InputError, match="give /dev/stdin"):
        api.experiment_path("-")  # (the command line's lookup)
    assert api.experiment_path("-") == Path("-")  # (the Python API: a file's name, as load_config takes it, h551)
    assert api.load_config("-").source == "-"  # (the Python API: a file that exists, as before; no stdin there)
