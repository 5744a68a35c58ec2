"""The packets' cost at the phase boundaries (tlm.arch.model.fill_and_drain, results.json
``timing.granularity``) and what the simulated run warns of (tlm.experiments.run_warnings.stream_warnings):
coarse packets, and arch keys the run provably never read. Hand-built programs of a few
packets, as in tests/test_model.py."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tlm.arch.frame_program import FrameProgram, JobSpec, PhaseSpec, Stage, Tile
from tlm.arch.granularity import fill_and_drain
from tlm.arch.model import simulate_program
from tlm.config import config_from_dict
from tlm.experiments.run_warnings import GRANULARITY_WARNING, stream_warnings


def _job(pm, cycles, role, entries):
    norm = np.asarray(cycles, dtype=np.int64)
    zeros = np.zeros_like(norm)
    return JobSpec(pm, "test", role, norm, zeros, zeros, np.ones_like(norm), np.asarray(entries, dtype=np.int64))


def _ti(t, i, entries=None):
    """One tiled stage of one tile: a Traversal/Intersection phase of packets costing t and i."""
    entries = [1] * len(t) if entries is None else entries
    ph = PhaseSpec("x.rays", (_job("traversal", t, 0, entries), _job("intersection", i, 1, entries)), 0)
    return FrameProgram((Stage("pixels", False, (Tile("tile 0", (ph,)),)),), {})


def _cfg(**arch):
    return config_from_dict({"arch": {"frames": 1, "images_in_flight": 1, "trace": False, **arch}}, "test")


# six rays, and the same rays in packets of two
FINE_T, FINE_I = [15, 15, 5, 5, 10, 10], [10, 10, 20, 20, 5, 5]
COARSE_T, COARSE_I = [30, 10, 20], [20, 40, 10]


def test_fill_and_drain_is_the_flow_shop_excess_over_its_finest_split():
    """Packets (t, i) = (30, 20), (10, 40), (20, 10): the phase takes max over k of
    t_1..t_k + i_k..i_n = max(30 + 70, 40 + 50, 60 + 10) = 100; its work split as finely as
    possible takes at least max(sum t, sum i, t_1..t_j + i_j+1..i_n) = max(60, 70, 30 + 50,
    40 + 10) = 80: the packets add up to 20. The six rays themselves: 90 against 80, 10."""
    a = _cfg().arch
    assert fill_and_drain(_ti(COARSE_T, COARSE_I), a) == [20]
    assert fill_and_drain(_ti(FINE_T, FINE_I), a) == [10]
    # the simulated phase takes exactly the flow shop's makespan (one image, an ample FIFO)
    coarse = simulate_program(_ti(COARSE_T, COARSE_I), a)
    fine = simulate_program(_ti(FINE_T, FINE_I), a)
    assert (coarse.cycles["throughput"], fine.cycles["throughput"]) == (100, 90)
    # what the packets added (10) is at most their estimate
    assert coarse.cycles["throughput"] - fine.cycles["throughput"] <= coarse.granularity["fill_drain_cycles"]
    # share: the smaller of the estimate and TThru over the slowest PM (I: 70), over TThru
    assert coarse.granularity == {"fill_drain_cycles": 20, "over_slowest_pm": 30, "share": 0.2}
    assert fine.granularity == {"fill_drain_cycles": 10, "over_slowest_pm": 20, "share": round(10 / 90, 4)}


def test_a_run_bound_by_its_slowest_pm_gets_no_share():
    """TThru at the slowest PM's cycles: the packets cannot have added anything to it."""
    a = _cfg().arch
    t = simulate_program(_ti([10] * 4, [100] * 4), a)  # the Intersection PM alone sets TThru, but the fill
    assert t.cycles["throughput"] == 410 and t.cycles["intersection"] == 400
    assert t.granularity["over_slowest_pm"] == 10 and t.granularity["share"] == round(10 / 410, 4)


def _granularity_lines(timing, cfg):
    return [w for w in stream_warnings(timing, cfg) if w.startswith("arch.packet_size")]


def test_coarse_packets_warn_and_fine_ones_do_not():
    """Twenty balanced rays (10 cycles on each PM): in packets of one the phase takes 210,
    4.8% over its work; in two packets of ten, 300, 33% (the Intersection PM waits for the
    first packet, the Traversal PM idles through the last)."""
    cfg = _cfg(packet_size=10)
    coarse = simulate_program(_ti([100, 100], [100, 100]), cfg.arch)
    assert coarse.granularity["share"] == round(100 / 300, 4) >= GRANULARITY_WARNING
    (line,) = _granularity_lines(coarse, cfg)
    assert line.startswith("arch.packet_size = 10 is coarse for this frame: ") and "about 33% of cycles.throughput" \
        in line and "'tlm granularity'" in line
    fine_cfg = _cfg(packet_size=1)
    fine = simulate_program(_ti([10] * 20, [10] * 20), fine_cfg.arch)
    assert fine.granularity["share"] == round(10 / 210, 4) < GRANULARITY_WARNING
    assert _granularity_lines(fine, fine_cfg) == []


def _inert(timing, cfg):
    return [w for w in stream_warnings(timing, cfg) if "has no effect in this run" in w]


@pytest.mark.parametrize(("entries", "depth", "why"), [
    ([2000, 3000], 4, "every packet carries at least 1024 triangle addresses, so it enters an empty FIFO alone at "
                      "depth 4 and at 1024"),
    ([2000, 3000], 2000, "every packet carries at least 2000 triangle addresses"),
    ([3, 4, 0], 8, "every Traversal/Intersection phase's packets fit in 8 FIFO entries together: the FIFO never fills"),
])
def test_a_fifo_depth_the_run_never_felt_is_named(entries, depth, why):
    """A packet takes min(entries, depth) FIFO entries (one at least): packets of at least
    both depths' addresses each enter an empty FIFO alone at either depth, and packets that
    fit together never fill it. Either way the depth changes no cycle, and the run says so."""
    cfg = _cfg(fifo_depth=depth)
    t = simulate_program(_ti([5] * len(entries), [7] * len(entries), entries), cfg.arch)
    default = simulate_program(_ti([5] * len(entries), [7] * len(entries), entries), _cfg().arch)
    assert t.cycles == default.cycles
    (line,) = _inert(t, cfg)
    assert line.startswith(f"arch.fifo_depth = {depth} has no effect in this run: {why}")


def test_a_fifo_depth_that_can_matter_is_not_named():
    """Packets of 500 addresses: two fit in 1024 entries, one in 600; the depth may change cycles."""
    cfg = _cfg(fifo_depth=600)
    t = simulate_program(_ti([5] * 3, [7] * 3, [500] * 3), cfg.arch)
    assert _inert(t, cfg) == []


def test_swaps_and_context_switches_that_never_happened_are_named():
    """One image in flight: no PM ever moves to another module, so arch.swap_cycles was
    never read; with two images and nothing to preempt, neither was arch.context_switch_cycles."""
    cfg = _cfg(swap_cycles=9)
    t = simulate_program(_ti([5, 5], [7, 7]), cfg.arch)
    assert t.crossbar["swaps"] == 0
    assert _inert(t, cfg) == ["arch.swap_cycles = 9 has no effect in this run: no PM moved to another module "
                              "(timing.crossbar.swaps is 0)"]
    two = dataclasses.replace(cfg, arch=dataclasses.replace(cfg.arch, images_in_flight=2, swap_cycles=2,
                                                            context_switch_cycles=0))
    t = simulate_program(_ti([5, 5], [7, 7]), two.arch)
    assert not any(t.crossbar["preemptions"].values())
    assert _inert(t, two) == ["arch.context_switch_cycles = 0 has no effect in this run: no PM was preempted "
                              "(timing.crossbar.preemptions are 0)"]
