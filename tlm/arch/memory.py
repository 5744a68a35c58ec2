"""The DDR memory modules: four per pipeline, two per image in flight.

"Modules 0&1 ... image 0 ... 2&3 ... image 1": image slot ``s`` owns a pipeline's
modules ``2s`` and ``2s+1`` (``Model.module``). The crossbar routes one PM to a module
at a time (:mod:`tlm.arch.crossbar`); the module serves that PM's page misses, each
opening a DDR row at ``page_miss_cycles`` (T_ms, reading 19 of docs/architecture.md),
and its side of the crossbar's block copies (T_norm, ``copy_words_per_cycle``).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import simpy
from simpy.events import Event, Timeout

from tlm.arch.events import Signal
from tlm.arch.units import Trace, Unit


@dataclass(frozen=True)
class ModuleResult:
    """What a memory module reports when the run ends (:meth:`Module.close`)."""

    scope: str  # mem<i>, or compose
    breakdown: dict  # eq. 5.1 over the run (units.Stats.breakdown): page misses T_ms, copies T_norm
    requests: int  # services: packets' page misses and sides of block copies
    rows_opened: int  # DDR rows opened (the page misses served)


class Module:
    """A DDR memory module, a SimPy process of its own: serves page requests and copies.

    Clients post requests (:meth:`request`): the PM the crossbar routes to the module
    asks for a packet's page misses, the crossbar for its side of a block copy. The
    module's process (:meth:`_serve`) takes them in order, books the service on its own
    row (T_ms for page misses, T_norm for copies) and opens the DDR rows
    (``rows_opened``). The crossbar grants a module to one client at a time, so a
    request never finds the module busy with another client's service and is served the
    cycle it is posted: its event (the data are in) fires ``cycles`` later. The process
    checks the grant on its own timeline (:meth:`_claim`) and raises if it was broken.
    Its row state is the page the client's cache pair holds (:mod:`tlm.kernels.memory`).
    """

    def __init__(self, env: simpy.Environment, scope: str, trace: Trace | None):
        self.env = env
        self.unit = Unit(env, scope, trace)
        self.rows_opened = 0
        self.requests = 0
        self.client: str | None = None  # the client of the latest service, busy until ``free_at``
        self.free_at = 0
        self._mailbox: deque = deque()  # (client, misses, cycles, label, cycle posted, tag) not yet booked
        self._mail = Signal(env)  # a request was posted (the process waits on it while the mailbox is empty)
        env.process(self._serve())

    def close(self, end: int) -> ModuleResult:
        """The module's books at cycle ``end``: its breakdown, its services and the rows they opened."""
        return ModuleResult(self.unit.scope, self.unit.breakdown(end), self.requests, self.rows_opened)

    def request(self, client: str, misses: int, cycles: int, label: str = "page misses", then: int = 0,
                tag: dict | None = None) -> Event:
        """Post a request of ``cycles`` (``misses`` rows opened), served from this cycle on.

        The event fires ``then`` cycles after the service ends: a PM passes the cycles
        it computes once its data are in, so that one event ends its packet. ``tag``: the
        args of the service's trace slice, the client job's (:meth:`tlm.arch.units.Trace.add_work`).
        """
        env = self.env
        self._mailbox.append((client, misses, cycles, label, env.now, tag))
        mail = self._mail
        ev = mail.event  # (mail.fire(), inline: once per packet with page misses)
        if ev is not None:
            mail.event = None
            ev.succeed()
        return Timeout(env, cycles + then)  # (the service starts now: the module is the client's)

    def _serve(self):
        mailbox = self._mailbox
        mail = self._mail
        unit = self.unit
        stats, raw, trace = unit.stats, unit._raw, unit.trace
        while True:
            if not mailbox:
                ev = mail.event  # (mail.wait(), inline)
                if ev is None:
                    ev = mail.event = Event(self.env)
                yield ev
                continue
            client, misses, cycles, label, start, tag = mailbox.popleft()
            end = start + cycles
            if start < self.free_at or client != self.client:
                self._claim(client, start, cycles)
            else:  # (its client again, after the previous service: the common case, inline)
                self.free_at = end
            self.requests += 1
            self.rows_opened += misses
            # unit.account(start, norm, ms, 0, label), inline (once per packet with page misses)
            if misses:  # page misses: T_ms
                norm, ms = 0, cycles
                stats.ms += cycles
            else:  # a copy's words: T_norm
                norm, ms = cycles, 0
                stats.norm += cycles
            raw.extend((label, start, end))
            if trace is not None and end > start:
                tid = unit._tid
                if tid is None:
                    tid = unit._tid = trace.row(unit.scope)
                trace.add_work(tid, label, start, end, norm, ms, 0, tag)

    def _claim(self, client: str, start: int, cycles: int) -> None:
        if start < self.free_at and client != self.client:
            raise AssertionError(f"{self.unit.scope} serves {client} from cycle {start} while it serves "
                                 f"{self.client} until cycle {self.free_at}: the crossbar grants a module "
                                 "to one client at a time")
        if start + cycles > self.free_at:
            self.client, self.free_at = client, start + cycles
