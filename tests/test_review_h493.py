"""h493: review of 527cd7b (h489, a sweep folder's stale report) and 7505665 (h488, eq. 5.2's untested fits).

1. h489 keeps a sweep folder's report where the sweep and its points are unchanged and the report is newer than the
   rows (``sweep.jsonl``); but every rerun rewrites ``sweep.jsonl``, so the first ``--no-report`` rerun kept the
   report and the second removed it, a report of the very rows left. Rows rewritten unchanged now keep their time.
2. h488 called a fit of three or more N whose sum_i max(...) / N is the same at every N "untested" (B not
   determined, "the error measures that choice"), hiding its error; but there eq. 5.2 predicts the cycles at N = 1
   at every N whatever B is, so the error measures that prediction, not B's choice: a test, its error shown.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.cli_tables import _error
from tlm.experiments.scaling import fit, fit_both, untested_notes
from tlm.report.scaling import error_text

V = 1_448_093  # (Cornell's T_vert0)


@pytest.mark.slow
def test_reruns_of_an_unchanged_sweep_without_its_report_keep_the_report(tmp_path, cache):
    path = tmp_path / "r1.yaml"
    path.write_text(yaml.safe_dump({"base": "cornell", "grid": {"arch.fifo_depth": [16, 256]},
                                    "set": {"mode": "rcast", "render.spp": 1, "render.light_samples": 1,
                                            "resolution": [8, 8]}}))
    out = tmp_path / "X"
    run = ["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress"]
    assert main(run) == 0
    page = (out / "report" / "report.html").stat().st_ino
    for _ in range(3):  # (the old code: the second of these removed it)
        assert main([*run, "--no-report"]) == 0
        assert (out / "report" / "report.html").stat().st_ino == page
    path.write_text(path.read_text().replace("256", "1024"))  # (other points: the report is no longer of the rows)
    assert main([*run, "--no-report"]) == 0
    assert not (out / "report").exists()


def _points(thru: dict[int, int]) -> list[dict]:
    """One group whose slowest pipeline holds the same work at every N (max_max the same: its M(N) does not vary)."""
    return [{"pipelines": n, "T_vert0": V, "sum_max": 600_000 + 100_000 * n, "max_max": 700_000, "throughput": t,
             "latency": 2 * t, "in_flight": 2, "scene": "cornell", "mode": "rcast", "scheduler": "static"}
            for n, t in thru.items()]


def test_a_fit_whose_b_is_not_determined_is_a_test_of_its_prediction_all_the_same():
    pts = _points({1: 2_000_000, 2: 1_900_000, 4: 1_850_000, 8: 1_800_000})
    f = fit_both(pts, "throughput")
    s = f["slowest"]
    assert s["B"] == 1.0 and s["max_abs_rel_error"] > 0.1  # (T(1) at every N: 11% off at N = 8, whatever B)
    for b in (0.0, 1.0, 7.0):  # (the variant's prediction does not depend on B: the error is no measure of it)
        a = (2_000_000 - b * 700_000) / V
        assert {round(a * V + b * 700_000)} == {r["analytical_slowest"] for r in f["rows"]}
    assert s["tested"] is True and "the error measures that prediction" in s["why"]  # (old: tested false)
    assert error_text({**s, "rows": f["rows"]}, True) == f"{s['max_abs_rel_error']:.1%}"  # (old: 'untested')
    assert _error(s, f) == f"{s['max_abs_rel_error']:6.1%}"
    lines = untested_notes(fit(pts))
    assert any(line.startswith("cornell/rcast/static latency, cornell/rcast/static throughput: its "
                               "slowest-pipeline variant: sum_i max") for line in lines)
    assert not any("untested" in line for line in lines)
    f = fit_both(_points(dict.fromkeys((1, 2, 4, 8), V)), "throughput")  # (T the same too: nothing tested)
    assert f["slowest"]["tested"] is False and "Vertex PM's T_vert0" in f["slowest"]["why"]
    f = fit_both(_points({1: 2_000_000, 2: 1_900_000}), "throughput")  # (two values of N: a test of nothing)
    assert f["slowest"]["tested"] is False and f["tested"] is False


def test_rows_rewritten_unchanged_keep_their_time(tmp_path: Path):
    from tlm.experiments.sweep_folder import rows_dated

    (tmp_path / "report").mkdir()
    (tmp_path / "report" / "report.html").write_text("a report")
    rows = tmp_path / "sweep.jsonl"
    rows.write_text("{}\n")
    os.utime(rows, ns=(1, 1_000_000_000))
    with rows_dated(tmp_path):
        rows.write_text("{}\n")  # (the same bytes: the time they were first written kept)
    assert rows.stat().st_mtime_ns == 1_000_000_000
    with rows_dated(tmp_path):
        rows.write_text("{\"a\": 1}\n")  # (other rows: their own time)
    assert rows.stat().st_mtime_ns > 1_000_000_000
