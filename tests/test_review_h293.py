"""Review of d8acfde (h293): the error-vs-cost figures' values of 0 and below 0 on a log axis, finished.

- The summary's relative-MSE figure (summary_tradeoff.png): where no error is above 0 (every one 0, or
  below 0) its log error axis had nothing to draw and ``tlm report`` stopped with matplotlib's "Data cannot
  be log-scaled"; now the axis is linear and the caption says why. Its lead text quoted an error below 0 (or
  NaN, where the first row's was) as "the lowest error", and a frame time of 0, below 0 or NaN was drawn
  nowhere (or quoted "at nan s a frame") unsaid.
- The study's own figures: a point with an RMSE of 0 whose time is below 0 (not drawn) was said to be
  "drawn at" the floor; where rows lack ``point`` a point was named by its place among the rows drawn,
  not among all the rows; a least positive value of 5e-324 put the floor at 0, which no log axis draws.
- error-vs-cost's points: an error of the sweep's check is named by the point's key with its class kept.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

import tlm.experiments.error_cost as ec
import tlm.report.summary as summary
import tlm.report.tradeoff as tradeoff
from tests.helpers_figures import capture
from tlm.errors import InputError
from tlm.report.collect import Inputs, Study


def _rows(errors, frame=None, truth=None, cost=None) -> list[dict]:
    frame = frame or [0.01 * (i + 1) for i in range(len(errors))]
    cost = cost or [0.01 * (i + 1) for i in range(len(errors))]
    return [{"point": i, "filter": "disk" if i % 2 == 0 else "mvoxel", "final_gather": 0, "photons": 100 * (i + 1),
             "rmse": e, "rel_mse": e, "frame_seconds": f, "trace_seconds": c, "gather_seconds": 0.0,
             "one_off_seconds": 0.0, "truth_rmse": None if truth is None else truth[i],
             "truth_spp": None if truth is None else 1024, "reference_converged": True,
             "factors": f"photons.count={100 * (i + 1)}"}
            for i, (e, f, c) in enumerate(zip(errors, frame, cost, strict=True))]


def _study(tmp_path, rows) -> Study:
    return Study("error-vs-cost", tmp_path / "evc", rows,
                 {"reference": {"reference_converged": True, "converged": True}, "provenance": {"overrides": []}})


def _summary(tmp_path, monkeypatch, rows):
    figs = capture(monkeypatch, summary)
    text, fig = summary._tradeoff(Inputs([tmp_path], studies=[_study(tmp_path, rows)]), tmp_path)
    ax = figs[0].axes[0] if figs else None
    points = {ln.get_label(): list(zip(ln.get_xdata(), ln.get_ydata(), strict=True)) for ln in ax.get_lines()} \
        if ax else {}
    return text, fig, ax, points


# ---------------------------------------------------------------- the summary's figure and lead text


@pytest.mark.parametrize(("errors", "lowest"), [([0.0, 0.0, 0.0], "disk's, relative MSE 0 at 0.01 s"),
                                               ([0.0], "disk's, relative MSE 0 at 0.01 s"),
                                               ([-0.1, 0.0], "mvoxel's, relative MSE 0 at 0.02 s")])
def test_the_summary_draws_errors_none_above_0_on_a_linear_axis(tmp_path, monkeypatch, errors, lowest):
    """Before: every error 0 (or one, or 0 and below 0) left the log axis nothing to draw: ValueError."""
    text, fig, ax, points = _summary(tmp_path, monkeypatch, _rows(errors))
    assert ax.get_yscale() == "linear" and ax.get_xscale() == "log"
    assert sorted(y for pts in points.values() for _, y in pts) == sorted(errors)  # (each drawn as it is)
    assert fig.caption.endswith("; no error is above 0, which a log axis needs: the error axis is linear")
    assert "drawn at" not in fig.caption and "not drawn" not in fig.caption
    assert f"the lowest error is {lowest} a frame" in text


def test_the_summary_quotes_no_error_below_0_as_the_lowest(tmp_path, monkeypatch):
    """Before: ``the lowest error is mvoxel's, relative MSE -0.01`` (a point the figure does not draw)."""
    text, fig, ax, points = _summary(tmp_path, monkeypatch, _rows([0.3, -0.01, 0.02]))
    assert ax.get_yscale() == "log" and "mvoxel" not in points  # (its one point is below 0: no empty key entry)
    assert "the lowest error is disk's, relative MSE 0.02 at 0.03 s a frame against our reference (1 row with a " \
           "relative MSE below 0 or not a finite number left out)." in text
    assert "-0.01" not in text
    assert "; 1 with an error below 0, which a log axis cannot show: not drawn" in fig.caption
    text, fig, ax, points = _summary(tmp_path, monkeypatch, _rows([-0.1, -0.2]))
    assert text.startswith("<b>What quality costs:</b> none of the 2 error-against-cost rows has a relative MSE of "
                           "0 or above (-0.1, -0.2): no lowest error to quote")
    assert ax.get_yscale() == "linear" and sorted(y for pts in points.values() for _, y in pts) == [-0.2, -0.1]


@pytest.mark.parametrize("odd", [math.nan, math.inf])
def test_the_summary_quotes_no_nan_and_says_which_it_does_not_draw(tmp_path, monkeypatch, odd):
    """Before: a first row of NaN was "the lowest error" (``relative MSE nan``); NaN and inf were drawn nowhere
    unsaid, and listed among the series' best (``mvoxel inf``)."""
    text, fig, _, points = _summary(tmp_path, monkeypatch, _rows([odd, 0.3, 0.02]))
    assert "the lowest error is disk's, relative MSE 0.02 at 0.03 s a frame against our reference; mvoxel 0.3 at " \
           "0.02 s (1 row with a relative MSE below 0 or not a finite number left out)." in text
    assert "nan" not in text and "inf" not in text
    assert fig.caption.endswith("; 1 with an error that is not a finite number: not drawn")
    assert sorted(y for pts in points.values() for _, y in pts) == [0.02, 0.3]


@pytest.mark.parametrize("frame", [0.0, -0.01, math.nan])
def test_the_summary_says_a_row_with_no_frame_time_above_0_is_not_drawn(tmp_path, monkeypatch, frame):
    """Before: a frame time of 0 was left out unsaid, one below 0 or NaN drawn nowhere on the log axis and
    quoted (``relative MSE 0.1 at -0.01 s a frame``, ``at nan s``)."""
    text, fig, _, points = _summary(tmp_path, monkeypatch, _rows([0.1, 0.2], frame=[frame, 0.01]))
    assert fig.caption.endswith("; 1 with no simulated frame time above 0: not drawn")
    assert "the lowest error is mvoxel's, relative MSE 0.2 at 0.01 s a frame" in text
    assert list(points) == ["mvoxel"]


def test_the_summary_draws_an_error_of_0_at_the_floor_and_says_so(tmp_path, monkeypatch):
    """The patch's own claim (before it: the 0 was drawn nowhere, unsaid): at a tenth of the least positive."""
    text, fig, ax, points = _summary(tmp_path, monkeypatch, _rows([0.3, 0.0, 0.02]))
    assert ax.get_yscale() == "log" and points["mvoxel"] == [(20.0, pytest.approx(0.002))]  # (ms: h546)
    assert points["error 0, drawn at 0.002"] == [(0, 0.002), (1, 0.002)]  # (the dotted line, in the key)
    assert "; 1 of them with an error of 0, which a log axis cannot show: drawn at 0.002 (the dotted line)" \
        in fig.caption
    assert "the lowest error is mvoxel's, relative MSE 0 at 0.02 s a frame" in text


# ---------------------------------------------------------------- the study's own figures


def test_the_floor_is_a_decade_below_and_never_0():
    assert tradeoff.log_floor([1e-300, 0.0, 0.5]) == pytest.approx(1e-301)
    assert tradeoff.log_floor([0.0, -1.0, math.nan]) != tradeoff.log_floor([0.0, -1.0, math.nan])  # (NaN: none)
    assert tradeoff.log_floor([5e-324, 0.0]) == 5e-324  # (before: 0.0, where a log axis draws nothing)


def test_a_study_figure_draws_an_rmse_of_0_above_a_least_value_of_5e_324(tmp_path, monkeypatch):
    figs = capture(monkeypatch, tradeoff)
    fig = tradeoff.evc_figure(_study(tmp_path, _rows([5e-324, 0.0, 0.5])), tmp_path, "w.png", "wall", [], "evc")
    drawn = np.concatenate([np.asarray(c.get_offsets(), dtype=float).reshape(-1, 2)
                            for c in figs[0].axes[0].collections if not str(c.get_label()).startswith("_")])
    assert figs[0].axes[0].get_yscale() == "log" and (drawn[:, 1] > 0).all()
    assert "Point 1 of rows.csv has an RMSE of 0, which a log axis cannot show: drawn at 4.9e-324" in fig.caption


def test_a_0_whose_time_is_below_0_is_not_said_drawn_at_the_floor(tmp_path, monkeypatch):
    """Before: ``Point 0 ... has an RMSE of 0 ...: drawn at 0.01 (the dotted line)`` and ``Point 0 ... has a host
    wall time below 0 ...: not drawn``, the dotted line not there."""
    figs = capture(monkeypatch, tradeoff)
    rows = _rows([0.0, 0.1, 1.0, 0.5], cost=[-0.01, 0.01, 0.5, 0.2])
    fig = tradeoff.evc_figure(_study(tmp_path, rows), tmp_path, "w.png", "wall", [], "evc")
    assert "RMSE of 0" not in fig.caption
    assert "Point 0 of rows.csv has a host wall time below 0 (-0.01), which a log axis cannot show: not drawn." \
        in fig.caption
    assert not [t for t in figs[0].axes[0].get_legend().get_texts() if "drawn at" in t.get_text()]
    rows = _rows([-0.1, 0.1, 1.0], cost=[0.0, 0.01, 0.5])  # (a time of 0 whose RMSE is below 0: likewise)
    fig = tradeoff.evc_figure(_study(tmp_path, rows), tmp_path, "v.png", "wall", [], "evc")
    assert "host wall time of 0" not in fig.caption and "Point 0 of rows.csv has an RMSE below 0" in fig.caption


def test_the_truth_figure_says_no_0_drawn_where_its_time_is_not(tmp_path, monkeypatch):
    capture(monkeypatch, tradeoff)
    rows = _rows([0.3, 0.2, 0.1], truth=[0.0, 0.3, 0.4], cost=[-0.01, 0.01, 0.5])
    fig = tradeoff.evc_truth_figure(_study(tmp_path, rows), tmp_path, "t.png", [], "evc")
    assert "RMSE against the ground truth of 0" not in fig.caption
    assert "Point 0 of rows.csv has a host wall time below 0 (-0.01), which a log axis cannot show: not drawn." \
        in fig.caption


def test_rows_without_a_point_column_are_named_by_their_place_among_all_rows(tmp_path, monkeypatch):
    """Before: by their place among the rows drawn (a row with no RMSE before it: ``Point 0`` for the second)."""
    capture(monkeypatch, tradeoff)
    rows = _rows([math.nan, 0.0, 0.1, 1.0])
    for r in rows:
        del r["point"]
    fig = tradeoff.evc_figure(_study(tmp_path, rows), tmp_path, "w.png", "wall", [], "evc")
    assert re.search(r"\bPoint 1 of rows\.csv has an RMSE of 0\b", fig.caption) and "Point 0" not in fig.caption


# ---------------------------------------------------------------- error-vs-cost's points


def test_a_points_error_of_the_sweeps_check_keeps_its_class(monkeypatch):
    class Twice(InputError):
        pass

    def refuse(grid, zipped, src):
        raise Twice("800 given twice", source=src, key="grid.photons.count")

    monkeypatch.setattr(ec, "given_once", refuse)
    with pytest.raises(Twice) as got:
        ec.expand([{"photons.count": [800, 800]}], "e.yaml")
    assert str(got.value) == "e.yaml: points[0].photons.count: 800 given twice"


def test_a_study_with_no_frame_times_is_not_called_no_study(tmp_path, monkeypatch):
    """Before: an older study's rows (no ``frame_seconds``, no ``point``, no ``final_gather``) made the summary say
    "no error-against-cost study among the inputs: no error to show", beside that study's own figures."""
    rows = [{"filter": f, "photons": n, "rmse": e, "rel_mse": e * e, "trace_seconds": t, "gather_seconds": 0.01}
            for f, n, e, t in [("disk", 100, 0.0, 0.01), ("mvoxel", 200, 0.1, 0.2)]]
    text, fig = summary._tradeoff(Inputs([tmp_path], studies=[_study(tmp_path, rows)]), tmp_path)
    assert fig is None and "no error-against-cost study" not in text
    assert text.startswith("<b>What quality costs:</b> no row of the error-against-cost study among the inputs has "
                           "both a relative MSE and a simulated frame time above 0")
