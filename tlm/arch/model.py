"""The thesis GPU as SimPy processes: PMs, memory modules, the crossbar, two images.

The frame program's pipelines (``pipe0``..), each of Processing Modules that are
:class:`PM` processes: Vertex (pipeline 0 only), Traversal, Ray-Triangle Intersection
(fixed function) and Fragment; four memory modules per pipeline (``mem4p``..``mem4p+3``,
:class:`Module`, serving the page misses of the PM routed to them); the crossbar
``xbar`` (:class:`Crossbar`), which routes PMs to modules (swaps) and copies blocks
between modules; with more than one pipeline, the ``compose`` unit that receives the
tiles. A stream of ``arch.frames`` frames passes through, ``arch.images_in_flight`` (2)
at a time: image slot ``s`` owns a pipeline's modules ``2s`` and ``2s+1``. A stream that
only settles after a transient (two images with the dynamic scheduler, or with the static one
where the asked frames' steady gaps do not repeat from the first) runs on past
``arch.frames`` until its completions repeat (:func:`settles`, :mod:`tlm.arch.steady`).

Each frame runs the program of :func:`frame_program` (the reconstruction of the
thesis's Figs. 13 and 14, see ``docs/architecture.md``): stages, shared ones on
pipeline 0 and tiled ones on every pipeline, each a chain of *phases*; a phase is one
job (Vertex or Fragment PM) or two coupled jobs (Traversal and Intersection PMs joined
by the FIFO). A phase may start when the previous phase of its
frame is done (the controller's semaphores: a PM that waits for it is in a *handshake*
stall) and when the block copy it needs is done (*copy* stall). A PM serves the jobs of
both images: the image that arrived first has priority, and a PM working for the other
image switches at its next packet boundary when a priority job is ready (*preemption*,
costing ``context_switch_cycles`` to save and again to restore). Moving a PM to another
module costs ``swap_cycles`` (*swap*). The Traversal PM waits when the FIFO is full
(*fifo_full*), the Intersection PM when it is empty (*fifo_empty*).

The units themselves are in :mod:`tlm.arch.pm` (the PMs), :mod:`tlm.arch.memory` (the
modules), :mod:`tlm.arch.crossbar` and :mod:`tlm.arch.fifo`; the schedulers that hand a
tiled stage's tiles to the pipelines in :mod:`tlm.arch.schedulers`; the order of a
cycle's events in :mod:`tlm.arch.events`. This module is the control unit (frames,
stages, copies) and the simulation. Every cycle of every unit is
accounted by :mod:`tlm.arch.units` (eq. 5.1), and
:func:`simulate` checks the invariants of every run: every work item issued is retired,
every FIFO entry pushed is popped, and busy + stall + idle = elapsed for every unit.
"""

from __future__ import annotations

import gc
import math
from dataclasses import dataclass, field
from fractions import Fraction

import simpy

from tlm.arch.costs import Programs
from tlm.arch.crossbar import Crossbar
from tlm.arch.events import CycleEnd, Flag, all_done
from tlm.arch.fifo import Fifo, fifo_peaks
from tlm.arch.frame_program import (
    PM_TABLE_NAMES,
    PMS,
    WORDS_PER_PIXEL,
    FrameProgram,
    JobSpec,
    PhaseSpec,
    Stage,
    frame_program,
)
from tlm.arch.functional import Functional
from tlm.arch.granularity import (
    fill_and_drain,
    fine_ti_cycles,
    flow_shop,
    flow_shop_python,
    granularity_estimate,
    ti_cycles,
)
from tlm.arch.memory import Module
from tlm.arch.pm import PM, PM_KINDS, Job
from tlm.arch.steady import frames_cap, keep_going, repeats_from_warmup, steady_throughput
from tlm.arch.units import Deadlock, MaxEventsReached, Trace, Waiting, run, within_int64
from tlm.config import ArchConfig
from tlm.registry import SCHEDULERS, may_run_on

# -- the model's state ------------------------------------------------------------------------

@dataclass
class FrameRecord:
    """A frame of the stream: its image slot, the cycle it arrived and the cycle it was done."""

    index: int
    slot: int
    arrival: int = 0
    done: int = -1


@dataclass
class Model:
    """The simulated GPU: every unit, the frames in flight, and the end-of-cycle events."""

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
    cycle_end: CycleEnd = field(init=False)  # the decisions taken at the end of a cycle (run releases them)

    def __post_init__(self) -> None:
        self.cycle_end = CycleEnd(self.env)

    def module(self, pipe: int, slot: int, role: int) -> int:
        """The index of pipeline ``pipe``'s module ``role`` of image slot ``slot``."""
        return 2 * (pipe * self.arch.images_in_flight + slot) + role

    def pm(self, pipe: int, name: str) -> PM:
        return self.pms[(pipe, name)]


# -- the control unit -------------------------------------------------------------------------

class _Frame:
    """One frame in flight, as the control unit and the schedulers see it.

    Holds the frame's record and the words each pipeline sends back to pipeline 0 after
    a tiled stage (``returns``); :meth:`chain` and :meth:`compose` are what a scheduler
    (:class:`tlm.arch.schedulers.Scheduler`) does with a tile.
    """

    def __init__(self, model: Model, rec: FrameRecord):
        self.model = model
        self.env = model.env
        self.rec = rec
        self.cycle_end = model.cycle_end
        self.returns = [0] * model.program.pipelines

    def returned(self, pipe: int, words: int) -> None:
        """Pipeline ``pipe``'s tile leaves ``words`` to send back to pipeline 0 (a fan-in)."""
        self.returns[pipe] += words

    def chain(self, pipe: int, phases, gate: list) -> simpy.events.Event:
        """Queue a tile's phases on pipeline ``pipe``'s PMs; the event fires when the last is done.

        The first phase waits for ``gate`` ([(event, cause, what)]); each later phase for its
        predecessor (a handshake) and for its block copy, if it needs one.
        """
        model, rec = self.model, self.rec
        env = self.env
        a, b = model.module(pipe, rec.slot, 0), model.module(pipe, rec.slot, 1)
        prev, prev_name = None, ""
        for spec in phases:
            if prev is None:
                after = list(gate)
            else:
                after = [(prev, "handshake", Waiting(f"semaphore '{prev_name}' of frame {rec.index}", on="phase",
                                                     on_name=prev_name, on_frame=rec.index))]
            if spec.copy_words:
                copy_done = Flag(env)
                waits = [ev for ev, _, _ in after]
                after.append((copy_done, "copy", Waiting(f"block copy for '{spec.name}' of frame {rec.index}",
                                                         on="copy", on_name=spec.name, on_frame=rec.index)))
                env.process(_copy_after(model, waits, copy_done, spec, a, b, rec.index, pipe))
            fifo = Fifo(env, model.arch.fifo_depth, pipe) if len(spec.jobs) == 2 else None
            if fifo is not None:
                model.fifos.append(fifo)
            dones = []
            for js in spec.jobs:
                done = env.event()
                dones.append(done)
                model.pm(pipe, js.pm).submit(Job(js, rec.index, spec.name, a if js.role == 0 else b, list(after),
                                                  fifo, done))
            prev = all_done(env, dones)
            prev_name = spec.name
        if prev is None:  # a tile without work still waits for its gate
            prev = all_done(env, [ev for ev, _, _ in gate])
        return prev

    def compose(self, pipe: int, tile):
        """Copy ``tile``'s pixels from pipeline ``pipe``'s module to the top-level unit (a process step)."""
        model, rec = self.model, self.rec
        yield from model.xbar.copy(model.module(pipe, rec.slot, 1), [model.compose], WORDS_PER_PIXEL * tile.pixels,
                                   f"{tile.name} to the image (frame {rec.index})", (rec.index, pipe),
                                   {"tile": tile.name})


def _frame_process(model: Model, rec: FrameRecord):
    """Submit one frame's stages: shared ones on pipeline 0, tiled ones through the scheduler."""
    env = model.env
    n_pipes = model.program.pipelines
    scheduler = SCHEDULERS[model.program.scheduler]()
    frame = _Frame(model, rec)
    returns = frame.returns  # words each pipeline sends back to pipeline 0 after a tiled stage
    prev, prev_name = None, ""
    pending_returns = 0
    tails = []  # the compose copies the frame waits for at its end (a scheduler's)
    for stage in model.program.stages:
        gate = []
        if prev is not None:
            gate.append((prev, "handshake", Waiting(f"semaphore '{prev_name}' of frame {rec.index}", on="stage",
                                                    on_name=prev_name, on_frame=rec.index)))
        if stage.shared:
            if pending_returns:
                fan_in = Flag(env)
                gate.append((fan_in, "copy", Waiting(f"results to pipeline 0 for '{stage.name}' of frame {rec.index}",
                                                     on="fan-in", on_name=stage.name, on_frame=rec.index)))
                env.process(_fan_in(model, rec, prev, stage, returns, fan_in))
            (tile,) = stage.tiles
            prev = frame.chain(0, tile.phases, gate)
            pending_returns = 0
        else:
            fan_out = [Flag(env) for _ in range(n_pipes)]
            env.process(_fan_out(model, rec, prev, stage, fan_out))
            gates = [[*gate, (fan_out[p], "copy", Waiting(f"'{stage.name}' data of frame {rec.index}", on="fan-out",
                                                          on_name=stage.name, on_frame=rec.index))]
                     for p in range(n_pipes)]
            prev, stage_tails = scheduler.run_stage(frame, stage, gates)
            tails.extend(stage_tails)
            pending_returns = sum(t.returns for t in stage.tiles)
        prev_name = stage.name
    yield all_done(env, [prev, *tails])
    rec.done = int(env.now)


def _fan_out(model: Model, rec: FrameRecord, prev, stage: Stage, events: list):
    """Copy pipeline 0's shared structures into every pipeline (broadcast or one by one)."""
    if prev is not None:
        yield prev
    n_pipes = len(events)
    src = {fo: model.module(0, rec.slot, fo.src_role) for fo in stage.fan_out}

    def targets(fo, pipes):
        return [model.module(p, rec.slot, fo.dst_role) for p in pipes
                if not (p == 0 and fo.src_role == fo.dst_role) and fo.words]

    if model.arch.fanout == "broadcast" or n_pipes == 1:
        for fo in stage.fan_out:
            dsts = targets(fo, range(n_pipes))
            if dsts:
                yield from model.xbar.copy(src[fo], dsts, fo.words, f"{fo.what} (frame {rec.index})", (rec.index, 0))
        for ev in events:
            ev.succeed()
        return
    # pipeline 0 last: its PMs start on the source module once its copies are done, and
    # the other pipelines' copies still read that module until then
    for p in [*range(1, n_pipes), 0]:
        for fo in stage.fan_out:
            dsts = targets(fo, [p])
            if dsts:
                yield from model.xbar.copy(src[fo], dsts, fo.words, f"{fo.what} (frame {rec.index})", (rec.index, p))
        events[p].succeed()


def _fan_in(model: Model, rec: FrameRecord, prev, stage: Stage, returns: list[int], done):
    """Each pipeline's results (stored photons, on its Fragment PM's module) to pipeline 0."""
    if prev is not None:
        yield prev
    dst = model.module(0, rec.slot, stage.fan_in_role)
    for p, words in enumerate(returns):
        if words:
            src = model.module(p, rec.slot, 1)
            if src != dst:
                yield from model.xbar.copy(src, [dst], words, f"{stage.name} (frame {rec.index})", (rec.index, p))
        returns[p] = 0
    done.succeed()


def _copy_after(model: Model, waits: list, copy_done, spec: PhaseSpec, a: int, b: int, frame: int, pipe: int):
    for ev in waits:  # noqa: UP028 - SimPy sends event values back; a list iterator cannot take them
        yield ev
    # data produced on one module of the image and needed on the other
    to = spec.jobs[0].role if spec.copy_to is None else spec.copy_to
    src, dst = (b, a) if to == 0 else (a, b)
    yield from model.xbar.copy(src, [dst], spec.copy_words, f"{spec.name} (frame {frame})", (frame, pipe),
                               {"job": spec.name})
    copy_done.succeed()


def settling(program: FrameProgram, arch: ArchConfig) -> bool:
    """Whether the stream may run past ``arch.frames`` until its completions repeat
    (:mod:`tlm.arch.steady`): two images in flight, with the dynamic queue, or with the static
    tiles where ``arch.frames`` leaves a steady window (at least ``3k - 1``); a static stream
    only where the asked frames' steady gaps do not already repeat from the first
    (:func:`settles`: their completions too may begin with a transient)."""
    return may_run_on(program.scheduler, arch.images_in_flight, arch.frames)


def settles(program: FrameProgram, arch: ArchConfig, done: list[int]) -> bool:
    """Whether the stream whose completions so far are ``done`` is measured as one that settles
    (ran on, or would have, until its completions repeat): :func:`settling`, less a static stream
    whose steady gaps among the asked frames' completions repeat from the first
    (:func:`~tlm.arch.steady.repeats_from_warmup`, the same at any length of the stream)."""
    if not settling(program, arch):
        return False
    static = SCHEDULERS[program.scheduler].periodic_from_warmup
    return not (static and repeats_from_warmup(done, arch.images_in_flight, arch.frames))


def _stream(model: Model, done: simpy.events.Event):
    """Frames arrive as image slots free up: ``arch.frames`` of them, and for a settling
    stream more, one at each completion, until the completions repeat (``keep_going``) or
    :func:`~tlm.arch.steady.frames_cap` frames have arrived."""
    env = model.env
    arch = model.arch
    slots = simpy.Store(env)
    for s in range(arch.images_in_flight):
        slots.put(s)
    running = []
    more = settling(model.program, arch)
    cap = frames_cap(arch.frames, arch.settle_frames) if more else arch.frames
    for f in range(cap):
        slot = yield slots.get()  # the raw data of frame f is accepted when a module pair is free
        if f >= arch.frames:
            so_far = [r.done for r in model.frames if r.done >= 0]
            if not (settles(model.program, arch, so_far) and keep_going(so_far, arch.images_in_flight)):
                break
        rec = FrameRecord(f, slot, arrival=int(env.now))
        model.frames.append(rec)
        proc = env.process(_frame_process(model, rec))

        def release(_ev, s=slot):
            slots.put(s)

        proc.callbacks.append(release)
        running.append(proc)
    yield env.all_of(running)
    done.succeed()


NOT_KEPT = ("timing.model: this Timing was pickled (or deep-copied), which keeps every figure and to_dict() "
            "but not the live SimPy model (its units and their logs); call tlm.simulate again for the model")


class ModelNotKept:
    """What ``timing.model`` is in a :class:`Timing` that was pickled or deep-copied: the live
    SimPy model (its environment, its units' process generators) cannot be pickled, so it is
    left out; reading anything of it raises an ``AttributeError`` saying so (:data:`NOT_KEPT`)."""

    __slots__ = ()

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)  # (the protocols of copy and pickle ask for these)
        raise AttributeError(NOT_KEPT)

    def __repr__(self) -> str:
        return "<the model of a pickled Timing: not kept>"

    def __reduce__(self) -> str:
        return "MODEL_NOT_KEPT"  # (the one instance, by name)


MODEL_NOT_KEPT = ModelNotKept()


@dataclass
class Timing:
    """The outcome of one simulation: cycles per frame, per-unit breakdowns, the trace.

    A Timing pickles (a process pool can return it) and deep-copies without its ``model``:
    every other field, so every figure and :meth:`to_dict`, is kept; ``model`` becomes
    :data:`MODEL_NOT_KEPT`, whose attributes raise an error that says so. A shallow copy
    (``copy.copy``) keeps the model.
    """

    cycles: dict
    fps: float
    units: dict
    frames: list[dict]
    events: int
    program: FrameProgram
    trace: Trace | None
    checks: dict
    crossbar: dict
    pipelines: list[dict] = field(default_factory=list)  # per pipeline: each PM's cycles per frame
    model: Model | None = None  # the simulated units (their logs), for tests and inspection
    throughput_estimate: dict = field(default_factory=dict)  # how TThru was measured (steady_throughput)
    event_budget: int = 0  # the run's stop at its end: min(arch.max_events, event_bound of the frames it started)
    granularity: dict = field(default_factory=dict)  # how far the packets move TThru (granularity_estimate)
    fifo: dict = field(default_factory=dict)  # the FIFOs' peak occupancy (tlm.arch.fifo.fifo_peaks)
    # the stream's warning lines where tlm.simulate made them (run_warnings.stream_warnings: it knows the config,
    # this class does not); None: not made here. A field, so dataclasses.replace keeps it too (h547)
    warnings: list[str] | None = None

    def to_dict(self) -> dict:
        """Every figure, by ``results.json``'s names where its ``timing`` holds it (h529): ``simpy_events`` (also
        ``events``, its name here before, kept for the code that reads it) and ``event_bound`` (:attr:`event_budget`);
        ``cycles`` and ``fps``, which ``results.json`` holds at its top; ``frame_times`` (``timing.frames`` there is
        their count). Not the config's (``clock_hz``, ``packet_size``, ``frames_asked``, ``images_in_flight``,
        ``memory``, ``programs``), which ``results.json``'s ``timing`` adds."""
        return {
            "cycles": self.cycles,
            "fps": self.fps,
            "units": self.units,
            "frame_times": self.frames,
            "events": self.events,
            "simpy_events": self.events,
            "event_bound": self.event_budget,
            "phases": [p.name for p in self.program.phases],
            "left_out": self.program.left_out,
            "invariants": self.checks,
            "crossbar": self.crossbar,
            "pipelines": self.pipelines,
            "scheduler": self.program.scheduler,
            "tiling": self.program.tiling,
            "throughput_estimate": self.throughput_estimate,
            "granularity": self.granularity,
            "fifo": self.fifo,
        }

    def __repr__(self) -> str:
        """Three lines (a notebook cell that shows one): throughput and latency cycles per
        frame and the frames per second, each PM's cycles per frame, the pipelines, the
        frames and the SimPy events. Reads no ``model``, so a pickled Timing shows too."""
        cyc = self.cycles
        pms = ", ".join(f"{k} {v:,}" for k, v in cyc.items() if k not in ("throughput", "latency"))
        pipes, frames = self.program.pipelines, len(self.frames)
        fps = f"{self.fps:,.1f}" if self.fps >= 1 else f"{self.fps:.3g}"  # (a big frame's 0.00123 fps)
        return (f"Timing: throughput {cyc['throughput']:,} cycles per frame, latency {cyc['latency']:,}, "
                f"{fps} fps\n"
                f"  cycles per PM: {pms}\n"
                f"  {pipes} pipeline{'s' if pipes != 1 else ''}, {frames} frame{'s' if frames != 1 else ''}, "
                f"{self.events:,} SimPy events")

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        if state.get("model") is not None:
            state["model"] = MODEL_NOT_KEPT  # (its SimPy generators cannot be pickled)
        return state

    def __copy__(self) -> Timing:
        new = object.__new__(type(self))
        new.__dict__.update(self.__dict__)
        return new


def simulate(fn: Functional, programs: Programs, arch: ArchConfig) -> Timing:
    """Run the stream of ``arch.frames`` frames of ``fn`` through the model (more, for a stream
    that settles only after a transient: :func:`settling`; ``timing.frames`` lists every one).

    ``timing.granularity`` compares the frame's packets with packets of one ray, pixel or
    photon (:func:`granularity_estimate`, after the run, with :func:`fine_ti_cycles`: the
    Traversal/Intersection phases of the frame program in packets of one, built one at a
    time and dropped once their flow shop is known; no other phase of it is built).
    """
    program = frame_program(fn, programs, arch)
    timing = simulate_program(program, arch)
    fine = None if arch.packet_size == 1 else fine_ti_cycles(fn, programs, arch)
    slowest = timing.throughput_estimate["slowest_pm"]
    timing.granularity = granularity_estimate(program, arch, timing.cycles["throughput"], timing.cycles[slowest],
                                              program if fine is None else fine)
    return timing


def simulate_program(program: FrameProgram, arch: ArchConfig) -> Timing:
    """Run a frame program (from :func:`frame_program`, or built by hand in tests).

    The program is the one source of how a frame is laid out: its pipelines, its
    scheduler and its tiles (and its packets) are what run. :func:`frame_program` read
    ``arch.pipelines``, ``arch.scheduler``, ``arch.tiles_per_pipeline`` and
    ``arch.packet_size`` to build it; the model reads the rest of ``arch`` (the stream,
    the images in flight, the FIFO, the cycles of swaps, copies and misses) and never
    those four.
    """
    # The run allocates a great many short-lived objects (events, log entries, trace slices)
    # and next to no garbage cycles: Python's cycle collector, triggered by the allocations
    # alone, would scan the growing trace again and again for nothing. It is off while the
    # model runs (reference counting still frees everything as usual) and on again after.
    collect = gc.isenabled()
    gc.disable()
    try:
        return _simulate_program(program, arch)
    finally:
        if collect:
            gc.enable()


def _simulate_program(program: FrameProgram, arch: ArchConfig) -> Timing:
    env = simpy.Environment()
    trace = Trace() if arch.trace else None
    model = Model(env, arch, program, trace)
    n_pipes = program.pipelines
    per_pipe = 2 * arch.images_in_flight
    model.modules = [Module(env, f"mem{i}", trace) for i in range(per_pipe * n_pipes)]
    if trace is not None:
        trace.modules_per_pipe = per_pipe
    if n_pipes > 1:  # the top-level unit that composes the tiles into the image
        model.compose = len(model.modules)
        model.modules.append(Module(env, "compose", trace))
    model.xbar = Crossbar(env, model.modules, arch, trace, model.cycle_end)
    used = {js.pm for ph in program.phases for js in ph.jobs}
    for p in range(n_pipes):
        for name in PMS:
            kind = PM_KINDS[name]
            if kind.shared and p > 0 and name in used:
                continue  # one PM of the kind for the GPU, on pipeline 0 (the Vertex PM, §V.D)
            model.pms[(p, name)] = kind(model, p)
    done = Flag(env)  # (the run loop asks it after every event)
    env.process(_stream(model, done))
    counts: dict = {}
    # a settling stream runs past arch.frames (tlm.arch.steady): a cap or a stop names the frames it may run
    cap = frames_cap(arch.frames, arch.settle_frames)
    ran_on = "" if not settling(program, arch) or cap == arch.frames else (
        f" (the stream of two images runs on past arch.frames = {arch.frames} until its completions "
        f"repeat, at most {cap} frames, arch.settle_frames: tlm/arch/steady.py)")
    static = SCHEDULERS[program.scheduler].periodic_from_warmup

    def said_on() -> str:  # (a static stream runs on only where its asked frames' gaps do not repeat: said if it did)
        return ran_on if not static or len(model.frames) > arch.frames else ""

    capped_why = Said(lambda: f"arch.max_events = {arch.max_events} events{said_on()}")
    most = event_bound(program, arch)  # (the most it may need, at the most frames it may run)
    per_frame = frame_events(program)

    def limit() -> tuple[int, object, type[Deadlock]]:
        """The run's stop now (asked again whenever it is reached): the liveness bound of the frames the
        stream has started, arch.frames at least (a settling one starts more only as it runs on), or the
        config's cap where lower; and what a stop there says and raises."""
        started = max(len(model.frames), arch.frames)
        bound = min(most, per_frame * started + EVENTS_FLOOR)
        if arch.max_events <= bound:
            return arch.max_events, capped_why, MaxEventsReached
        on = f" in each of the {started} frames started (arch.frames = {arch.frames}, run on)" \
            if started > arch.frames else ""
        return bound, (f"{bound} events passed, {EVENTS_PER_ITEM} per packet, job and tile of the program{on}: "
                       "it makes no progress"), Deadlock

    budget, why, capped = limit()
    end = run(env, done, [pm.unit for pm in model.pms.values()], max_events=budget, counts=counts, why=why,
              cycle_end=model.cycle_end, capped=capped, extend=limit)
    nf = len(model.frames)
    within_int64(end, f"the stream of {nf} frame{'s' * (nf != 1)}{said_on()}")  # (no unit's are more)
    timing = _results(model, program, end, counts["events"], trace)
    timing.model = model
    timing.event_budget = limit()[0]  # (the bound at its end: of the frames it ran)
    return timing


class Said:
    """Words read when they are said (``str``): a stop's, which may name what the stream did by then."""

    def __init__(self, words) -> None:
        self.words = words

    def __str__(self) -> str:
        return self.words()


EVENTS_PER_ITEM = 64  # the liveness bound's SimPy events per packet, job and tile (runs need 1.6-3.2)
EVENTS_FLOOR = 100_000  # and its events beside them, once a run


def frame_events(program: FrameProgram) -> int:
    """The liveness bound's events for one frame of ``program``: ``EVENTS_PER_ITEM`` per packet, job and tile."""
    items = sum(len(js.packets) + 1 for ph in program.phases for js in ph.jobs)
    tiles = sum(len(st.tiles) for st in program.stages)
    return EVENTS_PER_ITEM * (items + tiles)


def event_bound(program: FrameProgram, arch: ArchConfig, frames: int | None = None) -> int:
    """The most SimPy events a stream of ``program`` can need while it makes progress, having
    started ``frames`` frames (None: the most it may run, :func:`~tlm.arch.steady.frames_cap`
    of a settling stream, ``arch.frames`` of another).

    Every packet, job and tile costs a bounded number of events (its work, the module's
    service, a FIFO hand-over, a preemption's save, swap and restore, a copy): at most a
    few each in every run measured (1.6 to 3.2 per packet and job, packets of 1 to a
    whole frame, 1 to 16 pipelines). ``EVENTS_PER_ITEM`` times that per frame, plus
    ``EVENTS_FLOOR``, is the liveness bound: a model past it is not making progress, so it
    stops in seconds rather than after ``arch.max_events`` (which caps it). A run's bound
    grows with the frames its stream has started (``arch.frames`` at first; a settling one
    that runs on starts more, one at each completion), never past this one at None: a
    stream that runs the frames asked, most do, is stopped after ``arch.frames`` frames'
    worth, not ``frames_cap``'s (:func:`simulate_program`; ``timing.event_budget``, the
    bound at its end).
    """
    if frames is None:
        frames = frames_cap(arch.frames, arch.settle_frames) if settling(program, arch) else arch.frames
    return frame_events(program) * frames + EVENTS_FLOOR


def _results(model: Model, program: FrameProgram, end: int, events: int, trace: Trace | None) -> Timing:
    arch = model.arch
    nf = len(model.frames)  # arch.frames, or more where the stream ran on until it settled (settling)
    checks = {}
    # every unit closes its books and reports them (a PM's idle wait for a job is booked to the end)
    pms = [pm.close(end) for pm in model.pms.values()]
    xbar = model.xbar.close(end)
    units = {r.scope: r.breakdown for r in (*pms, *(m.close(end) for m in model.modules), xbar)}
    checks["busy + stall + idle = elapsed"] = True
    expected = dict.fromkeys(PMS, 0)
    expected_norm = dict.fromkeys(PMS, 0)
    for ph in program.phases:
        for js in ph.jobs:
            expected[js.pm] += int(js.items.sum()) * nf
            expected_norm[js.pm] += int(js.norm.sum()) * nf
    for name in PMS:
        kind = [r for r in pms if r.kind == name]
        issued = sum(r.issued for r in kind)
        retired = sum(r.retired for r in kind)
        left = sum(r.queued for r in kind)
        if issued != expected[name] or retired != issued or left:
            raise AssertionError(f"{name} PMs: {issued} work items issued, {retired} retired, "
                                 f"{expected[name]} expected, {left} jobs left")
        norm = sum(r.norm for r in kind)
        if norm != expected_norm[name]:
            raise AssertionError(f"{name} PMs: T_norm {norm} != the program's {expected_norm[name]}")
    checks["every work item issued is retired"] = True
    for fifo in model.fifos:
        if not fifo.drained:
            raise AssertionError(f"a FIFO ended with {fifo.pushed} addresses pushed, {fifo.popped} popped")
    checks["every FIFO entry pushed is popped"] = True
    checks["T_norm equals the programs' cycles"] = True
    for rec in model.frames:
        if rec.done < 0:
            raise AssertionError(f"frame {rec.index} did not finish")
    ran_as = settles(program, arch, [r.done for r in model.frames])
    throughput_i, estimate = steady_throughput([r.done for r in model.frames], arch.images_in_flight, ran_as)
    if ran_as:  # (the most frames it could run: arch.settle_frames, or arch.frames if more)
        estimate["frames_cap"] = frames_cap(arch.frames, arch.settle_frames)
    # latency over the frames that complete in the steady window and arrived after the
    # warm-up (the k-th completion: an earlier arrival met the half-empty pipeline of the
    # fill), all frames without a window; exact rational means rounded to whole cycles
    # (a float mean is off past 2**53 cycles)
    by_done = sorted(model.frames, key=lambda r: (r.done, r.index))
    window = estimate["window"]
    if estimate.get("latency_arrivals"):  # a settling stream: whole periods of arrivals (tlm.arch.steady)
        lo, hi = estimate.pop("latency_arrivals")
        steady = [r for r in model.frames if lo <= r.index < hi]
    elif window:
        warm = by_done[window[0]].done
        steady = [r for r in by_done[window[0] + 1:window[1] + 1] if r.arrival >= warm]
    else:
        steady = by_done
    steady = steady or by_done  # (a window with no frame that arrived in it: every frame, as without one)
    latency_i = round(Fraction(sum(r.done - r.arrival for r in steady), len(steady)))
    estimate["latency_frames"] = sorted(r.index for r in steady)
    per_pipe = [dict.fromkeys(PMS, 0) for _ in range(program.pipelines)]
    for r in pms:
        per_pipe[r.pipe][r.kind] = round(Fraction(r.own, nf))
    # a PM kind's cycles: its slowest pipeline's (the one the frame waits for)
    cycles = {name: max(pp[name] for pp in per_pipe) for name in PMS}
    cycles["throughput"] = throughput_i
    cycles["latency"] = latency_i
    slowest = max(PMS, key=lambda p: cycles[p])
    estimate["slowest_pm"] = slowest
    estimate["throughput_over_slowest_pm"] = throughput_i / cycles[slowest] if cycles[slowest] else None
    fps = arch.clock_hz / throughput_i if throughput_i > 0 else math.inf
    if trace is not None:
        trace.fill_idle(end)
    frames = [{"frame": r.index, "slot": r.slot, "arrival": r.arrival, "done": r.done} for r in model.frames]
    xb = {"swaps": xbar.swaps, "copies": xbar.copies, "words_copied": xbar.words_copied,
          "preemptions": {r.scope: r.preemptions for r in pms}}
    return Timing(cycles, fps, units, frames, events, program, trace, checks, xb, pipelines=per_pipe,
                  throughput_estimate=estimate,
                  granularity=granularity_estimate(program, arch, throughput_i, cycles[slowest]),
                  fifo=fifo_peaks(model.fifos, arch.fifo_depth, program.pipelines))


__all__ = ["PMS", "PM_TABLE_NAMES", "Deadlock", "FrameProgram", "JobSpec", "MaxEventsReached", "PhaseSpec", "Timing",
           "fill_and_drain", "fine_ti_cycles", "flow_shop", "flow_shop_python", "frame_program", "granularity_estimate",
           "simulate", "simulate_program", "steady_throughput", "ti_cycles"]
