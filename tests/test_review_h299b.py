"""(review h299) A piped study file's, and a piped base config's, relative paths
start at the working folder, as a piped config's and sweep file's do (not /proc/PID/fd/...); a base named as a pipe
loads (was: file not found)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tlm.experiments.study import read_study
from tlm.experiments.sweep_file import load_sweep

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(not os.path.isdir("/dev/fd"), reason="no /dev/fd here")


def test_a_piped_study_names_files_from_the_working_folder(piped, monkeypatch):
    monkeypatch.chdir(ROOT)
    study = piped("scenes: [cornell]\nmodes: [rcast]\nbase: {arch: {programs: tlm/arch/programs.yaml}}\n")
    _, base, _ = read_study(study, ("scenes", "modes"))
    assert base["arch"]["programs"] == str(ROOT / "tlm" / "arch" / "programs.yaml")  # (was /proc/PID/fd/tlm/...)


def test_a_sweeps_base_given_as_a_pipe(piped, monkeypatch):
    monkeypatch.chdir(ROOT)
    base = piped("scene: scenes/cornell.yaml\nmode: rcast\nresolution: [8, 8]\n")
    sweep = load_sweep(Path(piped(f"base: {base}\ngrid: {{arch.fifo_depth: [1, 2]}}\n")))  # (was: file not found)
    assert [p.config["scene"] for p in sweep.points] == [str(ROOT / "scenes" / "cornell.yaml")] * 2
