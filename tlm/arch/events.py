"""The order of events within one cycle: named priorities, end-of-cycle events, fast waits.

SimPy processes the events of one cycle by priority, then in the order they were
scheduled. The model leans on that order in four places, all named in :class:`Priority`:
SimPy's own two (a process starts before anything else of its cycle, every other event
is normal) and three decisions the hardware takes once the cycle's normal events have all
run, so that they never depend on the order of same-cycle events: a PM's packet-boundary
decision (:class:`tlm.arch.pm.PM`), the dynamic scheduler's tile dispatch
(:mod:`tlm.arch.schedulers`) and the crossbar's copy arbitration
(:class:`tlm.arch.crossbar.Crossbar`). Those wait in a :class:`CycleEnd`, which the run
loop (:func:`tlm.arch.units.run`) releases one at a time when the cycle has no other
event left.

The PMs wait on any-of sets of events through :func:`any_of_class`: the fast
:class:`_AnyOf`, the one place of the package that touches SimPy's internals, on the
SimPy minor release it is tested against, or ``simpy.AnyOf`` (public API: the same
cycles, one SimPy event more per wait) on any other release or when ``TLM_SIMPY_PUBLIC=1``.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from enum import IntEnum
from heapq import heappop, heappush
from itertools import count

import simpy
from simpy.events import PENDING, Event


class Priority(IntEnum):
    """The priorities of one cycle's events, in the order they run.

    SimPy runs a cycle's events by priority, then in the order they were scheduled.
    The last three are the model's decisions taken at the end of a cycle (through
    :class:`CycleEnd`): each must see everything the cycle's normal events did, and
    their own order matters too.
    """

    URGENT = simpy.events.URGENT
    """SimPy's: a new process starts (its ``Initialize``) before the cycle's other events."""
    NORMAL = simpy.events.NORMAL
    """SimPy's default: timeouts, ``succeed()``, a process ending; the model's work and hand-overs."""
    SETTLE = 2
    """A PM's packet-boundary decision while an older image's job is queued: that job may become
    ready this very cycle (a semaphore firing), and whether it preempts must not depend on the
    order of the cycle's events, so the PM decides once they have all run."""
    DISPATCH = 3
    """The dynamic scheduler hands out the tiles asked for this cycle, in pipeline order, after the
    PMs have settled: which pipeline gets which tile does not depend on event order either."""
    ARBITER = 4
    """The crossbar grants the waiting copy of smallest (frame, pipeline), last of all: every copy
    asked for this cycle (a tile handed out this cycle included) is in the running."""


class CycleEnd:
    """Events that fire at the end of the current cycle, by :class:`Priority`, then in order.

    SimPy would take one as ``env.schedule(event, priority)``, but only an event already
    triggered can be processed, and public API triggers an event only by scheduling it
    at normal priority (``succeed()``). So an end-of-cycle event waits here instead, and
    the run loop (:func:`tlm.arch.units.run`) calls :meth:`release` whenever the
    environment has no event left in the current cycle (``env.peek() > env.now``): the
    first one is triggered (``succeed()``) and processed next, alone in its cycle, as the
    heap entry ``(now, priority, order)`` would have been. The same events run in the
    same order, and each is one SimPy event, as a scheduled event of that priority is.
    An environment must be run by that loop while events wait here (``env.run()`` would
    pass them by: :meth:`release` raises if the cycle has moved on meanwhile).
    """

    def __init__(self, env: simpy.Environment):
        self.env = env
        self.queue: list[tuple[int, int, int | float, Event]] = []  # heap of (priority, order, cycle, event)
        self._order = count()

    def event(self, priority: Priority) -> Event:
        """An event that fires once every event of the current cycle before ``priority`` has run."""
        if priority <= Priority.NORMAL:
            raise ValueError(f"priority (={priority!r}) must come after Priority.NORMAL: an end-of-cycle event")
        ev = Event(self.env)
        heappush(self.queue, (priority, next(self._order), self.env.now, ev))
        return ev

    def release(self) -> None:
        """Trigger the first waiting event (call it when the current cycle has no other event left)."""
        _, _, cycle, ev = heappop(self.queue)
        if cycle != self.env.now:
            raise RuntimeError(f"an end-of-cycle event of cycle {cycle} was released at cycle {self.env.now}: "
                               "run the model with tlm.arch.units.run")
        ev.succeed()


class Signal:
    """A wake-up call re-armed on demand: :meth:`wait` gives the event to wait on, :meth:`fire` fires it.

    The event exists only while someone waits (or asked to): a :meth:`fire` with none
    made is a no-op, and costs no SimPy event. Once fired, the next :meth:`wait` makes a
    new one. A process's mailbox (a memory module, the crossbar's arbiter) and the FIFO's
    two conditions (space freed, data arrived) are such signals. On their hot paths (a
    request posted, a packet pushed or freed) the FIFO and the modules do what
    :meth:`fire` and :meth:`wait` do on :attr:`event` themselves, without the call.
    """

    __slots__ = ("env", "event")

    def __init__(self, env: simpy.Environment):
        self.env = env
        self.event: Event | None = None  # the event of :meth:`wait` not yet fired (None: nobody waits)

    def wait(self) -> Event:
        """The event the next :meth:`fire` fires (made now if there is none)."""
        ev = self.event
        if ev is None:
            ev = self.event = Event(self.env)
        return ev

    def fire(self) -> None:
        """Fire the event of :meth:`wait`, if one was made since the last fire."""
        ev = self.event
        if ev is not None:
            self.event = None
            ev.succeed()


class Flag(Event):
    """A plain event (``env.event()``) whose :attr:`triggered` is an attribute rather than a property.

    The model asks its own events whether they have fired on its hot paths: the run loop
    asks the stream's end after every SimPy event, a PM its jobs' semaphores and block
    copies, and its queue's wake-up, at every packet boundary and wait. SimPy's
    ``triggered`` is a property, whose call costs more than the rest of such a check; a
    flag's is a plain attribute, set by the public :meth:`succeed`, :meth:`fail` and
    :meth:`trigger` (the only ways an event is triggered) as they trigger it.
    """

    triggered = False  # (shadows Event.triggered; an instance's own attribute once it is triggered)

    def succeed(self, value=None) -> Event:
        Event.succeed(self, value)
        self.triggered = True
        return self

    def fail(self, exception: BaseException) -> Event:
        Event.fail(self, exception)
        self.triggered = True
        return self

    def trigger(self, event: Event) -> None:
        Event.trigger(self, event)
        self.triggered = True


def all_done(env: simpy.Environment, events: Iterable[Event]) -> Event:
    """A plain event that fires when every event of ``events`` has (a phase's semaphore).

    Not an ``AllOf``: SimPy strips the callbacks of a condition nested in another
    condition once the outer one fires, and PMs wait on any-of sets that include it.
    """
    done = Flag(env)
    waiting = [ev for ev in events if not ev.processed]
    left = [len(waiting)]

    def one(_ev):
        left[0] -= 1
        if left[0] == 0:
            done.succeed()

    for ev in waiting:
        ev.callbacks.append(one)
    if not waiting:
        done.succeed()
    return done


# -- the fast any-of: the one place that touches SimPy's internals ------------------------------

TESTED_SIMPY = (4, 1)  # the minor release _AnyOf is tested against (pyproject.toml pins simpy>=4.1,<4.2)
PUBLIC_ONLY = "TLM_SIMPY_PUBLIC"  # set to 1: the PMs wait with simpy.AnyOf, whatever the release


def simpy_release() -> tuple[int, ...]:
    """The installed SimPy's (major, minor)."""
    return tuple(int(part) for part in simpy.__version__.split(".")[:2] if part.isdigit())


def any_of_class() -> type[Event]:
    """What the PMs wait on any-of sets with: :class:`_AnyOf`, or ``simpy.AnyOf`` (public API).

    ``simpy.AnyOf`` when ``TLM_SIMPY_PUBLIC`` is set (other than 0) or when the installed
    SimPy is not the tested minor release :data:`TESTED_SIMPY`. Both give the same cycles
    (tests/test_timing_units.py); ``simpy.AnyOf`` processes one SimPy event more per wait.
    """
    if os.environ.get(PUBLIC_ONLY, "0") not in ("", "0") or simpy_release() != TESTED_SIMPY:
        return simpy.AnyOf
    return _AnyOf


class _AnyOf(Event):
    """``simpy.AnyOf(env, events)`` for the PMs' waits, without the cost of a general condition.

    Fires in the same cycle as :class:`simpy.AnyOf` would, when the first of ``events``
    is processed, but is processed at once, inside that event's processing, rather than
    scheduled as one event more: its waiter resumes as if it had waited on that event
    alone (one SimPy event less per wait; the cycles of every run are the same, see
    tests/test_golden.py and tests/test_timing_units.py). Its value is None rather than a
    ``ConditionValue`` (no PM reads it). Once processed it takes its callbacks off the
    events that have not fired, as a condition does.

    SimPy internals it touches (checked for SimPy 4.1 only, see :func:`any_of_class`):
    it sets its own ``_ok`` and ``_value`` and runs its own ``callbacks`` without being
    scheduled (public API triggers an event only by scheduling it); it reads the ``_ok``
    and ``_value`` of the event that fires it and marks a failed one ``_defused``; and it
    appends its callback to, and removes it from, the ``callbacks`` lists of ``events``
    (``None`` once an event is processed).
    """

    def __init__(self, env: simpy.Environment, events: list):
        self.env = env
        self.callbacks = []  # (its waiter's; the callbacks on ``events`` are taken off first, in _fire)
        self._value = PENDING
        self._events = events
        self._fired = fired = self._fire  # one bound method: appended, and later removed, as itself
        over = None
        for ev in events:
            if ev.callbacks is None:
                if over is None:
                    over = ev
            else:
                ev.callbacks.append(fired)
        if over is not None:  # already processed: fire now (and take the callbacks just added off)
            fired(over)

    def _fire(self, ev: Event) -> None:
        if self._value is not PENDING:
            return
        if ev._ok:
            # processed at once, inside the first event's processing: its waiter resumes with
            # that event rather than one event later in the same cycle
            self._ok = True
            self._value = None
            self._detach(self)  # first, as a condition's first callback
            callbacks, self.callbacks = self.callbacks, None
            for callback in callbacks:
                callback(self)
        else:  # (no event of the model fails; a condition would fail with it)
            ev._defused = True
            self._ok = False
            self._value = ev._value
            self.callbacks.insert(0, self._detach)
            self.env.schedule(self)

    def _detach(self, _ev: Event) -> None:
        fired = self._fired
        for ev in self._events:
            cbs = ev.callbacks
            if cbs:
                try:  # noqa: SIM105 - cheaper than contextlib.suppress, on the hot path
                    cbs.remove(fired)
                except ValueError:
                    pass
        self._fired = None  # (it refers to the event itself)
