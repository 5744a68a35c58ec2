"""The timing model's knobs at their extremes (probe h203): maxima that keep the model's cycles
within int64, a clock of at least 1 Hz, a clear error rather than a wrapped count past int64,
no null timestamp in a trace, an idle row for every unit, and the thesis study's slowest-PM
count qualified as its median is."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from tlm.arch.frame_program import FrameProgram, JobSpec, PhaseSpec, Stage, Tile
from tlm.arch.granularity import flow_shop, ti_cycles
from tlm.arch.model import simulate_program
from tlm.arch.units import Trace
from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.experiments.thesis import summarize

CYCLE_KNOBS = ("page_miss_cycles", "flush_cycles", "swap_cycles", "context_switch_cycles")


def _arch(**arch):
    return config_from_dict({"arch": {"frames": 1, "images_in_flight": 1, **arch}}, "test.yaml").arch


def _job(pm, role, norm, misses=0, flushes=0, n=4):
    full = np.full(n, 1, dtype=np.int64)
    return JobSpec(pm, "test", role, full * norm, full * misses, full * flushes, full, full)


def _ti_program(t_norm=10, i_norm=10, misses=0):
    """One tiled stage of one tile: a Traversal/Intersection phase of 4 packets."""
    ph = PhaseSpec("x.rays", (_job("traversal", 0, t_norm, misses), _job("intersection", 1, i_norm)), 0)
    return FrameProgram((Stage("pixels", False, (Tile("tile 0", (ph,)),)),), {})


@pytest.mark.parametrize("key", CYCLE_KNOBS)
def test_cycle_knobs_have_a_maximum(key):
    assert getattr(_arch(**{key: 1 << 20}), key) == 1 << 20  # (the maximum itself is taken)
    with pytest.raises(InputError, match=rf"^test\.yaml: arch\.{key}: 10000000000000000 must be <= 1048576$"):
        _arch(**{key: 10**16})


@pytest.mark.parametrize("key, value, most", [("fifo_depth", 10**20, 1 << 31), ("packet_size", 10**12, 1 << 31),
                                              ("max_events", 10**20, 1 << 53),
                                              ("copy_words_per_cycle", 10**20, 1 << 62)])
def test_size_knobs_have_a_maximum(key, value, most):
    with pytest.raises(InputError, match=rf"arch\.{key}: {value} must be <= {most}$"):
        _arch(**{key: value})


def test_a_float_past_the_maximum_says_the_maximum_not_a_whole_number_it_refuses():
    with pytest.raises(InputError) as e:
        _arch(page_miss_cycles=1e20)
    assert str(e.value) == "test.yaml: arch.page_miss_cycles: 1e20 must be <= 1048576"
    with pytest.raises(InputError, match=r"arch\.pipelines: 0\.0 must be >= 1$"):  # (not "write 0")
        _arch(pipelines=0.0)
    with pytest.raises(InputError, match=r"1e6 reads as a float .*; write 1000000$"):  # (in range: the hint stays)
        _arch(page_miss_cycles=1e6)


def test_the_clock_is_at_least_one_hertz():
    with pytest.raises(InputError, match=r"arch\.clock_hz: 1e-300 must be >= 1\.0$"):
        _arch(clock_hz=1e-300)
    # (h219, 6) 0 and -5 said "> 0.0" alone, then 0.5 ">= 1.0": the least at once; (h297) and one bound, not two
    with pytest.raises(InputError, match=r"arch\.clock_hz: 0\.0 must be >= 1\.0$"):
        _arch(clock_hz=0.0)
    with pytest.raises(InputError, match=r"arch\.clock_hz: -5 must be >= 1\.0$"):
        _arch(clock_hz=-5)
    with pytest.raises(InputError, match=r"arch\.clock_hz: 0\.5 must be >= 1\.0$"):
        _arch(clock_hz=0.5)
    assert _arch(clock_hz=1.0).clock_hz == 1.0


def test_the_trace_never_writes_a_null_timestamp(tmp_path):
    trace = Trace()
    trace.slice("pipe0.vertex", "busy", 0, (1 << 63) - 1)
    doc = trace.to_json(clock_hz=1.0)  # (the slowest clock the config takes: finite at int64's most cycles)
    assert all(np.isfinite(e["ts"]) and np.isfinite(e["dur"]) for e in doc["traceEvents"] if e["ph"] == "X")
    for hz in (1e-300, -5.0):
        with pytest.raises(ValueError, match="not a finite time"):
            trace.write(tmp_path / "trace.json", clock_hz=hz)
    assert not (tmp_path / "trace.json").exists()


def test_a_stream_past_int64_stops_with_one_line_not_wrapped_cycles():
    arch = _arch(trace=False)
    with pytest.raises(InputError, match=r"^arch: the stream of 1 frame: 1\.84e\+19 cycles, past the 2\*\*63"):
        simulate_program(_ti_program(t_norm=1 << 62), arch)


def test_the_granularity_estimate_stops_past_int64_not_negative():
    """Past the config's maxima (an ArchConfig built directly): a phase's packets costing more
    than int64 holds are refused, not wrapped to negative cycles (timing.granularity)."""
    arch = replace(_arch(trace=False), page_miss_cycles=1 << 61)
    with pytest.raises(InputError, match=r"a Traversal/Intersection phase's packets: 9\.22e\+18 cycles, past"):
        ti_cycles(_ti_program(misses=1), arch)
    assert ti_cycles(_ti_program(misses=1), replace(arch, page_miss_cycles=1 << 50)) == [4 * (10 + (1 << 50)) + 10]


@pytest.mark.parametrize("kernels", ["numba", "numpy"])
def test_a_fifo_deeper_than_int64_is_as_deep_as_any(kernels, monkeypatch):
    monkeypatch.setenv("TLM_KERNELS", kernels)
    t, i = np.array([3, 1, 4, 1, 5]), np.array([9, 2, 6, 5, 3])
    entries = np.array([2, 7, 1, 8, 2])
    assert flow_shop(t, i, entries, 10**20) == flow_shop(t, i, entries, 10**9)


def test_every_unit_has_its_trace_row_idle_ones_included():
    """One frame of two images in flight: modules 2 and 3 (the second image's) and the unused
    Vertex and Fragment PMs do nothing, and still have their idle row, as results.json lists them."""
    timing = simulate_program(_ti_program(), _arch(images_in_flight=2))
    doc = timing.trace.to_json(clock_hz=600e6, modules_per_pipe=4)
    rows = {e["tid"]: e["args"]["name"] for e in doc["traceEvents"] if e["name"] == "thread_name"}
    assert set(timing.units) <= set(rows.values())
    assert {"mem2", "mem3", "pipe0.vertex", "pipe0.fragment"} <= set(rows.values())
    spans = {}
    for e in doc["traceEvents"]:
        if e["ph"] == "X":
            spans[rows[e["tid"]]] = spans.get(rows[e["tid"]], 0) + e["args"]["cycles"]
    end = timing.frames[-1]["done"]
    assert all(spans.get(u) == end for u in timing.units), (spans, end)  # (every row covers the run)
    assert json.loads(json.dumps(doc)) == doc


def _rows(scene, ours_slowest):
    out = []
    for metric, t in (("TVert", 1.0), ("TTrav", 5.0), ("Tisct", 3.0), ("TFrag", 2.0)):
        ours = 9.0 if metric == ours_slowest else 1.0
        out.append({"scene": scene, "mode": "rcast", "metric": metric, "thesis": t, "ours": ours,
                    "rel_error": (ours - t) / t, "calibrated": False})
    return out


def test_the_slowest_pm_count_is_qualified_as_the_median_is():
    from tlm.experiments.thesis import slowest_words

    rows = _rows("ring", "TTrav") + _rows("room", "Tisct")
    assert slowest_words(summarize(rows)) == "slowest PM as in the thesis in 1 of 2 scene-modes"
    some = summarize(rows, {"room": ["32×32 pixels (thesis 320×240)"]})
    assert some["scene_modes"] == 2 and some["slowest_pm_comparable"] == 1
    assert slowest_words(some) == ("slowest PM as in the thesis in 1 of 1 comparable scene-modes "
                                   "(1 not comparable left out)")
    none = summarize(rows, {"ring": ["other"], "room": ["other"]})
    assert slowest_words(none) == ("slowest PM as in the thesis in 1 of 2 scene-modes, none comparable with the "
                                   "thesis (a count of the setting, not of the model)")
    from tlm.report.tables import _line  # (the report's line and tlm thesis's say it so: it was the bare count)

    assert "none comparable with the thesis" in _line(none) and "1 not comparable left out" in _line(some)


def test_the_scaling_report_says_where_eq52_goes_below_the_vertex_pm_s_floor():
    """A static sweep's fit (the probe's, cornell RCast at 32x32, dynamic scheduler) predicts a
    throughput below T_vert0 at N = 16, which no frame reaches: the report says so, once."""
    from tlm.report.scaling import below_floor

    rows = [{"pipelines": n, "analytical": a, "T_vert0": 1448093.0}
            for n, a in ((1, 7470834), (8, 1636911), (16, 1218824))]
    fits = {("cornell", "rcast", "dynamic", "throughput", ""): {"rows": rows},
            ("cornell", "rcast", "dynamic", "latency", ""): {"rows": [{**r, "analytical": 2 * r["analytical"]}
                                                                      for r in rows]}}
    assert below_floor(fits) == ["dynamic throughput: eq. 5.2's fit falls below T_vert0 = 1,448,093 cycles (the "
                                 "shared Vertex PM's cycles per frame, below which no frame goes) at N = 16: there "
                                 "it predicts what no count of pipelines reaches"]


def test_a_whole_float_past_an_integer_keys_range_is_echoed_by_its_exponent():
    """(h219, 9) ``arch.frames=1e5`` said ``100000.0 must be <= 10000``."""
    with pytest.raises(InputError, match=r"^test\.yaml: arch\.frames: 1e5 must be <= 10000$"):
        _arch(frames=1e5)
    with pytest.raises(InputError, match=r"^test\.yaml: arch\.frames: 1\.5e4 must be <= 10000$"):
        _arch(frames=1.5e4)
    with pytest.raises(InputError, match=r"^test\.yaml: arch\.frames: 12345\.0 must be <= 10000$"):  # (no rounding)
        _arch(frames=12345.0)


def test_a_stream_past_int64_by_the_programs_tables_scale_names_the_table(tmp_path, capsys):
    """(h219, 4) the line blamed the cycle knobs (page_miss_cycles ...) and the frames alone where the programs
    table's scale made every frame's 1.45e18 cycles: it names arch.programs too."""
    import re
    from pathlib import Path

    from tlm.cli import main

    repo = Path(__file__).resolve().parents[1]
    text = (repo / "tlm" / "arch" / "programs.yaml").read_text()
    (tmp_path / "big.yaml").write_text(re.sub(r"(?m)^(  scale: )[0-9.]+$", r"\g<1>7.54193e12", text, count=1))
    out = tmp_path / "o"
    assert main(["run", str(repo / "configs" / "cornell.yaml"), "--set", f"arch.programs={tmp_path / 'big.yaml'}",
                 "--set", "arch.frames=10", "--set", "resolution=[16,16]", "--set", "arch.trace=false",
                 "--no-reference", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("tlm: error: arch: the stream of 10 frames: 1.45e+19 cycles, past the 2**63 - 1"), err
    assert "the scale or record_cycles of the programs table (arch.programs" in err and "arch.frames" in err, err
    assert not out.exists()


def test_a_copy_bandwidth_is_a_divisor_and_may_be_as_large_as_a_test_s_infinite_one():
    """copy_words_per_cycle divides the words copied: 10**9 (tests/extreme's unbounded bandwidth) is taken; it was
    refused at 2**20 with the cycle knobs it does not multiply."""
    assert _arch(copy_words_per_cycle=10**9).copy_words_per_cycle == 10**9
