"""Hardware units as SimPy components: scoped names, eq. 5.1 accounting, stalls by cause.

Every Processing Module, memory module and the crossbar arbiter of the timing model
is a :class:`Unit`: a named component (``pipe0.traversal``, ``mem2``) whose time is
split the way eq. 5.1 splits it,

    T = sum T_norm + sum T_ms + sum T_ps + sum T_ds,

instructions, page misses and pipeline flushes while it works (:meth:`Unit.work`),
and data stalls while it waits (:meth:`Unit.stall`), each stall under its cause:
``handshake``, ``swap``, ``copy``, ``preemption``, ``fifo_full`` or ``fifo_empty``.
Whatever is neither is idle, so busy + stall + idle = elapsed for every unit, always.

SimPy time is an integer number of clock cycles: durations are checked to be
non-negative integers, never float seconds. A :class:`Trace` collects one slice per
work or stall interval in the Chrome trace-event format (``trace.json``, opens in
ui.perfetto.dev). :class:`Handshake` holds a unit until the data it needs has been
produced (the thesis's semaphores in the memory controller). :func:`run` runs a model
to completion or raises :class:`Deadlock`, naming every blocked unit and what it waits
for, when the event queue empties or an event budget passes with work unfinished.
"""

from __future__ import annotations

import json
from collections.abc import Generator, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import simpy

STALL_CAUSES = ("handshake", "swap", "copy", "preemption", "fifo_full", "fifo_empty")


class Deadlock(RuntimeError):
    """The model cannot finish: the message names each blocked unit and what it awaits."""


def _cycles(value: int, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f"{what} (={value!r}) must be a whole number of cycles >= 0")
    return value


@dataclass
class Stats:
    """One unit's eq. 5.1 breakdown, in cycles."""

    norm: int = 0
    ms: int = 0
    ps: int = 0
    stall: dict[str, int] = field(default_factory=lambda: dict.fromkeys(STALL_CAUSES, 0))

    @property
    def busy(self) -> int:
        return self.norm + self.ms + self.ps

    @property
    def ds(self) -> int:
        return sum(self.stall.values())

    def breakdown(self, elapsed: int) -> dict:
        """Eq. 5.1 terms, stalls by cause, and busy / stall / idle (summing to elapsed)."""
        idle = elapsed - self.busy - self.ds
        if idle < 0:
            raise AssertionError(f"busy {self.busy} + stall {self.ds} exceed elapsed {elapsed}")
        return {
            "T_norm": self.norm, "T_ms": self.ms, "T_ps": self.ps, "T_ds": self.ds,
            "stall": dict(self.stall), "busy": self.busy, "stalled": self.ds, "idle": idle,
            "elapsed": elapsed,
        }


class Trace:
    """Chrome trace events: one row per unit, one slice per interval."""

    def __init__(self) -> None:
        self._slices: list[list] = []  # [name, start, end, tid, args]
        self.rows: dict[str, int] = {}
        self._last: dict[int, list] = {}  # each row's latest slice

    def slice(self, scope: str, name: str, start: int, end: int, **args) -> None:
        """Add a slice; one that continues its row's latest slice of the same name extends it."""
        if end <= start:
            return
        tid = self.rows.get(scope)
        if tid is None:
            tid = self.rows[scope] = len(self.rows)
        last = self._last.get(tid)
        if last is not None and last[2] == start and last[0] == name:
            last[2] = end
            old_args = last[4]
            for k, v in args.items():
                old = old_args.get(k)
                if old is None:
                    old_args[k] = v
                elif type(v) is int and type(old) is int:
                    old_args[k] = old + v
            return
        event = [name, start, end, tid, args]
        self._slices.append(event)
        self._last[tid] = event

    @property
    def events(self) -> list[dict]:
        """The slices as Chrome trace events ("X": complete events)."""
        return [{"name": n, "ph": "X", "ts": s, "dur": e - s, "pid": 0, "tid": tid, "args": a}
                for n, s, e, tid, a in self._slices]

    def fill_idle(self, end: int) -> None:
        """Idle slices in every gap of every row, up to ``end``."""
        by_row: dict[int, list[tuple[int, int]]] = {}
        for _, s, e, tid, _ in self._slices:
            by_row.setdefault(tid, []).append((s, e))
        idle = []
        for tid, spans in by_row.items():
            spans.sort()
            t = 0
            for s, e in spans:
                if s > t:
                    idle.append(["idle", t, s, tid, {}])
                if e > t:
                    t = e
            if end > t:
                idle.append(["idle", t, end, tid, {}])
        self._slices.extend(idle)

    def to_json(self, clock_hz: float | None = None) -> dict:
        """The trace document; timestamps are cycles (displayed as microseconds)."""
        meta = [{"name": "thread_name", "ph": "M", "pid": 0, "tid": tid, "args": {"name": scope}}
                for scope, tid in self.rows.items()]
        return {"traceEvents": meta + self.events, "displayTimeUnit": "ns",
                "otherData": {"time_unit": "clock cycles", "clock_hz": clock_hz}}

    def write(self, path: Path, clock_hz: float | None = None) -> None:
        Path(path).write_text(json.dumps(self.to_json(clock_hz)))


class Unit:
    """A named hardware unit: its processes account every cycle through this object."""

    def __init__(self, env: simpy.Environment, scope: str, trace: Trace | None = None):
        self.env = env
        self.scope = scope
        self.stats = Stats()
        self.trace = trace
        self.waiting_for: str | None = None  # what a blocked unit waits for (Deadlock)
        self.log: list[tuple[str, int]] = []  # (what, cycle) pairs, for tests and debugging

    def work(self, norm: int, ms: int = 0, ps: int = 0, label: str = "busy") -> Generator:
        """Spend ``norm`` instruction, ``ms`` page-miss and ``ps`` flush cycles."""
        if not (type(norm) is int and type(ms) is int and type(ps) is int and norm >= 0 and ms >= 0 and ps >= 0):
            norm, ms, ps = _cycles(norm, "norm"), _cycles(ms, "ms"), _cycles(ps, "ps")
        start = self.env.now
        yield self.env.timeout(norm + ms + ps)
        self.account(start, norm, ms, ps, label)

    def account(self, start: int, norm: int, ms: int, ps: int, label: str) -> None:
        """Book work of ``norm + ms + ps`` cycles from ``start`` (done inside another process)."""
        stats = self.stats
        stats.norm += norm
        stats.ms += ms
        stats.ps += ps
        end = start + norm + ms + ps
        self.log.append((f"{label} start", start))
        if self.trace is not None:
            self.trace.slice(self.scope, label, start, end, T_norm=norm, T_ms=ms, T_ps=ps)
        self.log.append((f"{label} end", end))

    def stall(self, cause: str, event: simpy.events.Event, waiting_for: str) -> Generator:
        """Wait for ``event``; the time waited is a data stall (T_ds) under ``cause``."""
        if cause not in STALL_CAUSES:
            raise ValueError(f"stall cause {cause!r} is not one of {', '.join(STALL_CAUSES)}")
        start = self.env.now
        self.waiting_for = waiting_for
        value = yield event
        self.waiting_for = None
        waited = self.env.now - start
        self.stats.stall[cause] += waited
        if waited:
            self.log.append((f"stall {cause}", start))
            if self.trace is not None:
                self.trace.slice(self.scope, f"stall: {cause}", start, self.env.now, waiting_for=waiting_for)
        return value

    def delay(self, cause: str, cycles: int, what: str) -> Generator:
        """A fixed data stall (a swap's re-route, a block copy, a context switch)."""
        yield from self.stall(cause, self.env.timeout(_cycles(cycles, what)), what)


class Handshake:
    """The memory controller's semaphores: named data items produced once, awaited by any.

    ``produce(key)`` marks the item ready; ``ready(key)`` is an event that fires when it
    is (at once if it already is).
    """

    def __init__(self, env: simpy.Environment):
        self.env = env
        self._events: dict[object, simpy.events.Event] = {}

    def _event(self, key: object) -> simpy.events.Event:
        if key not in self._events:
            self._events[key] = self.env.event()
        return self._events[key]

    def produce(self, key: object) -> None:
        ev = self._event(key)
        if ev.triggered:
            raise RuntimeError(f"{key!r} was produced twice")
        ev.succeed()

    def ready(self, key: object) -> simpy.events.Event:
        return self._event(key)

    def is_ready(self, key: object) -> bool:
        return key in self._events and self._events[key].triggered


def run(env: simpy.Environment, done: simpy.events.Event, units: Iterable[Unit], max_events: int = 10_000_000,
        counts: dict | None = None) -> int:
    """Run until ``done`` fires; return the cycle it fired at.

    Raises :class:`Deadlock` if the event queue empties first, or if ``max_events`` events
    pass without ``done`` (the message names every blocked unit and what it awaits).
    ``counts``, if given, receives the number of events processed under ``"events"``.
    """
    units = list(units)
    steps = 0
    step = env.step
    try:
        while not done.triggered:
            if steps >= max_events:
                _deadlock(env, units, f"{max_events} events passed")
            step()
            steps += 1
    except simpy.core.EmptySchedule:
        _deadlock(env, units, "no event is scheduled")
    finally:
        if counts is not None:
            counts["events"] = steps
    return int(env.now)


def _deadlock(env: simpy.Environment, units: list[Unit], why: str) -> None:
    blocked = [f"{u.scope} waits for {u.waiting_for}" for u in units if u.waiting_for]
    detail = "; ".join(blocked) if blocked else "no unit is waiting (a process ended early)"
    raise Deadlock(f"the model cannot finish at cycle {int(env.now)} ({why}): {detail}")
