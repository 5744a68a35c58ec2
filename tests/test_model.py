"""The timing model (tlm.arch.model) on tiny hand-built frame programs, in SimPy's style.

Each test builds a :class:`FrameProgram` of a few packets with small integer costs,
runs it through :func:`simulate_program`, and asserts the exact ``(what, cycle)`` log
of the PMs against a timeline worked out by hand in the comments. Notation in the
timelines: ``V``/``T``/``I``/``F`` are the four PMs, ``f0``/``f1`` frames (f0 has
priority), ``p0``.. packets, ``a-b`` the cycles a slice covers.

Two frames in flight: frame ``f`` in image slot ``s`` uses modules ``2s`` (role 0) and
``2s+1`` (role 1). A PM's first route is free; every later change of route is a swap.
Page-miss waits are charged to T_ms but not written to the PM's log (only ``Unit.work``
and ``Unit.stall`` log), so the logs below start each packet at its ``busy start``.
"""

from __future__ import annotations

import copy
import itertools
import math
from fractions import Fraction

import numpy as np
import pytest
import yaml

from tlm.arch.costs import DEFAULT_PATH, load_programs
from tlm.arch.functional import Functional
from tlm.arch.model import (
    PMS,
    FrameProgram,
    JobSpec,
    PhaseSpec,
    frame_program,
    simulate,
    simulate_program,
    steady_throughput,
)
from tlm.arch.units import STALL_CAUSES, Deadlock
from tlm.config import config_from_dict
from tlm.errors import InputError

EQ_5_1 = ("T_norm", "T_ms", "T_ps", "T_ds", "idle")


# -- helpers ------------------------------------------------------------------------------------

def arch(**kw):
    return config_from_dict({"arch": kw}, "test").arch


def job(pm, norm, role=0, misses=None, flushes=None, entries=None, items=None):
    norm = np.asarray(norm, dtype=np.int64)

    def arr(v, default):
        return default if v is None else np.asarray(v, dtype=np.int64)

    return JobSpec(pm, "test", role, norm, arr(misses, np.zeros_like(norm)), arr(flushes, np.zeros_like(norm)),
                   arr(items, np.ones_like(norm)), None if entries is None else arr(entries, None))


def phase(name, *jobs, copy_words=0):
    return PhaseSpec(name, tuple(jobs), copy_words)


def program(*phases):
    return FrameProgram.linear(phases)


def log(timing, pm):
    return timing.model.pm(0, pm).unit.log


def stall(timing, pm, cause):
    return timing.model.pm(0, pm).unit.stats.stall[cause]


def stalls(timing, pm):
    """The PM's stall cycles by cause, the causes it never stalled on left out."""
    return {cause: c for cause, c in timing.model.pm(0, pm).unit.stats.stall.items() if c}


def row(timing, scope):
    """(name, ts, dur) of every slice of one trace row, in time order."""
    tid = timing.trace.rows[scope]
    return sorted(((e["name"], e["ts"], e["dur"]) for e in timing.trace.events if e["tid"] == tid),
                  key=lambda s: s[1])


def assert_eq_5_1(timing):
    """Every unit: T_norm + T_ms + T_ps + T_ds + idle == elapsed, each term >= 0."""
    for scope, b in timing.units.items():
        assert all(b[k] >= 0 for k in EQ_5_1), scope
        assert sum(b[k] for k in EQ_5_1) == b["elapsed"], scope
        assert b["T_ds"] == sum(b["stall"].values()), scope


# -- 1. handshake ------------------------------------------------------------------------------

def test_handshake_stall_lasts_the_previous_phase():
    """F waits on the semaphore of the V phase for exactly the V phase's 5 + 3 cycles.

    V  p0 0-5, p1 5-8          (phase 'v' done at 8)
    F  stall handshake 0-8, p0 8-12
    """
    t = simulate_program(program(phase("v", job("vertex", [5, 3])), phase("f", job("fragment", [4], role=1))),
                         arch(frames=1))
    assert log(t, "vertex") == [("busy start", 0), ("busy end", 5), ("busy start", 5), ("busy end", 8)]
    assert log(t, "fragment") == [("stall handshake", 0), ("busy start", 8), ("busy end", 12)]
    assert stall(t, "fragment", "handshake") == 5 + 3
    assert stalls(t, "fragment") == {"handshake": 8} and stalls(t, "vertex") == {}
    assert log(t, "traversal") == log(t, "intersection") == []
    assert t.frames == [{"frame": 0, "slot": 0, "arrival": 0, "done": 12}]
    assert t.units["pipe0.vertex"]["idle"] == 12 - 8
    assert t.units["pipe0.fragment"]["idle"] == 0


# -- 2. swaps ----------------------------------------------------------------------------------

SWAP_PROGRAM = program(phase("v", job("vertex", [10])), phase("f", job("fragment", [4], role=1)))


def test_swap_each_time_a_pm_changes_module():
    """Three frames, two images in flight: f0 and f2 in slot 0 (mem0/mem1), f1 in slot 1.

    V  f0 0-10 (mem0) | swap 10-12 | f1 12-22 (mem2) | swap 22-24 | f2 24-34 (mem0)
    F  handshake 0-10 | f0 10-14 (mem1) | handshake 14-22 | swap 22-24 | f1 24-28 (mem3)
       | handshake 28-34 | swap 34-36 | f2 36-40 (mem1)
    f0 done 14 frees slot 0: f2 arrives at 14. Frames done 14, 28, 40; 2 + 2 swaps.
    """
    t = simulate_program(SWAP_PROGRAM, arch(frames=3, swap_cycles=2))
    assert log(t, "vertex") == [
        ("busy start", 0), ("busy end", 10), ("stall swap", 10), ("busy start", 12), ("busy end", 22),
        ("stall swap", 22), ("busy start", 24), ("busy end", 34)]
    assert log(t, "fragment") == [
        ("stall handshake", 0), ("busy start", 10), ("busy end", 14), ("stall handshake", 14), ("stall swap", 22),
        ("busy start", 24), ("busy end", 28), ("stall handshake", 28), ("stall swap", 34), ("busy start", 36),
        ("busy end", 40)]
    assert stalls(t, "vertex") == {"swap": 2 * 2}
    assert stalls(t, "fragment") == {"swap": 2 * 2, "handshake": 10 + 8 + 6}
    assert t.model.xbar.swaps == t.crossbar["swaps"] == 4
    assert [(f["slot"], f["arrival"], f["done"]) for f in t.frames] == [(0, 0, 14), (1, 0, 28), (0, 14, 40)]
    assert row(t, "pipe0.vertex") == [("busy", 0, 10), ("stall: swap", 10, 2), ("busy", 12, 10),
                                      ("stall: swap", 22, 2), ("busy", 24, 10), ("idle", 34, 6)]


@pytest.mark.parametrize("swap_cycles", [0, 7])
def test_swap_cost_is_swap_cycles(swap_cycles):
    t = simulate_program(SWAP_PROGRAM, arch(frames=2, swap_cycles=swap_cycles))
    # V f0 0-10, swap, f1 10+s..20+s; F f0 10-14, handshake, swap 20+s..20+2s, f1 ..24+2s
    assert stall(t, "vertex", "swap") == stall(t, "fragment", "swap") == swap_cycles
    assert t.crossbar["swaps"] == 2
    assert [f["done"] for f in t.frames] == [14, 24 + 2 * swap_cycles]


# -- 3. block copies -----------------------------------------------------------------------------

@pytest.mark.parametrize(("words", "per_cycle"), [(7, 2), (8, 2), (1, 4), (9, 1)])
def test_block_copy(words, per_cycle):
    """F needs ``words`` copied from mem0 to mem1 after the V phase; V2 needs 3 words back.

    c = ceil(words / per_cycle), c2 = ceil(3 / per_cycle)
    V     p0 0-10 | handshake 10-(14+c) | copy (14+c)-(14+c+c2) | p0 of v2 .. +2
    xbar  copy mem0->mem1 10-(10+c) | copy mem1->mem0 (14+c)-(14+c+c2)
    F     handshake 0-10 | copy 10-(10+c) | p0 (10+c)-(14+c)
    """
    c, c2 = math.ceil(words / per_cycle), math.ceil(3 / per_cycle)
    t = simulate_program(program(phase("v", job("vertex", [10])),
                                 phase("f", job("fragment", [4], role=1), copy_words=words),
                                 phase("v2", job("vertex", [2]), copy_words=3)),
                         arch(frames=1, copy_words_per_cycle=per_cycle))
    assert log(t, "fragment") == [("stall handshake", 0), ("stall copy", 10), ("busy start", 10 + c),
                                  ("busy end", 14 + c)]
    assert stall(t, "fragment", "copy") == c
    assert log(t, "vertex") == [("busy start", 0), ("busy end", 10), ("stall handshake", 10),
                                ("stall copy", 14 + c), ("busy start", 14 + c + c2), ("busy end", 16 + c + c2)]
    assert stalls(t, "vertex") == {"handshake": 4 + c, "copy": c2}
    f_copy, v_copy = "copy mem0->mem1: f (frame 0)", "copy mem1->mem0: v2 (frame 0)"
    xbar = t.model.xbar
    assert xbar.unit.log == [(f"{f_copy} start", 10), (f"{f_copy} end", 10 + c),
                             (f"{v_copy} start", 14 + c), (f"{v_copy} end", 14 + c + c2)]
    for mem in (0, 1):  # both ends of each copy are busy for the copy
        assert t.model.modules[mem].unit.log == xbar.unit.log
        assert t.units[f"mem{mem}"]["T_norm"] == c + c2
    assert t.units["xbar"]["T_norm"] == c + c2
    assert (xbar.copies, xbar.words_copied) == (2, words + 3)
    assert t.units["mem2"]["busy"] == t.units["mem3"]["busy"] == 0
    assert t.frames[0]["done"] == 16 + c + c2


def test_copies_of_two_images_share_the_crossbar():
    """Both frames' first phases need a 6-word copy at cycle 0; the crossbar does one at a time.

    xbar  f0 copy mem0->mem1 0-3 | f1 copy mem2->mem3 3-6
    F     f0: copy 0-3, p0 3-8 | f1: copy 3-6 (overlaps f0's work), swap 8-9, p0 9-14
    """
    t = simulate_program(program(phase("f", job("fragment", [5], role=1), copy_words=6)),
                         arch(frames=2, copy_words_per_cycle=2, swap_cycles=1))
    assert t.model.xbar.unit.log == [
        ("copy mem0->mem1: f (frame 0) start", 0), ("copy mem0->mem1: f (frame 0) end", 3),
        ("copy mem2->mem3: f (frame 1) start", 3), ("copy mem2->mem3: f (frame 1) end", 6)]
    assert log(t, "fragment") == [("stall copy", 0), ("busy start", 3), ("busy end", 8), ("stall swap", 8),
                                  ("busy start", 9), ("busy end", 14)]
    assert [f["done"] for f in t.frames] == [8, 14]


# -- 4. preemption -----------------------------------------------------------------------------

PREEMPT_PROGRAM = program(phase("v", job("vertex", [4] * 5)), phase("f", job("fragment", [5], role=1)),
                          phase("v2", job("vertex", [3])))


def test_preemption_at_a_packet_boundary():
    """f1 works on V when f0's v2 becomes ready mid-packet; V switches at the boundary.

    swap 2, context switch 5:
    V  f0 v p0..p4 0-20 (mem0) | swap 20-22 | f1 v p0 22-26 (mem2)     f0's v2 ready at 25
       | save 26-31 | swap 31-33 | f0 v2 33-36 (mem0)                f0 done at 36
       | swap 36-38 | restore 38-43 | f1 v p1..p4 43-59 | handshake 59-66 | f1 v2 66-69
    F  handshake 0-20 | f0 f 20-25 (mem1) | handshake 25-59 | swap 59-61 | f1 f 61-66 (mem3)
    A row of its own (pipe0.vertex (preempted)) shows 'preempted' from the save's end to the restore.
    """
    t = simulate_program(PREEMPT_PROGRAM, arch(frames=2, swap_cycles=2, context_switch_cycles=5))
    four = [("busy start", 0), ("busy end", 4)]
    assert log(t, "vertex") == [
        *[(w, c + 4 * k) for k in range(5) for w, c in four],
        ("stall swap", 20), ("busy start", 22), ("busy end", 26),
        ("stall preemption", 26), ("stall swap", 31), ("busy start", 33), ("busy end", 36),
        ("stall swap", 36), ("stall preemption", 38),
        *[(w, c + 43 + 4 * k) for k in range(4) for w, c in four],
        ("stall handshake", 59), ("busy start", 66), ("busy end", 69)]
    assert log(t, "fragment") == [("stall handshake", 0), ("busy start", 20), ("busy end", 25),
                                  ("stall handshake", 25), ("stall swap", 59), ("busy start", 61),
                                  ("busy end", 66)]
    assert stalls(t, "vertex") == {"preemption": 5 + 5, "swap": 3 * 2, "handshake": 7}
    assert t.crossbar["preemptions"] == {"pipe0.vertex": 1, "pipe0.traversal": 0, "pipe0.intersection": 0,
                                         "pipe0.fragment": 0}
    assert t.crossbar["swaps"] == 3 + 1
    assert [f["done"] for f in t.frames] == [36, 69]
    assert ("preempted", 31, 38 - 31) in row(t, "pipe0.vertex (preempted)")
    assert [s for s in row(t, "pipe0.vertex") if s[0] == "stall: preemption"] == [
        ("stall: preemption", 26, 5), ("stall: preemption", 38, 5)]
    assert t.units["pipe0.vertex"]["T_norm"] == 2 * (20 + 3)  # a preemption loses no work


def test_preemption_cuts_fifo_waits_short():
    """A priority job interrupts a Traversal PM stalled on a full FIFO and an Intersection PM
    between packets; both resume where they left off. FIFO depth 1, swap 2, context switch 4.

    T  f0 p0 0-1 | p1 1-2, full 2-11 | p2 11-12, full 12-21 | swap 21-23 | f1 p0 23-24 | p1 24-25,
       full 25-36 (f0's ti2 ready at 36) | save 36-40 | swap 40-42 | f0 ti2 42-44 | swap 44-46
       | restore 46-50, p1 pushed (I freed its slot at 43) | p2 50-51, full 51-68
       | handshake 68-85 | f1 ti2 85-87
    I  empty 0-1 | f0 p0 1-11, p1 11-21, p2 21-31 | swap 31-33 | f1 p0 33-43 | save 43-47
       | swap 47-49 | f0 ti2 49-52 (f0 done) | swap 52-54 | restore 54-58 | f1 p1 58-68, p2 68-78
       | handshake 78-85 | empty 85-87 | f1 ti2 87-90
    V  handshake 0-31 | f0 v 31-36 | handshake 36-78 | swap 78-80 | f1 v 80-85
    """
    t = simulate_program(
        program(phase("ti1", job("traversal", [1] * 3, entries=[1] * 3),
                      job("intersection", [10] * 3, role=1, entries=[1] * 3)),
                phase("v", job("vertex", [5])),
                phase("ti2", job("traversal", [2], entries=[1]), job("intersection", [3], role=1, entries=[1]))),
        arch(frames=2, fifo_depth=1, swap_cycles=2, context_switch_cycles=4))
    assert log(t, "traversal") == [
        ("busy start", 0), ("busy end", 1), ("busy start", 1), ("busy end", 2), ("stall fifo_full", 2),
        ("busy start", 11), ("busy end", 12), ("stall fifo_full", 12), ("stall swap", 21),
        ("busy start", 23), ("busy end", 24), ("busy start", 24), ("busy end", 25), ("stall fifo_full", 25),
        ("stall preemption", 36), ("stall swap", 40), ("busy start", 42), ("busy end", 44),
        ("stall swap", 44), ("stall preemption", 46), ("busy start", 50), ("busy end", 51),
        ("stall fifo_full", 51), ("stall handshake", 68), ("busy start", 85), ("busy end", 87)]
    assert log(t, "intersection") == [
        ("stall fifo_empty", 0), ("busy start", 1), ("busy end", 11), ("busy start", 11), ("busy end", 21),
        ("busy start", 21), ("busy end", 31), ("stall swap", 31), ("busy start", 33), ("busy end", 43),
        ("stall preemption", 43), ("stall swap", 47), ("busy start", 49), ("busy end", 52),
        ("stall swap", 52), ("stall preemption", 54), ("busy start", 58), ("busy end", 68),
        ("busy start", 68), ("busy end", 78), ("stall handshake", 78), ("stall fifo_empty", 85),
        ("busy start", 87), ("busy end", 90)]
    assert stalls(t, "traversal") == {"fifo_full": 9 + 9 + 11 + 17, "preemption": 8, "swap": 6, "handshake": 17}
    assert stalls(t, "intersection") == {"fifo_empty": 1 + 2, "preemption": 8, "swap": 6, "handshake": 7}
    assert t.crossbar["preemptions"] == {"pipe0.vertex": 0, "pipe0.traversal": 1, "pipe0.intersection": 1,
                                         "pipe0.fragment": 0}
    assert [f["done"] for f in t.frames] == [52, 90]
    assert ("preempted", 40, 6) in row(t, "pipe0.traversal (preempted)")
    assert ("preempted", 47, 7) in row(t, "pipe0.intersection (preempted)")


def test_preemption_when_the_priority_job_is_ready_at_the_boundary():
    """As test_preemption_at_a_packet_boundary, but F takes 6: f0's v2 becomes ready at 26,
    the very cycle f1's p0 ends. The boundary decision waits for the cycle to settle, so V
    sees v2 ready and switches there (save 26-31, ...) and f0 is done at 36, rather than
    running f1's p1 26-30 first and switching at 30 (f0 done at 40), which an event order
    that decided before v2's semaphore fired would give."""
    t = simulate_program(program(phase("v", job("vertex", [4] * 5)), phase("f", job("fragment", [6], role=1)),
                                 phase("v2", job("vertex", [3]))),
                         arch(frames=2, swap_cycles=2, context_switch_cycles=5))
    assert ("stall preemption", 26) in log(t, "vertex")
    assert t.frames[0]["done"] == 36


# -- 5. the FIFO -------------------------------------------------------------------------------

def test_fifo_full():
    """T pushes 2 addresses a packet every cycle into a 2-deep FIFO; I takes 5 per packet.

    T  p0 0-1 | p1 1-2, full 2-6 | p2 6-7, full 7-11 | p3 11-12, full 12-16
    I  empty 0-1 | p0 1-6 | p1 6-11 | p2 11-16 | p3 16-21
    """
    t = simulate_program(program(phase("ti", job("traversal", [1] * 4, entries=[2] * 4),
                                       job("intersection", [5] * 4, role=1, entries=[2] * 4))),
                         arch(frames=1, fifo_depth=2))
    assert log(t, "traversal") == [
        ("busy start", 0), ("busy end", 1), ("busy start", 1), ("busy end", 2), ("stall fifo_full", 2),
        ("busy start", 6), ("busy end", 7), ("stall fifo_full", 7), ("busy start", 11), ("busy end", 12),
        ("stall fifo_full", 12)]
    assert log(t, "intersection") == [("stall fifo_empty", 0), *[(w, c) for k in range(4) for w, c in
                                                                 (("busy start", 1 + 5 * k), ("busy end", 6 + 5 * k))]]
    assert stalls(t, "traversal") == {"fifo_full": 3 * 4}
    assert stalls(t, "intersection") == {"fifo_empty": 1}
    assert t.frames[0]["done"] == 21


@pytest.mark.slow
def test_the_fifo_depth_matters_between_balanced_pms_at_fine_packets():
    """Cornell RCast at its 7 BSP levels, 128x128 (Traversal 27.9 M and Intersection 33.6 M
    cycles, within 17%): at packets of one ray a 1-entry FIFO makes the Intersection PM
    wait for addresses (TThru +6.4% against 4096 entries); at packets of 256 a packet's
    addresses fill any FIFO, so the depth is within 1% (``configs/sweep_fifo.yaml`` at
    full size)."""
    import dataclasses

    from tlm.arch.model import simulate
    from tlm.config import config_from_dict
    from tlm.experiments.run import render

    cfg = config_from_dict({"scene": "cornell", "mode": "rcast", "resolution": [128, 128],
                            "render": {"light_samples": 1}}, "fifo")
    fn = render(cfg).functional()

    def thru(packet_size, depth):
        a = dataclasses.replace(cfg.arch, packet_size=packet_size, fifo_depth=depth, trace=False)
        return simulate(fn, load_programs(), a).cycles["throughput"]

    assert thru(1, 1) / thru(1, 4096) > 1.05
    assert abs(thru(256, 1) / thru(256, 4096) - 1) < 0.01


def test_fifo_empty():
    """T takes 5 per packet, I 1: I waits for every packet.

    T  p0 0-5 | p1 5-10 | p2 10-15
    I  empty 0-5 | p0 5-6 | empty 6-10 | p1 10-11 | empty 11-15 | p2 15-16
    """
    t = simulate_program(program(phase("ti", job("traversal", [5] * 3, entries=[1] * 3),
                                       job("intersection", [1] * 3, role=1, entries=[1] * 3))),
                         arch(frames=1, fifo_depth=4))
    assert log(t, "intersection") == [
        ("stall fifo_empty", 0), ("busy start", 5), ("busy end", 6), ("stall fifo_empty", 6),
        ("busy start", 10), ("busy end", 11), ("stall fifo_empty", 11), ("busy start", 15), ("busy end", 16)]
    assert stalls(t, "intersection") == {"fifo_empty": 5 + 4 + 4}
    assert stalls(t, "traversal") == {}
    assert t.frames[0]["done"] == 16


def test_fifo_depth_one_with_packets_larger_than_it():
    """Packets of 3, 0 and 5 addresses through a 1-deep FIFO: each takes the whole FIFO
    (the empty packet its end marker), so T waits for I after every packet.

    T  p0 0-2 | p1 2-4, full 4-5 | p2 5-7, full 7-8
    I  empty 0-2 | p0 2-5 | p1 5-8 | p2 8-11
    """
    t = simulate_program(program(phase("ti", job("traversal", [2] * 3, entries=[3, 0, 5]),
                                       job("intersection", [3] * 3, role=1, entries=[3, 0, 5]))),
                         arch(frames=1, fifo_depth=1))
    assert log(t, "traversal") == [("busy start", 0), ("busy end", 2), ("busy start", 2), ("busy end", 4),
                                   ("stall fifo_full", 4), ("busy start", 5), ("busy end", 7),
                                   ("stall fifo_full", 7)]
    assert stalls(t, "traversal") == {"fifo_full": 2} and stalls(t, "intersection") == {"fifo_empty": 2}
    assert t.frames[0]["done"] == 11


# -- 6. deadlocks ------------------------------------------------------------------------------

def test_deadlock_traversal_waits_for_fifo_space():
    """I takes 1 packet of the 3 T pushes into a 1-deep FIFO: T's third push waits forever."""
    bad = program(phase("ti", job("traversal", [1] * 3, entries=[1] * 3),
                        job("intersection", [1], role=1, entries=[1])))
    with pytest.raises(Deadlock) as err:
        simulate_program(bad, arch(frames=1, fifo_depth=1, max_events=10_000))
    msg = str(err.value)
    assert "no event is scheduled" in msg
    assert "pipe0.traversal waits for FIFO space (frame 0 ti)" in msg


def test_deadlock_intersection_waits_for_fifo_data():
    bad = program(phase("ti", job("traversal", [1], entries=[1]),
                        job("intersection", [1] * 2, role=1, entries=[1] * 2)))
    with pytest.raises(Deadlock, match=r"pipe0\.intersection waits for FIFO data \(frame 0 ti\)"):
        simulate_program(bad, arch(frames=1, max_events=10_000))


def test_event_budget():
    with pytest.raises(Deadlock, match=r"stopped at arch\.max_events = 5 events, the cap the config sets"):
        simulate_program(SWAP_PROGRAM, arch(frames=3, max_events=5))


def test_the_event_cap_is_named_for_what_it_is(monkeypatch):
    """A run stopped by arch.max_events is MaxEventsReached (a cap the config sets, to raise
    if the run is only long), not a model that stopped making progress; a Deadlock still,
    for what reports a run that could not finish. Past the liveness bound it is a Deadlock."""
    from tlm.arch import model
    from tlm.arch.units import MaxEventsReached

    with pytest.raises(MaxEventsReached, match=r"^stopped at arch\.max_events = 5 events, the cap the config sets "
                       r"\(raise it if the run is only long\), unfinished at cycle \d+: "):
        simulate_program(SWAP_PROGRAM, arch(frames=3, max_events=5))
    monkeypatch.setattr(model, "event_bound", lambda program, arch: 7)
    with pytest.raises(Deadlock) as err:
        simulate_program(SWAP_PROGRAM, arch(frames=3))
    assert type(err.value) is Deadlock and "it makes no progress" in str(err.value)


def test_the_liveness_bound_follows_the_program():
    """64 events per packet, job and tile, per frame, plus 100 000; it caps ``max_events``."""
    from tlm.arch import model

    p = program(phase("v", job("vertex", [1, 2, 3])), phase("f", job("fragment", [4], role=1)))
    assert model.event_bound(p, arch(frames=2)) == 64 * ((3 + 1) + (1 + 1) + 1) * 2 + 100_000


def test_a_model_past_the_liveness_bound_stops_and_says_why(monkeypatch):
    from tlm.arch import model

    monkeypatch.setattr(model, "event_bound", lambda program, arch: 7)
    with pytest.raises(Deadlock, match=r"cannot finish at cycle \d+ \(7 events passed, 64 per packet, job and "
                                       r"tile of the program: it makes no progress\): pipe0\.\w+ waits for"):
        simulate_program(SWAP_PROGRAM, arch(frames=3))


# -- 7. eq. 5.1 --------------------------------------------------------------------------------

EQ_PROGRAM = program(
    phase("v", job("vertex", [5, 7], misses=[2, 1], flushes=[1, 0])),
    phase("ti", job("traversal", [3, 4], misses=[1, 0], flushes=[0, 2], entries=[2, 1]),
          job("intersection", [6, 2], role=1, misses=[0, 3], entries=[2, 1])),
    phase("f", job("fragment", [4], role=1, misses=[1], flushes=[1]), copy_words=5),
)


@pytest.mark.parametrize("frames", [1, 2, 3])
def test_eq_5_1_sums_exactly(frames):
    a = arch(frames=frames, page_miss_cycles=12, flush_cycles=4, copy_words_per_cycle=2, swap_cycles=1)
    t = simulate_program(EQ_PROGRAM, a)
    assert_eq_5_1(t)
    end = t.units["xbar"]["elapsed"]
    assert all(b["elapsed"] == end for b in t.units.values())
    specs = {js.pm: js for ph in EQ_PROGRAM.phases for js in ph.jobs}
    for name in PMS:
        b = t.units[f"pipe0.{name}"]
        js = specs.get(name)
        if js is None:
            assert b["busy"] == b["T_ds"] == 0 and b["idle"] == end
            continue
        assert b["T_norm"] == int(js.norm.sum()) * frames
        assert b["T_ms"] == int(js.misses.sum()) * frames * a.page_miss_cycles
        assert b["T_ps"] == int(js.flushes.sum()) * frames * a.flush_cycles
    # the modules serve exactly the PMs' page misses, and each copy at both ends
    misses = sum(int(js.misses.sum()) for js in specs.values()) * frames
    assert sum(t.units[f"mem{i}"]["T_ms"] for i in range(4)) == misses * a.page_miss_cycles
    copy_cycles = math.ceil(5 / 2) * frames
    assert sum(t.units[f"mem{i}"]["T_norm"] for i in range(4)) == 2 * copy_cycles
    assert t.units["xbar"]["T_norm"] == copy_cycles
    # the trace agrees: every row is tiled by its slices, and its idle slices are the idle cycles
    for scope in t.trace.rows:
        slices = row(t, scope)
        assert slices[0][1] == 0 and sum(d for _, _, d in slices) == end, scope
        assert all(a_[1] + a_[2] == b_[1] for a_, b_ in itertools.pairwise(slices)), scope
        assert sum(d for n, _, d in slices if n == "idle") == t.units[scope]["idle"], scope


# -- 8. throughput and latency -------------------------------------------------------------------

def test_one_frame_throughput_is_latency_is_done():
    t = simulate_program(SWAP_PROGRAM, arch(frames=1, swap_cycles=2))
    # V 0-10, F 10-14
    assert t.frames[0]["done"] == 14
    assert t.cycles["throughput"] == t.cycles["latency"] == 14
    assert t.fps == 600e6 / 14
    assert t.checks == {"busy + stall + idle = elapsed": True, "every work item issued is retired": True,
                        "T_norm equals the programs' cycles": True,
                        "every FIFO entry pushed is popped": True}


def test_three_frames_throughput_and_latency():
    """Frames done 14, 28, 40 (see test_swap_each_time_a_pm_changes_module); f2 arrives at 14.

    Three frames with two in flight have no steady-state window (it needs 3 x 2 - 1): TThru
    is the stream's elapsed cycles per frame, and the estimate says so.
    """
    t = simulate_program(SWAP_PROGRAM, arch(frames=3, swap_cycles=2))
    assert [f["done"] for f in t.frames] == [14, 28, 40]
    assert t.cycles["throughput"] == round(40 / 3) == 13
    assert t.throughput_estimate == {"steady": False, "frames": 3, "window": None, "min_frames": 5,
                                     "estimator": t.throughput_estimate["estimator"], "slowest_pm": "vertex",
                                     "throughput_over_slowest_pm": 13 / 11, "latency_frames": [0, 1, 2]}
    assert t.cycles["latency"] == round((14 + 28 + (40 - 14)) / 3) == 23
    # a PM's own cycles per frame: busy + swap + copy + preemption, averaged over frames
    assert t.cycles["vertex"] == round((3 * 10 + 2 * 2) / 3)
    assert t.cycles["fragment"] == round((3 * 4 + 2 * 2) / 3)
    assert t.cycles["traversal"] == t.cycles["intersection"] == 0
    assert t.cycles["throughput"] >= max(t.cycles[p] for p in PMS)


@pytest.mark.parametrize("frames", [5, 6])
def test_steady_state_window(frames):
    """Two images in flight: frames 0 and 1 arrive at 0 (warm-up); frame f + 2 arrives when
    frame f is done, so the last completion has no younger image beside it (drain).

    TThru is taken between the 2nd and the 4th completion: two gaps, one whole period of
    the two images' alternation; the latency over the frames completing in it that arrived
    after the warm-up (frame 3: frame 2 arrived at the first completion, into the fill).
    """
    t = simulate_program(SWAP_PROGRAM, arch(frames=frames, swap_cycles=2))
    fr = sorted(t.frames, key=lambda f: f["done"])
    assert t.throughput_estimate["steady"] is True and t.throughput_estimate["window"] == [1, 3]
    assert t.cycles["throughput"] == round(Fraction(fr[3]["done"] - fr[1]["done"], 2))
    assert t.cycles["throughput"] >= max(t.cycles[p] for p in PMS)
    assert fr[2]["arrival"] == fr[0]["done"] < fr[1]["done"] == fr[3]["arrival"]
    assert t.throughput_estimate["latency_frames"] == [fr[3]["frame"]] == [3]
    assert t.cycles["latency"] == fr[3]["done"] - fr[3]["arrival"]


@pytest.mark.parametrize(("done", "k", "value", "window"), [
    ([10, 12, 30, 32, 50], 2, 10, [1, 3]),            # (32 - 12) / 2, the fewest frames for k = 2
    ([10, 12, 30, 32, 50, 52], 2, 10, [1, 3]),        # one more frame: the same window
    ([10, 12, 30, 32, 50, 51, 60, 61], 2, 10, [1, 5]),  # (51 - 12) / 4 = 9.75
    ([52, 50, 32, 30, 12, 10], 2, 10, [1, 3]),        # completion order, not frame order
    ([3, 9, 12, 20, 21], 2, 6, [1, 3]),               # (20 - 9) / 2 = 5.5, rounded half to even
    ([6, 9], 1, 3, [0, 1]),                           # one image: frames back to back, every gap
    ([5, 10, 15], 1, 5, [0, 2]),                      # (15 - 5) / 2
    ([5, 10, 15, 20, 26], 1, 5, [0, 4]),              # (26 - 5) / 4 = 5.25
])
def test_steady_throughput_window(done, k, value, window):
    v, est = steady_throughput(done, k)
    assert (v, est["window"], est["steady"]) == (value, window, True)


@pytest.mark.parametrize(("done", "k", "value"), [([7], 2, 7), ([6, 9], 2, 4), ([3, 9, 12, 20], 2, 5)])
def test_steady_throughput_short_stream_is_elapsed_per_frame(done, k, value):
    v, est = steady_throughput(done, k)
    assert (v, est["steady"], est["min_frames"]) == (value, False, 3 * k - 1)


def test_one_image_in_flight_one_frame_is_already_steady():
    """With one image in flight every frame runs alone from the same state (each PM keeps
    the one module of its role), so the first frame's time is the steady value: no
    "too short" warning for arch.frames = 1."""
    v, est = steady_throughput([7], 1)
    assert (v, est["steady"], est["window"]) == (7, True, None)
    fn_frames = [simulate_program(SWAP_PROGRAM, arch(frames=f, images_in_flight=1)) for f in (1, 2, 5)]
    assert {t.cycles["throughput"] for t in fn_frames} == {14}
    assert all(t.throughput_estimate["steady"] for t in fn_frames)


def _module_story(requests):
    """Clients post (name, at, misses, cycles, then) to one module process; (name, done) log."""
    import simpy

    from tlm.arch.memory import Module

    env = simpy.Environment()
    m = Module(env, "mem0", None)
    log = []

    def client(name, at, misses, cycles, then):
        yield env.timeout(at)
        yield m.request(name, misses, cycles, then=then)
        log.append((name, env.now))

    for r in requests:
        env.process(client(*r))
    env.run()
    return m, log


def test_a_memory_module_is_a_process_that_serves_its_clients_requests():
    """mem0: V's 2 misses 0-24; F's miss 24-36, then F computes 5 (its event at 41); F again 41-53;
    the crossbar's copy (no rows) 53-61."""
    m, log = _module_story([("pipe0.vertex", 0, 2, 24, 0), ("pipe0.fragment", 24, 1, 12, 5),
                            ("pipe0.fragment", 41, 1, 12, 0), ("xbar", 53, 0, 8, 0)])
    assert log == [("pipe0.vertex", 24), ("pipe0.fragment", 41), ("pipe0.fragment", 53), ("xbar", 61)]
    assert (m.rows_opened, m.requests) == (4, 4)
    assert (m.unit.stats.ms, m.unit.stats.norm) == (48, 8)  # page misses are T_ms, a copy's words T_norm
    assert m.unit.log == [("page misses start", 0), ("page misses end", 24), ("page misses start", 24),
                          ("page misses end", 36), ("page misses start", 41), ("page misses end", 53),
                          ("page misses start", 53), ("page misses end", 61)]


def test_a_module_refuses_a_second_client_while_it_serves_one():
    """The crossbar's one-to-one grant, checked by the module process on its own timeline."""
    with pytest.raises(AssertionError, match=r"mem0 serves xbar from cycle 40 while it serves pipe0\.fragment "
                                             r"until cycle 42"):
        _module_story([("pipe0.fragment", 30, 1, 12, 0), ("xbar", 40, 0, 8, 0)])
    _, log = _module_story([("pipe0.fragment", 30, 1, 12, 0), ("xbar", 42, 0, 8, 0)])  # back to back: fine
    assert log == [("pipe0.fragment", 42), ("xbar", 50)]


@pytest.mark.parametrize("before", [
    [],  # V and F ask for mem0 at once
    [phase("v", job("vertex", [5])), phase("f", job("fragment", [5]))],  # F held mem0 before: a stale route
    [phase("v", job("vertex", [5], role=1)), phase("f", job("fragment", [5], role=1))],  # both swap to mem0
])
def test_two_pms_never_work_on_one_module(before):
    """A (malformed) phase that puts V and F on the same module at once is refused by the
    crossbar, whatever the PMs were routed to before (and during the swap's cycles)."""
    both = phase("both", job("vertex", [50], role=0), job("fragment", [50], role=0))
    with pytest.raises(AssertionError, match=r"pipe0\.fragment asks for mem0 while pipe0\.vertex works on it"):
        simulate_program(program(*before, both), arch(frames=1, swap_cycles=2))


def test_the_crossbar_grants_a_module_to_one_pm_at_a_time():
    import simpy

    from tlm.arch.crossbar import Crossbar
    from tlm.arch.memory import Module
    from tlm.config import ArchConfig

    class FakePM:
        def __init__(self, scope):
            self.unit = type("U", (), {"scope": scope})()
            self.route = None
            self.working_on = None

    env = simpy.Environment()
    mods = [Module(env, f"mem{i}", None) for i in range(4)]
    xb = Crossbar(env, mods, ArchConfig(), None)
    t, i = FakePM("pipe0.traversal"), FakePM("pipe0.intersection")
    xb.route(t, 0)
    t.route, t.working_on = 0, 0
    with pytest.raises(AssertionError, match=r"pipe0\.intersection asks for mem0 while pipe0\.traversal works on it"):
        xb.route(i, 0)
    t.working_on = None  # T's job is done: the module may go to another PM
    xb.route(i, 0)
    assert xb.holder == {0: i}


# -- 9. extreme scales -----------------------------------------------------------------------------

def test_time_scales_far_apart():
    """1-cycle swaps beside 1e9-cycle phases.

    V  f0 0-1e9 | swap | f1 1e9+1 .. 2e9+1
    F  f0 1e9-2e9 | handshake 2e9 .. 2e9+1 | swap .. 2e9+2 | f1 p0 .. 3e9+1, p1 .. 3e9+2
    """
    g = 10**9
    t = simulate_program(program(phase("v", job("vertex", [g])), phase("f", job("fragment", [g - 1, 1], role=1))),
                         arch(frames=2, swap_cycles=1))
    assert [f["done"] for f in t.frames] == [2 * g, 3 * g + 2]
    assert log(t, "fragment")[-6:] == [("stall handshake", 2 * g), ("stall swap", 2 * g + 1), ("busy start", 2 * g + 2),
                                       ("busy end", 3 * g + 1), ("busy start", 3 * g + 1), ("busy end", 3 * g + 2)]
    assert stall(t, "fragment", "swap") == stall(t, "vertex", "swap") == 1
    assert all(type(c) is int for _, c in log(t, "fragment") + log(t, "vertex"))
    assert all(type(v) is int for v in t.cycles.values())
    # two frames are too few for a steady-state window: the stream's elapsed cycles per frame
    assert t.cycles["throughput"] == round(Fraction(3 * g + 2, 2)) == 3 * g // 2 + 1
    assert t.throughput_estimate["steady"] is False
    assert_eq_5_1(t)


@pytest.mark.parametrize(("miss_cycles", "done"), [(0, 5 + 2), (12, 5 + 3 * 12 + 2 + 12), (10**6, 7 + 4 * 10**6)])
def test_page_miss_latency_zero_and_huge(miss_cycles, done):
    """V: 3 misses then 5 cycles; F: 1 miss then 2 cycles."""
    t = simulate_program(program(phase("v", job("vertex", [5], misses=[3])),
                                 phase("f", job("fragment", [2], role=1, misses=[1]))),
                         arch(frames=1, page_miss_cycles=miss_cycles))
    assert t.frames[0]["done"] == done and type(t.frames[0]["done"]) is int
    assert t.units["pipe0.vertex"]["T_ms"] == t.units["mem0"]["T_ms"] == 3 * miss_cycles
    assert t.units["pipe0.fragment"]["T_ms"] == t.units["mem1"]["T_ms"] == miss_cycles
    assert t.units["pipe0.fragment"]["stall"]["handshake"] == 3 * miss_cycles + 5
    assert_eq_5_1(t)


def test_empty_jobs_and_empty_program():
    t = simulate_program(program(), arch(frames=2))
    assert [f["done"] for f in t.frames] == [0, 0] and t.cycles["throughput"] == 0 and t.fps == math.inf
    none = np.zeros(0, dtype=np.int64)
    t = simulate_program(program(phase("ti", job("traversal", none, entries=none),
                                       job("intersection", none, role=1, entries=none))), arch(frames=1))
    assert t.frames[0]["done"] == 0


# -- 10. end to end on a real render ---------------------------------------------------------------

@pytest.fixture(scope="module")
def ring():
    from tlm.experiments.run import render

    cfg = config_from_dict({"scene": "ring", "mode": "rcast", "resolution": [32, 24], "render": {"spp": 1},
                            "arch": {"frames": 2}}, "test")
    return cfg, render(cfg).functional(), load_programs()


def _with(a, **kw):
    import dataclasses

    return dataclasses.replace(a, **kw)


@pytest.mark.parametrize("packet_size", [1, 64, 32 * 24])
def test_ring_end_to_end(ring, packet_size):
    cfg, fn, progs = ring
    t = simulate(fn, progs, _with(cfg.arch, packet_size=packet_size))
    assert set(t.cycles) == {*PMS, "throughput", "latency"}
    assert all(type(v) is int for v in t.cycles.values())
    assert t.cycles["throughput"] >= max(t.cycles[p] for p in PMS)
    assert t.cycles["throughput"] > 0 and t.cycles["latency"] > 0
    assert_eq_5_1(t)
    # T_norm of each PM is the programs' cycles whatever the packet size (running-total rounding)
    whole = frame_program(fn, progs, _with(cfg.arch, packet_size=fn.pixels))
    for name in PMS:
        norm = sum(int(js.norm.sum()) for ph in whole.phases for js in ph.jobs if js.pm == name)
        assert t.units[f"pipe0.{name}"]["T_norm"] == norm * cfg.arch.frames, name


def test_ring_t_norm_is_packet_size_invariant(ring):
    cfg, fn, progs = ring
    norms = []
    for ps in (1, 7, 64, fn.pixels):
        t = simulate(fn, progs, _with(cfg.arch, packet_size=ps, frames=1, trace=False))
        norms.append({name: pm.unit.stats.norm for name, pm in t.model.pms.items()})
    assert all(n == norms[0] for n in norms)


def test_ring_fifo_depth_one_finishes(ring):
    cfg, fn, progs = ring
    t = simulate(fn, progs, _with(cfg.arch, fifo_depth=1, packet_size=64))
    assert t.units["pipe0.traversal"]["stall"]["fifo_full"] > 0
    assert_eq_5_1(t)


def test_ring_functional_round_trip(ring, tmp_path):
    cfg, fn, progs = ring
    fn.save(tmp_path / "f.npz")
    back = Functional.load(tmp_path / "f.npz")
    a = _with(cfg.arch, packet_size=64)
    t1, t2 = simulate(fn, progs, a), simulate(back, progs, a)
    assert t1.cycles == t2.cycles and t1.frames == t2.frames and t1.units == t2.units


def test_ring_trace_json(ring):
    cfg, fn, progs = ring
    t = simulate(fn, progs, _with(cfg.arch, packet_size=64))
    doc = t.trace.to_json(cfg.arch.clock_hz)
    threads = {e["args"]["name"] for e in doc["traceEvents"] if e["ph"] == "M" and e["name"] == "thread_name"}
    assert threads == {*(f"pipe0.{p}" for p in PMS), *(f"mem{i}" for i in range(4)), "xbar"}
    names = {e["name"] for e in doc["traceEvents"] if e["ph"] == "X"}
    assert {"busy", "idle", "page misses", "stall: handshake", "stall: fifo_empty", "stall: swap",
            "stall: copy"} <= names
    assert all(n in {"busy", "idle", "page misses", "preempted"} or n.startswith(("stall: ", "copy mem"))
               for n in names)
    assert {n.removeprefix("stall: ") for n in names if n.startswith("stall: ")} <= set(STALL_CAUSES)


def test_ring_vertices_are_copied_towards_the_intersection_pm(ring):
    cfg, fn, progs = ring
    t = simulate(fn, progs, _with(cfg.arch, packet_size=64, frames=1))
    first = t.model.xbar.unit.log[0][0]
    assert first == "copy mem0->mem1: vertices (frame 0) start"


# -- 11. bad instruction-cost tables ---------------------------------------------------------------

def _table(tmp_path, edit):
    raw = copy.deepcopy(yaml.safe_load(DEFAULT_PATH.read_text()))
    edit(raw)
    path = tmp_path / "programs.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


@pytest.mark.slow
@pytest.mark.parametrize(("edit", "key", "what"), [
    (lambda r: r["vertex"]["geometry_bsp"].update(instructoins={}), "vertex.geometry_bsp.instructoins",
     "unknown key (did you mean 'instructions'?)"),
    (lambda r: r["vertex"]["geometry_bsp"]["instructions"].update(elements=-1),
     "vertex.geometry_bsp.instructions.elements", "-1 must be a number >= 0"),
    (lambda r: r["traversal"].update(scale=-0.5), "traversal.scale", "-0.5 must be a number >= 0"),
    (lambda r: r["intersection"].update(stages=1.5), "intersection.stages", "1.5 must be a whole number >= 0"),
    (lambda r: r["fragment"]["shade"].update(misses=3), "fragment.shade.misses", "3 must be a work key or null"),
    (lambda r: r.pop("fragment"), "fragment", "missing section"),
    (lambda r: r.update(verteks={}), "programs.verteks", "unknown key (did you mean 'vertex'?)"),
    (lambda r: r["traversal"].update(record_cycles=float("nan")), "traversal.record_cycles",
     "nan must be a number >= 0"),
    (lambda r: r["traversal"]["shadow"].update(records="shadow_rays"), "traversal.shadow.records",
     "'shadow_rays' must be a list of work keys"),
    (lambda r: r["traversal"]["shadow"].update(records=["shadow_ray"]), "traversal.shadow.records.shadow_ray",
     "unknown work item (did you mean 'shadow_rays'?)"),
    (lambda r: r["fragment"]["shade"].update(records=["items", "items"]), "fragment.shade.records",
     "['items', 'items'] names a key twice"),
])
def test_bad_programs_table(tmp_path, edit, key, what):
    path = _table(tmp_path, edit)
    with pytest.raises(InputError) as err:
        load_programs(path)
    assert str(err.value) == f"{path}: {key}: {what}"
    assert err.value.key == key and err.value.source == str(path)


def test_default_programs_table_loads(tmp_path):
    progs = load_programs(_table(tmp_path, lambda r: None))
    assert progs.scale == load_programs().scale
    assert progs.record_cycles == load_programs().record_cycles
    assert progs.jobs == load_programs().jobs


def test_a_record_costs_the_pms_record_cycles_on_top_of_its_instructions():
    """T_norm = round(scale x instructions + record_cycles x records), rounded on the running total."""
    progs = load_programs().with_scales({"traversal": 0.5, "fragment": 2.0}, {"traversal": 10.25, "fragment": 7.0})
    counts = {"primary_rays": np.array([4, 0, 3]), "secondary_rays": np.array([1, 2, 0]),
              "node_visits": np.array([10, 20, 30]), "shadow_rays": np.array([2, 2, 2])}
    items = np.array([4, 4, 3])
    norm, _, _ = progs.cost("traversal", "rays", counts, items)
    ins = progs.jobs[("traversal", "rays")].instructions
    instr = 0.5 * (ins["primary_rays"] * counts["primary_rays"] + ins["secondary_rays"] * counts["secondary_rays"]
                   + ins["node_visits"] * counts["node_visits"])
    raw = instr + 10.25 * (counts["primary_rays"] + counts["secondary_rays"])
    assert norm.tolist() == np.diff(np.concatenate([[0], np.rint(np.cumsum(raw))])).astype(int).tolist()
    assert int(norm.sum()) == round(raw.sum())
    without, _, _ = progs.with_scales({}, {"traversal": 0.0}).cost("traversal", "rays", counts, items)
    assert int(norm.sum() - without.sum()) == round(raw.sum()) - round(instr.sum())
    # a job without records (the Fragment PM's shadow-ray results) pays nothing per record
    assert progs.jobs[("fragment", "light")].records == ()
    light, _, _ = progs.cost("fragment", "light", counts, items)
    light0, _, _ = progs.with_scales({}, {"fragment": 0.0}).cost("fragment", "light", counts, items)
    assert light.tolist() == light0.tolist() and light.sum() > 0
    # the shade job's records are its eye rays: the fragment's own record_cycles, not the traversal's
    shade, _, _ = progs.cost("fragment", "shade", counts, items)
    shade0, _, _ = progs.with_scales({}, {"fragment": 0.0}).cost("fragment", "shade", counts, items)
    assert int(shade.sum() - shade0.sum()) == 7 * 7
    assert progs.record_count("traversal", "rays", {"primary_rays": 7, "secondary_rays": 3, "rays": 100}) == 10


@pytest.mark.parametrize(("edit", "key"), [
    (lambda r: r["vertex"].pop("photon_emit"), "vertex.photon_emit"),
    (lambda r: r["traversal"]["rays"]["instructions"].update(node_visit=4), "traversal.rays.instructions.node_visit"),
    (lambda r: r["traversal"]["rays"].update(misses="trav_mises"), "traversal.rays.misses"),
])
def test_programs_table_typos_are_errors(tmp_path, edit, key):
    path = _table(tmp_path, edit)
    with pytest.raises(InputError, match=f"{path}: {key}: "):
        load_programs(path)
