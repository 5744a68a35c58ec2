"""The hardware units of the timing model: PMs, memory modules, the crossbar, the FIFO.

:class:`PM` is a Processing Module (a SimPy process serving jobs of both images, the
older image's first, with preemption at packet boundaries), :class:`Module` a DDR
memory module, :class:`Crossbar` the memory controller's crossbar (re-routing and block
copies), :class:`Fifo` the Traversal PM's FIFO to the Intersection PM. :class:`Model`
holds them all; :mod:`tlm.arch.model` is the control unit that feeds them frames.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import simpy
from simpy.events import PENDING, Event, Timeout

from tlm.arch.program import FrameProgram, JobSpec
from tlm.arch.units import Trace, Unit, _cycles
from tlm.config import ArchConfig

# -- the units --------------------------------------------------------------------------------

def _wake_up(wake: Event | None) -> None:
    """Wake a process waiting on ``wake`` for its mailbox (``wake.succeed()``, inline); no-op if none waits."""
    if wake is not None and wake._value is PENDING:
        wake._ok, wake._value = True, None
        wake.env.schedule(wake)


class Module:
    """A DDR memory module, a SimPy process of its own: serves page requests and copies.

    Clients post requests (:meth:`request`): the PM the crossbar routes to the module
    asks for a packet's page misses, the crossbar for its side of a block copy. The
    module's process (:meth:`_serve`) takes them in order, books the service on its own
    row (T_ms for page misses, T_norm for copies), opens the DDR rows (``rows_opened``)
    and fires the request's event when the data are in: ``cycles`` after the service
    starts. The crossbar grants a module to one client at a time, so a request never
    finds the module busy with another client's service: the process checks it on its
    own timeline (:meth:`_claim`) and raises if the grant was broken. Its row state is
    the page the client's cache pair holds (:mod:`tlm.kernels.memory`): each page miss opens
    a row at ``page_miss_cycles`` (reading 19 of docs/architecture.md).
    """

    def __init__(self, env: simpy.Environment, scope: str, trace: Trace | None):
        self.env = env
        self.unit = Unit(env, scope, trace)
        self.rows_opened = 0
        self.requests = 0
        self.client: str | None = None  # the client of the latest service, busy until ``free_at``
        self.free_at = 0
        self._mailbox: deque = deque()  # (client, misses, cycles, label, done) not yet served
        self._wake: Event | None = None  # what the process waits on while the mailbox is empty
        env.process(self._serve())

    def request(self, client: str, misses: int, cycles: int, label: str = "page misses", then: int = 0) -> Event:
        """Post a request of ``cycles`` (``misses`` rows opened).

        The event fires ``then`` cycles after the service ends: a PM passes the cycles
        it computes once its data are in, so that one event ends its packet.
        """
        done = Event(self.env)
        self._mailbox.append((client, misses, cycles, label, then, done))
        _wake_up(self._wake)
        return done

    def _serve(self):
        env = self.env
        mailbox = self._mailbox
        unit = self.unit
        while True:
            if not mailbox:
                self._wake = Event(env)
                yield self._wake
                continue
            client, misses, cycles, label, then, done = mailbox.popleft()
            start = env._now
            if start < self.free_at or client != self.client:
                self._claim(client, start, cycles)
            else:  # (its client again, after the previous service: the common case, inline)
                self.free_at = start + cycles
            self.requests += 1
            self.rows_opened += misses
            if misses:
                unit.account(start, 0, cycles, 0, label)
            else:
                unit.account(start, cycles, 0, 0, label)
            done._ok, done._value = True, None
            env.schedule(done, delay=cycles + then)  # (the process is free for the next request meanwhile)

    def _claim(self, client: str, start: int, cycles: int) -> None:
        if start < self.free_at and client != self.client:
            raise AssertionError(f"{self.unit.scope} serves {client} from cycle {start} while it serves "
                                 f"{self.client} until cycle {self.free_at}: the crossbar grants a module "
                                 "to one client at a time")
        if start + cycles > self.free_at:
            self.client, self.free_at = client, start + cycles


class Crossbar:
    """The memory controller's crossbar, a SimPy process: routes PMs to modules, copies blocks.

    Routes: a PM that moves to another module asks the crossbar (:meth:`route`), which
    keeps the map of modules to PMs and grants a module to one PM at a time: a module
    still held by another PM that is working on it is refused (an AssertionError: the
    frame program never asks for it). Copies: the waiting copies go to the arbiter
    process (:meth:`_arbiter`), which, whenever the crossbar is free, grants the copy
    of smallest (frame, pipeline) once every other event of the cycle has run.
    """

    def __init__(self, env: simpy.Environment, modules: list[Module], arch: ArchConfig, trace: Trace | None):
        self.env = env
        self.unit = Unit(env, "xbar", trace)
        self.modules = modules
        self.arch = arch
        self.requests: list[tuple[tuple, simpy.events.Event]] = []  # (key, grant) of waiting copies
        self.holder: dict[int, object] = {}  # module index -> the PM routed to it
        self.copying: set[int] = set()  # the modules of the copy in progress
        self.swaps = 0
        self.copies = 0
        self.words_copied = 0
        self._wake: Event | None = None  # the arbiter waits on it while no copy waits
        self._released: Event | None = None  # fires when the granted copy is done
        env.process(self._arbiter())

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

    def copy(self, src: int, dsts: list[int], words: int, what: str, key: tuple = ()):
        """Copy ``words`` from module ``src`` to every module of ``dsts`` (one block at a time).

        More than one destination is the crossbar's fan-out: every destination is
        written at once, for the cycles of one copy. The copy waits for the arbiter's
        grant; the modules serve it as requests of their own.
        """
        cycles = -(-words // self.arch.copy_words_per_cycle)
        grant = self.env.event()
        self.requests.append(((*key, what), grant))
        _wake_up(self._wake)
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
            served = [src_m.request("xbar", 0, cycles, label),
                      *(self.modules[d].request("xbar", 0, cycles, label) for d in dsts)]
            yield from served  # every module serves it at once, for the same cycles
            self.unit.account(start, cycles, 0, 0, label)
        finally:
            self.copying.difference_update((src, *dsts))
            released.succeed()

    def _arbiter(self):
        env = self.env
        while True:
            if not self.requests:
                self._wake = Event(env)
                yield self._wake
                continue
            # decide once the cycle's normal (1) and settling (2) events and the tile dispatch (3) have run
            settle = Event(env)
            settle._ok, settle._value = True, None
            env.schedule(settle, priority=4)
            yield settle
            self.requests.sort(key=lambda r: r[0])
            _, grant = self.requests.pop(0)
            self._released = Event(env)
            grant.succeed()
            yield self._released


@dataclass(eq=False)
class Job:
    """A job in flight: one PM's part of one phase of one frame."""

    spec: JobSpec
    frame: int
    phase: str
    module: int
    after: list  # [(event, cause, what)] to wait for, in order
    fifo: Fifo | None
    done: simpy.events.Event
    next: int = 0
    suspended: bool = False
    pending_push: bool = False  # a Traversal packet done but not yet in the FIFO
    interrupted: bool = False  # a FIFO wait was cut short by a priority job
    retired: int = 0
    suspended_at: int = 0
    waited: int = 0  # how many of ``after`` have fired

    label: str = field(init=False, repr=False)  # "frame <frame> <phase>"

    def __post_init__(self) -> None:
        self.label = f"frame {self.frame} {self.phase}"

    def blocker(self):
        """The first (event, cause, what) of ``after`` not yet fired, or None: ready to run."""
        after = self.after
        k = self.waited
        n = len(after)
        while k < n:
            b = after[k]
            if b[0]._value is PENDING:  # (not b[0].triggered)
                self.waited = k
                return b
            k += 1
        self.waited = k  # events only ever fire: what has fired need not be looked at again
        return None


class Fifo:
    """The Traversal PM's FIFO of triangle addresses towards the Intersection PM.

    A packet's addresses enter together; a packet with more addresses than the FIFO
    holds enters when the FIFO is empty (the packet is the model's unit of transfer),
    and a packet without addresses takes one entry (its end marker).
    Its space is freed when the Intersection PM has tested the packet.
    """

    def __init__(self, env: simpy.Environment, depth: int):
        self.env = env
        self.depth = depth
        self.level = depth  # free entries
        self.queue: deque[int] = deque()  # packets in the FIFO, in order
        self.pushed = 0
        self.popped = 0
        self._space: simpy.events.Event | None = None  # fires when entries are freed
        self._data: simpy.events.Event | None = None  # fires when a packet enters

    def slots(self, entries: int) -> int:
        # a packet without addresses still passes its end-of-packet marker
        return max(1, min(int(entries), self.depth))

    def try_push(self, k: int, slots: int) -> bool:
        if self.level < slots:
            return False
        self.level -= slots
        self.queue.append(k)
        data = self._data
        if data is not None and data._value is PENDING:  # (not yet triggered)
            data.succeed()
        return True

    def try_pop(self) -> int | None:
        return self.queue.popleft() if self.queue else None

    def free(self, slots: int) -> None:
        self.level += slots
        space = self._space
        if space is not None and space._value is PENDING:
            space.succeed()

    def space_freed(self) -> simpy.events.Event:
        if self._space is None or self._space._value is not PENDING:
            self._space = Event(self.env)
        return self._space

    def data_arrived(self) -> simpy.events.Event:
        if self._data is None or self._data._value is not PENDING:
            self._data = Event(self.env)
        return self._data


class _AnyOf(Event):
    """``env.any_of(events)`` for the PMs' waits, without the cost of a general condition.

    Fires in the same cycle as :class:`simpy.AnyOf` would, when the first of ``events``
    is processed, but is processed at once, inside that event's processing, rather than
    scheduled as one event more: its waiter resumes as if it had waited on that event
    alone (one SimPy event less per wait; the cycles of every run are the same, see
    tests/test_golden.py). Its value is None rather than a ``ConditionValue`` (no PM reads
    it). Once processed it takes its callbacks off the events that have not fired, as a
    condition does.
    """

    def __init__(self, env: simpy.Environment, events: list):
        self.env = env
        self.callbacks = [self._detach]
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
            callbacks, self.callbacks = self.callbacks, None
            for callback in callbacks:
                callback(self)
        else:  # (no event of the model fails; a condition would fail with it)
            ev._defused = True
            self._ok = False
            self._value = ev._value
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


class PM:
    """A Processing Module: takes jobs of both images, the priority image's first.

    A job's rank is its frame (:meth:`_rank`): the image that arrived first has priority.
    The queue is kept in rank order, so only a job ahead of a running job's frame can
    preempt it (the hot paths compare ``job.frame`` directly).
    """

    def __init__(self, model: Model, pipe: int, name: str):
        self.model = model
        self.env = model.env
        self.pipe = pipe
        self.name = name
        self.unit = Unit(model.env, f"pipe{pipe}.{name}", model.trace)
        self.unit.stats.idle = 0  # booked in :meth:`_loop`, checked against elapsed at the end
        self.idle_since: int | None = None  # while the PM waits for a job
        self.queue: list[Job] = []
        self.route: int | None = None  # the module the crossbar routes this PM to
        self.working_on: int | None = None  # that module while a job runs on it
        self.changed = self.env.event()
        self.unit.waiting_for = "its process to start"  # (an event budget may end before it runs)
        self.issued = 0
        self.retired = 0
        self.switches = 0
        self.env.process(self._loop())

    # -- queue ------------------------------------------------------------------------
    @staticmethod
    def _rank(job: Job) -> int:
        return job.frame  # the image that arrived first has priority

    def submit(self, job: Job) -> None:
        """Queue ``job`` behind every job of the same or a higher priority."""
        q = self.queue
        i = len(q)
        rank = self._rank(job)
        while i > 0 and self._rank(q[i - 1]) > rank:
            i -= 1
        q.insert(i, job)
        self.issued += int(job.spec.items.sum())
        self.poke()

    def poke(self) -> None:
        if self.changed._value is PENDING:
            self.changed.succeed()

    def _rearm(self) -> None:
        if self.changed._value is not PENDING:
            self.changed = Event(self.env)

    def _ready(self) -> Job | None:
        """The ready job of the highest priority (the queue is kept in priority order)."""
        for j in self.queue:
            if j.blocker() is None:
                return j
        return None

    def _higher_ready(self, job: Job) -> bool:
        rank = job.frame
        for j in self.queue:
            if j.frame >= rank:
                return False
            if j.blocker() is None:
                return True
        return False

    def _wake_events(self, job: Job | None = None) -> list:
        """What may make a job ready: the first unfired event of each waiting job.

        With ``job`` (running, waiting on its FIFO), only jobs of a higher priority count:
        they alone can preempt it.
        """
        evs = [self.changed]
        seen = set()
        rank = None if job is None else job.frame
        for j in self.queue:
            if rank is not None and j.frame >= rank:
                break
            b = j.blocker()
            if b is not None and id(b[0]) not in seen:
                seen.add(id(b[0]))
                evs.append(b[0])
        return evs

    # -- the process ------------------------------------------------------------------
    def _loop(self):
        env = self.env
        unit = self.unit
        unit.waiting_for = None
        while True:
            self._rearm()
            ready = self._ready()
            if ready is not None:
                yield from self._run(ready)
                continue
            if not self.queue:  # no frame in flight needs this PM: idle (booked as such)
                unit.waiting_for = "a job (idle)"
                self.idle_since = start = env._now
                yield self.changed
                self.idle_since = None
                unit.stats.idle += env._now - start
                unit.waiting_for = None
                continue
            top = self.queue[0]  # (of the highest priority)
            _, cause, what = top.blocker()
            yield from unit.stall(cause, _AnyOf(env, self._wake_events()), f"{what} ({top.label})")

    def _run(self, job: Job):
        """Run ``job`` from its next packet until it is done or preempted.

        Each packet: (Intersection PM) take its addresses from the FIFO, waiting while it
        is empty; its work (page misses served by the routed module meanwhile); let the
        cycle settle if an older image's job is queued; (Traversal PM) put its addresses
        into the FIFO, waiting while it is full. A wait on the FIFO ends early when a
        priority job becomes ready: the job is then preempted.
        """
        m = self.model
        env = self.env
        unit = self.unit
        arch = m.arch
        if self.route != job.module or m.xbar.holder.get(job.module) is not self:
            m.xbar.route(self, job.module)  # (also when another PM held the module meanwhile)
        self.working_on = job.module  # (from the grant on: the swap's cycles are the module's too)
        if self.route != job.module:
            if self.route is not None:
                yield from unit.delay("swap", arch.swap_cycles, f"route to {m.modules[job.module].unit.scope}")
                m.xbar.swaps += 1
            self.route = job.module
        if job.suspended:
            # on a row of its own: the PM itself is busy for the other image meanwhile
            m.trace_slice(f"{unit.scope} (preempted)", "preempted", job.suspended_at, int(env.now),
                          job=job.label)
            yield from unit.delay("preemption", arch.context_switch_cycles, "restore context")
            job.suspended = False
        packets = job.spec.packets
        n = len(packets)
        queue = self.queue
        frame = job.frame
        fifo = job.fifo
        depth = 0 if fifo is None else fifo.depth
        pops = self.name == "intersection"
        pushes = self.name == "traversal"
        module = m.modules[job.module]
        page_cycles, flush_cycles = arch.page_miss_cycles, arch.flush_cycles
        schedule = env.schedule
        scope = unit.scope
        stats, raw, trace = unit.stats, unit._raw, unit.trace
        while job.next < n:
            if (job.next > 0 or job.pending_push or job.interrupted) and queue[0].frame < frame \
                    and self._higher_ready(job):
                yield from unit.delay("preemption", arch.context_switch_cycles, "save context")
                job.suspended = True
                job.interrupted = False
                job.suspended_at = int(env.now)
                self.switches += 1
                self.working_on = None
                return
            job.interrupted = False
            k = job.next
            norm, misses, flushes, items, entries = packets[k]
            if pops:  # take the packet's addresses from the FIFO
                got = fifo.try_pop()
                if got is None:
                    got = yield from self._pop(job)
                    if got is None:
                        job.interrupted = True  # a priority job became ready while the FIFO was empty
                        continue
                if got != k:
                    raise AssertionError(f"FIFO order broken: packet {got} arrived for {k}")
            if not job.pending_push:  # the packet's work
                ms = misses * page_cycles
                ps = flushes * flush_cycles
                if not (type(ms) is int and type(ps) is int and norm >= 0 and ms >= 0 and ps >= 0):
                    norm, ms, ps = _cycles(norm, "norm"), _cycles(ms, "ms"), _cycles(ps, "ps")
                start = env._now
                if ms:  # the routed module serves the packet's page misses (T_ms), then the PM computes
                    yield module.request(scope, misses, ms, then=norm + ps)
                else:
                    yield Timeout(env, norm + ps)
                # unit.account(start, norm, ms, ps, "busy"), inline (the hot path)
                stats.norm += norm
                stats.ms += ms
                stats.ps += ps
                end = env._now
                raw.append(("busy", start, end))
                if trace is not None and end > start:
                    tid = unit._tid
                    if tid is None:
                        tid = unit._tid = trace.row(scope)
                    trace.add_work(tid, "busy", start, end, norm, ms, ps)
                if queue[0].frame < frame:
                    # Let every event of this cycle run before the packet-boundary decision. Only
                    # needed when an older image's job is queued: it may become ready this very
                    # cycle (a semaphore firing now), and preemption must not depend on event order.
                    settle = Event(env)
                    settle._ok, settle._value = True, None
                    schedule(settle, 2)
                    yield settle
            if pushes:  # put the packet's addresses into the FIFO
                slots = max(1, min(int(entries), depth))  # (Fifo.slots)
                if fifo.try_push(k, slots):
                    job.pending_push = False
                elif not (yield from self._push(job, k, slots)):
                    job.interrupted = True  # preempted while the FIFO was full
                    continue
                fifo.pushed += int(entries)
            if pops:
                fifo.free(max(1, min(int(entries), depth)))
                fifo.popped += int(entries)
            job.retired += items
            self.retired += items
            job.next += 1
        self.queue.remove(job)
        self.working_on = None
        job.done.succeed()

    def _fifo_wait(self, job: Job, ready, cause: str, what: str):
        """Stall (``cause``) until the event ``ready()`` fires or a job of an older image
        may preempt this one; False, without waiting, if such a job is ready now.
        ``ready`` is called only when the PM waits (a FIFO event made and never awaited
        would still fire, one SimPy event more)."""
        if self.queue[0].frame < job.frame and self._higher_ready(job):  # an older image's job is ready
            return False
        env, unit = self.env, self.unit
        wake = _AnyOf(env, [ready(), *self._wake_events(job)])
        start = env._now
        unit.waiting_for = what
        yield wake
        unit.waiting_for = None
        unit.stalled(cause, start, what)
        self._rearm()
        return True

    def _push(self, job: Job, k: int, slots: int):
        """Packet k's addresses did not fit in the FIFO: wait until they do; False if preempted meanwhile."""
        fifo = job.fifo
        while True:
            job.pending_push = True
            if not (yield from self._fifo_wait(job, fifo.space_freed, "fifo_full", f"FIFO space ({job.label})")):
                return False
            if fifo.try_push(k, slots):
                job.pending_push = False
                return True

    def _pop(self, job: Job):
        """The FIFO was empty: wait for the next packet's addresses; the packet, or None if preempted meanwhile."""
        fifo = job.fifo
        while True:
            if not (yield from self._fifo_wait(job, fifo.data_arrived, "fifo_empty", f"FIFO data ({job.label})")):
                return None
            k = fifo.try_pop()
            if k is not None:
                return k


# -- the model's state ------------------------------------------------------------------------

@dataclass
class FrameRecord:
    index: int
    slot: int
    arrival: int = 0
    done: int = -1


@dataclass
class Model:
    env: simpy.Environment
    arch: ArchConfig
    program: FrameProgram
    trace: Trace | None
    modules: list[Module] = field(default_factory=list)  # per pipeline: 2 per image in flight
    xbar: Crossbar | None = None
    pms: dict[tuple[int, str], PM] = field(default_factory=dict)  # (pipeline, PM name)
    frames: list[FrameRecord] = field(default_factory=list)
    fifos: list = field(default_factory=list)
    compose: int | None = None  # index in ``modules`` of the top-level unit (more than one pipeline)

    def trace_slice(self, scope: str, name: str, start: int, end: int, **args) -> None:
        if self.trace is not None:
            self.trace.slice(scope, name, start, end, **args)

    def module(self, pipe: int, slot: int, role: int) -> int:
        """The index of pipeline ``pipe``'s module ``role`` of image slot ``slot``."""
        return 2 * (pipe * self.arch.images_in_flight + slot) + role

    def pm(self, pipe: int, name: str) -> PM:
        return self.pms[(pipe, name)]
