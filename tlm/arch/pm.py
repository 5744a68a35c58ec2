"""The Processing Modules of a pipeline (Fig. 11): Vertex, Traversal, Intersection, Fragment.

Each PM is a SimPy process (:class:`PM`) that serves the jobs of both images in flight,
the older image's first: a job is one PM's part of one phase of one frame, cut into
packets. Every PM runs a packet the same way (its page misses served by the module the
crossbar routes it to, then its instructions and pipeline flushes) and switches to an
older image's job at a packet boundary (*preemption*, ``context_switch_cycles`` to save
and again to restore). What differs is the unit:

* :class:`Vertex` builds the shared structures; one per GPU, on pipeline 0 (§V.D);
* :class:`Traversal` puts each packet's triangle addresses into the FIFO
  (:mod:`tlm.arch.fifo`), waiting while it is full;
* :class:`Intersection`, the fixed-function Ray-Triangle Intersection PM, takes each
  packet's addresses out of the FIFO before testing them, waiting while it is empty;
* :class:`Fragment` shades, estimates radiance and emits photons.

:data:`PM_KINDS` maps the program's PM names (``tlm.arch.program.PMS``) to the classes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from simpy.events import Event, Timeout

from tlm.arch.events import Priority, any_of_class
from tlm.arch.fifo import Fifo
from tlm.arch.program import JobSpec
from tlm.arch.units import Unit, _cycles


@dataclass(eq=False)
class Job:
    """A job in flight: one PM's part of one phase of one frame."""

    spec: JobSpec
    frame: int
    phase: str
    module: int
    after: list  # [(event, cause, what)] to wait for, in order
    fifo: Fifo | None
    done: Event
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
            if not b[0].triggered:
                self.waited = k
                return b
            k += 1
        self.waited = k  # events only ever fire: what has fired need not be looked at again
        return None


class PM:
    """A Processing Module: takes jobs of both images, the priority image's first.

    A job's rank is its frame (:meth:`_rank`): the image that arrived first has priority.
    The queue is kept in rank order, so only a job ahead of a running job's frame can
    preempt it (the hot paths compare ``job.frame`` directly). The base class runs a
    job's packets one after another (:meth:`_packets`); a PM coupled to the FIFO runs
    them its own way. ``model`` is the :class:`tlm.arch.model.Model` the PM belongs to.
    """

    kind = ""  # the program's name of the PM (tlm.arch.program.PMS)
    shared = False  # one per GPU, on pipeline 0, rather than one per pipeline

    def __init__(self, model, pipe: int):
        self.model = model
        self.env = model.env
        self.pipe = pipe
        self.unit = Unit(model.env, f"pipe{pipe}.{self.kind}", model.trace)
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
        self._any_of = any_of_class()  # what the PM waits on a set of events with
        self._page_cycles = model.arch.page_miss_cycles  # (read once per packet: kept at hand)
        self._flush_cycles = model.arch.flush_cycles
        self._scope = self.unit.scope
        self._settle = model.cycle_end.event  # (Priority.SETTLE): an event at the end of the cycle
        self._working: tuple[int, int, int, int] = (0, 0, 0, 0)  # the packet in work: (start, norm, ms, ps)
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
        if not self.changed.triggered:
            self.changed.succeed()

    def _rearm(self) -> None:
        if self.changed.triggered:
            self.changed = Event(self.env)

    def _ready(self) -> Job | None:
        """The ready job of the highest priority (the queue is kept in priority order)."""
        for j in self.queue:
            if j.blocker() is None:
                return j
        return None

    def _yields_to_older(self, job: Job, frame: int, pending: bool = False) -> bool:
        """At a packet boundary of a job under way (a packet done, or one ``pending`` to hand
        on, or the job interrupted): whether an older image's job is ready, so this one is
        suspended (the thesis's "finishes the ray/pixel operation ... before context switching")."""
        return (job.next > 0 or pending or job.interrupted) and self.queue[0].frame < frame \
            and self._higher_ready(job)

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
            if ready is not None:  # (its packets run in this process's own generator: the hot path)
                yield from self._enter(ready)
                if (yield from self._packets(ready, self.model.modules[ready.module])):
                    self.queue.remove(ready)
                    self.working_on = None
                    ready.done.succeed()
                continue
            if not self.queue:  # no frame in flight needs this PM: idle (booked as such)
                unit.waiting_for = "a job (idle)"
                self.idle_since = start = env.now
                yield self.changed
                self.idle_since = None
                unit.stats.idle += env.now - start
                unit.waiting_for = None
                continue
            top = self.queue[0]  # (of the highest priority)
            _, cause, what = top.blocker()
            yield from unit.stall(cause, self._any_of(env, self._wake_events()), f"{what} ({top.label})")

    def _enter(self, job: Job):
        """Start or resume ``job``: the PM is routed to the job's module (a *swap* if it moves)
        and, if the job was preempted, its context is restored. Its packets follow (:meth:`_packets`)."""
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

    def _packets(self, job: Job, module):
        """Run ``job``'s packets from its next one, on ``module``: True once done, False if preempted."""
        packets = job.spec.packets
        n = len(packets)
        queue = self.queue
        frame = job.frame
        while job.next < n:
            if job.next > 0 and queue[0].frame < frame and self._higher_ready(job):
                yield from self._suspend(job)
                return False
            norm, misses, flushes, items, _ = packets[job.next]
            yield self._begin_work(module, norm, misses, flushes)
            if self._end_work(frame):
                yield self._settle(Priority.SETTLE)
            job.retired += items
            self.retired += items
            job.next += 1
        return True

    def _suspend(self, job: Job):
        """Preempted at a packet boundary: save the context; the job waits in the queue."""
        yield from self.unit.delay("preemption", self.model.arch.context_switch_cycles, "save context")
        job.suspended = True
        job.interrupted = False
        job.suspended_at = int(self.env.now)
        self.switches += 1
        self.working_on = None

    # -- a packet's work, the same for every PM: yield _begin_work(...), then _end_work(...) --
    def _begin_work(self, module, norm: int, misses: int, flushes: int) -> Event:
        """Start a packet's work: its page misses served by ``module`` (T_ms), then its
        T_norm and T_ps. The event fires when it is done; :meth:`_end_work` books it."""
        ms = misses * self._page_cycles
        ps = flushes * self._flush_cycles
        if not (type(ms) is int and type(ps) is int and norm >= 0 and ms >= 0 and ps >= 0):
            norm, ms, ps = _cycles(norm, "norm"), _cycles(ms, "ms"), _cycles(ps, "ps")
        self._working = (self.env.now, norm, ms, ps)
        if ms:  # the routed module serves the packet's page misses, then the PM computes
            return module.request(self._scope, misses, ms, then=norm + ps)
        return Timeout(self.env, norm + ps)

    def _end_work(self, frame: int) -> bool:
        """Book the packet's work (eq. 5.1); True if the PM must let the cycle settle.

        It must when a job of an older image than ``frame`` is queued: that job may become
        ready this very cycle (a semaphore firing now), and whether it preempts must not
        depend on the order of the cycle's events, so the packet-boundary decision waits
        for an end-of-cycle event (:attr:`Priority.SETTLE`).
        """
        start, norm, ms, ps = self._working
        # unit.account(start, norm, ms, ps, "busy"), inline (the hot path)
        unit = self.unit
        stats = unit.stats
        stats.norm += norm
        stats.ms += ms
        stats.ps += ps
        end = start + norm + ms + ps
        unit._raw.append(("busy", start, end))
        trace = unit.trace
        if trace is not None and end > start:
            tid = unit._tid
            if tid is None:
                tid = unit._tid = trace.row(self._scope)
            trace.add_work(tid, "busy", start, end, norm, ms, ps)
        return self.queue[0].frame < frame

    def _fifo_wait(self, job: Job, ready, cause: str, what: str):
        """Stall (``cause``) until the event ``ready()`` fires or a job of an older image
        may preempt this one; False, without waiting, if such a job is ready now.
        ``ready`` is called only when the PM waits (a FIFO event made and never awaited
        would still fire, one SimPy event more)."""
        if self.queue[0].frame < job.frame and self._higher_ready(job):  # an older image's job is ready
            return False
        env, unit = self.env, self.unit
        wake = self._any_of(env, [ready(), *self._wake_events(job)])
        start = env.now
        unit.waiting_for = what
        yield wake
        unit.waiting_for = None
        unit.stalled(cause, start, what)
        self._rearm()
        return True


class Vertex(PM):
    """The Vertex PM: builds the frame's shared structures (the BSP trees), on pipeline 0 only."""

    kind = "vertex"
    shared = True  # one Vertex PM builds the shared structures (§V.D)


class Traversal(PM):
    """The Traversal PM: each packet's work, then its triangle addresses into the FIFO.

    A packet whose addresses do not fit waits (*fifo_full*); the wait ends early when an
    older image's job becomes ready, and the job is then preempted with the packet done
    but not yet in the FIFO (``Job.pending_push``: on its return it pushes, without
    working the packet again).
    """

    kind = "traversal"

    def _packets(self, job: Job, module):
        packets, frame, fifo = job.spec.packets, job.frame, job.fifo
        depth = fifo.depth
        while job.next < len(packets):
            if self._yields_to_older(job, frame, job.pending_push):
                yield from self._suspend(job)
                return False
            job.interrupted = False
            k = job.next
            norm, misses, flushes, items, entries = packets[k]
            if not job.pending_push:
                yield self._begin_work(module, norm, misses, flushes)
                if self._end_work(frame):
                    yield self._settle(Priority.SETTLE)
            slots = max(1, min(int(entries), depth))  # (Fifo.slots)
            if fifo.try_push(k, slots):
                job.pending_push = False
            elif not (yield from self._push(job, k, slots)):
                job.interrupted = True  # preempted while the FIFO was full
                continue
            fifo.pushed += int(entries)
            job.retired += items
            self.retired += items
            job.next += 1
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


class Intersection(PM):
    """The Ray-Triangle Intersection PM (fixed function): a packet's addresses out of the FIFO, then its tests.

    An empty FIFO stalls it (*fifo_empty*); the wait ends early when an older image's job
    becomes ready, and the job is then preempted before the packet. The packet's entries
    are freed once it is tested.
    """

    kind = "intersection"

    def _packets(self, job: Job, module):
        packets, frame, fifo = job.spec.packets, job.frame, job.fifo
        while job.next < len(packets):
            if self._yields_to_older(job, frame):
                yield from self._suspend(job)
                return False
            job.interrupted = False
            k = job.next
            norm, misses, flushes, items, entries = packets[k]
            got = fifo.try_pop()
            if got is None:
                got = yield from self._pop(job)
                if got is None:
                    job.interrupted = True  # a priority job became ready while the FIFO was empty
                    continue
            if got != k:
                raise AssertionError(f"FIFO order broken: packet {got} arrived for {k}")
            yield self._begin_work(module, norm, misses, flushes)
            if self._end_work(frame):
                yield self._settle(Priority.SETTLE)
            fifo.free(max(1, min(int(entries), fifo.depth)))  # (Fifo.slots)
            fifo.popped += int(entries)
            job.retired += items
            self.retired += items
            job.next += 1
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


class Fragment(PM):
    """The Fragment PM: shading, radiance estimates and photon emission, packet after packet."""

    kind = "fragment"


PM_KINDS: dict[str, type[PM]] = {cls.kind: cls for cls in (Vertex, Traversal, Intersection, Fragment)}
"""The PM class of each of the program's PM names, in pipeline order (``tlm.arch.program.PMS``)."""
