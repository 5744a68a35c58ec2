"""The sweep report's best point among ties, and its factor figures' axes (probe h484).

The summary deduplicated the points tied at the best frame rate by the factors that change nothing and named
each survivor at those factors' first values: 9 points of design_space tied at 411 FPS read as 3 points, each
"arch.fifo_depth = 16"; 12 of another sweep read as "the best point is ... packet_size = 1, fifo_depth = 1".
The tied points are now counted and the factors that vary among them said as "any". The figure of FPS against
arch.pipelines 1 to 64 had a linear axis (N = 1, 2, 4 crammed together), and one of ``bsp.levels [null, 7]``
was ticked 6.64 to 7.36.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from types import SimpleNamespace

from tlm.report.collect import Inputs, Sweep
from tlm.report.summary_effects import sweep_findings
from tlm.report.sweeps import factor_figure


def _sweep(grid: dict, fps, error=None) -> Sweep:
    keys = list(grid)
    rows = []
    for i, combo in enumerate(itertools.product(*grid.values())):
        row = {"point": i, "status": "ok", **dict(zip(keys, combo, strict=True)), "fps": fps(*combo)}
        if error is not None:
            row["error.rel_mse"] = error(*combo)
        rows.append(row)
    return Sweep(Path("sw"), {"grid": grid}, rows, [])


def _finding(sw: Sweep) -> str:
    (text,) = sweep_findings(Inputs([], sweeps=[sw]))
    return text


def test_points_tied_in_a_factor_that_changes_nothing_are_counted_and_said_as_any():
    """design_space's shape: fifo_depth changes nothing; at 7 levels cache.pairs does not matter either (it does
    at 5): 6 points tie, not 2 named at fifo_depth 16."""
    grid = {"bsp.levels": [5, 7], "cache.pairs": [1, 2, 4], "arch.fifo_depth": [16, 256]}
    text = _finding(_sweep(grid, lambda lv, pairs, fifo: 400.0 if lv == 7 else 250.0 + pairs))
    assert "arch.fifo_depth changes nothing between points that differ only in it; " in text
    assert text.endswith("6 points tie as the best at 400 FPS: bsp.levels = 7, any cache.pairs, "
                         "any arch.fifo_depth."), text


def test_a_single_best_point_of_many_tied_is_no_longer_named_at_the_first_values():
    """The other sweep: "the best point is bsp.levels = 7, arch.packet_size = 1, arch.fifo_depth = 1" of 12."""
    grid = {"bsp.levels": [7, 10], "arch.packet_size": [1, 16, 256], "arch.fifo_depth": [1, 16, 256, 4096]}
    text = _finding(_sweep(grid, lambda lv, size, fifo: 414.0 if lv == 7 else 229.0))
    assert "the best point is" not in text
    assert text.endswith("12 points tie as the best at 414 FPS: bsp.levels = 7, any arch.packet_size, "
                         "any arch.fifo_depth."), text


def test_the_tied_of_the_lowest_error_are_counted_too_and_values_not_all_said_by_name():
    """The fastest and the lowest error, each tied over a factor that changes nothing; a factor that takes some
    of its values among the tied is said by them ("b = 1 or 2"), one that takes all as "any"."""
    grid = {"n": [1, 2], "r": [25, 100, 400]}
    text = _finding(_sweep(grid, lambda n, r: 2.0 if n == 1 else 1.0, lambda n, r: 0.05 if n == 1 else 0.02))
    assert text.endswith("3 points tie as the fastest at 2 FPS (relative MSE 0.05): n = 1, any r; 3 points tie at "
                         "the lowest image error (relative MSE 0.02), at 1 FPS: n = 2, any r."), text
    grid = {"a": [1, 2], "b": [1, 2, 3], "c": [4, 8]}
    text = _finding(_sweep(grid, lambda a, b, c: 10.0 * a - 5.0 * (b == 3) * (a == 2)))
    assert text.endswith("4 points tie as the best at 20 FPS: a = 2, b = 1 or 2, any c."), text


def test_tied_points_that_are_not_every_combination_are_listed_each_counted():
    grid = {"a": [1, 2], "b": [1, 2], "c": [4, 8, 16]}
    text = _finding(_sweep(grid, lambda a, b, c: 10.0 if a == b else 2.0 * a + b))
    assert text.endswith("6 points tie as the best at 10 FPS: (3 points: a = 1, b = 1, any c) and "
                         "(3 points: a = 2, b = 2, any c)."), text


def _axis(monkeypatch, sw: Sweep, factor: str):
    figs = []
    monkeypatch.setattr("tlm.report.sweeps.save", lambda fig, *a, **k: figs.append(fig))
    factor_figure(sw, factor, Path("unused"), [])
    (fig,) = figs
    fig.canvas.draw()
    return fig.axes[0]


def _shown(ax) -> list[str]:
    lo, hi = ax.get_xlim()
    return [t.get_text() for t in ax.get_xticklabels() if lo <= t.get_position()[0] <= hi and t.get_text()]


def test_pipelines_over_powers_of_two_get_a_log2_axis_ticked_at_the_values(monkeypatch):
    ns = [1, 2, 4, 8, 16, 32, 64]
    ax = _axis(monkeypatch, _sweep({"arch.pipelines": ns}, lambda n: 100.0 * n ** 0.5), "arch.pipelines")
    assert ax.get_xscale() == "log"
    assert ax.xaxis.get_transform().base == 2
    assert _shown(ax) == [str(n) for n in ns]


def test_positive_values_spanning_8x_or_more_get_a_log_axis_ticked_at_the_values(monkeypatch):
    ax = _axis(monkeypatch, _sweep({"arch.pipelines": [1, 3, 5, 24]}, lambda n: 50.0 + n), "arch.pipelines")
    assert ax.get_xscale() == "log"
    assert _shown(ax) == ["1", "3", "5", "24"]


def test_levels_null_and_7_resolved_to_7_are_ticked_in_whole_numbers(monkeypatch):
    """bsp.levels [null, 7], null resolved to floor(ln n) = 7: every point at 7, the axis ticked 6.64 ... 7.36."""
    rows = [{"point": 0, "hash": "h0", "status": "ok", "bsp.levels": None, "fps": 410.0},
            {"point": 1, "hash": "h1", "status": "ok", "bsp.levels": 7, "fps": 411.0}]
    run = SimpleNamespace(path=Path("points/h0"), config={}, results={"scene": {"bsp": {"requested_levels": 7}}})
    sw = Sweep(Path("sw"), {"grid": {"bsp.levels": [None, 7]}}, rows, [run])
    ax = _axis(monkeypatch, sw, "bsp.levels")
    assert ax.get_xscale() == "linear"
    assert _shown(ax) == ["7"], _shown(ax)
