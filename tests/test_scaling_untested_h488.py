"""Eq. 5.2's fit says when it tested nothing (h488): every point Vertex-bound (TThru = T_vert0 at every N, a small
image) gave A 1, B 0 and a "0.0%" error in the printout, eq52.json, the figure's legend and the report."""

from __future__ import annotations

import json

import pytest
import yaml

from tlm.cli import main
from tlm.experiments.scaling import fit, fit_both
from tlm.experiments.sweep import run_sweep
from tlm.report.scaling import error_text

V = 1_448_093  # (Cornell's T_vert0)
SUMS = {1: 530_000, 2: 540_000, 4: 558_000, 8: 593_000}  # (sum_i max(T_t,i, T_r,i, T_f,i) at each N)


def _points(thru):
    """Points of one group: T_vert0 V, TThru ``thru[n]``, latency twice that (two images in flight)."""
    return [{"pipelines": n, "T_vert0": V, "sum_max": s, "max_max": s / n, "throughput": thru[n],
             "latency": 2 * thru[n], "in_flight": 2, "scene": "cornell", "mode": "rcast", "scheduler": "static"}
            for n, s in SUMS.items()]


def test_every_point_vertex_bound_is_untested_and_says_why():
    pts = _points(dict.fromkeys(SUMS, V))
    for target in ("throughput", "latency"):
        f = fit_both(pts, target)
        assert f["B"] == 0 and f["max_abs_rel_error"] == 0  # (the fit itself is as it was: a 0.0% of no test)
        assert f["tested"] is False and f["slowest"]["tested"] is False
        assert "Vertex PM's T_vert0 (1,448,093 cycles) at every N" in f["why"] and "B is untested" in f["why"]
        assert "resolution" in f["why"] and f["slowest"]["why"] == f["why"]
        assert f["vertex_bound"] == [1, 2, 4, 8]


def test_a_flat_throughput_above_t_vert0_is_untested_too():
    f = fit_both(_points(dict.fromkeys(SUMS, V + 5000)), "throughput")
    assert f["tested"] is False and "Vertex" not in f["why"]
    assert f["why"].startswith("the simulated throughput is 1,453,093 cycles at every N, N = 1, 2, 4, 8")
    assert "vertex_bound" not in f


def test_a_partly_vertex_bound_group_is_fitted_and_names_its_vertex_bound_n():
    from tlm.experiments.scaling import untested_notes

    pts = _points({1: 2_000_000, 2: 1_600_000, 4: V, 8: V})
    fits = fit(pts)
    f = fits[("cornell", "rcast", "static", "throughput")]
    assert f["tested"] is True and "why" not in f and f["vertex_bound"] == [4, 8]
    assert f["max_abs_rel_error"] > 0
    lines = untested_notes(fits)
    assert lines == ["cornell/rcast/static: N = 4, 8 Vertex-bound (TThru is the Vertex PM's T_vert0): fitted all "
                     "the same, though there the pipelines' work shows in nothing"]


def test_untested_notes_name_the_fits_once_per_reason():
    from tlm.experiments.scaling import untested_notes

    fits = fit(_points(dict.fromkeys(SUMS, V)))
    lines = untested_notes(fits)
    assert len(lines) == 1
    assert lines[0].startswith("cornell/rcast/static latency, cornell/rcast/static throughput: eq. 5.2 untested: "
                               "every point's throughput is the Vertex PM's T_vert0")


def test_a_normal_fit_is_tested_and_shown_as_before():
    f = fit_both(_points({1: 2_000_000, 2: 1_800_000, 4: 1_700_000, 8: 1_650_000}), "throughput")
    assert f["tested"] is True and f["slowest"]["tested"] is True
    assert "why" not in f and "vertex_bound" not in f
    assert error_text(f) == f"{f['max_abs_rel_error']:.1%}"


def test_the_report_says_untested_not_0_percent():
    f = fit_both(_points(dict.fromkeys(SUMS, V)), "throughput")
    assert error_text(f, True) == "untested"
    assert error_text(f).startswith("untested (every point's throughput is the Vertex PM's T_vert0")
    assert "0.0%" not in error_text(f)
    slowest = {**f["slowest"], "rows": f["rows"]}
    assert error_text(slowest, True) == "untested"


def test_an_eq52_json_of_an_older_tlm_is_judged_from_its_rows():
    from tlm.report.scaling import judged

    f = fit_both(_points(dict.fromkeys(SUMS, V)), "latency")
    old = {k: v for k, v in f.items() if k not in ("tested", "why", "vertex_bound")}
    old["slowest"] = {k: v for k, v in f["slowest"].items() if k in ("A", "B", "max_abs_rel_error")}
    old.update(target="latency", latency_multiple=2, rows=[{k: r[k] for k in ("pipelines", "simulated", "T_vert0")}
                                                           for r in f["rows"]])
    new = judged(old)
    assert new["tested"] is False and "Vertex PM's T_vert0 (1,448,093 cycles)" in new["why"]
    assert error_text(new, True) == "untested" and new["slowest"]["tested"] is False
    normal = fit_both(_points({1: 2_000_000, 2: 1_800_000, 4: 1_700_000, 8: 1_650_000}), "throughput")
    normal = {k: v for k, v in normal.items() if k != "tested"}
    assert judged(normal) is normal


@pytest.mark.slow
def test_tlm_scaling_of_a_vertex_bound_sweep_says_untested(tmp_path, cache, capsys):
    """Cornell at 32x32 is Vertex-bound at every N (docs/architecture.md): the probe's case, small."""
    sweep = tmp_path / "scaling.yaml"
    sweep.write_text(yaml.safe_dump({
        "base": {"scene": "cornell", "mode": "rcast", "resolution": [32, 32],
                 "render": {"light_samples": 1, "spp": 1},
                 "arch": {"trace": False, "scheduler": "static"}},
        "grid": {"arch.pipelines": [1, 2, 4]},
    }))
    assert run_sweep(sweep, tmp_path / "sw", jobs=1).ok == 3
    capsys.readouterr()
    assert main(["scaling", str(tmp_path / "sw"), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    out, err = capsys.readouterr()
    assert "eq. 5.2 untested: every point's throughput is the Vertex PM's T_vert0" in err
    lines = [line for line in out.splitlines() if line.startswith("  cornell")]
    assert len(lines) == 2 and all("max |error| untested" in line and "0.0%" not in line for line in lines)
    meta = json.loads((tmp_path / "eq" / "eq52.json").read_text())
    assert all(f["tested"] is False and "B is untested" in f["why"] for f in meta["fits"])
    assert any("eq. 5.2 untested" in n for n in meta["notes"])
