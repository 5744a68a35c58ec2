"""The summary says what a sweep's points show (h396, from probe h394): a factor whose image error is not
monotone over its values has each value's error said, not its worst and best as if one led to the other;
the point of the highest frame rate is "the fastest point" where a slower point has a lower image error,
and the point of the lowest error is named beside it."""

from __future__ import annotations

from pathlib import Path

from tlm.report import summary
from tlm.report.collect import Inputs, Sweep
from tlm.report.summary import sweep_findings


def _sweep(grid: dict, points: list[tuple]) -> Sweep:
    """A sweep of ``grid`` whose points are ``(*values, fps, rel_mse)`` (rel_mse None: not measured)."""
    rows = []
    for i, (*values, fps, err) in enumerate(points):
        row = {"point": i, "hash": f"h{i}", "status": "ok", "error": None, **dict(zip(grid, values, strict=True)),
               "fps": fps}
        if err is not None:
            row["error.rel_mse"] = err
        rows.append(row)
    return Sweep(Path("sweeps/sw"), {"grid": grid}, rows, [])


# the probe's sweep: 80,000 photons worse than 20,000 (the caustic's k = 8 on a glass sphere)
PROBE = _sweep({"photons.count": [5000, 20000, 80000]}, [(5000, 3.1, 0.104), (20000, 2.5, 0.031), (80000, 1.2, 0.062)])


def test_a_factor_whose_error_is_not_monotone_has_each_values_error_said():
    text = summary._other_errors(Inputs([], sweeps=[PROBE]))
    assert text.endswith(" In sw, photons.count moves the image error most: 3.35x, not monotone: relative MSE 0.104 at "
                         "5000, 0.031 at 20000, 0.062 at 80000."), text
    assert "→" not in text
    # one that falls all the way keeps its worst → best
    falls = _sweep({"photons.count": [5000, 20000, 80000]}, [(5000, 3.1, 0.104), (20000, 2.5, 0.062),
                                                             (80000, 1.2, 0.031)])
    assert summary._other_errors(Inputs([], sweeps=[falls])).endswith(
        " In sw, photons.count moves the image error most: 3.35x, relative MSE 0.104 at 5000 → 0.031 at 80000.")


def test_the_values_are_said_in_their_order_not_the_sweeps():
    sw = _sweep({"photons.count": [80000, 5000, 20000]}, [(80000, 1.2, 0.062), (5000, 3.1, 0.104),
                                                          (20000, 2.5, 0.031)])
    assert "not monotone: relative MSE 0.104 at 5000, 0.031 at 20000, 0.062 at 80000." in \
        summary._other_errors(Inputs([], sweeps=[sw]))
    # names have no order to break: worst → best
    names = _sweep({"estimate.filter": ["cone", "gauss", "box"]}, [("cone", 2.0, 0.1), ("gauss", 2.0, 0.02),
                                                                  ("box", 2.0, 0.05)])
    said = summary._other_errors(Inputs([], sweeps=[names]))
    assert "estimate.filter moves the image error most: 5.00x, relative MSE 0.1 at " in said and "→" in said
    assert "not monotone" not in said


def test_many_values_say_their_ends_and_extremes():
    errors = [0.05, 0.04, 0.01, 0.03, 0.035, 0.04, 0.09, 0.08]  # (lowest at 3, highest at 7 of 1..8)
    sw = _sweep({"estimate.radius_photons": list(range(1, 9))}, [(v, 2.0, e) for v, e in zip(range(1, 9), errors,
                                                                                             strict=True)])
    assert summary._other_errors(Inputs([], sweeps=[sw])).endswith(
        "estimate.radius_photons moves the image error most: 9.00x, not monotone over its 8 values: relative MSE 0.05 "
        "at 1, …, 0.01 at 3, …, 0.09 at 7, 0.08 at 8.")


def test_the_fastest_point_is_not_called_the_best_where_a_slower_one_has_less_error():
    (text,) = sweep_findings(Inputs([], sweeps=[PROBE]))
    assert "the best point" not in text
    assert text.endswith("the fastest point is photons.count = 5000 at 3.1 FPS (relative MSE 0.104); the point of the "
                         "lowest image error (relative MSE 0.031) is photons.count = 20000 at 2.5 FPS."), text


def test_the_fastest_point_of_the_lowest_error_is_the_best_and_says_so():
    sw = _sweep({"photons.count": [5000, 20000]}, [(5000, 3.1, 0.03), (20000, 2.5, 0.06)])
    (text,) = sweep_findings(Inputs([], sweeps=[sw]))
    assert text.endswith("the best point is photons.count = 5000 at 3.1 FPS, with the lowest image error (relative "
                         "MSE 0.03)."), text


def test_a_fastest_point_without_an_error_and_tied_lowest_points():
    sw = _sweep({"a": [1, 2], "b": [10, 20]}, [(1, 10, 5.0, 0.02), (1, 20, 4.0, 0.03), (2, 10, 3.0, 0.02),
                                               (2, 20, 9.0, None)])
    (text,) = sweep_findings(Inputs([], sweeps=[sw]))
    assert text.endswith("the fastest point is a = 2, b = 20 at 9 FPS; the points of the lowest image error (relative "
                         "MSE 0.02), tied, are (a = 1, b = 10) at 5 FPS and (a = 2, b = 10) at 3 FPS."), text


def test_a_factor_that_keeps_the_frame_rate_says_its_error_is_not_monotone():
    sw = _sweep({"estimate.radius_photons": [25, 100, 400]}, [(25, 2.0, 0.05), (100, 2.0, 0.01), (400, 2.0, 0.03)])
    (text,) = sweep_findings(Inputs([], sweeps=[sw]))
    assert ("estimate.radius_photons changes the image error (not monotone: relative MSE 0.05 at 25, 0.01 at 100, "
            "0.03 at 400), not the frame rate, between points that differ only in it; the best point is "
            "estimate.radius_photons = 100 at 2 FPS, the least image error (relative MSE 0.01) of the 3 points tied "
            "at that frame rate.") in text, text
