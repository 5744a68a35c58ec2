"""Review of 72920ba and a97f344 (h492): a section's factor that sets only the exposure, and a factor figure's x
axis (tlm.report.sweep_lines.factor_axis).

72920ba said ``grid: {render.exposure: [1, 2]}`` changes nothing (a sweep writes no image), but the same factor
given as its section, ``grid: {render: [{exposure: 1}, {exposure: 2}]}``, was said nothing of: a section's factor
is now judged by the keys its values set (and so ``estimate: [{k: 4}, {k: 8}]`` under the m-voxel filter).

Points tied at the best frame rate that all have one image error were said to be chosen by it: "4 points tie as
the best at 5 FPS, the least image error (relative MSE 0.01) of the 4 points tied at that frame rate", as though
the error had told them apart; that error is now said as one point's is.

a97f344 took a log axis wherever a factor's values span 8x or more: evenly spaced values, ``arch.page_miss_cycles``
1, 2, ... 10 (linear up to 100x before it), were drawn on a log axis, crammed at the right and ticked 1, 2, 5 and
10 only. A log axis is now taken where the values are spaced by ratios at least as evenly as by differences. A
base-2 axis of more powers of two than are ticked each was labelled in mathtext powers (``2^{10}``), not numbers.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import yaml

from tests.test_sweep_report_h491 import _axis, _shown  # (a factor's figure drawn, its ticks)
from tlm.experiments.sweep_file import load_sweep
from tlm.report.collect import Inputs, Sweep
from tlm.report.summary_effects import sweep_findings


def test_a_section_factor_that_sets_only_the_exposure_is_said_to_change_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr("tlm.experiments.sweep_file.point_inputs", lambda *a, **k: {"functional": "f"})
    path = tmp_path / "s.yaml"
    base = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "arch": {"trace": False}}
    path.write_text(yaml.safe_dump({"base": base, "grid": {"render": [{"exposure": 1.0}, {"exposure": 2.0}]}}))
    assert load_sweep(path).inert_factors() == [
        f"{path}: the factor render (render.exposure) changes nothing in any point: a sweep writes no image, and the "
        "exposure scales only the pictures tlm run writes (not the work, the cycles or the radiance's errors)"]
    path.write_text(yaml.safe_dump({"base": base, "grid": {"render": [{"exposure": 1.0, "spp": 1},
                                                                      {"exposure": 2.0, "spp": 2}]}}))
    assert load_sweep(path).inert_factors() == []  # (spp is read)


def _sweep(factor: str, values: list, fps) -> Sweep:
    rows = [{"point": i, "status": "ok", factor: v, "fps": fps(v)} for i, v in enumerate(values)]
    return Sweep(Path("sw"), {"grid": {factor: values}}, rows, [])


def _finding(grid: dict, fps, error) -> str:
    rows = [{"point": i, "status": "ok", **dict(zip(grid, combo, strict=True)), "fps": fps(*combo),
             "error.rel_mse": error(*combo)} for i, combo in enumerate(itertools.product(*grid.values()))]
    (text,) = sweep_findings(Inputs([], sweeps=[Sweep(Path("sw"), {"grid": grid}, rows, [])]))
    return text


def test_tied_points_of_one_error_are_not_said_to_be_told_apart_by_it():
    text = _finding({"a": [1, 2, 3], "z": [1, 2]}, lambda a, z: 1.0 if a == 2 else 5.0, lambda a, z: 0.01)
    assert "points tied at that frame rate" not in text, text
    assert text.endswith("4 points tie as the best at 5 FPS, with the lowest image error (relative MSE 0.01): "
                         "a = 1 or 3, any z."), text
    text = _finding({"a": [1, 2, 3]}, lambda a: 1.0 if a == 2 else 5.0, lambda a: 0.05 if a != 2 else 0.01)
    assert text.endswith("the fastest points, tied at 5 FPS (relative MSE 0.05), are a = 1 and a = 3; the point of "
                         "the lowest image error (relative MSE 0.01) is a = 2 at 1 FPS."), text


def test_evenly_spaced_values_spanning_10x_keep_a_linear_axis_those_spaced_by_ratios_a_log_one(monkeypatch):
    values = list(range(1, 11))
    ax = _axis(monkeypatch, _sweep("arch.page_miss_cycles", values, lambda n: 500.0 - n), "arch.page_miss_cycles")
    assert ax.get_xscale() == "linear"
    assert _shown(ax) == [str(n) for n in values], _shown(ax)
    ax = _axis(monkeypatch, _sweep("arch.fifo_depth", [4, 8, 12, 16, 20, 24, 28, 32], lambda n: 400.0 + n),
               "arch.fifo_depth")
    assert ax.get_xscale() == "linear"
    for values in ([1, 12, 48], [16, 256, 4096], [10, 20, 40, 80, 160], [1, 64]):
        ax = _axis(monkeypatch, _sweep("arch.fifo_depth", values, lambda n: 400.0 + n), "arch.fifo_depth")
        assert ax.get_xscale() == "log", values


def test_many_powers_of_two_are_labelled_as_numbers(monkeypatch):
    values = [2 ** i for i in range(15)]  # (more than are ticked each: the locator's ticks)
    ax = _axis(monkeypatch, _sweep("arch.pipelines", values, lambda n: 100.0 + n ** 0.5), "arch.pipelines")
    assert ax.get_xscale() == "log"
    assert ax.xaxis.get_transform().base == 2
    shown = _shown(ax)
    assert shown and all(s.isdigit() for s in shown), shown
    assert "1024" in shown or "256" in shown, shown
