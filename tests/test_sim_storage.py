"""The timing layer's compact bookkeeping gives what the plain forms it replaces give.

``Trace`` keeps its slices flat in one list (a work slice's T_norm, T_ms and T_ps as
entries of their own, its args dict made when it is first read) and finds the idle gaps
in one pass when every row comes in start order; ``Unit`` keeps its log flat until it is
read; ``events.Flag`` is an event whose ``triggered`` is an attribute. Each is checked here
against the plain form on random cases (``tests/test_golden.py`` checks whole runs).
"""

from __future__ import annotations

import random
from operator import itemgetter

import pytest
import simpy

from tlm.arch.events import Flag, _AnyOf
from tlm.arch.units import Trace, Unit


class _ListTrace:
    """The slices as they were kept before: a list [name, start, end, tid, args] each."""

    def __init__(self) -> None:
        self.slices: list[list] = []
        self.last: dict[int, list] = {}

    def add(self, tid, name, start, end, args) -> None:
        last = self.last.get(tid)
        if last is not None and last[2] == start and last[0] == name:
            last[2] = end
            for k, v in args.items():
                old = last[4].get(k)
                if old is None:
                    last[4][k] = v
                elif type(v) is int and type(old) is int:
                    last[4][k] = old + v
            return
        event = [name, start, end, tid, args]
        self.slices.append(event)
        self.last[tid] = event

    def add_work(self, tid, name, start, end, norm, ms, ps) -> None:
        self.add(tid, name, start, end, {"T_norm": norm, "T_ms": ms, "T_ps": ps})

    def fill_idle(self, end: int) -> None:
        by_row: dict[int, list[list]] = {}
        for ev in self.slices:
            by_row.setdefault(ev[3], []).append(ev)
        idle = []
        for tid, spans in by_row.items():
            spans.sort(key=itemgetter(1, 2))
            t = 0
            for ev in spans:
                if ev[1] > t:
                    idle.append(["idle", t, ev[1], tid, {}])
                t = max(t, ev[2])
            if end > t:
                idle.append(["idle", t, end, tid, {}])
        self.slices.extend(idle)

    @property
    def events(self) -> list[dict]:
        return [{"name": n, "ph": "X", "ts": s, "dur": e - s, "pid": 0, "tid": tid, "args": a}
                for n, s, e, tid, a in self.slices]


def _story(seed: int, in_order: bool):
    """Random slices on a few rows: work (often continuing the row's latest slice), stalls
    and other slices with args, reads of the events along the way; rows in start order
    unless ``in_order`` is False."""
    rng = random.Random(seed)
    ops = []
    ends = [0] * 5
    for _ in range(400):
        tid = rng.randrange(5)
        start = ends[tid] + (0 if rng.random() < 0.6 else rng.randrange(1, 6))
        if not in_order and rng.random() < 0.05:
            start = max(0, start - rng.randrange(1, 30))  # (a slice before the row's latest)
        end = start + rng.randrange(1, 7)
        ends[tid] = max(ends[tid], end)
        r = rng.random()
        if r < 0.6:
            ops.append(("work", tid, rng.choice(["busy", "page misses"]), start, end,
                        rng.randrange(4), rng.randrange(3), rng.randrange(2)))
        elif r < 0.9:
            args = rng.choice([{"waiting_for": "x"}, {"T_norm": 2}, {"T_norm": 1.5}, {}, {"job": "f0"}])
            ops.append(("add", tid, rng.choice(["busy", "stall: copy", "preempted"]), start, end, dict(args)))
        else:
            ops.append(("read",))
    return ops, max(ends) + 3


@pytest.mark.slow
@pytest.mark.parametrize("in_order", [True, False])
@pytest.mark.parametrize("seed", range(12))
def test_flat_trace_is_the_list_trace(seed, in_order):
    ops, end = _story(seed, in_order)
    flat, ref = Trace(), _ListTrace()
    for i in range(5):
        flat.row(f"u{i}")
    for op in ops:
        if op[0] == "work":
            flat.add_work(*op[1:])
            ref.add_work(*op[1:])
        elif op[0] == "add":
            flat.add(*op[1:5], dict(op[5]))
            ref.add(*op[1:5], dict(op[5]))
        else:
            assert flat.events == ref.events  # (a read makes the work slices' args dicts: the rest goes on)
    assert flat.events == ref.events
    flat.fill_idle(end)
    ref.fill_idle(end)
    assert flat.events == ref.events
    again = flat.to_json(1.0)
    assert again == flat.to_json(1.0)  # (reading made the args dicts once: the same document every time)
    assert [e["args"]["cycles"] for e in again["traceEvents"] if e["ph"] == "X"] == [e["dur"] for e in ref.events]


def test_flat_log_is_spelled_out_as_before():
    env = simpy.Environment()
    unit = Unit(env, "u", Trace())

    def proc():
        yield from unit.work(2, 1, label="busy")
        yield from unit.stall("copy", env.timeout(4), "a copy")
        yield from unit.stall("swap", env.timeout(0), "nothing")  # (no cycle waited: not logged)
        unit.account(7, 0, 4, 0, "page misses")

    env.process(proc())
    env.run()
    assert unit.log == [("busy start", 0), ("busy end", 3), ("stall copy", 3),
                        ("page misses start", 7), ("page misses end", 11)]
    unit.log = []
    unit.account(11, 1, 0, 0, "busy")
    assert unit.log == [("busy start", 11), ("busy end", 12)]
    assert [(e["name"], e["ts"], e["dur"], e["args"]) for e in unit.trace.events] == [
        ("busy", 0, 3, {"T_norm": 2, "T_ms": 1, "T_ps": 0}), ("stall: copy", 3, 4, {"waiting_for": "a copy"}),
        ("page misses", 7, 4, {"T_norm": 0, "T_ms": 4, "T_ps": 0}),
        ("busy", 11, 1, {"T_norm": 1, "T_ms": 0, "T_ps": 0})]


def test_a_flag_is_an_event_with_triggered_set_as_it_is_triggered():
    env = simpy.Environment()
    a, b, c, d = Flag(env), Flag(env), Flag(env), env.event()
    assert not (a.triggered or b.triggered or c.triggered)
    a.succeed(7)
    assert a.triggered and not a.processed
    with pytest.raises(RuntimeError):
        a.succeed()
    assert a.triggered
    b.fail(ValueError("no"))
    b.defused = True
    assert b.triggered
    d.succeed(3)
    d.callbacks.append(c.trigger)
    got = []

    def proc():
        got.append((yield a))
        got.append((yield c))
        got.append((yield _AnyOf(env, [Flag(env), a])))

    env.process(proc())
    env.run()
    assert c.triggered and c.value == 3
    assert got == [7, 3, None]
    assert [type(e).triggered for e in (a, d)] == [False, simpy.events.Event.triggered]
