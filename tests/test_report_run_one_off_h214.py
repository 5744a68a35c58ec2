"""The report's host seconds of a run count its one_off stage (a tlm run's: beside its other stages), not of a
sweep point (a part of its functional and simulate seconds), and say it."""

from __future__ import annotations

from tlm.report.provenance import _seconds


def test_a_runs_one_off_is_in_its_host_seconds_a_sweep_points_is_a_part():
    assert _seconds({"load_scene": 1.0, "cast": 0.5, "one_off": 2.0}) == 3.5
    assert _seconds({"functional": 3.0, "simulate": 1.0, "write": 0.5, "one_off": 2.0}) == 4.5
