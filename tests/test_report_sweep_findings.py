"""The report's sweep findings compare a factor's values like with like: a failed point
does not weigh one value's mean frame rate with other points than another's."""

from __future__ import annotations

from pathlib import Path

import pytest

from tlm.report.collect import Inputs, Sweep
from tlm.report.summary import sweep_findings

# a clock that scales the frame rate by 1e9 / 6e8 in every pair of points; a FIFO depth that changes nothing
BASE_FPS = {None: 2.6316391057149957, 20.0: 3.4824550374716225}
RADIUS = [None, None, None, None, 20.0, 20.0, 20.0, 20.0]
FIFO = [16, 1024, 16, 1024, 16, 1024, 16, 1024]
CLOCK = [600000000, 600000000, 1.0e9, 1.0e9, 600000000, 600000000, 1.0e9, 1.0e9]


def _zip_sweep(failed: set[int], events: list[int]) -> Sweep:
    spec = {"zip": {"estimate.radius": RADIUS, "arch.fifo_depth": FIFO, "arch.clock_hz": CLOCK,
                    "arch.max_events": events}}
    rows = []
    for i in range(8):
        row = {"point": i, "hash": f"{i:016x}", "estimate.radius": RADIUS[i], "arch.fifo_depth": FIFO[i],
               "arch.clock_hz": CLOCK[i], "arch.max_events": events[i]}
        if i in failed:
            row.update(status="failed", error="MaxEventsReached: the model cannot finish")
        else:
            row.update(status="ok", error=None, fps=BASE_FPS[RADIUS[i]] * CLOCK[i] / 6e8)
        rows.append(row)
    return Sweep(Path("sweeps/sw"), spec, rows, [])


BEST = ("2 points tie as the best at 5.8 FPS: estimate.radius = 20.0, any arch.fifo_depth, arch.clock_hz = "
        "1000000000.0, arch.max_events = 200000000.")


@pytest.mark.parametrize(("failed", "left"), [((5,), "1 of the 7"), ((0, 5), "2 of the 6")])
def test_a_failed_point_does_not_bias_the_factor_that_moves_the_frame_rate(failed, left):
    events = [200000000] * 8
    for i in failed:
        events[i] = 1000
    (text,) = sweep_findings(Inputs([], sweeps=[_zip_sweep(set(failed), events)]))
    assert text == (f"<b>Sweep sw</b> ({8 - len(failed)} of 8 points ok): arch.clock_hz moves the frame rate most, "
                    "1.67x between its best value (1000000000.0) and its worst (600000000), averaged over the other "
                    f"factors' values that finished with each of its values ({left} ok points left out for that); "
                    "arch.fifo_depth changes nothing between points that differ only in it; " + BEST)


def test_a_sweep_without_failures_keeps_its_plain_wording():
    (text,) = sweep_findings(Inputs([], sweeps=[_zip_sweep(set(), [200000000] * 8)]))
    assert text == ("<b>Sweep sw</b> (8 of 8 points ok): arch.clock_hz moves the frame rate most, 1.67x between its "
                    "best value (1000000000.0) and its worst (600000000), averaged over the other factors; "
                    "arch.fifo_depth changes nothing between points that differ only in it; " + BEST)


def test_a_grid_with_a_failed_point_compares_matched_points():
    """pipelines doubles the frame rate at every fifo; fifo changes nothing; (4, 8) failed."""
    rows = [{"status": "ok", "pipelines": p, "fifo": f, "fps": 10.0 * p} for p in (1, 2, 4) for f in (2, 8)
            if (p, f) != (4, 8)] + [{"status": "failed", "pipelines": 4, "fifo": 8}]
    sweep = Sweep(Path("pipes"), {"grid": {"pipelines": [1, 2, 4], "fifo": [2, 8]}}, rows, [])
    (text,) = sweep_findings(Inputs([], sweeps=[sweep]))
    # unmatched means would give fifo 1.56x (23.3 FPS over three points against 15 over two)
    assert text == ("<b>Sweep pipes</b> (5 of 6 points ok): pipelines moves the frame rate most, 4.00x between its "
                    "best value (4) and its worst (1), averaged over the other factors' values that finished with "
                    "each of its values (2 of the 5 ok points left out for that); fifo changes nothing between points "
                    "that differ only in it; the best point is pipelines = 4, fifo = 2 at 40 FPS.")


def test_factors_that_move_together_in_a_zip_are_named_together():
    rows = [{"status": "ok", "arch.pipelines": p, "arch.fifo_depth": f, "fps": 3.0 * p}
            for p, f in ((1, 4), (2, 8), (4, 16))]
    sweep = Sweep(Path("z"), {"zip": {"arch.pipelines": [1, 2, 4], "arch.fifo_depth": [4, 8, 16]}}, rows, [])
    (text,) = sweep_findings(Inputs([], sweeps=[sweep]))
    assert text == ("<b>Sweep z</b> (3 of 3 points ok): arch.pipelines moves the frame rate most (with "
                    "arch.fifo_depth, which moves with it), 4.00x between its best value (4) and its worst (1), "
                    "averaged over the other factors; the best point is arch.pipelines = 4, arch.fifo_depth = 16 "
                    "at 12 FPS.")
    # a failed zip point: its values are gone, the others are still compared
    rows[1] = {"status": "failed", "arch.pipelines": 2, "arch.fifo_depth": 8}
    (text,) = sweep_findings(Inputs([], sweeps=[sweep]))
    assert text.startswith("<b>Sweep z</b> (2 of 3 points ok): arch.pipelines moves the frame rate most (with "
                           "arch.fifo_depth, which moves with it), 4.00x between its best value (4) and its worst (1), "
                           "averaged over the other factors; ")


def test_a_factor_with_no_matched_points_is_not_ranked():
    """(2, 10) and (1, 20) failed: no value of b finished with both values of a, nor the other way round."""
    rows = [{"status": "ok", "a": 1, "b": 10, "fps": 1.0}, {"status": "ok", "a": 2, "b": 20, "fps": 5.0},
            {"status": "failed", "a": 2, "b": 10}, {"status": "failed", "a": 1, "b": 20}]
    sweep = Sweep(Path("ab"), {"grid": {"a": [1, 2], "b": [10, 20]}}, rows, [])
    (text,) = sweep_findings(Inputs([], sweeps=[sweep]))
    assert text == ("<b>Sweep ab</b> (2 of 4 points ok): a, b cannot be compared like with like (no values of the "
                    "other factors finished with each of their values); the best point is a = 2, b = 20 at 5 FPS.")


def test_a_factor_is_said_to_change_nothing_only_where_no_pair_of_its_points_differs():
    """a ties at b = 10 (the one combination that finished with all its values) but not at
    b = 20, where (3, 20) failed: a changes the frame rate there, so it is not said to change nothing."""
    rows = [{"status": "ok", "a": a, "b": 10, "fps": 4.0} for a in (1, 2, 3)] + [
        {"status": "ok", "a": 1, "b": 20, "fps": 5.0}, {"status": "ok", "a": 2, "b": 20, "fps": 7.0},
        {"status": "failed", "a": 3, "b": 20}]
    sweep = Sweep(Path("g"), {"grid": {"a": [1, 2, 3], "b": [10, 20]}}, rows, [])
    (text,) = sweep_findings(Inputs([], sweeps=[sweep]))
    assert text == ("<b>Sweep g</b> (5 of 6 points ok): b moves the frame rate most, 1.50x between its best value "
                    "(20) and its worst (10), averaged over the other factors' values that finished with each of its "
                    "values (1 of the 5 ok points left out for that); the best point is a = 2, b = 20 at 7 FPS.")
