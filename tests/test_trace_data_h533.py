"""trace.json as data (h533): a script summing its slices gets results.json's figures.

Each unit's row, read back by the slices' names, sums to the unit's busy, stall (by cause)
and idle cycles in results.json, also when its ``(preempted)`` row is summed with it (that
row holds its ``preempted`` slices alone, no idle filler); busy, page-miss, copy, stall and
preempted slices carry the job's frame, job and tile, stalls what they wait ``on``, and a
PM's busy cycles summed per (frame, job) are that job's work (busy slices of two jobs never
merge). docs/architecture.md, "trace.json", is what a script can rely on.
"""

from __future__ import annotations

import json
from collections import Counter, defaultdict

import numpy as np
import pytest

from tlm.arch.frame_program import FrameProgram, JobSpec, PhaseSpec
from tlm.arch.model import simulate_program
from tlm.arch.units import STALL_CAUSES
from tlm.config import config_from_dict
from tlm.experiments.run import run

TINY = {"resolution": [32, 32], "render": {"light_samples": 1}, "photons": {"count": 800}}
# what each cause of stall waits on (args.on)
ON = {"handshake": {"phase", "stage"}, "copy": {"copy", "fan-in", "fan-out"}, "swap": {"route"},
      "preemption": {"context save", "context restore"}, "fifo_full": {"fifo"}, "fifo_empty": {"fifo"}}


def _rows(doc: dict) -> dict[str, list[dict]]:
    """The slices of each row of a trace document, by the row's name."""
    names = {e["tid"]: e["args"]["name"] for e in doc["traceEvents"] if e["ph"] == "M" and e["name"] == "thread_name"}
    rows: dict[str, list[dict]] = defaultdict(list)
    for e in doc["traceEvents"]:
        if e["ph"] == "X":
            rows[names[e["tid"]]].append(e)
    return rows


def _check(doc: dict, units: dict, crossbar: dict, phases: set[str]) -> None:
    """Every unit's rows sum to its breakdown; every slice has the args the doc names."""
    rows = _rows(doc)
    assert set(units) <= set(rows)
    for u, b in units.items():
        mine = [r for r in rows if r == u or r.startswith(u + " (")]  # (summed by the row's name as a prefix)
        got: Counter = Counter()
        for r in mine:
            for e in rows[r]:
                n, c = e["name"], e["args"]["cycles"]
                got["busy" if n in ("busy", "page misses") or n.startswith("copy ") else n] += c
                for k in ("T_norm", "T_ms", "T_ps"):
                    got[k] += e["args"].get(k, 0)
        assert got["busy"] == b["busy"] and got["idle"] == b["idle"], (u, got, b)
        assert all(got[f"stall: {c}"] == b["stall"][c] for c in STALL_CAUSES), (u, got, b)
        assert all(got[k] == b[k] for k in ("T_norm", "T_ms", "T_ps")), (u, got, b)
        for r in mine[1:]:  # a preempted row: its preempted slices, nothing else
            assert r == f"{u} (preempted)" and {e["name"] for e in rows[r]} == {"preempted"}, r
    for r, slices in rows.items():
        for e in slices:
            n, a = e["name"], e["args"]
            if n == "idle":
                continue
            if n.startswith("copy "):
                assert type(a["frame"]) is int and type(a["words"]) is int, (r, e)
                continue
            assert type(a["frame"]) is int and a["job"] in phases and type(a["tile"]) is str, (r, e)
            if n.startswith("stall: "):
                assert a["on"] in ON[n.removeprefix("stall: ")] and type(a["waiting_for"]) is str, (r, e)
                if a["on"] in ("phase", "stage", "copy", "fan-in", "fan-out", "fifo"):
                    assert type(a["on_frame"]) is int and type(a["on_name"]) is str, (r, e)
            else:
                assert n in ("busy", "page misses", "preempted"), (r, e)
    copies = [e for e in rows["xbar"] if e["name"].startswith("copy ")]  # one slice a block copy
    assert len(copies) == crossbar["copies"] and sum(e["args"]["words"] for e in copies) == crossbar["words_copied"]


# -- a hand-built program: every cycle known ------------------------------------------------------

def _job(pm: str, norm: list[int], role: int = 0, misses: list[int] | None = None) -> JobSpec:
    n = np.asarray(norm, dtype=np.int64)
    m = np.zeros_like(n) if misses is None else np.asarray(misses, dtype=np.int64)
    return JobSpec(pm, "test", role, n, m, np.zeros_like(n), np.ones_like(n))


# (tests/test_model.py's preemption program, with page misses): frame 1's v is preempted by frame 0's v2
PROGRAM = FrameProgram.linear([PhaseSpec("v", (_job("vertex", [4] * 5, misses=[1, 0, 1, 0, 1]),), 0),
                               PhaseSpec("f", (_job("fragment", [5], role=1),), 3),
                               PhaseSpec("v2", (_job("vertex", [3]),), 0)])


def _simulated():
    arch = config_from_dict({"arch": {"frames": 2, "swap_cycles": 2, "context_switch_cycles": 5,
                                      "page_miss_cycles": 2}}, "test").arch
    return simulate_program(PROGRAM, arch)


def test_a_hand_built_run_reads_back_as_its_figures(tmp_path):
    t = _simulated()
    doc = t.trace.to_json(600e6)
    _check(doc, t.units, t.crossbar, {"v", "f", "v2"})
    rows = _rows(doc)
    assert {e["name"] for e in rows["pipe0.vertex (preempted)"]} == {"preempted"}
    # per (frame, job): a PM's busy cycles are the job's work, whatever preempted it
    per_job: Counter = Counter()
    for e in rows["pipe0.vertex"]:
        if e["name"] == "busy":
            per_job[(e["args"]["frame"], e["args"]["job"])] += e["args"]["T_norm"]
    assert per_job == {(0, "v"): 20, (1, "v"): 20, (0, "v2"): 3, (1, "v2"): 3}
    assert all(e["args"]["tile"] == "frame" for e in rows["pipe0.vertex"] if e["name"] == "busy")
    # the page misses on the modules: the job they served
    misses = Counter((r, e["args"]["frame"], e["args"]["job"]) for r in ("mem0", "mem2") for e in rows[r]
                     if e["name"] == "page misses")
    assert set(misses) == {("mem0", 0, "v"), ("mem2", 1, "v")}
    # the preemption: what was saved for what, and the job restored
    pre = [e["args"] for e in rows["pipe0.vertex"] if e["name"] == "stall: preemption"]
    assert [(a["frame"], a["job"], a["on"], a.get("on_name"), a.get("on_frame")) for a in pre] == [
        (1, "v", "context save", "v2", 0), (1, "v", "context restore", None, None)]
    (held,) = rows["pipe0.vertex (preempted)"]
    assert (held["args"]["frame"], held["args"]["job"]) == (1, "v")
    # the text written is the document (the slices' args spelt out as json.dumps writes them)
    t.trace.write(tmp_path / "trace.json", 600e6)
    assert json.loads((tmp_path / "trace.json").read_text()) == doc


# -- whole runs: a frame with preemptions, four pipelines of the dynamic queue ---------------------

@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("trace_data")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        run(config_from_dict({**TINY, "scene": "cornell", "mode": "pmap",
                              "arch": {"frames": 2, "packet_size": 64}}), root / "pmap", outputs=("trace",))
        run(config_from_dict({**TINY, "scene": "ring", "mode": "rcast",
                              "arch": {"frames": 2, "pipelines": 4, "scheduler": "dynamic",
                                       "tiles_per_pipeline": 2}}), root / "wide", outputs=("trace",))
    return root


@pytest.mark.slow
@pytest.mark.parametrize("name", ["pmap", "wide"])
def test_a_run_s_trace_sums_to_its_results(runs, name):
    res = json.loads((runs / name / "results.json").read_text())
    doc = json.loads((runs / name / "trace.json").read_text())
    tm = res["timing"]
    _check(doc, tm["units"], tm["crossbar"], set(tm["phases"]))
    rows = _rows(doc)
    if name == "pmap":  # two frames in flight on one pipeline: PMs were preempted
        assert any(r.endswith(" (preempted)") for r in rows)
    else:  # the dynamic queue: every tile of the pixel stage is named where its jobs ran
        tiles = {e["args"]["tile"] for r, s in rows.items() if r.startswith("pipe") for e in s if e["name"] == "busy"}
        assert {f"tile {i}" for i in range(8)} <= tiles
        composed = [e for e in rows["compose"] if e["name"].startswith("copy ")]
        assert sorted((e["args"]["frame"], e["args"]["tile"]) for e in composed) == sorted(
            (f, f"tile {i}") for f in range(len(tm["frame_times"])) for i in range(8))
