"""Report sections 'where the cycles go' (eq. 5.1, timeline) and 'error against run time'."""

from __future__ import annotations

import importlib.util
import json
import math
import shutil
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
import yaml
from matplotlib.image import imread

from tlm.arch.units import STALL_CAUSES
from tlm.config import config_from_dict
from tlm.experiments.error_cost import Truth, run_error_vs_cost
from tlm.experiments.granularity import run_granularity
from tlm.experiments.run import run
from tlm.report.collect import Inputs, Run, Study, Sweep, read
from tlm.report.cycles import (
    MAX_GANTT_ROWS,
    SEGMENTS,
    Gantt,
    breakdown,
    cycles_section,
    gantt,
    merge,
    pixel_spans,
    select_runs,
)
from tlm.report.tradeoff import granularity_points, pareto_front, tradeoff_section

from .scenes import sphere_scene

TINY = {"resolution": [32, 32], "render": {"light_samples": 1}, "photons": {"count": 800}}

ORACLE = importlib.util.find_spec("mitsuba") is not None


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A pmap run (1 pipeline, 2 frames: preemption), a 4-pipeline run, a granularity and an
    error-vs-cost study, all tiny; the functional cache and the reference in tmp."""
    root = tmp_path_factory.mktemp("report_inputs")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        run(config_from_dict({**TINY, "scene": "cornell", "mode": "pmap",
                              "arch": {"frames": 2, "packet_size": 64}}), root / "pmap")
        run(config_from_dict({**TINY, "scene": "ring", "mode": "rcast",
                              "arch": {"frames": 2, "pipelines": 4, "scheduler": "dynamic"}}), root / "wide")
        g = root / "gran.yaml"
        g.write_text(yaml.safe_dump({"base": {**TINY, "scene": "cornell", "mode": "rcast", "resolution": [24, 16],
                                              "arch": {"frames": 2}},
                                     "packet_sizes": [1, 16, 4096]}))
        run_granularity(g, root / "gran")
        sphere_scene(root)
        e = root / "evc.yaml"
        e.write_text(json.dumps({
            "base": {"scene": "furnace.yaml", "resolution": [16, 16], "arch": {"frames": 2},
                     "reference": {"photons": 1500, "k_nearest": 20, "tolerance": 0.5, "min_rounds": 2,
                                   "max_rounds": 2}},
            "points": [{"estimate.filter": ["disk", "mvoxel"], "photons.count": [500, 2000]},
                       {"estimate.filter": ["knn"], "photons.count": [2000], "estimate.k_nearest": [10]}],
        }))
        run_error_vs_cost(e, root / "evc", truth=Truth(spp=64))
    return root


def _nontrivial(path: Path) -> None:
    assert path.is_file(), path
    img = imread(path)
    assert img.shape[0] > 200 and img.shape[1] > 300
    assert img[..., :3].std() > 0.05, f"{path} looks blank"


def _run(inputs: Inputs, name: str) -> Run:
    (r,) = [r for r in inputs.runs if r.path.name == name]
    return r


# -- where the cycles go ---------------------------------------------------------------------

@pytest.mark.slow
def test_cycles_section_draws_both_figures_of_a_run(data, tmp_path):
    inputs = read([data / "pmap"])
    sec = cycles_section(inputs, tmp_path)
    assert sec.key == "cycles" and sec.absent is None and sec.notes == []
    assert len(sec.figures) == 2
    assert any("breakdown" in f.file for f in sec.figures) and any("timeline" in f.file for f in sec.figures)
    for f in sec.figures:
        _nontrivial(tmp_path / f.file)
        assert f.title and f.caption


def test_breakdown_bars_reach_each_pms_elapsed_cycles_per_frame(data):
    pmap = _run(read([data / "pmap"]), "pmap")
    units = pmap.results["timing"]["units"]
    bd = breakdown(pmap)
    assert bd.frames == 2 and bd.aggregate is None
    assert bd.labels == ["vertex", "traversal", "intersection", "fragment"]
    total = sum(bd.segments[s] for s in SEGMENTS)
    for i, label in enumerate(bd.labels):
        u = units[f"pipe0.{label}"]
        assert total[i] == pytest.approx(u["elapsed"] / 2, rel=1e-12)
        assert bd.segments["T_norm"][i] == u["T_norm"] / 2 and bd.segments["idle"][i] == u["idle"] / 2
        assert sum(bd.segments[f"stall: {c}"][i] for c in STALL_CAUSES) == pytest.approx(u["T_ds"] / 2)
    assert bd.throughput == pmap.results["cycles"]["throughput"]


def test_breakdown_of_many_pipelines_is_the_mean_per_pm_kind(data):
    wide = _run(read([data / "wide"]), "wide")
    units = wide.results["timing"]["units"]
    bd = breakdown(wide)
    assert bd.aggregate and "4 pipelines" in bd.aggregate
    assert [lb.split("\n")[0] for lb in bd.labels] == ["vertex", "traversal", "intersection", "fragment"]
    trav = [units[f"pipe{p}.traversal"] for p in range(4)]
    i = 1
    n = wide.results["timing"]["frames"]  # (the frames run: a dynamic stream runs on past arch.frames = 2)
    assert bd.frames == n >= 2
    assert bd.segments["T_norm"][i] == pytest.approx(np.mean([u["T_norm"] for u in trav]) / n)
    assert bd.segments["stall: handshake"][i] == pytest.approx(np.mean([u["stall"]["handshake"] for u in trav]) / n)
    total = sum(bd.segments[s] for s in SEGMENTS)
    assert total == pytest.approx(bd.elapsed) and bd.elapsed == pytest.approx(units["xbar"]["elapsed"] / n)
    # with a higher threshold every PM of every pipeline has its bar
    each = breakdown(wide, few=4)
    pms = [k for k in units if k.startswith("pipe")]
    assert len(each.labels) == len(pms) == 13 and each.aggregate is None
    assert sum(each.segments[s] for s in SEGMENTS) == pytest.approx([units[k]["elapsed"] / n for k in pms])


def test_gantt_totals_equal_the_trace_and_the_units_statistics(data):
    pmap = _run(read([data / "pmap"]), "pmap")
    g = gantt(pmap.trace)
    doc = json.loads(pmap.trace.read_text())
    names = {e["tid"]: e["args"]["name"] for e in doc["traceEvents"] if e["name"] == "thread_name"}
    raw: dict[tuple[str, str], int] = defaultdict(int)
    for e in doc["traceEvents"]:
        if e["ph"] == "X":  # timestamps are microseconds; the exact cycles are in args
            raw[(names[e["tid"]], "copy" if e["name"].startswith("copy") else e["name"])] += e["args"]["cycles"]
    units = pmap.results["timing"]["units"]
    elapsed = units["xbar"]["elapsed"]
    assert g.end == elapsed and set(g.rows) == {n.removesuffix(" (preempted)") for n in names.values()} <= set(units)
    for u in g.rows:
        for state in ("busy", "page misses", "idle", *(f"stall: {c}" for c in STALL_CAUSES)):
            assert g.total(u, state) == raw.get((u, state), 0), (u, state)
        assert g.total(u, "block copy") == raw.get((u, "copy"), 0)
        assert g.total(u, "preempted") == raw.get((f"{u} (preempted)", "preempted"), 0)
        assert sum(g.total(u, s) for s in {s for (v, s) in g.spans if v == u and s != "preempted"}) == elapsed
        for state in {s for (v, s) in g.spans if v == u}:  # merged: sorted, disjoint, not touching
            s, e = g.spans[(u, state)]
            assert np.all(s[1:] > e[:-1]) and np.all(e > s)
    # and the trace agrees with the eq. 5.1 statistics of results.json
    for pm in ("vertex", "traversal", "intersection", "fragment"):
        u, st = f"pipe0.{pm}", units[f"pipe0.{pm}"]
        assert g.total(u, "busy") == st["busy"] and g.total(u, "idle") == st["idle"]
        assert all(g.total(u, f"stall: {c}") == st["stall"][c] for c in STALL_CAUSES)
    for m in ("mem0", "mem1", "mem2", "mem3"):
        assert g.total(m, "page misses") == units[m]["T_ms"] and g.total(m, "block copy") == units[m]["T_norm"]
    assert g.total("xbar", "block copy") == units["xbar"]["T_norm"] > 0
    switches = sum(pmap.results["timing"]["crossbar"]["preemptions"].values())
    assert switches > 0 and sum(g.total(u, "preempted") for u in g.rows) > 0


def test_merge_and_pixel_resolution():
    s, e = merge(np.array([10, 0, 5, 3, 20]), np.array([12, 5, 8, 4, 21]))
    assert s.tolist() == [0, 10, 20] and e.tolist() == [8, 12, 21]
    # a row idle but for two 1-cycle bursts: at pixel resolution the bursts still show
    spans = {("u", "idle"): merge(np.array([0, 101, 601]), np.array([100, 600, 1000])),
             ("u", "busy"): (np.array([100, 600]), np.array([101, 601])),
             ("v", "busy"): (np.array([0]), np.array([1000])),
             ("v", "preempted"): (np.array([0, 500]), np.array([10, 1000]))}
    g = Gantt(["u", "v"], spans, 1000, 600e6, 6)
    px = pixel_spans(g, bins=100)
    bs, be = px[("u", "busy")]
    assert bs.tolist() == [100, 600] and be.tolist() == [110, 610]
    idle = px[("u", "idle")]
    assert sum((idle[1] - idle[0]).tolist()) + 20 == pytest.approx(1000)
    ps, pe = px[("v", "preempted")]  # the 10-cycle preemption fills one column: kept; the long one too
    assert ps.tolist() == [0, 500] and pe.tolist() == [10, 1000]


@pytest.mark.slow
def test_many_units_and_a_run_without_trace(data, tmp_path):
    quiet = tmp_path / "quiet"
    shutil.copytree(data / "wide", quiet, ignore=shutil.ignore_patterns("trace.json"))
    inputs = read([data / "wide", quiet])
    wide = _run(inputs, "wide")
    assert len(gantt(wide.trace).rows) > MAX_GANTT_ROWS
    out = tmp_path / "out"
    out.mkdir()
    sec = cycles_section(inputs, out)
    assert len(sec.figures) == 3  # two breakdowns, one timeline
    for f in sec.figures:
        _nontrivial(out / f.file)
    assert any("pipelines 0 and 3 of 4" in n for n in sec.notes)
    # (the copy's config says arch.trace: true: its trace was written, then removed)
    assert any(n.startswith("quiet") and "no trace.json (the run wrote one, and it is gone from the folder)" in n
               for n in sec.notes), sec.notes


def _fake(label: str, kind: str, scene: str, thr: int, factors: dict | None = None) -> Run:
    results = {"scene": {"name": scene}, "cycles": {"throughput": thr}, "timing": {"units": {"xbar": {}}}}
    return Run(Path(label), label, kind, results, {}, dict(factors or {}))


def test_select_runs_picks_representatives_and_says_so():
    cells = [_fake(f"{s}/{m}", "thesis", s, t) for s, m, t in
             [("ring", "rcast", 5), ("ring", "pmap", 9), ("room", "rcast", 7), ("room", "reflect", 3)]]
    points = [_fake(f"sw #{i}", "sweep-point", "ring", 1, {"arch.scheduler": s, "arch.pipelines": n})
              for i, (s, n) in enumerate([(s, n) for s in ("static", "dynamic") for n in (2, 1, 8, 4)])]
    single = _fake("one", "run", "ring", 1)
    untimed = _fake("bare", "run", "ring", 1)
    untimed.results["timing"] = None
    inputs = Inputs([], runs=[single, untimed, *cells, *points],
                    sweeps=[Sweep(Path("sw"), {}, [], points)])
    chosen, notes = select_runs(inputs)
    assert [r.label for r in chosen] == ["one", "ring/pmap", "room/rcast", "sw #1", "sw #2", "sw #5", "sw #6"]
    assert any("bare" in n for n in notes) and any("slowest mode" in n for n in notes)
    assert any("4 of 8 points" in n and "fewest and the most pipelines" in n for n in notes)
    chosen, notes = select_runs(inputs, limit=3)
    assert len(chosen) == 3 and any("left out: sw #1, sw #2, sw #5 and sw #6" in n for n in notes)


def test_cycles_section_absent_without_runs(data, tmp_path):
    sec = cycles_section(read([data / "gran"]), tmp_path)
    assert sec.absent and "no run" in sec.absent and not sec.figures


# -- error against run time ------------------------------------------------------------------

def test_pareto_front_on_hand_made_rows():
    cost = [1.0, 2.0, 2.0, 3.0, 4.0, 0.5, math.nan, 2.0, 5.0]
    err = [5.0, 3.0, 4.0, 3.0, 1.0, 9.0, 0.0, 3.0, 1.0]
    # (2,4) loses to (2,3); (3,3) costs more for the same error; nan is never on it;
    # the two (2,3) are the same point; (5,1) costs more than (4,1) for the same error
    assert pareto_front(cost, err).tolist() == [True, True, False, False, True, True, False, True, False]
    assert pareto_front([], []).tolist() == []


@pytest.mark.slow
def test_tradeoff_section_draws_both_curves(data, tmp_path):
    inputs = read([data / "evc", data / "gran"])
    sec = tradeoff_section(inputs, tmp_path)
    assert sec.key == "tradeoff" and sec.absent is None and sec.notes == []
    bias = ["tradeoff_00_bias_vs_wall_time.png"] if ORACLE else []  # the ground truth needs the oracle extra
    assert [f.file for f in sec.figures] == ["tradeoff_00_rmse_vs_frame_time.png",
                                             "tradeoff_00_rmse_vs_wall_time.png", *bias, "tradeoff_granularity.png"]
    for f in sec.figures:
        _nontrivial(tmp_path / f.file)
    (gran,) = inputs.of_kind("granularity")
    size, secs, err = granularity_points(gran)
    assert size.tolist() == [1, 16, 4096] and err[0] == 0 and np.all(secs > 0)
    assert (err[1:] > 0).any()  # else the figure would not need its floor
    assert "drawn hollow at" in sec.figures[-1].caption


@pytest.mark.slow
def test_tradeoff_notes_rows_without_simulated_time_and_absent_inputs(data, tmp_path):
    (evc,) = read([data / "evc"]).of_kind("error-vs-cost")
    old = Study("error-vs-cost", evc.path, [{k: v for k, v in r.items() if k != "frame_seconds"} for r in evc.rows])
    sec = tradeoff_section(Inputs([], studies=[old]), tmp_path)
    bias = ["tradeoff_00_bias_vs_wall_time.png"] if ORACLE else []
    assert [f.file for f in sec.figures] == ["tradeoff_00_rmse_vs_wall_time.png", *bias]
    assert any("no simulated frame time" in n for n in sec.notes)
    assert any("No granularity study" in n for n in sec.notes)
    sec = tradeoff_section(read([data / "pmap"]), tmp_path)
    assert sec.absent and "error-vs-cost" in sec.absent and not sec.figures


@pytest.mark.slow
def test_an_unreadable_trace_is_a_note(data, tmp_path):
    broken = tmp_path / "broken"
    shutil.copytree(data / "pmap", broken)
    (broken / "trace.json").write_text("{")
    out = tmp_path / "out"
    out.mkdir()
    sec = cycles_section(read([broken]), out)
    assert [f.file.endswith("_breakdown.png") for f in sec.figures] == [True]
    assert any("trace.json cannot be read" in n for n in sec.notes)
