"""Review of e57f7c0 (h548): tlm calibrate's fit statistics and the report's fitted cells.

* the condition number ``tlm calibrate`` prints is of the Jacobian with its columns at unit length: a
  parameter's units (cycles or kilocycles a record) moved it (traversal's fit: 561 unscaled, 4.48 scaled)
  without changing how well the fit is determined;
* photons.russian_roulette and arch.memory are given by the thesis (§III, §IV.B): named as the thesis's;
* a run whose instruction table can no longer be read (moved, deleted) marks every cell a calibration may
  fit, not none: its fitted cells must not pass for predictions.
* --leave-one-out on two scenes: its line says each fit has one scene.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from tlm.arch.costs import DEFAULT_PATH
from tlm.cli import main


def test_the_condition_number_is_independent_of_a_parameters_units():
    from tlm.experiments.calibrate_fit import fit_statistics

    n = np.array([1.1e7, 5.1e7, 3.0e7])  # (traversal's columns, as tlm calibrate configs/thesis.yaml has them)
    k = np.array([9.06e4, 1.39e5, 1.61e5])
    y = np.array([2.44e7, 4.12e7, 4.27e7])
    fitted = 253.5 * k * np.array([0.98, 1.0, 1.02])
    one = fit_statistics({"t.scale": n, "t.record_cycles": k}, {"t.scale": 0.0, "t.record_cycles": 253.5}, y, fitted)
    # the same fit with record_cycles in kilocycles a record: its column 1000x, its value and error /1000
    kilo = fit_statistics({"t.scale": n, "t.record_cycles": k * 1000}, {"t.scale": 0.0, "t.record_cycles": 0.2535},
                          y, fitted)
    assert kilo["condition_number"] == pytest.approx(one["condition_number"], rel=1e-9)
    assert kilo["standard_errors"]["t.record_cycles"] * 1000 == pytest.approx(one["standard_errors"]["t.record_cycles"])
    jac = np.column_stack([n / y, k / y])
    assert one["condition_number"] == pytest.approx(np.linalg.cond(jac / np.linalg.norm(jac, axis=0)))
    assert one["condition_number"] < 10  # (the two columns' correlation, not their units)


def test_a_run_whose_table_is_gone_marks_every_cell_a_calibration_may_fit(tmp_path):
    table = tmp_path / "table.yaml"
    table.write_text(DEFAULT_PATH.read_text(encoding="utf-8"), encoding="utf-8")
    run = tmp_path / "run"
    assert main(["run", "cornell", "--set", "scene=thesis/ring", "--set", "mode=rcast", "--set", "resolution=[32,32]",
                 "--set", "arch.frames=1", "--set", f"arch.programs={table}", "--out", str(run), "--no-report"]) == 0
    table.unlink()  # (moved, deleted: which cells it was fitted to is unknown)
    assert main(["report", str(run), "--out", str(tmp_path / "report")]) == 0
    html = (tmp_path / "report" / "report.html").read_text(encoding="utf-8")
    for metric in ("TVert", "TTrav", "TFrag"):
        cell = re.search(rf'<td data-cell="ring/rcast/{metric}"[^>]*>.*?</td>', html, re.S)
        assert cell is not None and "†" in cell.group(0), metric


def test_settings_the_thesis_gives_are_named_as_the_thesiss():
    from tlm.experiments.thesis_setting import setting_mismatches, thesis_setting

    ours = thesis_setting("ring", "pmap")
    ours["photons"] = {**ours["photons"], "russian_roulette": False}  # (§III: "Russian roulette method is used")
    ours["arch"] = {**ours["arch"], "memory": "copy", "swap_cycles": 3}  # (§IV.B: modules swapped; no cycle count)
    said = setting_mismatches("ring", ours)
    assert "photons.russian_roulette false (thesis: true)" in said, said
    assert "arch.memory copy (thesis: swap)" in said, said
    assert "arch.swap_cycles 3 (configs/thesis.yaml: 2; not in the thesis)" in said, said


def test_leave_one_out_on_two_scenes_says_why_one_line(tmp_path, capsys):
    import yaml

    spec = tmp_path / "two.yaml"
    spec.write_text(yaml.safe_dump({"base": {"resolution": [16, 16], "arch": {"frames": 1}},
                                    "scenes": ["thesis/ring", "cornell"], "modes": ["rcast"]}))
    assert main(["calibrate", str(spec), "--leave-one-out"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "scenes:" in err, err
    # (two scenes listed: each fit is to one, which the line says, not "one scene" of a list of two alone)
    assert "--leave-one-out fits all scenes but one, and one scene gives one RCast cell per PM" in err, err
