"""Timing-layer building blocks, in SimPy's style: exact (what, cycle) logs of tiny setups."""

from __future__ import annotations

import json

import pytest
import simpy

from tlm.arch.units import STALL_CAUSES, Deadlock, Trace, Unit, run


@pytest.fixture
def env():
    return simpy.Environment()


def test_handshake_stall(env):
    """The Traversal PM cannot start before the Vertex PM has built the tree."""
    trace = Trace()
    vertex, traversal = Unit(env, "pipe0.vertex", trace), Unit(env, "pipe0.traversal", trace)
    tree = env.event()  # the controller's semaphore: the tree of image 0 is built

    def build():
        yield from vertex.work(5, label="build")
        tree.succeed()

    def traverse():
        yield from traversal.stall("handshake", tree, "the tree of image 0")
        yield from traversal.work(3, label="traverse")

    env.process(build())
    done = env.process(traverse())
    assert run(env, done, [vertex, traversal]) == 8
    assert vertex.log == [("build start", 0), ("build end", 5)]
    assert traversal.log == [("stall handshake", 0), ("traverse start", 5), ("traverse end", 8)]
    assert traversal.stats.breakdown(8) == {
        "T_norm": 3, "T_ms": 0, "T_ps": 0, "T_ds": 5, "stall": {**dict.fromkeys(STALL_CAUSES, 0), "handshake": 5},
        "busy": 3, "stalled": 5, "idle": 0, "elapsed": 8, "idle_measured": False,
        "fractions": {"busy": 0.375, "stalled": 0.625, "idle": 0.0},
    }
    assert vertex.stats.breakdown(8)["idle"] == 3
    # a semaphore already fired does not stall
    late = Unit(env, "pipe0.fragment")

    def after():
        yield from late.stall("handshake", tree, "the tree")
        yield from late.work(1)

    done = env.process(after())
    run(env, done, [late])
    assert late.log == [("busy start", 8), ("busy end", 9)] and late.stats.ds == 0


def test_fifo_full_and_empty(env):
    """Traversal pushes a triangle address every cycle into a 2-deep FIFO; Intersection
    takes one and spends 3 cycles on it. Traversal stalls when the FIFO is full;
    Intersection stalls while it is empty, at the start."""
    fifo = simpy.Container(env, capacity=2)
    trav, isect = Unit(env, "t"), Unit(env, "i")

    def producer():
        for _ in range(5):
            yield from trav.work(1, label="address")
            yield from trav.stall("fifo_full", fifo.put(1), "a FIFO slot")

    def consumer():
        for _ in range(5):
            yield from isect.stall("fifo_empty", fifo.get(1), "a triangle address")
            yield from isect.work(3, label="triangle")

    env.process(producer())
    done = env.process(consumer())
    assert run(env, done, [trav, isect]) == 16
    # By hand: addresses are pushed at 1, 2, 3, 4, 5. Intersection waits 0..1 for the
    # first and takes one more at 4, 7, 10, 13. At 4 its take comes first (its event was
    # scheduled earlier), so address 4 fits; address 5 finds the FIFO full (3 and 4)
    # and waits from 5 to the take at 7.
    assert isect.log[:3] == [("stall fifo_empty", 0), ("triangle start", 1), ("triangle end", 4)]
    assert [c for what, c in isect.log if what == "triangle start"] == [1, 4, 7, 10, 13]
    assert [c for what, c in trav.log if what == "stall fifo_full"] == [5]
    assert trav.stats.stall["fifo_full"] == 2
    assert isect.stats.stall["fifo_empty"] == 1 and isect.stats.busy == 15
    for unit in (trav, isect):
        b = unit.stats.breakdown(16)
        assert b["busy"] + b["stalled"] + b["idle"] == 16


@pytest.mark.parametrize("cause", ["swap", "copy", "preemption"])
def test_fixed_delays(env, cause):
    unit = Unit(env, "mem2")

    def proc():
        yield from unit.work(4)
        yield from unit.delay(cause, 7, f"a {cause}")
        yield from unit.work(1)

    done = env.process(proc())
    assert run(env, done, [unit]) == 12
    assert unit.log == [("busy start", 0), ("busy end", 4), (f"stall {cause}", 4), ("busy start", 11),
                        ("busy end", 12)]
    assert unit.stats.stall[cause] == 7


def test_eq_5_1_sums_exactly(env):
    trace = Trace()
    unit = Unit(env, "pipe0.fragment", trace)

    def proc():
        yield from unit.work(30, ms=24, ps=8, label="shade")
        yield env.timeout(5)  # idle
        yield from unit.delay("swap", 2, "the next module")

    done = env.process(proc())
    end = run(env, done, [unit])
    b = unit.stats.breakdown(end)
    assert (b["T_norm"], b["T_ms"], b["T_ps"], b["T_ds"], b["idle"]) == (30, 24, 8, 2, 5)
    assert b["T_norm"] + b["T_ms"] + b["T_ps"] + b["T_ds"] + b["idle"] == end == 69
    doc = json.loads(json.dumps(trace.to_json(600e6)))
    slices = [e for e in doc["traceEvents"] if e["ph"] == "X"]
    assert [(e["name"], e["args"]["start_cycle"], e["args"]["cycles"]) for e in slices] == [
        ("shade", 0, 62), ("stall: swap", 67, 2)]
    assert [x for e in slices for x in (e["ts"], e["dur"])] == pytest.approx([0, 62 / 600, 67 / 600, 2 / 600])  # us
    assert doc["traceEvents"][0]["args"]["name"] == "pipe0.fragment"
    assert doc["otherData"]["time_unit"] == "microseconds at the modelled clock"


def test_trace_rows_go_pipe_by_pipe():
    """PMs of pipeline 0 in the thesis's order, its modules, then pipeline 1's, compose and the crossbar last."""
    trace = Trace()
    trace.modules_per_pipe = 4
    for scope in ("xbar", "mem5", "pipe1.traversal", "compose", "mem0", "pipe0.fragment", "pipe0.vertex",
                  "pipe0.fragment (preempted)", "pipe1.intersection", "mem3", "pipe0.traversal"):
        trace.slice(scope, "busy", 0, 1)
    doc = trace.to_json(600e6)
    names = [e["args"]["name"] for e in doc["traceEvents"] if e["name"] == "thread_name"]
    assert names == ["pipe0.vertex", "pipe0.traversal", "pipe0.fragment", "pipe0.fragment (preempted)", "mem0",
                     "mem3", "pipe1.traversal", "pipe1.intersection", "mem5", "compose", "xbar"]
    sort = {e["tid"]: e["args"]["sort_index"] for e in doc["traceEvents"] if e["name"] == "thread_sort_index"}
    assert sort == {i: i for i in range(len(names))}


@pytest.mark.parametrize("n", [0, 1, 4090, 4091, 8186, 9000])
def test_trace_file_is_the_document_written_event_by_event(tmp_path, n):
    """``write`` writes the events in chunks of 4,096, and the text ``json.dumps`` makes of
    ``to_json``: no slice, one, and at the chunk seams (with the 3 rows' 6 metadata events:
    4,096 and 4,097 events, two full chunks, and a third part)."""
    trace = Trace()
    for k in range(n):
        trace.slice(f"pipe{k % 2}.traversal" if k % 3 else "mem1", "work", 3 * k, 3 * k + 2, tris=k)
    for hz in (None, 600e6):
        trace.write(tmp_path / "trace.json", hz)
        text, expected = (tmp_path / "trace.json").read_text(), json.dumps(trace.to_json(hz))
        same = text == expected  # (not in the assert: pytest's diff of two long lines takes minutes)
        assert same, next((i for i, (a, b) in enumerate(zip(text, expected)) if a != b), min(len(text), len(expected)))
        assert len(json.loads(text)["traceEvents"]) == n + 2 * len(trace.rows)


def test_deadlock_is_detected_and_named(env):
    a, b = Unit(env, "pipe0.vertex"), Unit(env, "pipe0.fragment")
    made = {a.scope: env.event(), b.scope: env.event()}  # each unit's semaphore

    def wait(unit, other, what):
        yield from unit.stall("handshake", made[other.scope], what)
        made[unit.scope].succeed()

    env.process(wait(a, b, "the fragments of image 0"))
    done = env.process(wait(b, a, "the rays of image 0"))
    with pytest.raises(Deadlock) as err:
        run(env, done, [a, b])
    msg = str(err.value)
    assert "cycle 0" in msg and "no event is scheduled" in msg
    assert "pipe0.vertex waits for the fragments of image 0" in msg
    assert "pipe0.fragment waits for the rays of image 0" in msg


def test_event_budget_stops_a_livelock(env):
    unit = Unit(env, "pipe0.traversal")
    never = env.event()

    def spin():
        while True:
            yield from unit.work(1)

    env.process(spin())
    with pytest.raises(Deadlock, match="100 events passed"):
        run(env, never, [unit], max_events=100)


@pytest.mark.parametrize("bad", [1.5, -1, True, "3"])
def test_cycles_are_whole_numbers(env, bad):
    unit = Unit(env, "u")

    def proc():
        yield from unit.work(bad)

    env.process(proc())
    with pytest.raises(ValueError, match="whole number of cycles"):
        env.run()


def test_unknown_stall_cause(env):
    unit = Unit(env, "u")
    with pytest.raises(ValueError, match="stall cause"):
        next(unit.stall("coffee", env.timeout(1), "x"))


def test_booked_idle_must_close_the_sum():
    """A unit that books its idle cycles (the PMs) is checked: a cycle lost or booked twice raises."""
    from tlm.arch.units import Stats

    s = Stats(norm=3, idle=4)
    s.stall["fifo_empty"] = 1
    assert s.breakdown(8)["idle"] == 4
    assert s.breakdown(8)["fractions"] == {"busy": 0.375, "stalled": 0.125, "idle": 0.5}
    with pytest.raises(AssertionError, match=r"busy 3 \+ stall 1 \+ idle 4 = 8 != elapsed 9"):
        s.breakdown(9)  # a cycle nobody booked
    with pytest.raises(AssertionError, match=r"!= elapsed 7"):
        s.breakdown(7)  # a cycle booked twice
