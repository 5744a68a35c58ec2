"""The timing layer's plumbing: the order of a cycle's events, the PM kinds, the schedulers.

:mod:`tlm.arch.events` names the priorities of one cycle and releases the end-of-cycle
decisions (:class:`CycleEnd`); the PMs wait on any-of sets with the fast ``_AnyOf`` or,
outside the tested SimPy release, with ``simpy.AnyOf``: both must give the same cycles.
Each PM kind is a class of :mod:`tlm.arch.pm`; each scheduler a class of
:mod:`tlm.arch.schedulers` that the control unit dispatches to by name.
"""

from __future__ import annotations

import dataclasses
import heapq
import re
from pathlib import Path

import numpy as np
import pytest
import simpy

from tlm.arch import events, pm
from tlm.arch.costs import load_programs
from tlm.arch.events import CycleEnd, Priority, Signal, _AnyOf, any_of_class
from tlm.arch.frame_program import PMS, FrameProgram, JobSpec, PhaseSpec, Stage, Tile
from tlm.arch.model import simulate, simulate_program
from tlm.arch.schedulers import Static
from tlm.arch.units import Unit, run
from tlm.config import config_from_dict
from tlm.registry import SCHEDULERS

ARCH = Path(__file__).resolve().parents[1] / "tlm" / "arch"


# -- the order of one cycle's events ----------------------------------------------------------

def test_priorities_extend_simpys_in_the_order_the_model_needs():
    assert (Priority.URGENT, Priority.NORMAL) == (simpy.events.URGENT, simpy.events.NORMAL)
    assert list(Priority) == sorted(Priority)
    assert [p.name for p in Priority] == ["URGENT", "NORMAL", "SETTLE", "DISPATCH", "ARBITER"]


def test_end_of_cycle_events_run_after_the_cycle_by_priority():
    """Cycle 0: the normal events, then SETTLE (and the normal event it starts), DISPATCH,
    ARBITER; the two SETTLE events in the order they were asked for. Cycle 1 after them all."""
    env = simpy.Environment()
    late = CycleEnd(env)
    log = []

    def note(what):
        return lambda _ev: log.append((what, env.now))

    def asks():
        late.event(Priority.ARBITER).callbacks.append(note("arbiter"))
        late.event(Priority.SETTLE).callbacks.append(note("settle a"))
        late.event(Priority.DISPATCH).callbacks.append(note("dispatch"))
        yield late.event(Priority.SETTLE)
        log.append(("settle b", env.now))
        env.timeout(0).callbacks.append(note("normal, after settle b"))

    def normal():
        yield env.timeout(0)
        log.append(("normal", env.now))
        yield env.timeout(1)
        log.append(("next cycle", env.now))

    env.process(asks())
    done = env.process(normal())
    counts = {}
    assert run(env, done, [], counts=counts, cycle_end=late) == 1
    assert log == [("normal", 0), ("settle a", 0), ("settle b", 0), ("normal, after settle b", 0),
                   ("dispatch", 0), ("arbiter", 0), ("next cycle", 1)]
    # two process starts, 2 timeouts + 1, 4 end-of-cycle events, the end of asks: one SimPy event each
    assert counts["events"] == 10


def test_end_of_cycle_events_are_after_normal_priority_only():
    late = CycleEnd(simpy.Environment())
    for p in (Priority.URGENT, Priority.NORMAL):
        with pytest.raises(ValueError, match=r"must come after Priority\.NORMAL"):
            late.event(p)


def test_an_end_of_cycle_event_left_behind_by_the_clock_is_refused():
    env = simpy.Environment()
    late = CycleEnd(env)
    late.event(Priority.SETTLE)
    env.run(until=3)  # (env.run does not release them)
    with pytest.raises(RuntimeError, match="of cycle 0 was released at cycle 3"):
        late.release()


def test_a_signal_costs_an_event_only_when_awaited():
    env = simpy.Environment()
    sig = Signal(env)
    sig.fire()  # nobody waits: nothing scheduled
    assert env.peek() == float("inf")
    woke = []

    def waiter():
        yield sig.wait()
        woke.append(env.now)
        yield sig.wait()  # a new event, fired by the second fire
        woke.append(env.now)

    def firer():
        yield env.timeout(2)
        sig.fire()
        sig.fire()  # (the same cycle: the event is gone, nothing more)
        yield env.timeout(3)
        sig.fire()

    env.process(waiter())
    env.process(firer())
    env.run()
    assert woke == [2, 5]


# -- the fast any-of and its public fallback --------------------------------------------------

def test_the_fast_any_of_is_used_on_the_tested_release_only(monkeypatch):
    monkeypatch.delenv(events.PUBLIC_ONLY, raising=False)
    assert events.simpy_release() == events.TESTED_SIMPY  # (pyproject.toml pins it)
    assert any_of_class() is _AnyOf
    monkeypatch.setenv(events.PUBLIC_ONLY, "1")
    assert any_of_class() is simpy.AnyOf
    monkeypatch.setenv(events.PUBLIC_ONLY, "0")
    assert any_of_class() is _AnyOf
    monkeypatch.setattr(events, "simpy_release", lambda: (4, 2))
    assert any_of_class() is simpy.AnyOf


@pytest.fixture(scope="module")
def cornell_pmap():
    from tlm.experiments.run import render

    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "resolution": [24, 24], "photons": {"count": 3000},
                            "arch": {"frames": 3, "packet_size": 16, "trace": False}}, "test")
    return cfg, render(cfg).functional(), load_programs()


@pytest.mark.slow
@pytest.mark.parametrize(("pipelines", "scheduler"), [(1, "static"), (3, "static"), (2, "dynamic"), (3, "dynamic")])
def test_the_public_any_of_gives_the_same_cycles(cornell_pmap, monkeypatch, pipelines, scheduler):
    """Two images in flight, preemption on (16 cycles to save or restore), FIFOs of 4: the
    model with ``simpy.AnyOf`` gives the fast path's cycles, unit by unit, and its frames; it
    processes one SimPy event more for each wait that was not over when it began."""
    cfg, fn, progs = cornell_pmap
    a = dataclasses.replace(cfg.arch, pipelines=pipelines, scheduler=scheduler, fifo_depth=4,
                            context_switch_cycles=16, images_in_flight=2)
    monkeypatch.delenv(events.PUBLIC_ONLY, raising=False)
    fast = simulate(fn, progs, a)
    monkeypatch.setenv(events.PUBLIC_ONLY, "1")
    public = simulate(fn, progs, a)
    assert all(type(p._any_of) is type and p._any_of is simpy.AnyOf for p in public.model.pms.values())
    assert sum(fast.crossbar["preemptions"].values()) > 0  # (preemption happens)
    assert (fast.cycles, fast.frames, fast.units, fast.crossbar) == \
           (public.cycles, public.frames, public.units, public.crossbar)
    assert public.events > fast.events


# -- same-cycle order: the end-of-cycle events too ---------------------------------------------

class _Reversed(simpy.Environment):
    """Runs events of one cycle and one priority in the reverse of the order they were scheduled."""

    def schedule(self, event, priority=1, delay=0):
        heapq.heappush(self._queue, (self._now + delay, priority, -next(self._eid), event))


def _reversed_event(self, priority):
    """:meth:`CycleEnd.event` with the events of one priority in the reverse order."""
    ev = self.env.event()
    heapq.heappush(self.queue, (priority, -next(self._order), self.env.now, ev))
    return ev


@pytest.mark.slow
@pytest.mark.parametrize(("pipelines", "scheduler"), [(2, "static"), (3, "dynamic")])
def test_no_result_depends_on_the_order_of_end_of_cycle_events(cornell_pmap, monkeypatch, pipelines, scheduler):
    """Same-cycle events in reverse order, the end-of-cycle ones of each priority too (the
    PMs' settling, the tile dispatches, the arbiter's grants): the same cycles, unit by unit."""
    cfg, fn, progs = cornell_pmap
    a = dataclasses.replace(cfg.arch, pipelines=pipelines, scheduler=scheduler, fanout="serial")
    t = simulate(fn, progs, a)
    monkeypatch.setattr(simpy, "Environment", _Reversed)
    monkeypatch.setattr(CycleEnd, "event", _reversed_event)
    r = simulate(fn, progs, a)
    assert (t.cycles, t.frames, t.units) == (r.cycles, r.frames, r.units)


# -- one class per PM kind -----------------------------------------------------------------------

def _job(kind, role, norms, entries=None):
    n = len(norms)
    return JobSpec(kind, "test", role, np.array(norms, np.int64), np.zeros(n, np.int64), np.zeros(n, np.int64),
                   np.ones(n, np.int64), None if entries is None else np.array(entries, np.int64))


def _arch(**kw):
    return config_from_dict({"arch": {"trace": False, **kw}}, "test").arch


def test_each_pm_kind_is_a_class_and_the_vertex_pm_is_shared():
    """Three pipelines: one Vertex PM (pipeline 0), a Traversal, Intersection and Fragment PM each."""
    assert list(pm.PM_KINDS) == list(PMS)
    geometry = Stage("g", True, (Tile("g", (PhaseSpec("g", (_job("vertex", 0, [3]),), 0),)),))
    tiles = tuple(Tile(f"t{i}", (PhaseSpec("ti", (_job("traversal", 0, [2, 2], [1, 3]),
                                                   _job("intersection", 1, [1, 4], [1, 3])), 0),
                                 PhaseSpec("f", (_job("fragment", 1, [5]),), 0)))
                  for i in range(3))
    prog = FrameProgram((geometry, Stage("px", False, tiles)), {}, 3, "static")
    t = simulate_program(prog, _arch(pipelines=3, frames=1))
    kinds = {key: type(unit) for key, unit in t.model.pms.items()}
    assert kinds == {(0, "vertex"): pm.Vertex,
                     **{(p, k): pm.PM_KINDS[k] for p in range(3) for k in ("traversal", "intersection", "fragment")}}
    assert {u.unit.scope for u in t.model.pms.values()} >= {"pipe0.vertex", "pipe2.intersection"}
    # pipeline 1 behind V 0-3:  T  3-5, 5-7 (each packet's addresses into the FIFO)
    #                           I  fifo_empty 3-5 | 5-6 | fifo_empty 6-7 | 7-11    F  11-16
    assert t.model.pm(1, "traversal").unit.log == [("stall handshake", 0), ("busy start", 3), ("busy end", 5),
                                                   ("busy start", 5), ("busy end", 7)]
    assert t.model.pm(1, "intersection").unit.log == [
        ("stall handshake", 0), ("stall fifo_empty", 3), ("busy start", 5), ("busy end", 6),
        ("stall fifo_empty", 6), ("busy start", 7), ("busy end", 11)]
    assert t.model.pm(1, "fragment").unit.log == [("stall handshake", 0), ("busy start", 11), ("busy end", 16)]


def test_no_unit_behaviour_is_chosen_by_its_name():
    """The PM classes, not comparisons of a unit's name, decide what a unit does (nor does a
    comparison with a scheduler's name decide how tiles go out)."""
    pattern = re.compile(r"""(\bname|\.pm|\bkind|scheduler)\s*(==|!=|\bin\b)\s*[("']""")
    for path in ARCH.glob("*.py"):
        hits = [line for line in path.read_text().splitlines()
                if pattern.search(line) and not line.lstrip().startswith("for ")]
        assert hits == [], path.name


# -- schedulers: one class and one YAML value ----------------------------------------------------

class _Mirror(Static):
    """Static tiles, pipeline p running tile N - 1 - p: a scheduler added as one class."""

    def run_stage(self, frame, stage, gates):
        flipped = dataclasses.replace(stage, tiles=stage.tiles[::-1])
        return super().run_stage(frame, flipped, gates)


def test_a_scheduler_is_one_class_the_model_dispatches_to(monkeypatch):
    """The control unit asks SCHEDULERS[program.scheduler] for each tiled stage: a scheduler
    registered under a new name runs without a change to the model."""
    SCHEDULERS.names()  # (the built-in ones loaded)
    monkeypatch.setitem(SCHEDULERS._classes, "mirror", _Mirror)
    geometry = Stage("g", True, (Tile("g", (PhaseSpec("g", (_job("vertex", 0, [3]),), 0),)),))
    tiles = (Tile("big", (PhaseSpec("f", (_job("fragment", 1, [40]),), 0),)),
             Tile("small", (PhaseSpec("f", (_job("fragment", 1, [10]),), 0),)))
    a = _arch(pipelines=2, frames=1, images_in_flight=1)
    by = {}
    for name in ("static", "mirror"):
        t = simulate_program(FrameProgram((geometry, Stage("px", False, tiles)), {}, 2, name), a)
        by[name] = [t.model.pm(p, "fragment").unit.stats.norm for p in range(2)]
    assert by == {"static": [40, 10], "mirror": [10, 40]}


def test_the_program_is_the_one_source_of_pipelines_and_scheduler():
    """A program cut for two static tiles runs on two pipelines under its scheduler, whatever
    ``arch.pipelines`` and ``arch.scheduler`` say: the model reads them in the program alone
    (frame_program read them in the arch config to cut it)."""
    geometry = Stage("g", True, (Tile("g", (PhaseSpec("g", (_job("vertex", 0, [3]),), 0),)),))
    tiles = (Tile("big", (PhaseSpec("f", (_job("fragment", 1, [40]),), 0),)),
             Tile("small", (PhaseSpec("f", (_job("fragment", 1, [10]),), 0),)))
    prog = FrameProgram((geometry, Stage("px", False, tiles)), {}, 2, "static")
    runs = [simulate_program(prog, _arch(frames=1, images_in_flight=1, **kw))
            for kw in ({"pipelines": 2, "scheduler": "static"}, {"pipelines": 1, "scheduler": "dynamic"},
                       {"pipelines": 4, "scheduler": "dynamic", "tiles_per_pipeline": 3})]
    for t in runs:
        assert sorted({p for p, _ in t.model.pms}) == [0, 1]
        assert [t.model.pm(p, "fragment").unit.stats.norm for p in range(2)] == [40, 10]
        assert len(t.pipelines) == 2 and t.to_dict()["scheduler"] == "static"
        assert (t.cycles, t.units) == (runs[0].cycles, runs[0].units)


def test_units_report_their_own_results():
    """Each PM, memory module and the crossbar closes its books and reports them; the
    model's results are those reports. A PM that waits for a job at the end is idle to the end."""
    geometry = Stage("g", True, (Tile("g", (PhaseSpec("g", (_job("vertex", 0, [3, 4]),), 0),)),))
    tiles = (Tile("t0", (PhaseSpec("f", (_job("fragment", 1, [5]),), 6),), pixels=2),
             Tile("t1", (PhaseSpec("f", (_job("fragment", 1, [7, 1]),), 0),), pixels=2))
    t = simulate_program(FrameProgram((geometry, Stage("px", False, tiles)), {}, 2, "static"),
                         _arch(pipelines=2, frames=1, images_in_flight=1))
    model, end = t.model, max(f["done"] for f in t.frames)
    vertex = model.pm(0, "vertex").close(end)
    assert (vertex.scope, vertex.pipe, vertex.kind) == ("pipe0.vertex", 0, "vertex")
    assert (vertex.issued, vertex.retired, vertex.queued, vertex.norm, vertex.preemptions) == (2, 2, 0, 7, 0)
    assert vertex.breakdown == t.units["pipe0.vertex"] and vertex.breakdown["idle"] == end - 7
    frag1 = model.pm(1, "fragment").close(end)
    assert (frag1.issued, frag1.norm, frag1.own) == (2, 8, t.pipelines[1]["fragment"])
    xbar = model.xbar.close(end)
    assert xbar.breakdown == t.units["xbar"]
    assert {"swaps": xbar.swaps, "copies": xbar.copies, "words_copied": xbar.words_copied} == \
        {k: t.crossbar[k] for k in ("swaps", "copies", "words_copied")}
    # tile 0's copy of 6 words, then each tile's 2 pixels to the compose unit
    assert (xbar.swaps, xbar.copies, xbar.words_copied) == (0, 3, 10)
    assert xbar.breakdown["T_norm"] == sum(-(-w // model.arch.copy_words_per_cycle) for w in (6, 2, 2))
    for m in model.modules:
        r = m.close(end)
        assert r.breakdown == t.units[r.scope] and (r.requests, r.rows_opened) == (m.requests, m.rows_opened)
    assert list(t.units) == [*(pm.unit.scope for pm in model.pms.values()),
                             *(m.unit.scope for m in model.modules), "xbar"]
    model.pm(0, "vertex").unit.stats.idle += 1  # a cycle booked twice: the report names the unit
    with pytest.raises(AssertionError, match=r"^pipe0\.vertex: busy 7 \+ stall 0 \+ idle"):
        model.pm(0, "vertex").close(end)


def test_the_dynamic_tile_queue_dispatches_at_the_end_of_the_cycle():
    """Two pipelines ask for a tile in the same cycle: they get them in pipeline order, once
    the cycle's normal events have run (a request made later in the cycle still counts)."""
    from tlm.arch.schedulers import TileQueue

    env = simpy.Environment()
    late = CycleEnd(env)
    queue = TileQueue(env, ["t0", "t1", "t2"], late)
    got = []

    def pipe(p, after):
        for _ in range(after):
            yield env.timeout(0)
        tile = yield queue.request(p)
        got.append((p, tile, env.now))

    procs = [env.process(pipe(1, 0)), env.process(pipe(0, 3)), env.process(pipe(2, 1))]
    run(env, simpy.AllOf(env, procs), [], cycle_end=late)
    assert sorted(got) == [(0, "t0", 0), (1, "t1", 0), (2, "t2", 0)]


def test_a_pm_unit_is_named_by_its_kind_and_pipeline():
    class FakeModel:
        env = simpy.Environment()
        trace = None
        arch = _arch()
        cycle_end = CycleEnd(env)

    unit = pm.Traversal(FakeModel(), 3).unit
    assert isinstance(unit, Unit) and unit.scope == "pipe3.traversal"


def test_only_the_fast_any_of_touches_simpy_internals():
    """The one documented exception: SimPy's private attributes are read or set in
    tlm/arch/events.py's _AnyOf and nowhere else in the timing layer."""
    private = re.compile(r"\._(ok|value|defused|queue|now|eid|triggered|callbacks)\b")
    for path in ARCH.glob("*.py"):
        text = path.read_text()
        if path.name == "events.py":
            start = text.index("class _AnyOf(")
            text = text[:start]
        assert private.findall(text) == [], path.name

