"""A sweep report's best point and warning count, read honestly (h509, from the timing-model probe h498).

A sweep's finding named ``arch.swap_cycles = 50`` in its best point at 102.03 FPS beside the same point with
swaps of 2 at 101.84 FPS, 0.18% apart: it read as "slower swaps are better". Points within 1% of the highest
frame rate (:data:`~tlm.report.summary_effects.NEAR_TIE`: the share by which the model lets a steady stream's
estimate move) are said to tie with it, the tolerance in the line, the factors that do not part them as ``any``,
as an exact tie says them; an exact tie keeps its words. The warnings box said "144 of the 144 runs recorded 89
warnings" where 89 counted different lines and each run recorded one or more: it says "89 different warnings".
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from tlm.report.collect import Inputs, Sweep
from tlm.report.summary import sweep_findings
from tlm.report.warnings import warnings_html


def _finding(grid: dict, rows: list[dict]) -> str:
    sw = Sweep(Path("sweeps/sw"), {"grid": grid},
               [{"point": i, "hash": f"h{i}", "status": "ok", "error": None, **r} for i, r in enumerate(rows)], [])
    (text,) = sweep_findings(Inputs([], sweeps=[sw]))
    return text


def test_the_tolerance_is_the_models_steady_bound():
    from tlm.arch.steady import STEADY_SPREAD
    from tlm.report.summary_effects import NEAR_TIE

    assert NEAR_TIE == STEADY_SPREAD == 0.01


def test_points_within_one_percent_of_the_best_tie_with_it():
    """The probe's case: swaps of 50 at 102.03 FPS, of 2 at 101.84; the other pipelines far below. An exact tie
    keeps its words, and a point 1.1% below the best is not tied with it."""
    fps = {(8, 50): 102.03, (8, 2): 101.84, (2, 50): 40.0, (2, 2): 40.5}
    text = _finding({"arch.pipelines": [2, 8], "arch.swap_cycles": [2, 50]},
                    [{"arch.pipelines": p, "arch.swap_cycles": s, "fps": fps[p, s]} for p in (2, 8) for s in (2, 50)])
    assert text.endswith("2 points tie within 1% as the best, at 101.8 to 102.0 FPS: arch.pipelines = 8, "
                         "any arch.swap_cycles."), text
    assert "the best point is" not in text and "arch.swap_cycles = 50" not in text
    rows = [{"bsp.levels": b, "arch.fifo_depth": f, "fps": 411.0 if b == 7 else 300.0} for b in (5, 7) for f in (4, 8)]
    exact = _finding({"bsp.levels": [5, 7], "arch.fifo_depth": [4, 8]}, rows)
    assert exact.endswith("2 points tie as the best at 411 FPS: bsp.levels = 7, any arch.fifo_depth."), exact
    assert "within" not in exact
    apart = _finding({"arch.swap_cycles": [2, 50]},
                     [{"arch.swap_cycles": 2, "fps": 100.0}, {"arch.swap_cycles": 50, "fps": 98.9}])  # (1.1% apart)
    assert apart.endswith("the best point is arch.swap_cycles = 2 at 100 FPS."), apart


def test_many_near_points_not_of_every_combination_say_how_many_of_them():
    """Of more near points than are named one by one, the factors that do not part them at once (``any``) and how
    many of their combinations are near; of few, each with its frame rate."""
    fps = {(1, 2): 100.0, (1, 50): 99.5, (2, 2): 99.2, (2, 50): 95.0, (4, 2): 99.9, (4, 50): 99.4, (8, 2): 99.3,
           (8, 50): 99.1, (16, 2): 90.0, (16, 50): 99.6}
    rows = [{"arch.copy_words_per_cycle": w, "arch.swap_cycles": s, "fps": f} for (w, s), f in fps.items()]
    text = _finding({"arch.copy_words_per_cycle": [1, 2, 4, 8, 16], "arch.swap_cycles": [2, 50]}, rows)
    assert text.endswith("8 points tie within 1% as the best, at 99.1 to 100 FPS: any arch.copy_words_per_cycle, "
                         "any arch.swap_cycles (8 of the 10 combinations of these values)."), text
    few = _finding({"a": [1, 2], "b": [1, 2]}, [{"a": 1, "b": 1, "fps": 50.0}, {"a": 1, "b": 2, "fps": 10.0},
                                               {"a": 2, "b": 1, "fps": 10.0}, {"a": 2, "b": 2, "fps": 49.8}])
    assert few.endswith("2 points tie within 1% as the best, at 49.8 to 50.0 FPS: (a = 1, b = 1) at 50 FPS and "
                        "(a = 2, b = 2) at 49.8 FPS."), few


def test_the_least_image_error_decides_among_points_near_the_best():
    """As among points at one frame rate: the slower of two near points has the lower error, and is the best."""
    rows = [{"render.spp": 1, "fps": 102.0, "error.rel_mse": 0.2},
            {"render.spp": 2, "fps": 101.5, "error.rel_mse": 0.1},
            {"render.spp": 4, "fps": 60.0, "error.rel_mse": 0.05}]
    text = _finding({"render.spp": [1, 2, 4]}, rows)
    assert ("the fastest point is render.spp = 2 at 101.5 FPS, the least image error (relative MSE 0.1) of the 2 "
            "points within 1% of the highest frame rate (102 FPS); the point of the lowest image error (relative MSE "
            "0.05) is render.spp = 4 at 60 FPS.") in text, text


def _box(said: list[list[str]]) -> str:
    runs = [SimpleNamespace(label=f"p{i}", results={"warnings": lines}) for i, lines in enumerate(said)]
    return warnings_html(SimpleNamespace(runs=runs, damaged=[]))


def test_the_warnings_count_says_different_lines_and_all_of_them():
    page = _box([["coarse packets", "a period of 15"], ["coarse packets"], ["coarse packets", "not settled"]])
    assert ("3 of the 3 runs recorded 3 different warnings (results.json <code>warnings</code>; 5 in all);"
            in page), page
    same = _box([["coarse packets"], ["coarse packets"], []])
    assert "2 of the 3 runs recorded 1 warning, the same in each (results.json <code>warnings</code>);" in same, same
    each = _box([["coarse packets"], ["not settled"]])  # (each line by one run: the count is of warnings)
    assert "2 of the 2 runs recorded 2 warnings (results.json <code>warnings</code>);" in each, each
