"""A sweep's findings bound the values and points they name as tied (h408): of more than
:data:`~tlm.report.common.NAMED` tied values, how many and the first few (``49 of its 50 values, tied: 2, 3, 4,
5 and 45 more``), as the tied points are; and where every point runs at one frame rate, they say what else no
factor changes (a PM's cycles, the image error), or, where a factor moves a PM's cycles, name the factors that
change nothing at all."""

from __future__ import annotations

import html
from pathlib import Path

import pytest
import yaml

from tlm.report import summary
from tlm.report.collect import Inputs, Sweep
from tlm.report.summary import sweep_findings

VALUES = list(range(1, 51))
CYCLES = {"cycles.vertex": 1448093, "cycles.traversal": 121029, "cycles.intersection": 154708,
          "cycles.fragment": 19680, "cycles.throughput": 1448093, "cycles.latency": 2896186}


def _sweep(grid: dict, rows: list[dict]) -> Sweep:
    return Sweep(Path("sweeps/sw"), {"grid": grid},
                 [{"point": i, "hash": f"h{i}", "status": "ok", "error": None, **r} for i, r in enumerate(rows)], [])


def _finding(sw: Sweep) -> str:
    (text,) = sweep_findings(Inputs([], sweeps=[sw]))
    return text


def test_many_best_values_tied_are_counted_not_each_named():
    sw = _sweep({"arch.fifo_depth": VALUES}, [{"arch.fifo_depth": v, "fps": 2.0 if v > 1 else 1.0} for v in VALUES])
    text = _finding(sw)
    assert ("arch.fifo_depth moves the frame rate most, 2.00x between its best values (49 of its 50 values, tied: "
            "2, 3, 4, 5 and 45 more) and its worst (1), averaged over the other factors; ") in text, text
    assert ", 6," not in text and "49 and 50" not in text  # (it listed all 49)
    assert text.endswith("the best points, tied at 2 FPS, are arch.fifo_depth = 2, arch.fifo_depth = 3, "
                         "arch.fifo_depth = 4, arch.fifo_depth = 5 and 45 more.")
    # the worst tied alike; up to 8 tied values are each named, as before
    worst = _finding(_sweep({"arch.fifo_depth": VALUES},
                            [{"arch.fifo_depth": v, "fps": 1.0 if v > 1 else 2.0} for v in VALUES]))
    assert "between its best value (1) and its worst (49 of its 50 values, tied: 2, 3, 4, 5 and 45 more)" in worst
    eight = _finding(_sweep({"a": VALUES[:9]}, [{"a": v, "fps": 2.0 if v > 1 else 1.0} for v in VALUES[:9]]))
    assert "between its best values (2, 3, 4, 5, 6, 7, 8 and 9, tied) and its worst (1)" in eight


def test_an_image_errors_tied_values_are_counted_too():
    sw = _sweep({"arch.fifo_depth": VALUES},
                [{"arch.fifo_depth": v, "fps": 2.0, "error.rel_mse": 0.1 if v > 1 else 0.2} for v in VALUES])
    said = "relative MSE 0.2 at 1 → 0.1 at 49 of its 50 values, tied: 2, 3, 4, 5 and 45 more"
    text = _finding(sw)
    assert f"arch.fifo_depth changes the image error ({said}), not the frame rate" in text, text
    assert ", 6," not in text
    quality = summary._other_errors(Inputs([], sweeps=[sw]))
    assert quality.endswith(f" In sw, arch.fifo_depth moves the image error most: 2.00x, {said}."), quality


def test_a_tie_everywhere_says_the_cycles_and_the_error_do_not_change_either():
    rows = [{"arch.fifo_depth": v, "fps": 414.3, **CYCLES} for v in VALUES]
    assert _finding(_sweep({"arch.fifo_depth": VALUES}, rows)) == (
        "<b>Sweep sw</b> (50 of 50 points ok): no factor changes the frame rate or any PM's cycles: every point runs "
        "at 414 FPS.")
    measured = [{**r, "error.rel_mse": 0.0125} for r in rows]
    assert _finding(_sweep({"arch.fifo_depth": VALUES}, measured)).endswith(
        "no factor changes the frame rate, any PM's cycles or the image error: every point runs at 414 FPS with a "
        "relative MSE of 0.0125.")
    some = [{**r, "error.rel_mse": 0.0125} if r["arch.fifo_depth"] <= 10 else r for r in rows]
    assert _finding(_sweep({"arch.fifo_depth": VALUES}, some)).endswith(
        "every point runs at 414 FPS, and each of the 10 that measured its image error has a relative MSE of 0.0125.")
    # the points' errors differ: not said to be one
    apart = [{**r, "error.rel_mse": 0.01 * (r["arch.fifo_depth"] % 2 + 1)} for r in rows]
    assert "relative MSE of" not in _finding(_sweep({"arch.fifo_depth": VALUES}, apart))


def test_beside_a_factor_that_moves_cycles_one_that_changes_nothing_is_named():
    rows = [{"a": a, "b": b, "fps": 414.3, **CYCLES, "cycles.traversal": 110000 * (1 + a / 10)} for a in (1, 2)
            for b in VALUES]
    text = _finding(_sweep({"a": [1, 2], "b": VALUES}, rows))
    assert text == ("<b>Sweep sw</b> (100 of 100 points ok): no factor changes the frame rate: every point runs at "
                    "414 FPS; a keeps the frame rate between points that differ only in it, but moves TTrav (by up to "
                    "9.1%); b changes nothing between points that differ only in it."), text


@pytest.fixture
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def test_a_sweep_of_a_factor_that_changes_nothing_says_so_in_its_report(tmp_path, _own_cache):
    """End to end: 16x16 Cornell, ray cast, arch.fifo_depth over 12 values (the Vertex PM the bottleneck: the
    FIFO changes no cycle count)."""
    from tlm.api import run_sweep, write_report

    base = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
            "arch": {"trace": False}}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"arch.fifo_depth": list(range(1, 13))}}))
    done = run_sweep(path, tmp_path / "o", jobs=1)
    assert done.ok == 12 and len({r["cycles.throughput"] for r in done.rows}) == 1
    write_report([tmp_path / "o"], tmp_path / "r")
    page = html.unescape((tmp_path / "r" / "report.html").read_text())
    assert "(12 of 12 points ok): no factor changes the frame rate or any PM's cycles: every point runs at " in page
