"""The packets' estimated effect on TThru (tlm.arch.model.granularity_estimate, results.json
``timing.granularity``) against what packets of one measure: each Traversal/Intersection
phase a two-machine flow shop through the FIFO (tlm.arch.model.flow_shop), in the frame's
packets and in packets of one, and the warning of tlm.experiments.run.stream_warnings
on it (docs/architecture.md, "Packet size")."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import tlm
import tlm.arch.model as model
from tlm.arch.frame_program import FrameProgram, JobSpec, PhaseSpec, Stage, Tile
from tlm.arch.model import flow_shop, simulate_program
from tlm.config import config_from_dict
from tlm.experiments.run import GRANULARITY_WARNING, stream_warnings


def _job(pm, cycles, role, entries):
    norm = np.asarray(cycles, dtype=np.int64)
    zeros = np.zeros_like(norm)
    return JobSpec(pm, "test", role, norm, zeros, zeros, np.ones_like(norm), np.asarray(entries, dtype=np.int64))


def _ti(t, i, entries):
    """One tiled stage of one tile: a Traversal/Intersection phase of packets costing t and i."""
    ph = PhaseSpec("x.rays", (_job("traversal", t, 0, entries), _job("intersection", i, 1, entries)), 0)
    return FrameProgram((Stage("pixels", False, (Tile("tile 0", (ph,)),)),), {})


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("depth", [3, 40])
def test_the_flow_shop_is_the_simulated_phase_with_one_image(seed, depth):
    """Packets of random cycles and FIFO entries (some more than the FIFO holds, some
    none): with one image in flight the simulated phase takes exactly the flow shop's
    cycles, the FIFO full or empty as it may be."""
    rng = np.random.default_rng(seed)
    n = 60
    t, i = rng.integers(1, 50, n), rng.integers(1, 50, n)
    entries = rng.integers(0, 2 * depth, n)
    arch = config_from_dict({"arch": {"frames": 1, "images_in_flight": 1, "trace": False, "fifo_depth": depth}},
                            "test").arch
    timing = simulate_program(_ti(t, i, entries), arch)
    assert timing.units["pipe0.traversal"]["stall"].get("fifo_full", 0) > 0  # (the FIFO did fill)
    assert flow_shop(t, i, entries, depth) == timing.cycles["throughput"]
    # an ample FIFO: the flow shop of the packets alone, max over k of t_1..t_k + i_k..i_n
    deep = flow_shop(t, i, entries, 10**9)
    assert deep == int((np.cumsum(t) + np.cumsum(i[::-1])[::-1]).max()) <= flow_shop(t, i, entries, depth)


def test_flow_shop_edges(monkeypatch):
    """No packets: no cycles; no entries given: one entry each; the packets taken a few at
    a time (the chunks a phase of millions of pixels is cut into) give the same cycles."""
    empty = np.zeros(0, dtype=np.int64)
    assert flow_shop(empty, empty, empty, 8) == 0
    assert flow_shop(np.array([5, 5]), np.array([7, 7]), None, 1) == 5 + 7 + 7
    rng = np.random.default_rng(3)
    t, i, entries = rng.integers(1, 50, 500), rng.integers(1, 50, 500), rng.integers(0, 30, 500)
    whole = {depth: flow_shop(t, i, entries, depth) for depth in (1, 4, 40, 10**6)}
    monkeypatch.setattr(model, "FLOW_SHOP_CHUNK", 7)
    assert {depth: flow_shop(t, i, entries, depth) for depth in whole} == whole


@pytest.fixture(scope="module")
def cornell_rcast_48(tmp_path_factory):
    """``configs/cornell.yaml --mode rcast --set resolution=[48,48]``'s frame (spp 4, 4 light samples)."""
    mp = pytest.MonkeyPatch()
    mp.setenv("TLM_CACHE", str(tmp_path_factory.mktemp("cache")))
    try:
        yield tlm.render_image(tlm.load_config({"scene": "cornell", "mode": "rcast", "resolution": [48, 48],
                                                "arch": {"trace": False}}))
    finally:
        mp.undo()


def _packet_lines(timing, res, **arch):
    cfg = replace(res.cfg, arch=replace(res.cfg.arch, **arch))
    return [w for w in stream_warnings(timing, cfg) if w.startswith("arch.packet_size")]


def test_with_one_image_the_estimate_is_the_measured_change(cornell_rcast_48):
    """Cornell RCast at 48x48, one image in flight: the Traversal/Intersection phases'
    flow shops in the frame's packets minus in packets of one are the change in TThru
    that simulating packets of one measures, to the cycle, either way: packets of 64 are
    faster (the FIFO: a whole packet enters at once), packets of 256 about as fast."""
    one = {"images_in_flight": 1, "frames": 1}
    fine = tlm.simulate(cornell_rcast_48, {**one, "packet_size": 1})
    assert fine.granularity["change_cycles"] == 0 and fine.granularity["share"] == 0.0
    shares = {}
    for size in (64, 256):
        t = tlm.simulate(cornell_rcast_48, {**one, "packet_size": size})
        change = t.cycles["throughput"] - fine.cycles["throughput"]
        assert t.granularity["change_cycles"] == change
        assert t.granularity["share"] == round(min(change, t.granularity["over_slowest_pm"]) / t.cycles["throughput"],
                                               4)
        shares[size] = t.granularity["share"]
        lines = _packet_lines(t, cornell_rcast_48, **one, packet_size=size)
        assert len(lines) == (abs(shares[size]) >= GRANULARITY_WARNING)
    assert shares[64] <= -GRANULARITY_WARNING and abs(shares[256]) < 0.02


def test_no_false_alarm_where_packets_barely_move_the_cycles(cornell_rcast_48):
    """Two images in flight, the default stream: packets of 256 move TThru by 0.6% against
    packets of one, which the hand-overs alone put at 9.9% (the warning said so); packets of
    64 move it by -6.1% (they were below the threshold at 2.4%). The run warns of the second only."""
    coarse = tlm.simulate(cornell_rcast_48)
    fine = tlm.simulate(cornell_rcast_48, {"packet_size": 1})
    assert abs(coarse.cycles["throughput"] / fine.cycles["throughput"] - 1) < 0.02
    assert _packet_lines(coarse, cornell_rcast_48) == []
    mid = tlm.simulate(cornell_rcast_48, {"packet_size": 64})
    assert mid.cycles["throughput"] / fine.cycles["throughput"] - 1 < -0.05
    (line,) = _packet_lines(mid, cornell_rcast_48, packet_size=64)
    assert line.startswith("arch.packet_size = 64 is coarse for this frame: packets of one ray would take about 6% "
                           "of cycles.throughput more") and "'tlm granularity'" in line
