"""``write_calibrated`` (``tlm calibrate --write``) replaces its target atomically through a
hidden temporary file of its own: a file of the user's named like a temporary one beside the
table is never overwritten or moved."""

from __future__ import annotations

from tlm.arch.costs import load_programs
from tlm.experiments.thesis import fitted_parameters, write_calibrated


def test_a_calibrated_table_leaves_the_files_beside_it_alone(tmp_path):
    target = tmp_path / "programs.yaml"
    mine = tmp_path / "programs.yaml.tmp"  # (a user's file, named as the old code's temporary file)
    mine.write_text("my notes\n")
    programs = load_programs()
    write_calibrated(programs, {"cells": {}, "fitted": fitted_parameters()}, target, "tlm calibrate study.yaml")
    assert mine.read_text() == "my notes\n"
    again = load_programs(target)
    assert again.scale == programs.scale and again.calibration["command"] == "tlm calibrate study.yaml"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["programs.yaml", "programs.yaml.tmp"]
