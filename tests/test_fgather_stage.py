"""Final gathering's host seconds are the fgather pass's (``host_seconds.pass_fgather``),
not the photon-map pass's, in which it runs; booked once (tlm.progress.booked_apart)."""

from __future__ import annotations

import math
import threading
import time

import pytest

import tlm.render.pmap as pmap_mod
from tlm.config import config_from_dict
from tlm.experiments.run import render
from tlm.progress import Timer, booked_apart

TINY = {"scene": "cornell", "mode": "pmap", "resolution": [16, 16],
        "render": {"spp": 1, "threads": 1, "light_samples": 1}, "photons": {"count": 4000}}


def test_a_block_booked_apart_leaves_its_stage():
    timer = Timer()
    t0 = time.perf_counter()
    with timer.stage("pass_pmap"):
        time.sleep(0.02)
        t1 = time.perf_counter()
        with booked_apart("pass_fgather", within="pass_pmap"):
            time.sleep(0.05)
            with booked_apart("pass_fgather", within="pass_pmap"):  # (not within pass_pmap now: nothing)
                time.sleep(0.01)
        t2 = time.perf_counter()
        time.sleep(0.02)
    t3 = time.perf_counter()
    s = dict(timer.seconds)
    assert 0.06 <= s["pass_fgather"] <= t2 - t1 and s["pass_pmap"] >= 0.04, s
    # booked once: the two add up to the stage's wall time (the hand-overs at one instant each)
    assert t3 - t0 - 0.01 <= s["pass_pmap"] + s["pass_fgather"] <= t3 - t0, s
    with timer.stage("reference"), booked_apart("pass_fgather", within="pass_pmap"):  # another stage: its own
        time.sleep(0.01)
    assert timer.seconds["reference"] >= 0.01 and timer.seconds["pass_fgather"] == s["pass_fgather"]
    with booked_apart("pass_fgather", within="pass_pmap"):  # no stage at all: nothing booked
        pass
    assert set(timer.seconds) == {"pass_pmap", "pass_fgather", "reference"}


def test_a_stage_on_two_threads_counts_the_wall_time_while_either_runs_it():
    """Thread A in pmap, the middle of it booked apart; thread B in pmap meanwhile: pmap
    holds the wall time while one of them is in pmap (A's ends and B's whole), fgather A's
    middle."""
    timer = Timer()
    go, done = threading.Event(), threading.Event()
    b_span = []

    def b():
        go.wait(10)
        t = time.perf_counter()
        with timer.stage("pass_pmap"):
            time.sleep(0.03)
        b_span.append(time.perf_counter() - t)
        done.set()

    other = threading.Thread(target=b, daemon=True)  # (a failing test never waits on it)
    other.start()
    t0 = time.perf_counter()
    with timer.stage("pass_pmap"):
        time.sleep(0.02)
        t1 = time.perf_counter()
        with booked_apart("pass_fgather", within="pass_pmap"):
            go.set()
            done.wait(10)
            time.sleep(0.01)
        t2 = time.perf_counter()
        time.sleep(0.02)
    t3 = time.perf_counter()
    other.join()
    s = timer.seconds
    assert 0.04 <= s["pass_fgather"] <= t2 - t1, s
    a_ends = (t1 - t0) + (t3 - t2)
    assert 0.07 <= s["pass_pmap"] <= a_ends + b_span[0] + 0.01, (s, a_ends, b_span)  # (0.01: the clocks' reads)


def _timed_chunks(monkeypatch) -> list[float]:
    """The wall seconds of every final-gather chunk the render runs."""
    spent: list[float] = []
    chunk = pmap_mod._final_gather_chunk

    def timed(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return chunk(*args, **kwargs)
        finally:
            spent.append(time.perf_counter() - t0)

    monkeypatch.setattr(pmap_mod, "_final_gather_chunk", timed)
    return spent


def test_final_gathering_is_booked_to_the_fgather_pass(monkeypatch):
    spent = _timed_chunks(monkeypatch)
    cfg = config_from_dict({**TINY, "estimate": {"final_gather": 4}})
    t0 = time.perf_counter()
    res = render(cfg)
    wall = time.perf_counter() - t0
    s = res.timer.seconds
    assert spent and "fgather" in res.plan.run_names
    # every chunk's rays and gathers are in the fgather stage, and the pmap stage holds the rest
    assert s["pass_fgather"] >= sum(spent) > 0, (s, sum(spent))
    assert s["pass_pmap"] > 0
    assert s["pass_pmap"] + s["pass_fgather"] <= wall
    assert sum(s.values()) <= wall  # (one thread: the stages one after the other, none counted twice)


def test_no_final_gathering_no_fgather_seconds(monkeypatch):
    spent = _timed_chunks(monkeypatch)
    cfg = config_from_dict({**TINY, "estimate": {"final_gather": 0}})
    res = render(cfg)
    assert not spent and "fgather" not in res.plan.run_names
    assert "pass_fgather" not in res.timer.seconds and res.timer.seconds["pass_pmap"] > 0


def _union(spans: list[tuple[float, float]]) -> float:
    """The length of the union of ``spans``."""
    total, end = 0.0, -math.inf
    for a, b in sorted(spans):
        if b > end:
            total += b - max(a, end)
            end = b
    return total


def test_batches_at_once_count_each_stage_once(monkeypatch):
    """Two threads run whole batches at once (``render.batch_rays`` small): they share the
    run's timer, so a stage holds the wall time while any batch was in it, not the sum of
    the batches' times in it, and no stage holds more seconds than the render took (the
    batches' stages summed, as before, held more: pass_fgather 52.7 s in a 41.6 s run of
    configs/cornell_pmap.yaml). Each thread's first final-gather chunk waits for the
    other's (a barrier) and then 0.3 s, so the two threads are in pass_fgather at once for
    at least those 0.3 s however loaded the machine: the stage holds at least 0.3 s less
    than the sum of the threads' times in it, which the test reads from the timer's own
    clock readings on each thread."""
    from tlm.render import batches

    monkeypatch.delenv("TLM_FORK_WORKERS", raising=False)  # (threads: the barrier is one process's)
    hold = 0.3
    open_at: dict[tuple, list[float]] = {}
    spans: dict[str, list[tuple[float, float]]] = {}  # every thread's spans in each stage
    enter, leave = Timer._enter, Timer._leave

    def spy_enter(self, name, now):
        open_at.setdefault((id(self), threading.get_ident(), name), []).append(now)
        enter(self, name, now)

    def spy_leave(self, name, now):
        since = open_at[id(self), threading.get_ident(), name].pop()
        spans.setdefault(name, []).append((since, now))
        leave(self, name, now)

    monkeypatch.setattr(Timer, "_enter", spy_enter)
    monkeypatch.setattr(Timer, "_leave", spy_leave)

    chunk = pmap_mod._final_gather_chunk
    calls: list[int] = []
    met: list[int] = []  # the threads whose first chunks met at the barrier
    lock, barrier = threading.Lock(), threading.Barrier(2, timeout=60)

    def meeting(*args, **kwargs):
        me = threading.get_ident()
        with lock:
            meet = len(met) < 2 and me not in met
            if meet:
                met.append(me)
        if meet:
            try:
                barrier.wait()
            except threading.BrokenBarrierError:
                raise AssertionError("no second thread reached a final-gather chunk within 60 s of the first: "
                                     "the batches did not run at once") from None
            time.sleep(hold)
        calls.append(me)
        return chunk(*args, **kwargs)

    monkeypatch.setattr(pmap_mod, "_final_gather_chunk", meeting)
    cfg = config_from_dict({**TINY, "resolution": [32, 32], "estimate": {"final_gather": 4},
                            "render": {**TINY["render"], "threads": 2, "batch_rays": 128}})
    assert len(batches.batches_for(32 * 32, 1, 128, 2)) > 1
    t0 = time.perf_counter()
    res = render(cfg)
    wall = time.perf_counter() - t0
    s = res.timer.seconds
    assert len(set(met)) == 2 and len(calls) >= 4, (met, calls)
    assert {"cast", "pass_rcast", "pass_pmap", "pass_fgather"} <= set(s)
    fg = spans["pass_fgather"]
    # the wall time while any thread was in the stage; at least ``hold`` less than the threads' sum
    assert s["pass_fgather"] == pytest.approx(_union(fg), rel=0, abs=1e-6), (s, fg)
    assert s["pass_fgather"] <= sum(b - a for a, b in fg) - hold + 1e-6, (s, fg)
    for name in ("cast", "pass_rcast", "pass_pmap"):  # (the other stages of the batches, the same)
        assert s[name] == pytest.approx(_union(spans[name]), rel=0, abs=1e-6), (name, s, spans[name])
    assert max(s.values()) <= wall, (s, wall)
    assert s["pass_pmap"] + s["pass_fgather"] <= wall, (s, wall)


def test_timers_of_blocks_run_elsewhere_add_as_their_union():
    """Forked workers' timers (their spans on the one monotonic clock) add the wall time
    while any of them ran: overlapping spans once, apart ones each."""
    mine = Timer(seconds={"cast": 1.0}, spans={"cast": [(0.0, 1.0)]})
    a = Timer(seconds={"cast": 2.0, "pass_x": 1.0}, spans={"cast": [(0.5, 2.5)], "pass_x": [(3.0, 4.0)]})
    b = Timer(seconds={"cast": 1.0, "pass_x": 1.0}, spans={"cast": [(2.0, 3.0)], "pass_x": [(5.0, 6.0)]})
    mine.add_spans([a])
    mine.add_spans([b])
    assert mine.seconds == {"cast": 3.0, "pass_x": 2.0}
