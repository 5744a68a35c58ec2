"""The timing layer's shortcuts give what the general forms they replace give.

The hot paths of the SimPy layer avoid some general machinery: ``events._AnyOf`` for
``env.any_of``, ``JobSpec.packets`` for numpy scalars, ``Trace.add_work`` for
``Trace.slice(**args)``, a unit log spelled out when read, lazily summed packet counts in
the frame program. Each is checked here against the
general form on small cases (``tests/test_golden.py`` checks whole runs).
"""

from __future__ import annotations

import random

import numpy as np
import pytest
import simpy

from tlm.arch.events import _AnyOf
from tlm.arch.frame_program import JobSpec, _PacketSums, split
from tlm.arch.units import Trace, Unit, run


def _any_of_story(make, seed: int) -> list:
    """When, and with what, processes that wait on any-of sets of random events wake.

    Each waiter draws from a generator of its own, so its story does not depend on the
    order in which same-cycle events run. Returns each waiter's (cycle, value is None or
    a ConditionValue) wake-ups, the cycle each event fired, the callbacks left on the
    events, and the number of SimPy events processed.
    """
    env = simpy.Environment()
    events = [env.event() for _ in range(8)]  # events 6 and 7 never fire: callbacks stay on them
    fired, woke = {}, {w: [] for w in range(4)}

    def firer(i, ev):
        yield env.timeout(random.Random(seed * 1000 + i).randint(0, 4))
        if not ev.triggered:
            ev.succeed(i)
        fired[i] = env.now

    def waiter(w):
        rng = random.Random(seed * 1000 + 100 + w)
        yield env.timeout(rng.randint(0, 3))
        for _ in range(3):
            pick = rng.sample(events[:6], rng.randint(1, 3))
            if rng.random() < 0.5:  # sometimes wait on a never-fired event too, first or last
                pick.insert(rng.choice([0, len(pick)]), events[6 + rng.randint(0, 1)])
            value = yield make(env, pick)
            woke[w].append((env.now, value is None or isinstance(value, simpy.events.ConditionValue)))
            yield env.timeout(rng.randint(0, 1))

    for i, ev in enumerate(events[:6]):
        env.process(firer(i, ev))
    for w in range(4):
        env.process(waiter(w))
    steps = 0
    while True:
        try:
            env.step()
        except simpy.core.EmptySchedule:
            break
        steps += 1
    return [woke, fired, [len(ev.callbacks or ()) for ev in events], steps]


@pytest.mark.parametrize("seed", range(40))
def test_any_of_fires_as_simpy_any_of(seed):
    """The same wake-ups in the same cycles, the callbacks taken off; one event less per wait
    that was not already over when it began."""
    ours, simpys = _any_of_story(_AnyOf, seed), _any_of_story(simpy.AnyOf, seed)
    assert ours[:3] == simpys[:3]
    waits = sum(len(v) for v in ours[0].values())
    assert simpys[3] - waits <= ours[3] < simpys[3]


def test_job_spec_packets_are_python_ints():
    rng = np.random.default_rng(1)
    arrays = [rng.integers(0, 1000, 7) for _ in range(5)]
    spec = JobSpec("traversal", "rays", 0, *arrays)
    assert spec.packets == [tuple(int(a[k]) for a in arrays) for k in range(7)]
    assert all(type(v) is int for p in spec.packets for v in p)
    bare = JobSpec("vertex", "geometry_bsp", 0, *arrays[:4])
    assert [p[4] for p in bare.packets] == [None] * 7


@pytest.mark.parametrize("packet_size", [1, 3, 8, 100])
def test_packet_sums_are_the_split_counts(packet_size):
    rng = np.random.default_rng(packet_size)
    work = {k: rng.integers(0, 50, 40) for k in ("a", "b", "c")}
    for idx in (np.arange(40), np.flatnonzero(work["a"] > 20), np.zeros(0, np.int64)):
        want = split("sub", {k: v[idx] for k, v in work.items()}, packet_size)
        got = _PacketSums(work, idx, packet_size)
        for k in work:
            assert np.array_equal(got.get(k), want.counts[k]) and got.get(k).dtype == np.int64
        assert got.get("missing") is None
        assert got.get("missing", 7) == 7


def test_add_work_merges_as_slice():
    a, b = Trace(), Trace()
    row = b.row("u")
    for name, s, e, norm, ms, ps in [("busy", 0, 4, 3, 1, 0), ("busy", 4, 6, 2, 0, 0), ("page misses", 6, 8, 0, 2, 0),
                                     ("busy", 9, 10, 1, 0, 0), ("busy", 10, 13, 1, 1, 1)]:
        a.slice("u", name, s, e, T_norm=norm, T_ms=ms, T_ps=ps)
        b.add_work(row, name, s, e, norm, ms, ps)
    a.fill_idle(20)
    b.fill_idle(20)
    assert a.to_json(1.0) == b.to_json(1.0)


def test_log_read_while_the_unit_works():
    env = simpy.Environment()
    unit = Unit(env, "u")
    reads = []

    def proc():
        yield from unit.work(2, label="a")
        reads.append(list(unit.log))
        yield from unit.stall("copy", env.timeout(3), "a copy")
        yield from unit.stall("swap", env.timeout(0), "nothing")
        reads.append(list(unit.log))
        yield from unit.work(1, 1, 1)

    done = env.process(proc())
    counts: dict = {}
    assert run(env, done, [unit], counts=counts) == 8
    assert reads[0] == [("a start", 0), ("a end", 2)]
    assert reads[1] == [*reads[0], ("stall copy", 2)]
    assert unit.log == [*reads[1], ("busy start", 5), ("busy end", 8)]
    assert unit.log is unit.log
    assert counts["events"] == 5  # the process's start and its four timeouts (run stops once it has ended)
