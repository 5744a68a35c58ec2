"""Error-vs-cost leftovers (task h287): a points value given twice is refused by ``tlm sweep``'s own check
(:func:`~tlm.experiments.sweep_factors.given_once`), and a point whose RMSE (or cost) is 0 or below 0, which a
log axis cannot show, is no longer dropped from the figure unsaid: a 0 is drawn at a floor a decade below the
least positive value (a dotted line in the key), a value below 0 is left off, and the caption names them."""

from __future__ import annotations

import html
import json
import re

import numpy as np
import pytest

import tlm.experiments.error_cost as ec
import tlm.report.tradeoff as tradeoff
from tests.helpers_figures import capture
from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.sweep_factors import given_once
from tlm.report.collect import Study

from .scenes import sphere_scene

# ---------------------------------------------------------------- 1. a value given twice: the sweep's one check


def test_a_points_value_given_twice_is_refused_by_the_sweeps_own_check(monkeypatch):
    calls = []

    def spy(grid, zipped, src):
        calls.append((grid, zipped, src))
        return given_once(grid, zipped, src)

    monkeypatch.setattr(ec, "given_once", spy)  # (the old code had its own loop: no such name to patch)
    with pytest.raises(InputError) as got:
        ec.expand([{"estimate.filter": ["disk"], "photons.count": [800, 800]}], "e.yaml")
    assert str(got.value) == "e.yaml: points[0].photons.count: 800 given twice"
    assert calls == [({"estimate.filter": ["disk"]}, {}, "e.yaml"), ({"photons.count": [800, 800]}, {}, "e.yaml")]
    with pytest.raises(InputError) as sweep:  # (the same words as a sweep's, the key the point's)
        given_once({"photons.count": [800, 800]}, {}, "e.yaml")
    assert got.value.message == sweep.value.message
    calls.clear()  # (its rule: 1 and 1.0 are two values; a list given twice is refused as a sweep's)
    assert len(ec.expand([{"estimate.k": [1, 1.0]}], "e.yaml")) == 2 and calls == [({"estimate.k": [1, 1.0]}, {},
                                                                                      "e.yaml")]
    with pytest.raises(InputError, match=r"^e\.yaml: points\[0\]\.photons\.aim_triangles: \[2, 3\] given twice$"):
        ec.expand([{"photons.aim_triangles": [[2, 3], [2, 3]]}], "e.yaml")


def test_the_helpers_rule_is_the_points_rule(monkeypatch):
    """What the helper refuses, error-vs-cost refuses (a rule changed there changes here too)."""
    def none_twice(grid, zipped, src):
        for key, values in grid.items():
            if len(values) > 1:
                raise InputError("two values", source=src, key=f"grid.{key}")

    monkeypatch.setattr(ec, "given_once", none_twice)
    with pytest.raises(InputError, match=r"^e\.yaml: points\[1\]\.estimate\.k: two values$"):
        ec.expand([{"photons.count": [800]}, {"estimate.k": [4, 8]}], "e.yaml")


# ---------------------------------------------------------------- 2. RMSE 0 or below 0 on a log axis


def _rows(rmse, cost=None, truth=None) -> list[dict]:
    cost = cost or [0.01 * (i + 1) for i in range(len(rmse))]
    return [{"point": i, "filter": "disk" if i % 2 == 0 else "mvoxel", "final_gather": 0, "photons": 100 * (i + 1),
             "rmse": e, "rel_mse": None if e is None else e * e, "frame_seconds": c / 10, "trace_seconds": c,
             "gather_seconds": 0.0, "one_off_seconds": 0.0, "truth_rmse": None if truth is None else truth[i],
             "truth_spp": None if truth is None else 1024, "reference_converged": True,
             "factors": f"photons.count={100 * (i + 1)}"} for i, (e, c) in enumerate(zip(rmse, cost, strict=True))]


def _study(tmp_path, rows) -> Study:
    ref = {"reference_converged": True, "converged": True}
    return Study("error-vs-cost", tmp_path / "evc", rows, {"reference": ref, "provenance": {"overrides": []}})


def _drawn(ax) -> np.ndarray:
    """Every point the axes' labelled series draw (not the ringed front's or the key's)."""
    parts = [c.get_offsets() for c in ax.collections if not str(c.get_label()).startswith("_")]
    return np.concatenate([np.asarray(p, dtype=float).reshape(-1, 2) for p in parts if len(p)])


def test_an_rmse_of_0_is_drawn_at_a_floor_and_one_below_0_is_named(tmp_path, monkeypatch):
    figs = capture(monkeypatch, tradeoff)
    rows = _rows([0.3, 0.0, -0.001, 0.009, 0.1])
    fig = tradeoff.evc_figure(_study(tmp_path, rows), tmp_path, "w.png", "wall", [], "evc")
    ax = figs[0].axes[0]
    assert ax.get_yscale() == "log"
    drawn = _drawn(ax)
    assert sorted(drawn[:, 1]) == pytest.approx([0.0009, 0.009, 0.1, 0.3])  # (the 0 at a tenth of 0.009)
    assert "Point 1 of rows.csv has an RMSE of 0, which a log axis cannot show: drawn at 0.0009" in fig.caption
    assert "Point 2 of rows.csv has an RMSE below 0 (-0.001), which a log axis cannot show: not drawn" in fig.caption
    assert fig.caption.startswith("4 points;")  # (those drawn)
    assert "RMSE 0, drawn at 0.0009" in [t.get_text() for t in ax.get_legend().get_texts()]
    front = [t.get_text() for t in ax.get_legend().get_texts() if re.match(r"\d+: ", t.get_text())]
    assert front == ["1: disk, 100 ph", "2: mvoxel, 200 ph"]  # (the 0 is on the front, and drawn)


def test_a_wall_time_of_0_is_drawn_at_a_floor(tmp_path, monkeypatch):
    figs = capture(monkeypatch, tradeoff)
    rows = _rows([0.3, 0.2, 0.1], cost=[0.0, 0.01, 0.5])
    fig = tradeoff.evc_figure(_study(tmp_path, rows), tmp_path, "w.png", "wall", [], "evc")
    ax = figs[0].axes[0]
    assert ax.get_xscale() == "log" and sorted(_drawn(ax)[:, 0]) == pytest.approx([0.001, 0.01, 0.5])
    assert "Point 0 of rows.csv has a host wall time of 0, which a log axis cannot show: drawn at 0.001" in fig.caption
    assert ax.get_yscale() == "linear" and "RMSE of 0" not in fig.caption  # (a linear axis draws its 0s as they are)
    fig = tradeoff.evc_figure(_study(tmp_path, _rows([0.3, 0.0, 0.2], cost=[0.0, 0.01, 0.5])), tmp_path, "z.png",
                              "wall", [], "evc")
    assert sorted(_drawn(figs[-1].axes[0])[:, 1]) == pytest.approx([0.0, 0.2, 0.3]) and "RMSE of 0" not in fig.caption


def test_the_truth_figure_draws_an_rmse_of_0_and_names_one_below_0(tmp_path, monkeypatch):
    figs = capture(monkeypatch, tradeoff)
    rows = _rows([0.3, 0.0, -0.001, 0.2], truth=[0.4, 0.3, 0.3, 0.0])
    fig = tradeoff.evc_truth_figure(_study(tmp_path, rows), tmp_path, "t.png", [], "evc")
    ax = figs[0].axes[0]
    assert ax.get_yscale() == "log"
    assert sorted(_drawn(ax)[:, 1]) == pytest.approx([0.02, 0.02, 0.2, 0.3, 0.3, 0.3, 0.4])  # (7: not the -0.001)
    for words in ("Point 3 of rows.csv has an RMSE against the ground truth of 0, which a log axis cannot show: "
                  "drawn at 0.02",
                  "Point 1 of rows.csv has an RMSE against our reference of 0",
                  "Point 2 of rows.csv has an RMSE against our reference below 0 (-0.001), which a log axis cannot "
                  "show: not drawn"):
        assert words in fig.caption


def test_a_small_study_s_page_says_which_points_are_off_the_log_axis(tmp_path, cache):
    """A real study (8x8, a few hundred photons), its rows.jsonl given an RMSE of 0 and one below 0 (which no
    photon frame of a lit scene gives, but a log axis must not lose unsaid), then ``tlm report``."""
    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "furnace.yaml", "resolution": [8, 8],
                 "reference": {"photons": 800, "k_nearest": 20, "tolerance": 0.9, "min_rounds": 2, "max_rounds": 4,
                               "spp": 1},
                 "estimate": {"final_gather": 0}},
        "points": [{"photons.count": [100, 200], "estimate.filter": ["disk", "mvoxel"]}]}))
    out = tmp_path / "out"
    assert main(["error-vs-cost", str(exp), "--out", str(out), "--truth-spp", "0", "--no-report"]) == 0
    rows = [json.loads(line) for line in (out / "rows.jsonl").read_text().splitlines()]
    rows[1]["rmse"], rows[2]["rmse"], rows[3]["rmse"] = 0.0, -0.001, rows[0]["rmse"] / 20
    (out / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert main(["report", str(out), "--no-progress"]) == 0
    page = html.unescape(re.sub(r"<[^>]+>", "", (out / "report" / "report.html").read_text()))
    page = " ".join(page.split())
    floor = f"{rows[3]['rmse'] / 10:.2g}"
    assert page.count(f"Point 1 of rows.csv has an RMSE of 0, which a log axis cannot show: drawn at {floor}") == 2
    assert page.count("Point 2 of rows.csv has an RMSE below 0 (-0.001), which a log axis cannot show: not "
                      "drawn") == 2  # (the frame-time figure and the wall-time one)
