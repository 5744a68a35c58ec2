"""`tlm calibrate`'s leftovers from review h548: ``--no-progress`` drops the iteration lines (the result
lines stay); ``--leave-one-out``'s progress names a scene as its result lines do (the table's name); a
singular fit's infinite condition number is written so that YAML reads it back as a number, and said."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest
import yaml

import tlm.arch.costs as costs
import tlm.experiments.calibrate_fit as calibrate_fit
from tlm import api
from tlm.cli import main
from tlm.cli_tables import fit_lines
from tlm.experiments.thesis_tables import FIT_PMS, FIT_RECORDS

STATS = {"traversal": {"cells": 2, "parameters": {"traversal.scale": 1.0, "traversal.record_cycles": 0.0},
                       "dof": 0, "median_abs_rel_error": 0.0, "max_abs_rel_error": 0.0,
                       "standard_errors": {"traversal.scale": None, "traversal.record_cycles": None},
                       "on_bound": ["traversal.record_cycles"], "condition_number": float("inf")}}


def _fake_calibrate(path, held_out=False, progress=None):
    """api.calibrate without renders: one progress call, then a report (or a leave-one-out result)."""
    if held_out:
        progress("ring", 1, {"traversal.scale": 1.5})
        loo = {"scenes": {"ring": {"parameters": {"traversal.scale": 1.5},
                                   "cells": {"T": {"rel_error": 0.01, "in_sample": 0.02}}}},
               "held_out": {"median": 0.01, "max": 0.01, "cells": 1},
               "in_sample": {"median": 0.02, "max": 0.02, "cells": 1}, "not_comparable": {}}
        return None, loo
    progress(1, {"traversal.scale": 1.5})
    report = {"cells": {"ring": {"T": {"ours": 1.0, "thesis": 1.0}}}, "fit": STATS, "not_comparable": {}}
    return None, report


@pytest.mark.parametrize("extra", [[], ["--leave-one-out"]])
def test_no_progress_drops_the_iteration_lines_and_keeps_the_results(tmp_path, monkeypatch, capsys, extra):
    study = tmp_path / "study.yaml"
    study.write_text("scenes: [thesis/ring, cornell]\nmodes: [rcast]\n")
    monkeypatch.setattr(api, "calibrate", _fake_calibrate)
    dry = [] if extra else ["--dry-run"]
    assert main(["calibrate", str(study), *dry, *extra]) == 0
    shown = capsys.readouterr().out
    assert "iteration 1" in shown
    assert main(["calibrate", str(study), *dry, *extra, "--no-progress"]) == 0
    quiet = capsys.readouterr().out
    assert "iteration" not in quiet
    kept = [line for line in shown.splitlines() if "iteration" not in line]
    assert quiet.splitlines() == kept and kept


def test_leave_one_out_progress_names_the_scene_as_its_results_do(monkeypatch):
    scenes = ["thesis/ring", "cornell", "thesis/room"]
    tables = {"thesis/ring": "ring", "cornell": "cornell", "thesis/room": "room"}
    programs = SimpleNamespace(scale=dict.fromkeys(FIT_PMS, 1.0), record_cycles=dict.fromkeys(FIT_RECORDS, 0.0))
    sim = SimpleNamespace(cycles={}, fps=None)

    def fit(inputs, fitted, iterations, progress):
        if progress is not None:
            progress(1, {"traversal.scale": 1.0})
        return programs, [], dict.fromkeys(scenes, sim), {}

    monkeypatch.setattr(calibrate_fit, "fit", fit)
    monkeypatch.setattr(calibrate_fit, "simulate", lambda fn, p, arch: sim)
    monkeypatch.setattr(calibrate_fit, "_ours", lambda cycles, fps: dict.fromkeys(FIT_PMS.values(), 1.0))
    monkeypatch.setattr(calibrate_fit, "thesis_value", lambda table, mode, metric: 1.0)
    told = []
    inputs = {"scenes": scenes, "tables": tables, "fns": {s: (None, SimpleNamespace(arch=None)) for s in scenes},
              "differ": {}}
    out = calibrate_fit.held_out(inputs, 1, lambda left, it, params: told.append(left))
    assert told == list(out["scenes"]) == ["ring", "cornell", "room"]


def test_an_infinite_condition_number_reads_back_as_a_number(tmp_path):
    block = yaml.safe_load("calibration:\n" + calibrate_fit._fit_block(STATS))
    cond = block["calibration"]["fit"]["traversal"]["cond"]
    assert isinstance(cond, float) and math.isinf(cond)
    programs = costs.load_programs(costs.DEFAULT_PATH)
    report = {"cells": {"ring": {"T": {"thesis": 1.0, "ours": 1.0}}}, "fit": STATS, "fitted": ["traversal.scale"]}
    target = tmp_path / "programs.yaml"
    calibrate_fit.write_calibrated(programs, report, target, "tlm calibrate thesis --write programs.yaml")
    loaded = costs.load_programs(target)
    assert math.isinf(loaded.calibration["fit"]["traversal"]["cond"])
    line = fit_lines(STATS)[0]
    assert "condition number infinite" in line and "singular" in line
