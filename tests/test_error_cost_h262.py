"""Error-vs-cost findings of a probe (h262): a log axis over less than a decade (frame times of
0.15 to 0.33 s) got eight long labels that ran into each other; a cached ground truth was thrown
away where Mitsuba could not be imported (and all of it where flip-evaluator could not); the
ground-truth line read like a past event before minutes of computing; the progress line did not
say which error is against what; one filter series was "lowest in 3 of 3"; a point list that
repeats a value wrote two identical rows."""

from __future__ import annotations

import html
import itertools
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from tests.helpers_figures import capture
from tests.test_installed_copy_leftovers import _run, _study
from tlm.errors import InputError
from tlm.experiments import error_cost as ec
from tlm.report import common
from tlm.report import summary as summary_mod
from tlm.report.collect import Inputs, Study
from tlm.report.summary import summary_section

# (lo, hi) of the data: narrow (a fraction of a decade, down to a hundredth of one), about a decade, and wide
RANGES = [(0.145, 0.34), (0.011, 0.019), (0.9, 1.1), (0.00123, 0.00129), (3.0, 30.0), (0.2, 0.8),
          (1.6e3, 4.2e4), (2e5, 3e6), (1e-3, 1e3), (1e-12, 1e12), (0.0061, 0.0142)]


def _drawn_labels(fig: Figure, ax, axis: str) -> list:
    """The window boxes of the tick labels ``axis`` draws (visible, with text, within the view), in order."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    a = ax.xaxis if axis == "x" else ax.yaxis
    lo, hi = sorted(ax.get_xlim() if axis == "x" else ax.get_ylim())
    at = 0 if axis == "x" else 1
    labels = [t for t in a.get_majorticklabels() + a.get_minorticklabels()
              if t.get_visible() and t.get_text() and lo * (1 - 1e-9) <= t.get_position()[at] <= hi * (1 + 1e-9)]
    return sorted((t.get_window_extent(renderer) for t in labels), key=lambda b: b.x0 if axis == "x" else b.y0)


def _apart(boxes: list, axis: str) -> bool:
    return all((a.x1 <= b.x0) if axis == "x" else (a.y1 <= b.y0) for a, b in itertools.pairwise(boxes))


@pytest.mark.parametrize("size", [(5.4, 3.1), (3.2, 2.4)])
@pytest.mark.parametrize("axis", ["x", "y"])
def test_log_ticks_labels_never_run_into_each_other_and_are_at_least_two(size, axis):
    bad = []
    for lo, hi in RANGES:
        fig = Figure(figsize=size, layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        data = np.geomspace(lo, hi, 12)
        if axis == "x":
            ax.plot(data, np.linspace(0, 1, 12), "o")
            ax.set_xscale("log")
        else:
            ax.plot(np.linspace(0, 1, 12), data, "o")
            ax.set_yscale("log")
        common.log_ticks(ax, axis)
        boxes = _drawn_labels(fig, ax, axis)
        if len(boxes) < 2 or not _apart(boxes, axis):
            bad.append((lo, hi, len(boxes), [(round(b.x0), round(b.x1), round(b.y0), round(b.y1)) for b in boxes]))
    assert not bad, bad


def test_the_summary_tradeoff_figure_of_frame_times_under_a_decade_has_labels_apart(tmp_path, monkeypatch):
    """The probe's study: frame times 0.15 to 0.33 s gave 1.5x10^-1, 1.75x10^-1, ..., 3.25x10^-1, overlapping."""
    rows = [{"filter": f, "final_gather": 0, "photons": 5000 * 4**i, "rel_mse": e, "truth_rel_mse": t,
             "frame_seconds": s} for i, (f, e, t, s) in enumerate((
                 ("disk", 0.174, 0.0140, 0.226), ("disk", 0.0431, 0.00827, 0.248), ("disk", 0.0187, 0.00643, 0.332),
                 ("knn", 0.0506, 0.0142, 0.151), ("knn", 0.0301, 0.00795, 0.274)))]
    figs = capture(monkeypatch, summary_mod)
    summary_section(Inputs([], studies=[Study("error-vs-cost", tmp_path / "ec", rows)]), tmp_path)
    fig = figs[-1]
    (ax,) = fig.axes
    for axis in ("x", "y"):
        boxes = _drawn_labels(fig, ax, axis)
        assert len(boxes) >= 2 and _apart(boxes, axis), (axis, [(b.x0, b.x1, b.y0, b.y1) for b in boxes])


def test_a_cached_ground_truth_is_used_without_mitsuba(tmp_path, monkeypatch, capsys):
    pytest.importorskip("mitsuba")
    exp = _study(tmp_path)
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    assert _run(exp, tmp_path / "first", truth_spp=1) == 0
    out = capsys.readouterr().out
    (computing,) = [line for line in out.splitlines() if "the ground truth" in line]  # (said before it is computed)
    assert computing.startswith("error-vs-cost: computing the ground truth (not cached): Mitsuba 3 path tracer, "
                                "1 spp;"), computing
    assert "this may take minutes" in computing and "it is then cached" in computing
    first = json.loads((tmp_path / "first" / "rows.jsonl").read_text().splitlines()[0])
    assert first["truth_rel_mse"] is not None and first["truth_flip"] is not None

    monkeypatch.setitem(sys.modules, "mitsuba", None)  # (import mitsuba: ImportError)
    assert _run(exp, tmp_path / "again", truth_spp=1) == 0
    out = capsys.readouterr().out
    assert "no ground truth" not in out
    (found,) = [line for line in out.splitlines() if "ground truth" in line]
    assert found == (f"error-vs-cost: ground truth: Mitsuba 3 path tracer, 1 spp, found cached in "
                     f"{tmp_path / 'cache' / 'oracle'}"), found
    again = json.loads((tmp_path / "again" / "rows.jsonl").read_text().splitlines()[0])
    assert {k: again[k] for k in ("truth_rmse", "truth_rel_mse", "truth_flip", "truth_spp")} == \
        {k: first[k] for k in ("truth_rmse", "truth_rel_mse", "truth_flip", "truth_spp")}

    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "empty"))  # (none cached, no Mitsuba: no ground truth, said why)
    assert _run(exp, tmp_path / "none", truth_spp=1) == 0
    (line,) = [line for line in capsys.readouterr().out.splitlines() if "ground truth" in line]
    assert "no ground truth:" in line and "needs the optional package mitsuba" in line and "none is cached" in line


def test_without_flip_evaluator_the_other_truth_columns_are_filled_and_the_line_says_which_is_not(
        tmp_path, monkeypatch):
    pytest.importorskip("mitsuba")
    exp = _study(tmp_path)
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    monkeypatch.setitem(sys.modules, "flip_evaluator", None)
    notes: list[str] = []
    rows = ec.run_error_vs_cost(exp, tmp_path / "out", truth=ec.Truth(spp=1), note=notes.append,
                                warned=lambda line: None)
    (row,) = rows
    assert row["truth_rmse"] is not None and row["truth_rel_mse"] is not None and row["truth_flip"] is None
    (line,) = [n for n in notes if "truth_flip" in n]
    assert line.startswith("the truth_flip column is empty: FLIP needs the optional package flip-evaluator"), line
    truth = json.loads((tmp_path / "out" / "truth.json").read_text())
    assert truth["available"] is True and "flip-evaluator" in truth["flip_missing"]


def test_one_series_over_seeds_is_not_said_to_win(tmp_path):
    rows = [{"filter": "disk", "rel_mse": e, "frame_seconds": 0.1, "factors": f"estimate.filter=disk; seed={s}"}
            for s, e in ((0, 0.04), (1, 0.05), (2, 0.045))]
    lead = html.unescape(summary_section(Inputs([], studies=[Study("error-vs-cost", tmp_path / "ec", rows)]),
                                         tmp_path).lead)
    assert "lowest in" not in lead, lead
    assert "disk: mean 0.045 (0.04-0.05) over 3 seeds" in lead, lead
    two = rows + [{**r, "filter": "mvoxel", "rel_mse": r["rel_mse"] * 1.1,
                   "factors": r["factors"].replace("disk", "mvoxel")} for r in rows]
    lead = html.unescape(summary_section(Inputs([], studies=[Study("error-vs-cost", tmp_path / "ec", two)]),
                                         tmp_path).lead)
    assert "disk: lowest in 3 of 3" in lead and "mvoxel: lowest in 0 of 3" in lead, lead


@pytest.mark.parametrize("points, message", [
    ([{"photons.count": [800, 800]}], "points[0].photons.count: 800 given twice"),
    ([{"photons.count": [800]}, {"photons.count": [800]}], "points: {photons.count=800} given twice"),
    ([{"photons.count": [800]}, {"estimate.filter": ["disk"]}],
     "points: {photons.count=800} and {estimate.filter=disk} are one point (one config)"),
])
def test_a_point_given_twice_is_refused_before_any_work(tmp_path, monkeypatch, capsys, points, message):
    exp = _study(tmp_path)
    doc = json.loads(exp.read_text())
    doc["base"]["estimate"]["filter"] = "disk"
    doc["points"] = points
    exp.write_text(json.dumps(doc))
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(ec, "compute_reference", lambda *a, **k: pytest.fail("worked before the check"))
    with pytest.raises(InputError, match=message.replace("[", r"\[").replace("{", r"\{").replace("(", r"\(")
                       .replace(")", r"\)")):
        ec.load_experiment(exp)
    assert _run(exp, tmp_path / "out") == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err
    assert not Path(tmp_path / "out").exists()


def test_the_cli_progress_line_says_what_each_error_is_against_and_takes_no_flip(tmp_path, monkeypatch, capsys):
    """The study's progress line says which error is against tlm's reference and which against Mitsuba, and
    prints no FLIP where flip-evaluator is missing (it raised a TypeError formatting None)."""
    pytest.importorskip("mitsuba")
    exp = _study(tmp_path)
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    assert _run(exp, tmp_path / "first", truth_spp=1) == 0
    (line,) = [x for x in capsys.readouterr().out.splitlines() if "[  1/1]" in x]
    assert " vs reference (composite vs Mitsuba " in line and ", FLIP " in line, line
    monkeypatch.setitem(sys.modules, "flip_evaluator", None)
    assert _run(exp, tmp_path / "again", truth_spp=1) == 0  # (truth_flip empty: no TypeError formatting it)
    (line,) = [x for x in capsys.readouterr().out.splitlines() if "[  1/1]" in x]
    assert " vs reference (composite vs Mitsuba " in line and "FLIP" not in line, line
