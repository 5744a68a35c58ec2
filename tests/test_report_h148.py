"""The report's review findings of h145 (h148): a study's own warnings in the warnings box; the sweep
points without image error and the command that measures them; a run's --mode not in the --set column;
the error sentence's references counted and one measure (relative MSE) for runs and points."""

from __future__ import annotations

from pathlib import Path

from tlm.report import provenance, summary
from tlm.report.collect import Inputs, Run, Study, Sweep
from tlm.report.warnings import warnings_html

UNREAD = ("--set estimate.final_gather=0 changes nothing in 1 of 2 cells (mode rcast of every scene): the photon-map "
          "pass is left out")


def _cell(mode: str, warnings: list[str]) -> Run:
    return Run(Path(f"T/cornell/{mode}"), f"cornell/{mode}", "thesis", {"warnings": warnings}, {})


def test_a_thesis_study_s_own_warnings_are_in_the_box_once():
    """tlm thesis says an unread --set once, in thesis_summary.json's warnings (no cell's results.json
    has it): the box read only the runs' and showed nothing."""
    study = Study("thesis", Path("T"), [], {"warnings": [UNREAD], "per_item": {}})
    page = warnings_html(Inputs([Path("T")], runs=[_cell("rcast", []), _cell("pmap", [])], studies=[study]))
    assert page.count("estimate.final_gather=0 changes nothing") == 1 and "(the thesis study T)" in page
    assert "The thesis study T recorded 1 warning (thesis_summary.json <code>warnings</code>)" in page
    # (an older study whose cells recorded the line too: still once, the study's; a cell's own line kept)
    page = warnings_html(Inputs([Path("T")], runs=[_cell("rcast", [UNREAD, "frames too short"]), _cell("pmap", [])],
                                studies=[study]))
    assert page.count("estimate.final_gather=0 changes nothing") == 1
    assert "1 of the 2 runs and the thesis study T recorded 2 warnings" in page and "frames too short" in page
    assert "(results.json and thesis_summary.json <code>warnings</code>)" in page


def _point(sw: Path, h: str, error: dict | None) -> Run:
    return Run(sw / "points" / h, f"kmixed #{h}", "sweep-point", {"error": error}, {})


def _sweep(measured: int, unmeasured: int, keys=("k1",)) -> tuple[Sweep, list[Run]]:
    sw = Path("/x/kmixed")
    rows, runs = [], []
    for i in range(measured + unmeasured):
        h = f"h{i}"
        if i < measured:
            key = keys[i % len(keys)]
            runs.append(_point(sw, h, {"available": True, "reference": key, "rel_mse": 0.25, "rmse": 0.04}))
            rows.append({"point": i, "hash": h, "status": "ok", "error.rel_mse": 0.25, "error.rmse": 0.04})
        else:
            runs.append(_point(sw, h, {"available": False, "reference": "k9"}))
            rows.append({"point": i, "hash": h, "status": "ok"})
    return Sweep(sw, {}, rows, runs), runs


def test_sweep_points_without_error_are_counted_with_the_command_that_measures_them():
    """A photon-map sweep with no reference cached: the summary said only "no error to show"."""
    sw, runs = _sweep(0, 3)
    text = summary._other_errors(Inputs([sw.path], runs=runs, sweeps=[sw]))
    assert "no error to show" not in text
    assert "3 of 3 photon-map points of kmixed have no image error" in text
    assert "tlm reference /x/kmixed/points/h0/config.resolved.yaml</code> computes it" in text
    assert "the same 'tlm sweep' run again into /x/kmixed measures them" in text


def test_a_mixed_sweep_says_how_many_points_measured_their_error():
    sw, runs = _sweep(2, 2)
    text = summary._other_errors(Inputs([sw.path], runs=runs, sweeps=[sw]))
    assert "2 of 4 points of kmixed measured their image error: relative MSE 0.25 against their reference" in text
    assert "2 of 4 photon-map points of kmixed have no image error" in text


def test_the_error_sentence_counts_references_and_quotes_relative_mse_for_runs_too(tmp_path):
    sw, runs = _sweep(2, 0, keys=("k1", "k2"))
    (tmp_path / "images").mkdir()
    run = Run(tmp_path, "r: cornell/pmap", "run", {"error": {"available": True, "reference": "k3", "rmse": 0.04,
                                                              "rel_mse": 0.5}}, {})
    text = summary._other_errors(Inputs([sw.path], runs=[run, *runs], sweeps=[sw]))
    assert "against their 2 references" in text and "their reference " not in text
    assert "(relative MSE 0.5)" in text and "RMSE" not in text.replace("relative MSE", "")


def test_a_run_s_mode_flag_is_not_in_its_set_column():
    """tlm run --mode rcast --set resolution=[40,30] records overrides [resolution=[40,30], mode=rcast]."""
    run = Run(Path("r"), "rcast: cornell/rcast", "run", {"overrides": ["resolution=[40,30]", "mode=rcast", "seed=3"],
                                                         "seed": 3}, {})
    assert provenance.given_set(run) == ["resolution=[40,30]"]
    assert provenance._run_row(run, None, True)[3] == "resolution=[40,30]"
    only = Run(Path("r"), "rcast: cornell/rcast", "run", {"overrides": ["mode=rcast"]}, {})
    assert provenance.given_set(only) == []
    point = Run(Path("p"), "sw #0", "sweep-point", {}, {}, sweep_overrides=["mode=pmap"])
    assert provenance.given_set(point) == ["mode=pmap"]


def test_the_points_error_sentence_is_said_by_the_summary_points_module():
    """tlm.report.summary_points (moved out of summary.py, h150) says the sweep points' error sentence."""
    from tlm.report.summary_points import points_error

    sw, runs = _sweep(2, 2)
    text = points_error(Inputs([sw.path], runs=runs, sweeps=[sw]))
    assert text.startswith(" 2 of 4 points of kmixed measured their image error: relative MSE 0.25")
    assert text in summary._other_errors(Inputs([sw.path], runs=runs, sweeps=[sw]))
