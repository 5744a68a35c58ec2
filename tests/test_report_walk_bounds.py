"""``tlm report ~``: the search of a big folder for tlm folders passes over the folders of installed
software (a virtual or conda environment, site-packages, node_modules), as it does hidden ones
(``.git``, ``.venv``), and says so in one line, as it says a long search; runs at any depth under
ordinary folders are still found (tests/test_report_folders_words.py)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.errors import InputError
from tlm.report import folders
from tlm.report.collect import read
from tlm.report.folders import find


def _run_folder(folder: Path) -> Path:
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps(
        {"scene": {"name": "Box", "source": "/x/Box.yaml"}, "mode": "refract", "fps": 0.772, "timing": {}}))
    return folder


def _home(tmp_path: Path) -> tuple[Path, list[Path], list[Path]]:
    """A home-like folder: two runs at depth among installed software, each with a results.json
    of its own inside (a package's test data) that is no run of the researcher's."""
    home = tmp_path / "home"
    runs = [_run_folder(home / "data" / "2026" / "nov" / "run1"), _run_folder(home / "project" / "runs" / "run2")]
    venv, conda = home / "env", home / "miniconda3"
    (venv / "lib" / "python3.11" / "site-packages").mkdir(parents=True)
    (venv / "pyvenv.cfg").write_text("home = /usr/bin\n")
    (conda / "conda-meta").mkdir(parents=True)
    _run_folder(conda / "pkgs" / "somepkg" / "tests" / "data")
    _run_folder(home / "project" / "web" / "node_modules" / "pkg" / "fixtures")
    _run_folder(home / "lib" / "python3" / "dist-packages" / "tlm_copy" / "tests" / "data")
    _run_folder(home / ".venv" / "lib" / "site-packages" / "pkg" / "tests" / "data")  # (hidden: as before)
    software = [home / "env", home / "lib" / "python3" / "dist-packages", home / "miniconda3",
                home / "project" / "web" / "node_modules"]
    return home, runs, software


def test_installed_software_is_not_searched_and_one_line_says_so(tmp_path):
    home, runs, software = _home(tmp_path)
    notes: list[str] = []
    assert [p for p, _ in find(home, None, notes)] == runs
    shown = ", ".join(str(p) for p in software[:3]) + f" and {software[3]}"  # (h413: the one left named)
    assert notes == [f"{home / 'lib'}: no run, sweep or study in it",
                     f"{home / 'project' / 'web'}: no run, sweep or study in it",
                     f"{home}: 4 folders of installed software not searched (a virtual or conda environment, "
                     f"site-packages, dist-packages or node_modules: no tlm command writes there): {shown}"]


def test_the_folders_of_installed_software_are_not_even_listed(tmp_path, monkeypatch):
    home, runs, software = _home(tmp_path)
    listed: list[str] = []
    scandir = os.scandir

    def counting(path):
        listed.append(str(path))
        return scandir(path)

    monkeypatch.setattr(os, "scandir", counting)
    assert [p for p, _ in find(home)] == runs
    inside = [p for p in listed if any(p == str(s) or p.startswith(f"{s}/") for s in software[1::2])]
    assert inside == []  # (dist-packages and node_modules: passed over by their names)
    assert not [p for p in listed if any(p.startswith(f"{s}/") for s in software)]  # (the environments: opened only)
    assert sorted(os.path.relpath(p, home) for p in listed) == [
        ".", "data", "data/2026", "data/2026/nov", "data/2026/nov/run1", "env", "lib", "lib/python3", "miniconda3",
        "project", "project/runs", "project/runs/run2", "project/web"]  # (a run, an environment: listed, not searched)


def test_a_long_search_is_said_in_that_line(tmp_path, monkeypatch):
    runs = tmp_path / "runs"
    _run_folder(runs / "a" / "b" / "run")
    monkeypatch.setattr(folders, "LONG_FOLDERS", 4)  # (runs, a, b and run, whose names say it is one)
    notes: list[str] = []
    assert [p for p, _ in find(runs, None, notes)] == [runs / "a" / "b" / "run"]
    assert len(notes) == 1 and notes[0].startswith(f"{runs}: the search for tlm folders listed 4 folders in ")
    assert notes[0].endswith(" s (name the folders that hold the runs, or one nearer them, for a quicker report)")
    monkeypatch.setattr(folders, "LONG_FOLDERS", 5)  # (a search of 4 folders is not long)
    notes.clear()
    find(runs, None, notes)
    assert notes == []


def test_a_folder_of_installed_software_alone_is_named_among_what_was_passed_over(tmp_path):
    home = tmp_path / "home"
    (home / "env").mkdir(parents=True)
    (home / "env" / "pyvenv.cfg").write_text("")
    _run_folder(home / "env" / "lib" / "site-packages" / "pkg" / "data")
    with pytest.raises(InputError) as e:
        read([home])
    said = str(e.value)
    assert "holds no tlm output" in said
    assert said.endswith(f"; {home / 'env'}: a Python virtual environment (pyvenv.cfg), not searched"), said


def test_tlm_report_says_it_on_one_line_of_stderr(tmp_path, capsys):
    home = _home(tmp_path)[0]
    notes: list[str] = []
    find(home, None, notes)
    assert main(["report", str(home), "--out", str(tmp_path / "rep")]) == 0
    assert capsys.readouterr().err.splitlines() == [f"tlm: note: {n}" for n in notes]
    assert len(notes) == 3 and "4 folders of installed software not searched" in notes[2]
    assert ": 2 runs, 0 sweeps, 0 studies (none)." in (tmp_path / "rep" / "report.html").read_text()
