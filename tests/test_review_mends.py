"""Mends of a review of the installed-copy and cache changes: the fingerprint skips only the
folders the wheel adds, a folder named as a built-in experiment does not hide it."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from tlm import fingerprint
from tlm.builtin import experiment_path, list_experiments
from tlm.errors import InputError

REPO = Path(__file__).resolve().parents[1]


def test_the_fingerprint_skips_exactly_the_folders_the_wheel_adds():
    """pyproject.toml's force-include targets are the folders skipped, and a code folder of
    the package whose name starts with ``_`` is hashed (it was skipped: any ``_`` folder)."""
    toml = tomllib.loads((REPO / "pyproject.toml").read_text())
    added = toml["tool"]["hatch"]["build"]["targets"]["wheel"]["force-include"].values()
    assert sorted(Path(t).parts[1] for t in added) == sorted(fingerprint.ADDED)
    root = REPO / "tlm"
    assert fingerprint.added(root, root / "_scenes" / "cornell.yaml")
    assert not fingerprint.added(root, root / "_private" / "kernel.py")


def test_a_folder_named_as_a_built_in_experiment_does_not_hide_it(tmp_path, monkeypatch):
    """Run where a folder ``extreme/`` is (the repository's scenes/), ``extreme`` is still the
    built-in experiment (it was the folder: 'cannot read (Is a directory)')."""
    assert "extreme" in list_experiments()
    (tmp_path / "extreme").mkdir()
    (tmp_path / "other").mkdir()
    monkeypatch.chdir(tmp_path)
    assert experiment_path("extreme").is_file() and experiment_path("extreme").name == "extreme.yaml"
    assert experiment_path("other") == Path("other")  # (a folder no built-in is named as is still the path given)
    (tmp_path / "mine.yaml").write_text("scene: cornell\n")
    assert experiment_path("mine.yaml") == Path("mine.yaml")
    with pytest.raises(InputError):
        experiment_path("no_such_thing")
