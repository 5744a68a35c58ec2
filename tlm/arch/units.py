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
ui.perfetto.dev). :func:`run` runs a model to completion or raises :class:`Deadlock`,
naming every blocked unit and what it waits for, when the event queue empties or an
event budget passes with work unfinished.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Generator, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import simpy

from tlm.arch.events import CycleEnd
from tlm.errors import InputError
from tlm.storage import json_text, write_atomic

STALL_CAUSES = ("handshake", "swap", "copy", "preemption", "fifo_full", "fifo_empty")


class Deadlock(RuntimeError):
    """The model cannot finish: the message names each blocked unit and what it awaits."""


class MaxEventsReached(Deadlock):
    """The run was stopped unfinished at ``arch.max_events`` events, the cap the config sets:
    not a model that stopped making progress (the liveness bound's :class:`Deadlock`), so a
    run that is only long finishes with the cap raised. A :class:`Deadlock` still, for
    whatever reports a model that could not finish (nothing written, exit status 1)."""


INT64_MAX = (1 << 63) - 1  # the most cycles numpy, the compiled kernels and results.json's readers hold


def within_int64(cycles: int, what: str) -> int:
    """``cycles`` (a Python int, exact), or an InputError (one line, exit status 2) where it is past int64:
    the frames times a frame's cycles (T_norm, the programs table's instructions times its PMs' ``scale``
    and ``record_cycles``, plus the frame's events times the config's cycle counts, ``arch.page_miss_cycles``
    ...) would wrap in numpy or lose the report's exactness. The config's maxima keep the events' share within
    it up to 2**29 events a frame (tlm/config.py, ArchConfig); T_norm is bounded only by
    :data:`tlm.arch.costs.MAX_CYCLES` (2**62) a job's work, so a table's scale can pass it over the frames
    alone. Either stops here, never wraps; the line names both."""
    if cycles > INT64_MAX:
        raise InputError(f"{what}: {cycles:.3g} cycles, past the 2**63 - 1 that the model's counts hold: lower "
                         "arch.frames, the scale or record_cycles of the programs table (arch.programs; null: "
                         "tlm/arch/programs.yaml), arch.page_miss_cycles, flush_cycles, swap_cycles or "
                         "context_switch_cycles, or render a smaller frame", key="arch")
    return cycles


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
    idle: int | None = None  # measured idle cycles (a PM books them where it waits for a job), else derived

    @property
    def busy(self) -> int:
        return self.norm + self.ms + self.ps

    @property
    def ds(self) -> int:
        return sum(self.stall.values())

    def breakdown(self, elapsed: int) -> dict:
        """Eq. 5.1 terms, stalls by cause, and busy / stall / idle (summing to elapsed).

        A unit that books its idle cycles (:attr:`idle`, the PMs) is checked:
        busy + stall + idle must equal ``elapsed`` exactly, or a cycle was booked twice or
        not at all. Any other unit's idle time is what is left of ``elapsed``.
        """
        busy, ds = self.busy, self.ds
        if self.idle is None:
            idle = elapsed - busy - ds
            if idle < 0:
                raise AssertionError(f"busy {busy} + stall {ds} exceed elapsed {elapsed}")
        else:
            idle = self.idle
            if busy + ds + idle != elapsed:
                raise AssertionError(f"busy {busy} + stall {ds} + idle {idle} = {busy + ds + idle} "
                                     f"!= elapsed {elapsed}")
        frac = (lambda c: round(c / elapsed, 6)) if elapsed else (lambda c: 0.0)
        return {
            "T_norm": self.norm, "T_ms": self.ms, "T_ps": self.ps, "T_ds": ds,
            "stall": dict(self.stall), "busy": busy, "stalled": ds, "idle": idle,
            "elapsed": elapsed, "idle_measured": self.idle is not None,
            "fractions": {"busy": frac(busy), "stalled": frac(ds), "idle": frac(idle)},
        }


_PM_ORDER = ("vertex", "traversal", "intersection", "fragment")


def row_order(scope: str, modules_per_pipe: int = 4) -> tuple:
    """Where a unit's row goes in the trace: pipe by pipe (its PMs, then its memory
    modules), then the compose unit and the crossbar, then anything else by name."""
    preempted = scope.endswith(" (preempted)")
    base = scope.removesuffix(" (preempted)")
    m = re.fullmatch(r"pipe(\d+)\.(\w+)", base)
    if m:
        kind = m[2]
        rank = _PM_ORDER.index(kind) if kind in _PM_ORDER else len(_PM_ORDER)
        return (int(m[1]), 0, rank, kind, preempted)
    m = re.fullmatch(r"mem(\d+)", base)
    if m:
        return (int(m[1]) // max(modules_per_pipe, 1), 1, int(m[1]), "", preempted)
    last = {"compose": 0, "xbar": 1}
    return (1 << 30, 2, last.get(base, 2), base, preempted)


_SLICE = 9  # the entries of a slice in Trace._flat: name, start, end, tid, args, T_norm, T_ms, T_ps, tag
_EXACT = object()  # the tag of a slice that merges only with one of equal args (Trace.add_exact)


class Waiting(str):
    """What a unit waits for: its text (``waiting_for``, the Deadlock message), and ``args``,
    the same in structured form for the trace's stall slices (``on``: the kind of thing waited
    for, ``on_name``, ``on_frame``; docs/architecture.md, "trace.json")."""

    def __new__(cls, text: str, **args):
        self = super().__new__(cls, text)
        self.args = args
        return self


class Trace:
    """Chrome trace events: one row per unit, one slice per interval.

    The slices are kept flat, :data:`_SLICE` entries each in one list, rather than an
    object per slice: a run makes tens of thousands of them, and the garbage collector
    then has one object to look at rather than one per slice (a run's survivors are
    scanned once after it, and its results collected when they are dropped). A work
    slice (:meth:`add_work`) keeps its T_norm, T_ms and T_ps as entries of their own,
    summed in place when the next work continues it, and its *tag*: a dict of the args it
    shares with every slice of the same job (frame, job, tile; one object per job), which
    only a slice of that same tag continues; its args dict (the tag's, then the three) is
    made when the slice is first read (:meth:`_slices`). Any other slice has its args
    dict from the start (and None for the three): :meth:`add_exact` continues a slice
    only with equal args (a stall, a preemption), :meth:`add` any of the same name.
    """

    def __init__(self) -> None:
        self._flat: list = []  # the slices: name, start, end, tid, args, norm, ms, ps, name, start, ...
        self.rows: dict[str, int] = {}
        self._last: dict[int, int] = {}  # each row's latest slice: the index of its name in _flat
        self.modules_per_pipe = 4  # memory modules of a pipeline (the model sets it): rows' order

    def _args(self, i: int) -> dict:
        """The args dict of the slice at ``i`` (a work slice's made from its three counts now)."""
        flat = self._flat
        args = flat[i + 4]
        if args is None:
            tag = flat[i + 8]
            args = flat[i + 4] = {**(tag or {}), "T_norm": flat[i + 5], "T_ms": flat[i + 6], "T_ps": flat[i + 7]}
        return args

    def _slices(self):
        """The slices as (name, start, end, tid, args) tuples, in the order they were added."""
        flat = self._flat
        for i in range(0, len(flat), _SLICE):
            yield flat[i], flat[i + 1], flat[i + 2], flat[i + 3], self._args(i)

    def slice(self, scope: str, name: str, start: int, end: int, **args) -> None:
        """Add a slice; one that continues its row's latest slice of the same name extends it."""
        if end > start:
            self.add(self.row(scope), name, start, end, args)

    def row(self, scope: str) -> int:
        """The row (tid) of ``scope``, a new one the first time a slice goes there."""
        tid = self.rows.get(scope)
        if tid is None:
            tid = self.rows[scope] = len(self.rows)
        return tid

    def add(self, tid: int, name: str, start: int, end: int, args: dict) -> None:
        """:meth:`slice` on row ``tid`` (``end > start``), with its args as a dict of its own."""
        flat = self._flat
        i = self._last.get(tid)
        if i is not None and flat[i + 2] == start and flat[i] == name and flat[i + 8] is None:
            flat[i + 2] = end
            old_args = self._args(i)
            for k, v in args.items():
                old = old_args.get(k)
                if old is None:
                    old_args[k] = v
                elif type(v) is int and type(old) is int:
                    old_args[k] = old + v
            return
        self._last[tid] = len(flat)
        flat += (name, start, end, tid, args, None, None, None, None)

    def add_exact(self, tid: int, name: str, start: int, end: int, args: dict) -> None:
        """:meth:`add`, continuing the row's latest slice only where its args are equal
        (``args`` is kept as it is, never changed: a dict shared by slices may be given)."""
        flat = self._flat
        i = self._last.get(tid)
        if i is not None and flat[i + 2] == start and flat[i] == name and flat[i + 8] is _EXACT \
                and flat[i + 4] == args:
            flat[i + 2] = end
            return
        self._last[tid] = len(flat)
        flat += (name, start, end, tid, args, None, None, None, _EXACT)

    def add_work(self, tid: int, name: str, start: int, end: int, norm: int, ms: int, ps: int,
                 tag: dict | None = None) -> None:
        """:meth:`add` of a work slice, args the ``tag``'s (the job's: frame, job, tile), then T_norm,
        T_ms and T_ps (ints), without building them to merge: it continues the row's latest slice
        only where that has the same name and the same tag (the same object)."""
        flat = self._flat
        i = self._last.get(tid)
        if i is not None and flat[i + 2] == start and flat[i] == name and flat[i + 8] is tag:
            flat[i + 2] = end
            args = flat[i + 4]
            if args is None:  # a work slice not read yet: its counts, summed in place
                flat[i + 5] += norm
                flat[i + 6] += ms
                flat[i + 7] += ps
                return
            old = args.get("T_norm")
            if old is None:
                args["T_norm"] = norm
            elif type(old) is int:
                args["T_norm"] = old + norm
            old = args.get("T_ms")
            if old is None:
                args["T_ms"] = ms
            elif type(old) is int:
                args["T_ms"] = old + ms
            old = args.get("T_ps")
            if old is None:
                args["T_ps"] = ps
            elif type(old) is int:
                args["T_ps"] = old + ps
            return
        self._last[tid] = len(flat)
        flat += (name, start, end, tid, None, norm, ms, ps, tag)

    @property
    def events(self) -> list[dict]:
        """The slices as Chrome trace events ("X": complete events)."""
        return [{"name": n, "ph": "X", "ts": s, "dur": e - s, "pid": 0, "tid": tid, "args": a}
                for n, s, e, tid, a in self._slices()]

    def fill_idle(self, end: int) -> None:
        """Idle slices in every gap of every unit's row, up to ``end``: not on a PM's
        ``(preempted)`` row, which is not a unit of its own (its gaps are no cycles of the PM)."""
        flat = self._flat
        tids, starts, ends = flat[3::_SLICE], flat[1::_SLICE], flat[2::_SLICE]
        aside = {tid for scope, tid in self.rows.items() if scope.endswith(" (preempted)")}
        # one pass over the slices while every row's come in increasing start, as each unit
        # books them (they are then in the (start, end) order the gaps are found in); a row
        # out of that order sorts each row's slices first
        reach: dict[int, int] = {}  # each row's latest end so far (rows in the order of their first slice)
        latest: dict[int, int] = {}  # each row's latest start
        gaps: dict[int, list] = {}  # each row's idle slices
        for tid, s, e in zip(tids, starts, ends, strict=True):
            t = reach.get(tid)
            if t is None:
                t = 0
                gaps[tid] = []
            elif s <= latest[tid]:
                gaps = None  # (a row out of order)
                break
            latest[tid] = s
            if s > t:
                gaps[tid] += ("idle", t, s, tid, {}, None, None, None, None)
            reach[tid] = e if e > t else t
        if gaps is None:  # sort each row's slices by (start, end), then the same pass
            by_row: dict[int, list[tuple[int, int]]] = {}
            for tid, s, e in zip(tids, starts, ends, strict=True):
                row = by_row.get(tid)
                if row is None:
                    by_row[tid] = [(s, e)]
                else:
                    row.append((s, e))
            reach, gaps = {}, {}
            for tid, spans in by_row.items():
                spans.sort()
                t = 0
                idle = gaps[tid] = []
                for s, e in spans:
                    if s > t:
                        idle += ("idle", t, s, tid, {}, None, None, None, None)
                    if e > t:
                        t = e
                reach[tid] = t
        for tid, idle in gaps.items():
            if tid in aside:
                continue
            flat += idle
            if end > reach[tid]:
                flat += ("idle", reach[tid], end, tid, {}, None, None, None, None)
        for tid in self.rows.values():  # a unit that did nothing (a row made with no slice): idle throughout
            if tid not in reach and tid not in aside and end > 0:
                flat += ("idle", 0, end, tid, {}, None, None, None, None)

    def to_json(self, clock_hz: float | None = None, modules_per_pipe: int | None = None) -> dict:
        """The trace document, as Perfetto and chrome://tracing open it.

        Timestamps and durations are microseconds at the modelled clock (``clock_hz``;
        without one, one cycle is drawn as one microsecond); every slice's ``args`` keep its
        exact ``start_cycle`` and ``cycles``. Rows go pipe by pipe: each pipeline's PMs in
        pipeline order (Vertex, Traversal, Intersection, Fragment, a PM's "(preempted)" row
        after it), then its memory modules (``modules_per_pipe`` to a pipeline), then the
        top-level compose unit and the crossbar (``thread_sort_index`` and the row ids both
        follow that order).
        """
        events, rest = self._document(clock_hz, modules_per_pipe)
        return {"traceEvents": list(events), **rest}

    def _layout(self, clock_hz: float | None, modules_per_pipe: int | None):
        """The rows in the document's order, each row's id there (by its id here), and the
        microseconds of a cycle."""
        per_pipe = modules_per_pipe or self.modules_per_pipe
        order = sorted(self.rows, key=lambda scope: row_order(scope, per_pipe))
        tid_of = {self.rows[scope]: i for i, scope in enumerate(order)}
        if not clock_hz:
            return order, tid_of, 1.0
        us = 1e6 / clock_hz if clock_hz > 0 else math.nan
        last = max(self._flat[2::_SLICE], default=0)
        if not (math.isfinite(us) and math.isfinite(last * us)):  # (never a null or negative timestamp)
            raise ValueError(f"trace: clock_hz = {clock_hz!r} Hz puts its {last} cycles at {last * us!r} "
                             "microseconds, not a finite time (arch.clock_hz is at least 1 Hz)")
        return order, tid_of, us

    def _document(self, clock_hz: float | None, modules_per_pipe: int | None):
        """The events of :meth:`to_json`'s document, one at a time (the rows' metadata,
        then the slices), and its other keys."""
        order, tid_of, us = self._layout(clock_hz, modules_per_pipe)

        def events():
            yield from _row_events(order)
            for n, s, e, tid, a in self._slices():
                yield _slice_event(n, s, e, tid, a, tid_of, us)

        unit = "microseconds at the modelled clock" if clock_hz else "clock cycles (no clock given)"
        other = {"time_unit": unit, "clock_hz": clock_hz, "cycles_in": "args.start_cycle, args.cycles"}
        return events(), {"displayTimeUnit": "ns", "otherData": other}

    def _texts(self, clock_hz: float | None):
        """The JSON text of each event of :meth:`to_json`'s document, in its order, a list at
        a time (the rows' metadata, then the slices 4,096 at a time): exactly
        :func:`~tlm.storage.json_text` of each event. A slice's is spelt out here, a column
        at a time, as ``json.dumps`` writes it (:func:`_slice_texts`): about three times
        faster than making its dict and dumping it, and a run has tens of thousands."""
        order, tid_of, us = self._layout(clock_hz, None)
        yield [json_text(ev) for ev in _row_events(order)]
        flat, size = self._flat, _CHUNK * _SLICE
        made: dict = {}  # the texts of the names, arg keys and string args met
        for i in range(0, len(flat), size):
            texts = _slice_texts(flat[i:i + size], tid_of, us, made) if type(us) is float else None
            if texts is None:  # (a slice of anything else, a numpy float clock: as json_text makes it)
                texts = [json_text(_slice_event(*flat[j:j + 4], self._args(j), tid_of, us))
                         for j in range(i, min(i + size, len(flat)), _SLICE)]
            yield texts

    def write(self, path: Path, clock_hz: float | None = None) -> None:
        """:meth:`to_json`'s document as ``path``, the same text as ``json.dumps`` of it,
        written 4,096 events at a time (:meth:`_texts`): the event dicts and the text are
        never held whole (at 1080p they were about 280 MiB, at the run's peak). Strict JSON
        (a number that is not finite as null, :func:`tlm.storage.json_text`): trace viewers
        parse it with JavaScript's ``JSON.parse``, which refuses ``Infinity`` and ``NaN``."""
        _, rest = self._document(clock_hz, None)
        with write_atomic(path, "w") as fh:
            fh.write('{"traceEvents": [')
            sep = ""
            for texts in self._texts(clock_hz):
                if texts:
                    fh.write(sep + ", ".join(texts))
                    sep = ", "
            fh.write("]")
            for key, value in rest.items():
                fh.write(f", {json.dumps(key)}: {json_text(value)}")
            fh.write("}")


_CHUNK = 4096  # the slices Trace.write spells out and writes at a time


def _row_events(order: list[str]):
    """The metadata events of the rows ``order``: each one's name and place."""
    for i, scope in enumerate(order):
        yield {"name": "thread_name", "ph": "M", "pid": 0, "tid": i, "args": {"name": scope}}
        yield {"name": "thread_sort_index", "ph": "M", "pid": 0, "tid": i, "args": {"sort_index": i}}


def _slice_event(n, s, e, tid, a: dict, tid_of: dict, us: float) -> dict:
    """A slice's event: its times in microseconds, its exact cycles in its args."""
    return {"name": n, "ph": "X", "ts": s * us, "dur": (e - s) * us, "pid": 0, "tid": tid_of[tid],
            "args": {**a, "start_cycle": s, "cycles": e - s}}


_NOT_FINITE = frozenset(("inf", "-inf", "nan"))  # float.__repr__ of a float json_text writes as null
_NO_ARG = frozenset(("start_cycle", "cycles"))  # (keys the event sets: a slice's own one is json_text's to place)


def _slice_texts(part: list, tid_of: dict, us: float, made: dict) -> list[str] | None:
    """The JSON texts of the slices ``part`` (a run of :attr:`Trace._flat`), each exactly
    ``json_text`` of its event, or None if any slice is not of the kinds spelt out here: a
    name that is a str, start and end ints, args of str keys (not start_cycle or cycles) and
    values of type str, int, float, bool or None. ``json.dumps`` writes an int as ``int.__repr__``,
    a float as ``float.__repr__`` (json_text: null if it is not finite), a str with its
    non-ASCII escaped. ``made`` keeps the texts of the strings met (names, keys, str args)."""
    names, starts, ends, args = part[0::_SLICE], part[1::_SLICE], part[2::_SLICE], part[4::_SLICE]
    if not ({*map(type, starts), *map(type, ends)} <= {int} and set(map(type, names)) <= {str}):
        return None
    cycles = list(map(int.__sub__, ends, starts))
    ts = list(map(float.__repr__, map(us.__mul__, starts)))  # (s * us: the same product as us * s)
    lasting = set(cycles)  # (a few thousand durations in tens of thousands of slices: each spelt once)
    dur = list(map(dict(zip(lasting, map(float.__repr__, map(us.__mul__, lasting)))).__getitem__, cycles))
    for col in (ts, dur):
        if not _NOT_FINITE.isdisjoint(col):
            col[:] = ["null" if t in _NOT_FINITE else t for t in col]
    for n in set(names).difference(made):
        made[n] = json.dumps(n)
    arg_texts = []
    for a, norm, ms, ps, tag in zip(args, part[5::_SLICE], part[6::_SLICE], part[7::_SLICE], part[8::_SLICE],
                                    strict=True):
        if a is None:  # a work slice not read yet: its tag's args, then its three counts
            if not (type(norm) is int and type(ms) is int and type(ps) is int):
                return None
            if tag:
                text = made.get(id(tag))  # (a tag is one dict per job, kept by the trace: its id is its own)
                if text is None:
                    text = _args_text(tag, made)
                    if text is None:
                        return None
                    made[id(tag)] = text
            else:
                text = ""
            arg_texts.append(f'{text}"T_norm": {norm}, "T_ms": {ms}, "T_ps": {ps}, ')
        elif a:
            shared = tag is _EXACT  # (an add_exact dict, never changed, often one for many slices: spelt once)
            text = made.get(id(a)) if shared else None
            if text is None:
                text = _args_text(a, made)
                if text is None:
                    return None
                if shared:
                    made[id(a)] = text
            arg_texts.append(text)
        else:
            arg_texts.append("")
    return [f'{{"name": {made[n]}, "ph": "X", "ts": {t}, "dur": {d}, "pid": 0, "tid": {tid_of[tid]}, '
            f'"args": {{{a}"start_cycle": {s}, "cycles": {c}}}}}'
            for n, t, d, tid, a, s, c in zip(names, ts, dur, part[3::_SLICE], arg_texts, starts, cycles, strict=True)]


def _args_text(args: dict, made: dict) -> str | None:
    """The JSON text of a slice's ``args`` before its start_cycle and cycles (each entry and a
    comma after it), as :func:`_slice_texts` spells them; None where it does not."""
    out = []
    for k, v in args.items():
        if type(k) is not str or k in _NO_ARG:
            return None
        key = made.get(k)
        if key is None:
            key = made[k] = json.dumps(k)
        t = type(v)
        if t is int:
            out.append(f"{key}: {v}, ")
        elif t is str:
            word = made.get(v)
            if word is None:
                word = made[v] = json.dumps(v)
            out.append(f"{key}: {word}, ")
        elif t is float:
            text = float.__repr__(v)
            out.append(f"{key}: {'null' if text in _NOT_FINITE else text}, ")
        elif v is None or t is bool:
            out.append(f"{key}: {'null' if v is None else 'true' if v else 'false'}, ")
        else:
            return None
    return "".join(out)


_STALL_LOG = {cause: f"stall {cause}" for cause in STALL_CAUSES}  # a stall's log entry
_STALL_SLICE = {cause: f"stall: {cause}" for cause in STALL_CAUSES}  # its trace slice


class Unit:
    """A named hardware unit: its processes account every cycle through this object."""

    def __init__(self, env: simpy.Environment, scope: str, trace: Trace | None = None):
        self.env = env
        self.scope = scope
        self.stats = Stats()
        self.trace = trace
        self.waiting_for: str | None = None  # what a blocked unit waits for (Deadlock)
        # what the unit did since :attr:`log` was last read, flat, three entries a record: label,
        # start, end per work interval, "stall <cause>", start, None per stall (no object per
        # record, as in Trace); :attr:`log` spells it out when it is read
        self._raw: list = []
        self._log: list[tuple[str, int]] = []
        self._tid: int | None = None if trace is None else trace.row(scope)  # the unit's row in the trace (one
        # from the start: a unit that does nothing has its idle row, Trace.fill_idle)

    @property
    def log(self) -> list[tuple[str, int]]:
        """(what, cycle) pairs, for tests and debugging: "<label> start", "<label> end", "stall <cause>"."""
        raw = self._raw
        if raw:  # spell out what was recorded since the last read
            log = self._log
            it = iter(raw)
            for label, start, end in zip(it, it, it, strict=True):
                if end is None:
                    log.append((label, start))
                else:
                    log.append((f"{label} start", start))
                    log.append((f"{label} end", end))
            raw.clear()
        return self._log

    @log.setter
    def log(self, value: list[tuple[str, int]]) -> None:
        self._raw.clear()
        self._log = value

    def breakdown(self, end: int) -> dict:
        """The unit's eq. 5.1 breakdown over cycles 0 .. ``end`` (:meth:`Stats.breakdown`).

        The component that owns the unit reports it when the run ends; a sum that does not
        close raises an AssertionError naming the unit.
        """
        try:
            return self.stats.breakdown(end)
        except AssertionError as exc:
            raise AssertionError(f"{self.scope}: {exc}") from None

    def work(self, norm: int, ms: int = 0, ps: int = 0, label: str = "busy") -> Generator:
        """Spend ``norm`` instruction, ``ms`` page-miss and ``ps`` flush cycles."""
        if not (type(norm) is int and type(ms) is int and type(ps) is int and norm >= 0 and ms >= 0 and ps >= 0):
            norm, ms, ps = _cycles(norm, "norm"), _cycles(ms, "ms"), _cycles(ps, "ps")
        start = self.env.now
        yield self.env.timeout(norm + ms + ps)
        self.account(start, norm, ms, ps, label)

    def account(self, start: int, norm: int, ms: int, ps: int, label: str, tag: dict | None = None) -> None:
        """Book work of ``norm + ms + ps`` cycles from ``start`` (done inside another process);
        ``tag``: the args its trace slice shares with the job's others (:meth:`Trace.add_work`)."""
        stats = self.stats
        stats.norm += norm
        stats.ms += ms
        stats.ps += ps
        end = start + norm + ms + ps
        self._raw.extend((label, start, end))
        trace = self.trace
        if trace is not None and end > start:
            tid = self._tid
            if tid is None:
                tid = self._tid = trace.row(self.scope)
            trace.add_work(tid, label, start, end, norm, ms, ps, tag)

    def stalled(self, cause: str, start: int, waiting_for: str, args: dict | None = None) -> None:
        """Book a data stall under ``cause`` from ``start`` to now (done by the waiting process).
        Its trace slice's args: ``args`` (``waiting_for``'s text, the stalled job's frame, job and
        tile, what it waits ``on``: one dict, never changed, that a job's stalls may share), else
        ``waiting_for`` and, where it is a :class:`Waiting`, its ``args``."""
        now = self.env.now
        waited = now - start
        self.stats.stall[cause] += waited
        if waited:
            self._raw.extend((_STALL_LOG[cause], start, None))
            trace = self.trace
            if trace is not None:
                tid = self._tid
                if tid is None:
                    tid = self._tid = trace.row(self.scope)
                if args is None:
                    args = {"waiting_for": str(waiting_for), **getattr(waiting_for, "args", {})}
                trace.add_exact(tid, _STALL_SLICE[cause], start, now, args)

    def stall(self, cause: str, event: simpy.events.Event, waiting_for: str, args: dict | None = None) -> Generator:
        """Wait for ``event``; the time waited is a data stall (T_ds) under ``cause`` (``args``: :meth:`stalled`)."""
        if cause not in STALL_CAUSES:
            raise ValueError(f"stall cause {cause!r} is not one of {', '.join(STALL_CAUSES)}")
        start = self.env.now
        self.waiting_for = waiting_for
        value = yield event
        self.waiting_for = None
        self.stalled(cause, start, waiting_for, args)
        return value

    def delay(self, cause: str, cycles: int, what: str, args: dict | None = None) -> Generator:
        """A fixed data stall (a swap's re-route, a block copy, a context switch)."""
        yield from self.stall(cause, self.env.timeout(_cycles(cycles, what)), what, args)


def run(env: simpy.Environment, done: simpy.events.Event, units: Iterable[Unit], max_events: int = 10_000_000,
        counts: dict | None = None, why: str | None = None, cycle_end: CycleEnd | None = None,
        capped: type[Deadlock] = Deadlock, extend: Callable[[], tuple[int, object, type[Deadlock]]] | None = None,
        ) -> int:
    """Run until ``done`` fires; return the cycle it fired at.

    Raises :class:`Deadlock` if the event queue empties first, or if ``max_events`` events
    pass without ``done`` (the message names every blocked unit and what it awaits).
    ``counts``, if given, receives the number of events processed under ``"events"``;
    ``why``, if given, is what the error says when ``max_events`` pass, and ``capped`` the
    error raised then (:class:`MaxEventsReached` when ``max_events`` is the config's cap: ``why``
    then names it, ``arch.max_events = 100 events``, and the message says it stopped there).
    ``extend``, if given, is asked when ``max_events`` events have passed for the limit now, and
    the ``why`` and ``capped`` of a stop there: a limit that grows as the run goes (the liveness
    bound of the frames a stream has started, :func:`tlm.arch.model.event_bound`); the run goes on
    while it is above the events passed (asked at the limit only: no cost between).
    ``cycle_end``, if given, holds the model's end-of-cycle events
    (:class:`tlm.arch.events.CycleEnd`): one is released whenever the current cycle has no
    other event left, before time moves on.
    """
    budget_why = why or f"{max_events} events passed"
    units = list(units)
    steps = 0
    step, peek = env.step, env.peek
    late = () if cycle_end is None else cycle_end.queue  # (the heap itself: empty most of the time)
    try:
        while not done.triggered:
            if steps >= max_events:
                if extend is not None:  # (a bound that may have grown since: asked again)
                    max_events, budget_why, capped = extend()
                if steps >= max_events:
                    _deadlock(env, units, budget_why, capped)
            if late and peek() > env.now:  # the cycle's other events have all run
                cycle_end.release()
            step()
            steps += 1
    except simpy.core.EmptySchedule:
        _deadlock(env, units, "no event is scheduled")
    finally:
        if counts is not None:
            counts["events"] = steps
    return int(env.now)


def _deadlock(env: simpy.Environment, units: list[Unit], why: str, error: type[Deadlock] = Deadlock) -> None:
    blocked = [f"{u.scope} waits for {u.waiting_for}" for u in units if u.waiting_for]
    detail = "; ".join(blocked) if blocked else "no unit is waiting (a process ended early)"
    if issubclass(error, MaxEventsReached):  # (a cap hit, not a model that stopped making progress)
        # (the advice first: a long list of blocked units is cut, tlm.errors.error_line)
        raise error(f"stopped at {why}, the cap the config sets (raise it if the run is only long), unfinished "
                    f"at cycle {int(env.now)}: {detail}")
    raise error(f"the model cannot finish at cycle {int(env.now)} ({why}): {detail}")
