"""h542: an A/B in the API sees what ``tlm run`` and the report say.

``tlm.simulate``'s Timing has the simulated stream's ``warnings`` (the coarse-packet caveat among them), as
``tlm.run``'s dict and ``results.json`` have them; ``tlm.sweep``'s table has the report's findings on the sweep
(``attrs["findings"]``: the factor that moves the frame rate most, what moves with it); and ``sweep.csv`` has the
bottleneck's stall cycles per frame by cause and a few work counts (``bottleneck.*``, ``work.*``).
"""

from __future__ import annotations

import html
import json
import pickle
import re
from fractions import Fraction

import pandas as pd
import pytest
import yaml

import tlm
from tlm.experiments.run_warnings import stream_warnings
from tlm.experiments.sweep_rows import result_columns, result_fields

# Cornell refract 32x32 at packets of 256: packets move TThru by about 9% (tests/test_granularity_warning_honest.py)
COARSE = {"scene": "cornell", "mode": "refract", "resolution": [32, 32], "arch": {"trace": False, "packet_size": 256}}

NEW_COLUMNS = ["bottleneck.pm", "bottleneck.pipeline", "bottleneck.handshake", "bottleneck.swap", "bottleneck.copy",
               "bottleneck.preemption", "bottleneck.fifo_full", "bottleneck.fifo_empty", "bottleneck.memory",
               "work.rays", "work.tri_tests", "work.gathers"]


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def test_simulate_gives_the_streams_warnings_as_tlm_run_does(tmp_path):
    res = tlm.render_image(COARSE)
    timing = tlm.simulate(res)
    coarse = [w for w in timing.warnings if w.startswith("arch.packet_size = 256 is coarse for this frame")]
    assert len(coarse) == 1
    assert timing.warnings == stream_warnings(timing, res.cfg)  # (the run's own code, not a copy)
    fine = tlm.simulate(res, {"packet_size": 1})  # (the other side of an A/B: its own stream's lines)
    assert not [w for w in fine.warnings if w.startswith("arch.packet_size")]
    assert pickle.loads(pickle.dumps(timing)).warnings == timing.warnings
    # tlm.run's lines: the render's, then these
    said = tlm.run(COARSE, tmp_path / "run", outputs="images")["warnings"]
    assert said == [*res.warnings, *timing.warnings]


def _point(out, row) -> dict:
    return json.loads((out / "points" / row["hash"] / "results.json").read_text())


def test_a_sweeps_rows_carry_the_reports_findings_and_the_bottlenecks_stalls(tmp_path):
    spec = tmp_path / "ab.yaml"
    spec.write_text(yaml.safe_dump({"base": {"scene": "cornell", "mode": "rcast", "resolution": [48, 48],
                                             "render": {"spp": 1, "light_samples": 1}, "arch": {"trace": False}},
                                    "zip": {"arch.pipelines": [1, 4], "arch.fifo_depth": [8, 16]}}))
    out = tmp_path / "ab"
    rows = tlm.sweep(spec, out, jobs=1)
    (line,) = rows.attrs["findings"]
    # the factor that moves the frame rate most, and the one that moves with it (confounded), in plain text
    assert line.startswith("Sweep ab (2 of 2 points ok): arch.")
    assert "moves the frame rate most (with arch." in line and "which moves with it)" in line
    assert "<" not in line and "&" not in line
    from tlm.report.collect import read
    from tlm.report.summary_effects import sweep_findings

    (said,) = sweep_findings(read([out]))  # (the report's sentence, whose tags the line leaves out)
    assert line == html.unescape(re.sub(r"<[^>]+>", "", said))

    # sweep.csv: the new columns after the utilization, before functional_cached, as in the table
    csv = pd.read_csv(out / "sweep.csv", dtype={"hash": str})
    cols = list(csv.columns)
    at = cols.index("idle.fragment") + 1
    assert cols[at:at + len(NEW_COLUMNS)] == NEW_COLUMNS and cols[at + len(NEW_COLUMNS)] == "functional_cached"
    assert list(rows.columns) == cols
    for _, row in rows.iterrows():
        res = _point(out, row)
        timing, frames = res["timing"], res["timing"]["frames"]
        pm = timing["throughput_estimate"]["slowest_pm"]
        pipe = max(range(len(timing["pipelines"])), key=lambda p: (timing["pipelines"][p][pm], -p))
        unit = timing["units"][f"pipe{pipe}.{pm}"]
        assert (row["bottleneck.pm"], row["bottleneck.pipeline"]) == (pm, pipe)
        assert timing["pipelines"][pipe][pm] == res["cycles"][pm]  # (the PM's cycles are that pipeline's)
        for cause in ("handshake", "swap", "copy", "preemption", "fifo_full", "fifo_empty"):
            assert row[f"bottleneck.{cause}"] == round(Fraction(unit["stall"][cause], frames))
        assert row["bottleneck.memory"] == round(Fraction(unit["T_ms"], frames))
        rcast = res["work"]["rcast"]
        assert row["work.rays"] == rcast["primary_rays"] + rcast["secondary_rays"] + rcast["shadow_rays"] > 0
        assert row["work.tri_tests"] == rcast["tri_tests"] + rcast["shadow_tri_tests"] > 0
        assert row["work.gathers"] is None  # (no photon-map pass)
    assert csv["bottleneck.pm"].tolist() == rows["bottleneck.pm"].tolist()
    assert csv["work.rays"].tolist() == rows["work.rays"].tolist()


def _results(**timing) -> dict:
    units = {f"pipe{p}.{pm}": {"busy": 10, "stalled": 4, "idle": 6, "elapsed": 20} for p in (0, 1)
             for pm in ("traversal", "intersection")}
    return {"cycles": {"traversal": 5, "intersection": 9, "throughput": 9, "latency": 18}, "fps": 1.0,
            "timing": {"simpy_events": 3, "throughput_estimate": {}, "units": units, **timing},
            "functional": {"cached": False},
            "host_seconds": {"functional": 0.1, "simulate": 0.1, "one_off": 0.0, "write": 0.0}}


def test_the_bottleneck_is_the_pipeline_where_the_slowest_pm_costs_most():
    res = _results(throughput_estimate={"slowest_pm": "intersection"}, frames=4,
                   pipelines=[{"traversal": 5, "intersection": 7}, {"traversal": 4, "intersection": 9}])
    res["timing"]["units"]["pipe1.intersection"].update(
        stall={"handshake": 10, "swap": 2, "copy": 6, "preemption": 0, "fifo_full": 0, "fifo_empty": 14}, T_ms=9)
    res["work"] = {"direct": {"primary_rays": 100, "secondary_rays": 20, "shadow_rays": 50, "tri_tests": 700,
                              "shadow_tri_tests": 300},
                   "pmap": {"gathers": 80, "photons_tested": 4000}}
    row = result_fields(res)
    assert {k: row[k] for k in NEW_COLUMNS} == {
        "bottleneck.pm": "intersection", "bottleneck.pipeline": 1, "bottleneck.handshake": 2,  # (10/4: 2.5, to even)
        "bottleneck.swap": 0, "bottleneck.copy": 2, "bottleneck.preemption": 0, "bottleneck.fifo_full": 0,
        "bottleneck.fifo_empty": 4, "bottleneck.memory": 2, "work.rays": 170, "work.tri_tests": 1000,
        "work.gathers": 80}
    # a results.json of an older tlm (no slowest_pm, pipelines nor work): the columns, empty
    old = result_fields(_results())
    assert all(old[k] is None for k in NEW_COLUMNS)
    cols = result_columns()
    at = cols.index("idle.fragment") + 1
    assert cols[at:at + len(NEW_COLUMNS)] == NEW_COLUMNS and cols[at + len(NEW_COLUMNS)] == "functional_cached"
