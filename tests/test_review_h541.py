"""h541's review of 7bc2ced (tlm report A B), 10864fe (the sweep report's errors ranked within one reference) and
5a7e576: what the comparison said of a built-in scene against its own file, of a setting of the reference alone and
of two photon-map runs' image errors; the bottleneck's rows beside a thesis study; a sweep of one point; the factors
of a ``zip:`` that move with a part of the reference's key."""

from __future__ import annotations

import html
from pathlib import Path

from tests.test_report_compare_h530 import A_BUSY, A_CYCLES, B_BUSY, B_CYCLES, run
from tests.test_sweep_report_h531 import _sweep
from tlm.report.collect import Inputs, Study
from tlm.report.compare import differs, pair_line
from tlm.report.summary import _bottleneck
from tlm.report.summary_effects import ERROR, error_factor, sweep_findings

SOURCE = "/repo/scenes/cornell.yaml"
DIGEST = "sha256 4d54f82a31c7e696"


def _scene(r, source: str = SOURCE, digest: str = DIGEST):
    r.results["scene"] = {"name": "cornell", "source": source}
    r.results["scene_digest"] = digest
    return r


def test_a_builtin_scene_and_its_own_file_are_one_scene_not_a_difference(tmp_path):
    a = _scene(run("bi", A_CYCLES, A_BUSY))
    b = _scene(run("fi", A_CYCLES, A_BUSY, scene=SOURCE))
    assert differs(a, b) == [f"scene cornell → {SOURCE} (one scene file, the same contents)"]
    line = html.unescape(pair_line(a, b))
    assert line.endswith(f"What differs: scene cornell → {SOURCE} (one scene file, the same contents): the same run "
                         "twice."), line
    # (with another difference: one difference, not two whose joint effect the ratios are)
    c = _scene(run("fc", B_CYCLES, B_BUSY, pipelines=8, scene=SOURCE))
    line = html.unescape(pair_line(a, c))
    assert "arch.pipelines 4 → 8." in line and "joint effect" not in line, line
    # (another file of other contents stays a difference, counted)
    d = _scene(run("fd", B_CYCLES, B_BUSY, pipelines=8, scene="/x/cornell.yaml"), "/x/cornell.yaml", "sha256 1")
    line = html.unescape(pair_line(a, d))
    assert "same contents" not in line and "(3 differences: the ratios are their joint effect" in line, line


def test_a_setting_of_the_reference_alone_is_said_to_change_no_cycles(tmp_path):
    a = run("qA", A_CYCLES, A_BUSY, estimate__filter="mvoxel", reference__max_rounds=16)
    b = run("qC", B_CYCLES, B_BUSY, estimate__filter="kvoxel", reference__max_rounds=8)
    line = html.unescape(pair_line(a, b))
    assert ("What differs: estimate.filter mvoxel → kvoxel; reference.max_rounds 16 → 8 (the reference's: no "
            "cycles).") in line, line


def _error(r, rel_mse: float, reference: str):
    r.results["error"] = {"reference": reference, "rel_mse": rel_mse, "available": True}
    return r


def test_two_photon_map_runs_errors_are_compared_against_one_reference_only(tmp_path):
    a = _error(run("qA", A_CYCLES, A_BUSY, estimate__filter="mvoxel"), 0.024143886876247047, "97fce86dc0524170e6da")
    b = _error(run("qB", B_CYCLES, B_BUSY, estimate__filter="kvoxel"), 0.03198685894205169, "97fce86dc0524170e6da")
    d = _error(run("qD", B_CYCLES, B_BUSY, estimate__filter="kvoxel"), 0.031662383421428755, "4d7b4e19c83672c841de")
    assert "image error (relative MSE) 1.32x (0.0241 → 0.032, against one reference)" in html.unescape(pair_line(a, b))
    other = html.unescape(pair_line(a, d))
    assert ("image error (relative MSE) 0.0241 → 0.0317, against other references (results.json error.reference): "
            "not comparable") in other and "1.31x" not in other, other


def test_the_bottleneck_beside_a_thesis_study_counts_rows_not_runs(tmp_path):
    cell = run("ring", A_CYCLES, A_BUSY)
    cell.kind = "thesis"
    cell.results["scene"] = {"name": "ring"}
    a, b = run("cA", A_CYCLES, A_BUSY), run("cB", B_CYCLES, B_BUSY, pipelines=8)
    inputs = Inputs([], runs=[cell, a, b], studies=[Study("thesis", Path("th"), [], {})])
    text, _ = _bottleneck(inputs, tmp_path)
    assert "of 3 rows (the thesis study's scene-modes and the runs compared)" in text, text
    alone, _ = _bottleneck(Inputs([], runs=[a, b]), tmp_path)
    assert "in 2 of 2 runs" in alone, alone


def test_a_sweep_of_one_point_measures_no_factor():
    sw = _sweep({"arch.pipelines": [2]}, [{"arch.pipelines": 2, "fps": 414.2}], ["r"])
    (text,) = sweep_findings(Inputs([], sweeps=[sw]))
    assert "no factor changes" not in text, text
    assert text.endswith("its one point ok runs at 414 FPS; one point compares no factor's values, so no factor's "
                         "effect is measured."), text


def test_a_zipped_factor_is_not_said_to_be_part_of_the_references_key():
    sw = _sweep({}, [{"photons.count": 1000, "photons.max_bounces": 2, "fps": 22.65, ERROR: 0.01996},
                     {"photons.count": 3000, "photons.max_bounces": 8, "fps": 18.88, ERROR: 0.02414}],
                ["38fa6a9355ec1e3653a7", "97fce86dc0524170e6da"])
    sw.spec = {"zip": {"photons.count": [1000, 3000], "photons.max_bounces": [2, 8]}}
    quality = error_factor(Inputs([], sweeps=[sw]))
    assert "part of the reference's key" not in quality and "parts of the reference's key" not in quality, quality
    assert ("the reference changing with photons.count and photons.max_bounces, and errors against different "
            "references are not comparable") in quality, quality


def test_one_cycle_count_at_another_clock_is_no_tie_in_frame_rate(tmp_path):
    a = run("cA", A_CYCLES, A_BUSY)
    b = run("cK", A_CYCLES, A_BUSY, arch__clock_hz=720e6)
    b.results["fps"] = 720e6 / A_CYCLES["throughput"]
    line = html.unescape(pair_line(a, b))
    assert ("frame rate 1.2x (76.4 → 91.6 FPS)" in line and "the same throughput cycles: a tie in cycles, not in "
            "frame rate (1.2x: another clock). What differs: arch.clock_hz") in line, line
