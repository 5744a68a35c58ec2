"""The memory controller's crossbar: swaps (re-routing PMs to modules) and block copies.

"A 1-to-1 match of all memory modules and PMs": a swap re-routes a PM to another module
"by re-routing the top-two address bits" (the PM stalls ``swap_cycles``), and the
crossbar can "copy entire blocks of data from one memory module to another" (a copy
holds its modules for ``words / copy_words_per_cycle`` cycles). Copies go one at a
time; the arbiter grants the waiting copy of smallest (frame, pipeline) at the end of
the cycle (:attr:`tlm.arch.events.Priority.ARBITER`).
"""

from __future__ import annotations

from dataclasses import dataclass

import simpy
from simpy.events import Event

from tlm.arch.events import CycleEnd, Priority, Signal
from tlm.arch.memory import Module
from tlm.arch.units import Trace, Unit
from tlm.config import ArchConfig


@dataclass(frozen=True)
class CrossbarResult:
    """What the crossbar reports when the run ends (:meth:`Crossbar.close`)."""

    scope: str  # xbar
    breakdown: dict  # eq. 5.1 over the run (units.Stats.breakdown): its copies are its T_norm
    swaps: int  # PMs re-routed to another module
    copies: int  # block copies
    words_copied: int


class Crossbar:
    """The memory controller's crossbar, a SimPy process: routes PMs to modules, copies blocks.

    Routes: a PM that moves to another module asks the crossbar (:meth:`route`), which
    keeps the map of modules to PMs and grants a module to one PM at a time: a module
    still held by another PM that is working on it is refused (an AssertionError: the
    frame program never asks for it). Copies: the waiting copies go to the arbiter
    process (:meth:`_arbiter`), which, whenever the crossbar is free, grants the copy
    of smallest (frame, pipeline) once every other event of the cycle has run (an event
    of ``cycle_end``, the model's; one of its own if none is given).
    """

    def __init__(self, env: simpy.Environment, modules: list[Module], arch: ArchConfig, trace: Trace | None,
                 cycle_end: CycleEnd | None = None):
        self.env = env
        self.unit = Unit(env, "xbar", trace)
        self.modules = modules
        self.arch = arch
        self.cycle_end = CycleEnd(env) if cycle_end is None else cycle_end
        self.requests: list[tuple[tuple, Event]] = []  # (key, grant) of waiting copies
        self.holder: dict[int, object] = {}  # module index -> the PM routed to it
        self.copying: set[int] = set()  # the modules of the copy in progress
        self.swaps = 0
        self.copies = 0
        self.words_copied = 0
        self._asked = Signal(env)  # a copy was asked for (the arbiter waits on it while no copy waits)
        self._released: Event | None = None  # fires when the granted copy is done
        env.process(self._arbiter())

    def close(self, end: int) -> CrossbarResult:
        """The crossbar's books at cycle ``end``: its breakdown and what it swapped and copied."""
        return CrossbarResult(self.unit.scope, self.unit.breakdown(end), self.swaps, self.copies, self.words_copied)

    def route(self, pm, module: int) -> None:
        """Grant ``module`` to ``pm`` (one to one): the PM it leaves, if any, is released."""
        holder = self.holder.get(module)
        if holder is not None and holder is not pm and holder.working_on == module:
            raise AssertionError(f"{pm.unit.scope} asks for {self.modules[module].unit.scope} while "
                                 f"{holder.unit.scope} works on it: the crossbar grants a module to one PM at a time")
        if module in self.copying:
            raise AssertionError(f"{pm.unit.scope} asks for {self.modules[module].unit.scope} while the crossbar "
                                 "copies into or out of it")
        for k in [k for k, v in self.holder.items() if v is pm]:  # the module it leaves
            del self.holder[k]
        self.holder[module] = pm

    def copy(self, src: int, dsts: list[int], words: int, what: str, key: tuple = (), args: dict | None = None):
        """Copy ``words`` from module ``src`` to every module of ``dsts`` (one block at a time).

        More than one destination is the crossbar's fan-out: every destination is
        written at once, for the cycles of one copy. The copy waits for the arbiter's
        grant; the modules serve it as requests of their own. ``key``: (frame, pipeline),
        the arbiter's order; ``args``: what the copy's trace slices hold besides its frame
        and words (one dict per copy: a copy's slices never merge with another's).
        """
        cycles = -(-words // self.arch.copy_words_per_cycle)
        grant = self.env.event()
        self.requests.append(((*key, what), grant))
        self._asked.fire()
        yield grant
        released = self._released
        try:
            self.copies += 1
            self.words_copied += words
            src_m = self.modules[src]
            to = self.modules[dsts[0]].unit.scope if len(dsts) == 1 else f"{len(dsts)} modules"
            label = f"copy {src_m.unit.scope}->{to}: {what}"
            start = int(self.env.now)
            for k in (src, *dsts):  # copies go between phases: no PM may be working on these modules
                holder = self.holder.get(k)
                if holder is not None and holder.working_on == k:
                    raise AssertionError(f"the crossbar copies {label!r} while {holder.unit.scope} works on "
                                         f"{self.modules[k].unit.scope}: it grants a module to one client at a time")
            self.copying.update((src, *dsts))
            tag = None
            if self.unit.trace is not None:
                tag = {"frame": key[0]} if key else {}
                tag.update(args or {})
                tag["words"] = words
            served = [src_m.request("xbar", 0, cycles, label, 0, tag),
                      *(self.modules[d].request("xbar", 0, cycles, label, 0, tag) for d in dsts)]
            yield from served  # every module serves it at once, for the same cycles
            self.unit.account(start, cycles, 0, 0, label, tag)
        finally:
            self.copying.difference_update((src, *dsts))
            released.succeed()

    def _arbiter(self):
        env = self.env
        while True:
            if not self.requests:
                yield self._asked.wait()
                continue
            yield self.cycle_end.event(Priority.ARBITER)  # every copy asked for this cycle is in
            self.requests.sort(key=lambda r: r[0])
            _, grant = self.requests.pop(0)
            self._released = Event(env)
            grant.succeed()
            yield self._released
