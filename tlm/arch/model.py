"""The thesis GPU as SimPy processes: four PMs, four memory modules, the crossbar, two images.

One pipeline (``pipe0``) of four Processing Modules, each a :class:`PM` process:
Vertex, Traversal, Ray-Triangle Intersection (fixed function) and Fragment; four memory
modules ``mem0``..``mem3`` (:class:`Module`), each a process that serves its routed PM's
page misses; the crossbar arbiter ``xbar`` (:class:`Crossbar`), a process that routes
PMs to modules (swaps) and copies blocks between modules. A stream of ``arch.frames``
frames passes through, ``arch.images_in_flight`` (2) at a time: image slot ``s`` owns
modules ``2s`` and ``2s+1``.

Each frame runs the program of :func:`frame_program` (the reconstruction of the
thesis's Figs. 13 and 14, see ``docs/architecture.md``): a sequence of *phases*; a
phase is one job (Vertex or Fragment PM) or two coupled jobs (Traversal and
Intersection PMs joined by the FIFO). A phase may start when the previous phase of its
frame is done (the controller's semaphores: a PM that waits for it is in a *handshake*
stall) and when the block copy it needs is done (*copy* stall). A PM serves the jobs of
both images: the image that arrived first has priority, and a PM working for the other
image switches at its next packet boundary when a priority job is ready (*preemption*,
costing ``context_switch_cycles`` to save and again to restore). Moving a PM to another
module costs ``swap_cycles`` (*swap*). The Traversal PM waits when the FIFO is full
(*fifo_full*), the Intersection PM when it is empty (*fifo_empty*).

Every cycle of every unit is accounted by :mod:`tlm.arch.units` (eq. 5.1), and
:func:`simulate` checks the invariants of every run: every work item issued is retired,
every FIFO entry pushed is popped, and busy + stall + idle = elapsed for every unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import simpy

from tlm.arch.functional import Functional, TreeWork
from tlm.arch.programs import Programs
from tlm.arch.units import Deadlock, Trace, Unit, run
from tlm.arch.work import split
from tlm.config import ArchConfig

PMS = ("vertex", "traversal", "intersection", "fragment")
PM_TABLE_NAMES = {"vertex": "TVert", "traversal": "TTrav", "intersection": "Tisct", "fragment": "TFrag"}
WORDS_PER_RAY = 2  # a ray record: origin and direction, two 128-bit words
WORDS_PER_PHOTON = 2  # position and power (with the incoming direction packed)
WORDS_PER_HIT = 2  # a hit record: t, triangle, barycentrics, pixel


# -- the frame program (Figs. 13 and 14) ---------------------------------------------------

@dataclass(frozen=True)
class JobSpec:
    """One PM's part of a phase, in packets (all arrays (packets,) int64)."""

    pm: str
    kind: str  # program entry (vertex: geometry_bsp, ...; intersection: the phase's ray kind)
    role: int  # 0: the image's first module (tree, rays), 1: its second (vertices, hits)
    norm: np.ndarray
    misses: np.ndarray
    flushes: np.ndarray
    items: np.ndarray  # work items retired per packet (pixels, photons, rays, levels)
    entries: np.ndarray | None = None  # FIFO entries pushed (traversal) or popped (intersection)

    @property
    def n(self) -> int:
        return int(self.items.shape[0])


@dataclass(frozen=True)
class PhaseSpec:
    name: str
    jobs: tuple[JobSpec, ...]
    copy_words: int  # words the crossbar copies between the image's modules before the phase
    copy_to: int | None = None  # the role the copy goes to (None: the role of the phase's first job)


@dataclass(frozen=True)
class FrameProgram:
    phases: tuple[PhaseSpec, ...]
    left_out: dict[str, str]  # what was not built, and why


def _level_packets(tw: TreeWork) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """A BSP build cut into one packet per level."""
    n = tw.n_levels
    counts = {k: v.astype(np.int64) for k, v in tw.levels.items()}
    elements = np.zeros(n, dtype=np.int64)
    restarts = np.full(n, 3, dtype=np.int64)  # per level: read P twice, write P'
    if n:
        elements[0] = tw.n_elements
        restarts[0] += 1  # the element list itself
    else:  # a tree of 0 levels still reads its elements once
        elements = np.array([tw.n_elements], dtype=np.int64)
        restarts = np.array([1], dtype=np.int64)
        counts = {k: np.zeros(1, dtype=np.int64) for k in counts}
        counts["nodes"][:] = 1
    counts["elements"] = elements
    counts["stream_restarts"] = restarts
    return counts, np.ones(elements.shape[0], dtype=np.int64)


def _programmable(programs: Programs, arch: ArchConfig, pm: str, kind: str, role: int,
                  counts: dict[str, np.ndarray], items: np.ndarray,
                  entries: np.ndarray | None = None) -> JobSpec:
    norm, flushes, misses = programs.cost(pm, kind, counts, items)
    return JobSpec(pm, kind, role, norm, misses, flushes, items, entries)


def _intersection(programs: Programs, kind: str, rays: np.ndarray, tris: np.ndarray,
                  misses: np.ndarray) -> JobSpec:
    fx = programs.intersection
    norm = fx["ray_load_cycles"] * rays + fx["triangle_cycles"] * tris
    if norm.shape[0]:
        norm = norm.copy()
        norm[-1] += fx["stages"] * fx["triangle_cycles"]  # the pipeline drains at the job's end
    return JobSpec("intersection", kind, 1, norm.astype(np.int64), misses.astype(np.int64),
                   np.zeros_like(rays), rays.astype(np.int64), tris.astype(np.int64))


def _compact(work: dict[str, np.ndarray], mask: np.ndarray, packet_size: int):
    """The packets of the pixels in ``mask`` (a pass's ray buffer holds only its rays)."""
    idx = np.flatnonzero(mask)
    p = split("sub", {k: v[idx] for k, v in work.items()}, packet_size)
    return p.counts, p.sizes


def frame_program(fn: Functional, programs: Programs, arch: ArchConfig) -> FrameProgram:
    """The phases of one frame, in the order the control unit runs them."""
    ps = arch.packet_size
    phases: list[PhaseSpec] = []
    left_out: dict[str, str] = {}
    copy_mode = arch.memory == "copy"
    g = fn.geometry
    tree_words = g.nodes + -(-g.slots // 4)  # nodes, and the leaves' triangle indices (4 per word)
    vertex_words = 3 * g.slots

    counts, items = _level_packets(g)
    phases.append(PhaseSpec("geometry", (_programmable(programs, arch, "vertex", "geometry_bsp", 0, counts,
                                                       items),), 0))

    def ti_phase(name: str, t_kind: str, work: dict[str, np.ndarray], mask: np.ndarray, keys: dict,
                 copy_words: int, copy_to: int | None = None) -> None:
        counts, items = _compact(work, mask, ps)
        zero = np.zeros(items.shape[0], dtype=np.int64)
        rays = sum((counts.get(k, zero) for k in keys["rays"]), zero)
        tris = counts.get(keys["tris"], zero)
        t = _programmable(programs, arch, "traversal", t_kind, 0, counts, items, tris)
        i = _intersection(programs, t_kind, rays, tris, counts.get(keys["isect_misses"], zero))
        if copy_mode:
            copy_words += tree_words + vertex_words
        phases.append(PhaseSpec(name, (t, i), copy_words, copy_to))

    def f_phase(name: str, kind: str, work: dict[str, np.ndarray], mask: np.ndarray, copy_words: int = 0) -> None:
        counts, items = _compact(work, mask, ps)
        if copy_mode:
            copy_words += WORDS_PER_HIT * int(items.sum())
        phases.append(PhaseSpec(name, (_programmable(programs, arch, "fragment", kind, 1, counts, items),),
                                copy_words))

    # the vertices go to the image's second module, where the Intersection PM reads them
    first_ti_copy = vertex_words

    if "pmap" in fn.passes and fn.photon_work is not None and fn.photon_tree is not None:
        pw = fn.photon_work
        n = pw["photons_emitted"].shape[0]
        emit = split("emit", {"photons_emitted": pw["photons_emitted"]}, ps)
        emit_counts = dict(emit.counts)
        emit_counts["stream_restarts"] = np.zeros(emit.n, dtype=np.int64)
        if emit.n:
            emit_counts["stream_restarts"][0] = 1
        phases.append(PhaseSpec("photons.emit", (_programmable(programs, arch, "vertex", "photon_emit", 0,
                                                               emit_counts, emit.sizes),), 0))
        ti_phase("photons.trace", "photons", pw, np.ones(n, dtype=bool),
                 {"rays": ("rays",), "tris": "tri_tests", "isect_misses": "isect_misses"}, first_ti_copy, 1)
        first_ti_copy = 0
        f_phase("photons.store", "photons", pw, pw["bounces"] > 0)
        stored = int(pw["stored"].sum())
        counts, items = _level_packets(fn.photon_tree)
        copy = WORDS_PER_PHOTON * stored  # the stored photons, from the Fragment PM's module
        phases.append(PhaseSpec("photons.bsp", (_programmable(programs, arch, "vertex", "photon_bsp", 0, counts,
                                                              items),), copy))
    else:
        left_out["photon programs, photon memory and photon tree"] = "the plan has no pmap pass"

    ray_keys = {"rays": ("primary_rays", "secondary_rays"), "tris": "tri_tests", "isect_misses": "isect_misses"}
    shadow_keys = {"rays": ("shadow_rays",), "tris": "shadow_tri_tests", "isect_misses": "shadow_isect_misses"}
    for name in ("rcast", "reflect", "refract"):
        if name not in fn.passes:
            left_out[f"{name} frames"] = "the plan does not render this pass"
            continue
        w = fn.work[name]
        rays = w["primary_rays"] + w["secondary_rays"]
        if not rays.any():
            left_out[f"{name} frames"] = "no ray of this pass: no eye path meets its material"
            continue
        # the first ray phase receives the vertices (towards the Intersection PM's module);
        # a secondary pass receives the Fragment PM's new rays (towards the Traversal PM's)
        if first_ti_copy:
            ti_phase(f"{name}.rays", "rays", w, rays > 0, ray_keys, first_ti_copy, 1)
        else:
            ti_phase(f"{name}.rays", "rays", w, rays > 0, ray_keys, WORDS_PER_RAY * int(w["secondary_rays"].sum()), 0)
        first_ti_copy = 0
        f_phase(f"{name}.shade", "shade", w, rays > 0)
        shadow = w["shadow_rays"]
        if shadow.any():
            ti_phase(f"{name}.shadow", "shadow", w, shadow > 0, shadow_keys, WORDS_PER_RAY * int(shadow.sum()))
            f_phase(f"{name}.light", "light", w, shadow > 0)
        else:
            left_out[f"{name} shadow frames"] = "no shadow ray (no light, or no Lambertian hit)"
    if "pmap" in fn.passes and fn.photon_tree is not None:
        w = fn.work["pmap"]
        copy = WORDS_PER_PHOTON * fn.photon_tree.n_elements + fn.photon_tree.nodes
        f_phase("pmap.gather", "gather", w, w["gathers"] > 0, copy)
    return FrameProgram(tuple(phases), left_out)


# -- the units --------------------------------------------------------------------------------

class Module:
    """A DDR memory module: serves its routed PM's page misses, one at a time."""

    def __init__(self, env: simpy.Environment, index: int, miss_cycles: int, trace: Trace | None):
        self.env = env
        self.index = index
        self.unit = Unit(env, f"mem{index}", trace)
        self.miss_cycles = miss_cycles
        self.requests: simpy.Store = simpy.Store(env)
        self.rows_opened = 0
        self.unit.waiting_for = None
        env.process(self._serve())

    def _serve(self):
        while True:
            misses, done = yield self.requests.get()
            self.rows_opened += misses
            yield from self.unit.work(0, misses * self.miss_cycles, 0, label="page misses")
            done.succeed()

    def copy(self, cycles: int, label: str):
        yield from self.unit.work(cycles, 0, 0, label=label)


class Crossbar:
    """The memory controller's crossbar: routes PMs to modules, copies blocks."""

    def __init__(self, env: simpy.Environment, modules: list[Module], arch: ArchConfig, trace: Trace | None):
        self.env = env
        self.unit = Unit(env, "xbar", trace)
        self.modules = modules
        self.arch = arch
        self.lock = simpy.Resource(env, capacity=1)
        self.swaps = 0
        self.copies = 0
        self.words_copied = 0

    def copy(self, src: int, dst: int, words: int, what: str):
        """Copy ``words`` from module ``src`` to ``dst`` (the crossbar copies one block at a time)."""
        cycles = -(-words // self.arch.copy_words_per_cycle)
        with self.lock.request() as req:
            yield req
            self.copies += 1
            self.words_copied += words
            label = f"copy mem{src}->mem{dst}: {what}"
            self.env.process(self.modules[src].copy(cycles, label))
            self.env.process(self.modules[dst].copy(cycles, label))
            yield from self.unit.work(cycles, 0, 0, label=label)


@dataclass
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

    def blocker(self):
        for ev, cause, what in self.after:
            if not ev.triggered:
                return ev, cause, what
        return None

    @property
    def label(self) -> str:
        return f"frame {self.frame} {self.phase}"


class Fifo:
    """The Traversal PM's FIFO of triangle addresses towards the Intersection PM.

    A packet's addresses enter together; a packet with more addresses than the FIFO
    holds enters when the FIFO is empty (the packet is the model's unit of transfer),
    and a packet without addresses takes one entry (its end marker).
    Its space is freed when the Intersection PM has tested the packet.
    """

    def __init__(self, env: simpy.Environment, depth: int):
        self.depth = depth
        self.space = simpy.Container(env, capacity=depth, init=depth)
        self.packets = simpy.Store(env)
        self.pushed = 0
        self.popped = 0

    def slots(self, entries: int) -> int:
        # a packet without addresses still passes its end-of-packet marker
        return max(1, min(int(entries), self.depth))


class PM:
    """A Processing Module: takes jobs of both images, the priority image's first."""

    def __init__(self, model: Model, name: str):
        self.model = model
        self.env = model.env
        self.name = name
        self.unit = Unit(model.env, f"pipe0.{name}", model.trace)
        self.queue: list[Job] = []
        self.route: int | None = None
        self.changed = self.env.event()
        self.issued = 0
        self.retired = 0
        self.switches = 0
        self.env.process(self._loop())

    # -- queue ------------------------------------------------------------------------
    def submit(self, job: Job) -> None:
        self.queue.append(job)
        self.issued += int(job.spec.items.sum())
        self.poke()

    def poke(self) -> None:
        if not self.changed.triggered:
            self.changed.succeed()

    def _rearm(self) -> None:
        if self.changed.triggered:
            self.changed = self.env.event()

    def _rank(self, job: Job) -> int:
        return job.frame  # the image that arrived first has priority

    def _ready(self) -> list[Job]:
        return sorted((j for j in self.queue if j.blocker() is None), key=self._rank)

    def _higher_ready(self, job: Job) -> bool:
        return any(j is not job and j.blocker() is None and self._rank(j) < self._rank(job) for j in self.queue)

    def _wake_events(self) -> list:
        evs = [self.changed]
        for j in self.queue:
            b = j.blocker()
            if b is not None:
                evs.append(b[0])
        return evs

    # -- the process ------------------------------------------------------------------
    def _loop(self):
        env = self.env
        while True:
            self._rearm()
            ready = self._ready()
            if ready:
                yield from self._run(ready[0])
                continue
            if not self.queue:  # no frame in flight needs this PM: idle
                self.unit.waiting_for = "a job (idle)"
                yield self.changed
                self.unit.waiting_for = None
                continue
            top = min(self.queue, key=self._rank)
            _, cause, what = top.blocker()
            yield from self.unit.stall(cause, env.any_of(self._wake_events()), f"{what} ({top.label})")

    def _run(self, job: Job):
        m = self.model
        if self.route != job.module:
            if self.route is not None:
                yield from self.unit.delay("swap", m.arch.swap_cycles, f"route to mem{job.module}")
                m.xbar.swaps += 1
            self.route = job.module
        if job.suspended:
            # on a row of its own: the PM itself is busy for the other image meanwhile
            m.trace_slice(f"{self.unit.scope} (preempted)", "preempted", job.suspended_at, env_now(self),
                          job=job.label)
            yield from self.unit.delay("preemption", m.arch.context_switch_cycles, "restore context")
            job.suspended = False
        spec = job.spec
        while job.next < spec.n:
            if (job.next > 0 or job.pending_push or job.interrupted) and self._higher_ready(job):
                yield from self.unit.delay("preemption", m.arch.context_switch_cycles, "save context")
                job.suspended = True
                job.interrupted = False
                job.suspended_at = env_now(self)
                self.switches += 1
                return
            job.interrupted = False
            k = job.next
            if self.name == "intersection" and not (yield from self._pop(job)):
                job.interrupted = True  # a priority job became ready while the FIFO was empty
                continue
            if not job.pending_push:
                yield from self._packet(job, k)
            if self.name == "traversal" and not (yield from self._push(job, k)):
                job.interrupted = True
                continue
            if self.name == "intersection":
                job.fifo.space.put(job.fifo.slots(spec.entries[k]))
                job.fifo.popped += int(spec.entries[k])
            job.retired += int(spec.items[k])
            self.retired += int(spec.items[k])
            job.next += 1
        self.queue.remove(job)
        job.done.succeed()

    def _packet(self, job: Job, k: int):
        spec = job.spec
        m = self.model
        misses = int(spec.misses[k])
        if misses and m.arch.page_miss_cycles:
            done = self.env.event()
            start = self.env.now
            m.modules[job.module].requests.put((misses, done))
            yield done
            waited = self.env.now - start
            self.unit.stats.ms += waited
            if self.unit.trace is not None:
                self.unit.trace.slice(self.unit.scope, "busy", start, self.env.now, T_ms=waited)
        yield from self.unit.work(int(spec.norm[k]), 0, int(spec.flushes[k]) * m.arch.flush_cycles, label="busy")
        if len(self.queue) > 1:
            # let every event of this cycle (a semaphore firing now) settle before the
            # packet-boundary check, so preemption does not depend on event order
            settle = self.env.event()
            settle._ok, settle._value = True, None
            self.env.schedule(settle, priority=2)
            yield settle

    def _push(self, job: Job, k: int):
        """Put packet k's triangle addresses into the FIFO; False if preempted while it was full."""
        fifo = job.fifo
        n = int(job.spec.entries[k])
        put = fifo.space.get(fifo.slots(n))
        while not put.triggered:
            job.pending_push = True
            yield from self.unit.stall("fifo_full", self.env.any_of([put, *self._wake_events()]),
                                       f"FIFO space ({job.label})")
            self._rearm()
            if not put.triggered and self._higher_ready(job):
                put.cancel()
                return False
        job.pending_push = False
        fifo.pushed += n
        fifo.packets.put(k)
        return True

    def _pop(self, job: Job):
        """Take the next packet's addresses from the FIFO; False if preempted while it was empty."""
        get = job.fifo.packets.get()
        while not get.triggered:
            yield from self.unit.stall("fifo_empty", self.env.any_of([get, *self._wake_events()]),
                                       f"FIFO data ({job.label})")
            self._rearm()
            if not get.triggered and self._higher_ready(job):
                get.cancel()
                return False
        if get.value != job.next:
            raise AssertionError(f"FIFO order broken: packet {get.value} arrived for {job.next}")
        return True


def env_now(pm: PM) -> int:
    return int(pm.env.now)


# -- the model ----------------------------------------------------------------------------------

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
    modules: list[Module] = field(default_factory=list)
    xbar: Crossbar | None = None
    pms: dict[str, PM] = field(default_factory=dict)
    frames: list[FrameRecord] = field(default_factory=list)
    fifos: list = field(default_factory=list)

    def trace_slice(self, scope: str, name: str, start: int, end: int, **args) -> None:
        if self.trace is not None:
            self.trace.slice(scope, name, start, end, **args)


def _frame_process(model: Model, rec: FrameRecord):
    env = model.env
    a, b = 2 * rec.slot, 2 * rec.slot + 1
    prev = None
    prev_name = ""
    for spec in model.program.phases:
        after = []
        if prev is not None:
            after.append((prev, "handshake", f"semaphore '{prev_name}' of frame {rec.index}"))
        copy_done = None
        if spec.copy_words:
            copy_done = env.event()
            after.append((copy_done, "copy", f"block copy for '{spec.name}' of frame {rec.index}"))
        fifo = Fifo(env, model.arch.fifo_depth) if len(spec.jobs) == 2 else None
        if fifo is not None:
            model.fifos.append(fifo)
        dones = []
        for js in spec.jobs:
            done = env.event()
            dones.append(done)
            model.pms[js.pm].submit(Job(js, rec.index, spec.name, a if js.role == 0 else b, list(after), fifo, done))
        if copy_done is not None:
            env.process(_copy_after(model, prev, copy_done, spec, a, b, rec.index))
        prev = _all_done(env, dones)
        prev_name = spec.name
    if prev is not None:
        yield prev
    rec.done = int(env.now)


def _all_done(env: simpy.Environment, events: list) -> simpy.events.Event:
    """A plain event that fires when every event of ``events`` has (the phase's semaphore).

    Not an ``AllOf``: SimPy strips the callbacks of a condition nested in another
    condition once the outer one fires, and PMs wait on any-of sets that include it.
    """
    done = env.event()
    left = [len(events)]

    def one(_ev):
        left[0] -= 1
        if left[0] == 0:
            done.succeed()

    for ev in events:
        ev.callbacks.append(one)
    if not events:
        done.succeed()
    return done


def _copy_after(model: Model, prev, copy_done, spec: PhaseSpec, a: int, b: int, frame: int):
    if prev is not None:
        yield prev
    # data produced on one module of the image and needed on the other
    to = spec.jobs[0].role if spec.copy_to is None else spec.copy_to
    src, dst = (b, a) if to == 0 else (a, b)
    yield from model.xbar.copy(src, dst, spec.copy_words, f"{spec.name} (frame {frame})")
    copy_done.succeed()


def _stream(model: Model, done: simpy.events.Event):
    env = model.env
    slots = simpy.Store(env)
    for s in range(model.arch.images_in_flight):
        slots.put(s)
    running = []
    for f in range(model.arch.frames):
        slot = yield slots.get()  # the raw data of frame f is accepted when a module pair is free
        rec = FrameRecord(f, slot, arrival=int(env.now))
        model.frames.append(rec)
        proc = env.process(_frame_process(model, rec))

        def release(_ev, s=slot):
            slots.put(s)

        proc.callbacks.append(release)
        running.append(proc)
    yield env.all_of(running)
    done.succeed()


@dataclass
class Timing:
    """The outcome of one simulation: cycles per frame, per-unit breakdowns, the trace."""

    cycles: dict
    fps: float
    units: dict
    frames: list[dict]
    events: int
    program: FrameProgram
    trace: Trace | None
    checks: dict
    crossbar: dict
    model: Model | None = None  # the simulated units (their logs), for tests and inspection

    def to_dict(self) -> dict:
        return {
            "cycles": self.cycles,
            "fps": self.fps,
            "units": self.units,
            "frame_times": self.frames,
            "events": self.events,
            "phases": [p.name for p in self.program.phases],
            "left_out": self.program.left_out,
            "invariants": self.checks,
            "crossbar": self.crossbar,
        }


def simulate(fn: Functional, programs: Programs, arch: ArchConfig) -> Timing:
    """Run the stream of ``arch.frames`` frames of ``fn`` through the model."""
    return simulate_program(frame_program(fn, programs, arch), arch)


def simulate_program(program: FrameProgram, arch: ArchConfig) -> Timing:
    """Run a frame program (from :func:`frame_program`, or built by hand in tests)."""
    env = simpy.Environment()
    trace = Trace() if arch.trace else None
    model = Model(env, arch, program, trace)
    model.modules = [Module(env, i, arch.page_miss_cycles, trace) for i in range(2 * arch.images_in_flight)]
    model.xbar = Crossbar(env, model.modules, arch, trace)
    model.pms = {name: PM(model, name) for name in PMS}
    done = env.event()
    env.process(_stream(model, done))
    units = [pm.unit for pm in model.pms.values()]
    counter = _EventCounter(env)
    end = run(env, done, units, max_events=arch.max_events)
    timing = _results(model, program, end, counter.count(), trace)
    timing.model = model
    return timing


class _EventCounter:
    """Counts processed SimPy events (``env.step`` calls) without slowing the loop."""

    def __init__(self, env: simpy.Environment):
        self.env = env
        self.n = 0
        step = env.step

        def counted():
            self.n += 1
            step()

        env.step = counted

    def count(self) -> int:
        return self.n


def _results(model: Model, program: FrameProgram, end: int, events: int, trace: Trace | None) -> Timing:
    arch = model.arch
    nf = arch.frames
    units = {}
    checks = {}
    all_units = [*(pm.unit for pm in model.pms.values()), *(m.unit for m in model.modules), model.xbar.unit]
    for u in all_units:
        units[u.scope] = u.stats.breakdown(end)  # raises if busy + stall exceed elapsed
    checks["busy + stall + idle = elapsed"] = True
    expected = dict.fromkeys(PMS, 0)
    expected_norm = dict.fromkeys(PMS, 0)
    for ph in program.phases:
        for js in ph.jobs:
            expected[js.pm] += int(js.items.sum()) * nf
            expected_norm[js.pm] += int(js.norm.sum()) * nf
    for name, pm in model.pms.items():
        if pm.issued != expected[name] or pm.retired != pm.issued or pm.queue:
            raise AssertionError(f"pipe0.{name}: {pm.issued} work items issued, {pm.retired} retired, "
                                 f"{expected[name]} expected, {len(pm.queue)} jobs left")
        if pm.unit.stats.norm != expected_norm[name]:
            raise AssertionError(f"pipe0.{name}: T_norm {pm.unit.stats.norm} != the program's "
                                 f"{expected_norm[name]}")
    checks["every work item issued is retired"] = True
    for fifo in model.fifos:
        if fifo.pushed != fifo.popped or fifo.space.level != fifo.depth:
            raise AssertionError(f"a FIFO ended with {fifo.pushed} addresses pushed, {fifo.popped} popped")
    checks["every FIFO entry pushed is popped"] = True
    checks["T_norm equals the programs' cycles"] = True
    for rec in model.frames:
        if rec.done < 0:
            raise AssertionError(f"frame {rec.index} did not finish")
    done = [r.done for r in model.frames]
    throughput = (done[-1] - done[0]) / (nf - 1) if nf > 1 else done[0]
    latency = float(np.mean([r.done - r.arrival for r in model.frames]))
    cycles = {}
    for name, pm in model.pms.items():
        s = pm.unit.stats
        own = s.busy + s.stall["swap"] + s.stall["copy"] + s.stall["preemption"]
        cycles[name] = round(own / nf)
    throughput_i = round(throughput)
    cycles["throughput"] = throughput_i
    cycles["latency"] = round(latency)
    fps = arch.clock_hz / throughput_i if throughput_i > 0 else math.inf
    if trace is not None:
        _fill_idle(trace, end)
    frames = [{"frame": r.index, "slot": r.slot, "arrival": r.arrival, "done": r.done} for r in model.frames]
    xb = {"swaps": model.xbar.swaps, "copies": model.xbar.copies, "words_copied": model.xbar.words_copied,
          "preemptions": {name: pm.switches for name, pm in model.pms.items()}}
    return Timing(cycles, fps, units, frames, events, program, trace, checks, xb)


def _fill_idle(trace: Trace, end: int) -> None:
    """Idle slices in every gap of every row, up to the end of the run."""
    by_row: dict[int, list[tuple[int, int]]] = {}
    for e in trace.events:
        by_row.setdefault(e["tid"], []).append((e["ts"], e["ts"] + e["dur"]))
    scopes = {tid: scope for scope, tid in trace.rows.items()}
    for tid, spans in by_row.items():
        spans.sort()
        t = 0
        for s, e in spans:
            if s > t:
                trace.slice(scopes[tid], "idle", t, s)
            t = max(t, e)
        if end > t:
            trace.slice(scopes[tid], "idle", t, end)


__all__ = ["PMS", "PM_TABLE_NAMES", "Deadlock", "FrameProgram", "JobSpec", "PhaseSpec", "Timing", "frame_program",
           "simulate", "simulate_program"]
