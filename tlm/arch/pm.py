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

:data:`PM_KINDS` maps the program's PM names (``tlm.arch.frame_program.PMS``) to the classes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from simpy.events import Event, Timeout

from tlm.arch.events import Flag, Priority, Signal, any_of_class
from tlm.arch.fifo import Fifo
from tlm.arch.frame_program import JobSpec
from tlm.arch.units import Unit, _cycles

_SETTLE = Priority.SETTLE  # (an enum member read once: the packet loops pass it on every settle)


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
    space_what: str = field(init=False, repr=False)  # what a FIFO-full stall waits for (made once)
    data_what: str = field(init=False, repr=False)  # what a FIFO-empty stall waits for
    # the args its trace slices share (frame, job, tile: PM.submit, with a trace), one dict for all of them
    tag: dict | None = field(default=None, init=False, repr=False)
    stall_args: dict | None = field(default=None, init=False, repr=False)  # its stall slices' args, by what

    def args(self, waiting_for: str, on: str, on_name: str | None = None, on_frame: int | None = None
             ) -> dict | None:
        """A stall slice's args (None without a trace): ``waiting_for``, the job's :attr:`tag`, what it
        waits ``on`` (``on_name``, ``on_frame``); one dict for every stall of the job on the same
        ``waiting_for`` (kept in :attr:`stall_args`: the trace writes a shared dict's text once)."""
        if self.tag is None:
            return None
        cache = self.stall_args
        if cache is None:
            cache = self.stall_args = {}
        out = cache.get(waiting_for)
        if out is None:
            out = cache[waiting_for] = {"waiting_for": waiting_for, **self.tag, "on": on}
            if on_name is not None:
                out["on_name"] = on_name
            if on_frame is not None:
                out["on_frame"] = on_frame
        return out

    def __post_init__(self) -> None:
        self.label = label = f"frame {self.frame} {self.phase}"
        self.space_what = f"FIFO space ({label})"
        self.data_what = f"FIFO data ({label})"

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


@dataclass(frozen=True)
class PMResult:
    """What a PM reports when the run ends (:meth:`PM.close`): its books, closed."""

    scope: str  # pipe<p>.<kind>
    pipe: int
    kind: str  # the program's name of the PM (tlm.arch.frame_program.PMS)
    breakdown: dict  # eq. 5.1 over the run (units.Stats.breakdown), idle booked to the end
    issued: int  # work items of the jobs submitted to it
    retired: int  # work items it finished
    queued: int  # jobs still in its queue (none in a run that finished)
    norm: int  # T_norm, its instruction cycles
    own: int  # its busy cycles and its swap, copy and preemption stalls: the cycles a frame costs it
    preemptions: int  # jobs it suspended for an older image's


class PM:
    """A Processing Module: takes jobs of both images, the priority image's first.

    A job's rank is its frame (:meth:`_rank`): the image that arrived first has priority.
    The queue is kept in rank order, so only a job ahead of a running job's frame can
    preempt it (the hot paths compare ``job.frame`` directly). Every PM runs a job's
    packets one after another the same way (:meth:`_packets`); a PM coupled to the FIFO
    takes each packet's addresses out of it first (:attr:`pops`, its :meth:`_pop` waits
    while it is empty) or puts them into it after the packet's work (:attr:`pushes`, its
    :meth:`_push` waits while it is full). ``model`` is the :class:`tlm.arch.model.Model`
    the PM belongs to.
    """

    kind = ""  # the program's name of the PM (tlm.arch.frame_program.PMS)
    shared = False  # one per GPU, on pipeline 0, rather than one per pipeline
    pops = False  # each packet's addresses come out of the job's FIFO before its work (Intersection)
    pushes = False  # each packet's addresses go into the job's FIFO after its work (Traversal)

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
        self.changed = Flag(self.env)  # fires when the queue changes (a job submitted)
        self.unit.waiting_for = "its process to start"  # (an event budget may end before it runs)
        self.issued = 0
        self.retired = 0
        self.switches = 0
        self._any_of = any_of_class()  # what the PM waits on a set of events with
        self._page_cycles = model.arch.page_miss_cycles  # (read once per packet: kept at hand)
        self._flush_cycles = model.arch.flush_cycles
        self._scope = self.unit.scope
        self._stats = self.unit.stats  # (the unit's books, kept at hand for the packet loops)
        self._raw = self.unit._raw
        self._trace = model.trace
        # the tile of each of the program's jobs (by the JobSpec's id: the program outlives the run), for the trace
        self._tiles = {} if model.trace is None else {
            id(js): tile.name for st in model.program.stages for tile in st.tiles for ph in tile.phases
            for js in ph.jobs if js.pm == self.kind}
        self._settle = model.cycle_end.event  # (Priority.SETTLE): an event at the end of the cycle
        self.env.process(self._loop())

    def close(self, end: int) -> PMResult:
        """Close the PM's books at cycle ``end`` and report them.

        A PM that waits for a job when the run ends has been idle since it began to wait:
        that wait is booked now, so busy + stall + idle = elapsed closes (checked by
        :meth:`tlm.arch.units.Unit.breakdown`).
        """
        stats = self.unit.stats
        if self.idle_since is not None:
            stats.idle += end - self.idle_since
            self.idle_since = None
        own = stats.busy + stats.stall["swap"] + stats.stall["copy"] + stats.stall["preemption"]
        return PMResult(self.unit.scope, self.pipe, self.kind, self.unit.breakdown(end), self.issued, self.retired,
                        len(self.queue), stats.norm, own, self.switches)

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
        if self._trace is not None:
            job.tag = {"frame": job.frame, "job": job.phase, "tile": self._tiles.get(id(job.spec), "")}
        self.issued += int(job.spec.items.sum())
        self.poke()

    def poke(self) -> None:
        if not self.changed.triggered:
            self.changed.succeed()

    def _rearm(self) -> None:
        if self.changed.triggered:
            self.changed = Flag(self.env)

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
            text = f"{what} ({top.label})"
            args = None if top.tag is None else top.args(text, **getattr(what, "args", {"on": cause}))
            yield from unit.stall(cause, self._any_of(env, self._wake_events()), text, args)

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
                to = m.modules[job.module].unit.scope
                what = f"route to {to}"
                yield from unit.delay("swap", arch.swap_cycles, what, job.args(what, "route", to))
                m.xbar.swaps += 1
            self.route = job.module
        if job.suspended:
            trace = self._trace
            if trace is not None and env.now > job.suspended_at:
                # on a row of its own: the PM itself is busy for the other image meanwhile
                trace.add_exact(trace.row(f"{unit.scope} (preempted)"), "preempted", job.suspended_at, int(env.now),
                                job.tag)
            yield from unit.delay("preemption", arch.context_switch_cycles, "restore context",
                                  job.args("restore context", "context restore"))
            job.suspended = False

    def _packets(self, job: Job, module):
        """Run ``job``'s packets from its next one, on ``module``: True once done, False if preempted.

        At each packet boundary an older image's job that is ready preempts this one
        (:meth:`_yields_to_older`). A packet: (:attr:`pops`) its addresses out of the FIFO;
        its work, the same for every PM: its page misses served by ``module`` (T_ms), then
        the PM computes (T_norm and T_ps), one SimPy event in all, booked on the PM's unit
        as :meth:`Unit.account` books it (eq. 5.1), inline (the model's hot path, once per
        packet); (:attr:`pushes`) its addresses into the FIFO; (:attr:`pops`) its entries
        freed. After the work, if a job of an older image is queued, the PM lets the cycle
        settle first (:attr:`Priority.SETTLE`): that job may become ready this very cycle (a
        semaphore firing now), and whether it preempts must not depend on the order of the
        cycle's events. A wait on the FIFO that an older image's job cuts short leaves the
        job ``interrupted`` (and a Traversal packet done but not pushed ``pending_push``: on
        its return it pushes without working the packet again).
        """
        packets, frame, fifo = job.spec.packets, job.frame, job.fifo
        n = len(packets)
        pops, pushes = self.pops, self.pushes
        depth = fifo.depth if pops or pushes else 0
        queue = self.queue
        env, unit, scope, trace, stats, raw = self.env, self.unit, self._scope, self._trace, self._stats, self._raw
        page_cycles, flush_cycles = self._page_cycles, self._flush_cycles
        while job.next < n:
            if self._yields_to_older(job, frame, job.pending_push):
                yield from self._suspend(job)
                return False
            job.interrupted = False
            k = job.next
            norm, misses, flushes, items, entries = packets[k]
            if pops:
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
                start = env.now
                yield module.request(scope, misses, ms, "page misses", norm + ps, job.tag) if ms else \
                    Timeout(env, norm + ps)
                stats.norm += norm
                stats.ms += ms
                stats.ps += ps
                end = start + norm + ms + ps
                raw.extend(("busy", start, end))
                if trace is not None and end > start:
                    tid = unit._tid
                    if tid is None:
                        tid = unit._tid = trace.row(scope)
                    trace.add_work(tid, "busy", start, end, norm, ms, ps, job.tag)
                if queue[0].frame < frame:  # an older image's job is queued: let the cycle settle
                    yield self._settle(_SETTLE)
            if pushes or pops:
                slots = entries if entries < depth else depth  # (Fifo.slots: max(1, min(entries, depth)))
                if slots < 1:
                    slots = 1
                if pops:
                    fifo.free(slots, entries)
                    fifo.popped += entries
                elif fifo.try_push(k, slots, entries):
                    job.pending_push = False
                    fifo.pushed += entries
                elif (yield from self._push(job, k, slots, entries)):
                    fifo.pushed += entries
                else:
                    job.interrupted = True  # preempted while the FIFO was full
                    continue
            job.retired += items
            self.retired += items
            job.next = k + 1
        return True

    def _suspend(self, job: Job):
        """Preempted at a packet boundary: save the context; the job waits in the queue."""
        args = None
        if job.tag is not None:  # (the trace's args: the job suspended, for the older image's job that runs next)
            by = self._ready()
            args = {"waiting_for": "save context", **job.tag, "on": "context save"}
            if by is not None:
                args.update(on_name=by.phase, on_frame=by.frame)
        yield from self.unit.delay("preemption", self.model.arch.context_switch_cycles, "save context", args)
        job.suspended = True
        job.interrupted = False
        job.suspended_at = int(self.env.now)
        self.switches += 1
        self.working_on = None

    def _fifo_wake(self, job: Job, signal: Signal):
        """What a wait of ``job`` on its FIFO waits for: the FIFO's ``signal`` (space freed or
        data arrived), or any event that may make a job of an older image ready (it would
        preempt this one); None, without waiting, if such a job is ready now. The signal's
        event is made only when the PM waits (a FIFO event made and never awaited would
        still fire, one SimPy event more)."""
        rank = job.frame
        # _higher_ready(job) and _wake_events(job) in one pass over the older images' jobs
        waits = []  # their first unfired events, each once (an event is in a list by identity)
        for j in self.queue:
            if j.frame >= rank:
                break
            b = j.blocker()
            if b is None:
                return None  # an older image's job is ready
            if b[0] not in waits:
                waits.append(b[0])
        ready = signal.event  # (signal.wait(), inline)
        if ready is None:
            ready = signal.event = Event(self.env)
        return self._any_of(self.env, [ready, self.changed, *waits])


    def _fifo_stall(self, job: Job, signal: Signal, cause: str, what: str):
        """One wait of ``job`` on its FIFO's ``signal``, booked as a ``cause`` stall (*fifo_full*
        or *fifo_empty*): True once something woke the PM (the FIFO may have room or data
        now, or an older image's job may be ready), False without waiting if an older
        image's job is ready now (it preempts this one)."""
        wake = self._fifo_wake(job, signal)
        if wake is None:
            return False
        unit = self.unit
        start = self.env.now
        unit.waiting_for = what
        yield wake
        unit.waiting_for = None
        unit.stalled(cause, start, what, job.args(what, "fifo", job.phase, job.frame))
        if self.changed.triggered:  # (self._rearm(), inline)
            self.changed = Flag(self.env)
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
    pushes = True

    def _push(self, job: Job, k: int, slots: int, entries: int):
        """Packet k's addresses did not fit in the FIFO: wait until they do; False if preempted meanwhile."""
        fifo = job.fifo
        job.pending_push = True
        while (yield from self._fifo_stall(job, fifo.space, "fifo_full", job.space_what)):  # (fifo.space_freed)
            if fifo.try_push(k, slots, entries):
                job.pending_push = False
                return True
        return False


class Intersection(PM):
    """The Ray-Triangle Intersection PM (fixed function): a packet's addresses out of the FIFO, then its tests.

    An empty FIFO stalls it (*fifo_empty*); the wait ends early when an older image's job
    becomes ready, and the job is then preempted before the packet. The packet's entries
    are freed once it is tested.
    """

    kind = "intersection"
    pops = True

    def _pop(self, job: Job):
        """The FIFO was empty: wait for the next packet's addresses; the packet, or None if preempted meanwhile."""
        fifo = job.fifo
        while (yield from self._fifo_stall(job, fifo.data, "fifo_empty", job.data_what)):  # (fifo.data_arrived)
            k = fifo.try_pop()
            if k is not None:
                return k
        return None


class Fragment(PM):
    """The Fragment PM: shading, radiance estimates and photon emission, packet after packet."""

    kind = "fragment"


PM_KINDS: dict[str, type[PM]] = {cls.kind: cls for cls in (Vertex, Traversal, Intersection, Fragment)}
"""The PM class of each of the program's PM names, in pipeline order (``tlm.arch.frame_program.PMS``)."""
