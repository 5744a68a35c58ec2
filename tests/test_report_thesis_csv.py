"""`tlm report` of a thesis folder whose thesis_comparison.csv is damaged or edited, and the
first screen's "How fast" sentence saying the pipeline count its runs were simulated at.

A thesis_comparison.csv without a column, without a metric row of a cell, with a row twice,
a value that is not a (finite) number or not true/false, or no rows is one line naming the
file (and the column, row or line); as the report's only input, exit 2 and no report folder
(with other inputs it is named and left out: tests/test_report_probe_mends.py).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.experiments.thesis import COLUMNS, METRICS, comparison_rows, summarize
from tlm.report.collect import Inputs, Run, read
from tlm.report.summary import summary_section

OURS = {"TVert": 0.4, "TTrav": 24.0, "Tisct": 19.0, "TFrag": 4.2, "TThru": 24.0, "FPS": 2.5}


def _rows() -> list[dict]:
    return [*comparison_rows("ring", "rcast", OURS), *comparison_rows("ring", "pmap", OURS)]


def _write(folder: Path, rows: list[dict], columns=COLUMNS) -> Path:
    folder.mkdir()
    buf = io.StringIO()
    w = csv.DictWriter(buf, list(columns), extrasaction="ignore")
    w.writeheader()
    w.writerows(rows)
    (folder / "thesis_comparison.csv").write_text(buf.getvalue())
    return folder


def _refused(folder: Path, says: str, capsys) -> None:
    capsys.readouterr()
    assert main(["report", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "internal error" not in err
    assert err.startswith(f"tlm: error: {folder / 'thesis_comparison.csv'}: ") and err.count("\n") == 1, err
    assert says in err, err
    assert not (folder / "report").exists()


def test_an_intact_table_is_read(tmp_path):
    inputs = read([_write(tmp_path / "th", _rows())])
    assert len(inputs.studies[0].rows) == 2 * len(METRICS)


def test_a_table_without_its_calibrated_column_is_refused(tmp_path, capsys):
    _refused(_write(tmp_path / "th", _rows(), [c for c in COLUMNS if c != "calibrated"]),
             "has no 'calibrated' column", capsys)


@pytest.mark.parametrize("metric", ["TTrav", "FPS"])
def test_a_cell_without_a_metric_row_is_refused(tmp_path, capsys, metric):
    rows = [r for r in _rows() if not (r["mode"] == "pmap" and r["metric"] == metric)]
    _refused(_write(tmp_path / "th", rows), f"has no {metric} row for ring/pmap", capsys)


def test_a_row_twice_is_refused(tmp_path, capsys):
    rows = _rows()
    _refused(_write(tmp_path / "th", [*rows, rows[1]]), "repeats the TTrav row of ring/rcast (first on line 3)", capsys)


@pytest.mark.parametrize(("column", "value", "says"), [
    ("ours", "abc", "line 3: 'ours' is 'abc', not a finite number"),
    ("ours", "nan", "line 3: 'ours' is nan, not a finite number"),
    ("ours", "", "line 3: 'ours' is None, not a finite number"),
    ("thesis", "inf", "line 3: 'thesis' is inf, not a finite number or empty"),
    ("calibrated", "maybe", "line 3: 'calibrated' is 'maybe', not true or false"),
    ("calibrated", "", "line 3: 'calibrated' is None, not true or false"),
    ("metric", "TFoo", "line 3: 'metric' is 'TFoo', not a metric"),
    ("rel_error", "", "line 3: has a 'thesis' but an empty 'rel_error'"),
])
def test_a_value_of_the_wrong_kind_is_refused(tmp_path, capsys, column, value, says):
    rows = _rows()
    rows[1] = {**rows[1], column: value}
    _refused(_write(tmp_path / "th", rows), says, capsys)


def test_an_empty_table_or_one_without_rows_is_refused(tmp_path, capsys):
    _refused(_write(tmp_path / "header", []), "has a header but no rows", capsys)
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "thesis_comparison.csv").write_text("")
    _refused(empty, "is empty", capsys)


def test_summarize_names_no_slowest_pm_for_a_cell_without_every_pm():
    rows = [r for r in _rows() if not (r["mode"] == "pmap" and r["metric"] == "Tisct")]
    s = summarize(rows)
    assert list(s["slowest_pm"]) == ["ring/rcast"] and s["scene_modes"] == 1


def _run(scene: str, mode: str, fps: float, pipelines: int | None) -> Run:
    results = {"scene": {"name": scene}, "mode": mode, "fps": fps, "timing": {"units": {}}}
    if pipelines is not None:
        results["pipelines"] = [{"vertex": 1}] * pipelines
    return Run(Path(f"runs/{scene}-{mode}-{pipelines}"), f"{scene}/{mode}/{pipelines}", "run", results, {})


def test_how_fast_says_the_pipelines_of_its_runs(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    lead = summary_section(Inputs([], runs=[_run("ring", "rcast", 40.0, 4), _run("cornell", "pmap", 0.5, 4)]),
                           tmp_path / "a").lead
    assert "from 0.5 FPS (cornell PMap) to 40 FPS (ring RCast) at 4 pipelines." in lead
    assert "at one pipeline" not in lead
    lead = summary_section(Inputs([], runs=[_run("ring", "rcast", 40.0, 2), _run("cornell", "pmap", 0.5, None)]),
                           tmp_path / "b").lead
    assert "from 0.5 FPS (cornell PMap, 1 pipeline) to 40 FPS (ring RCast, 2 pipelines)." in lead


def test_a_second_run_of_a_scene_mode_is_said_not_dropped(tmp_path):
    runs = [_run("ring", "rcast", 40.0, 1), _run("ring", "rcast", 90.0, 4)]
    lead = summary_section(Inputs([], runs=runs), tmp_path).lead
    # (h530: two runs of one scene-mode are compared, both drawn, the second said against the first)
    assert "<b>How fast:</b> from 40 FPS (ring/rcast/1 RCast) to 90 FPS (ring/rcast/4 RCast)." in lead
    assert "<b>ring/rcast/4 against ring/rcast/1</b> (B/A): frame rate 2.25x (40 → 90 FPS)." in lead
