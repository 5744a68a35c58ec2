"""The batch render loop: every planned pass of a frame over the whole image, in batches.

The image is rendered in batches of consecutive pixels, ``render.batch_rays`` eye rays
each (:func:`~tlm.render.frame.pixel_batches`): every pass of a batch runs before the
next batch is cast, the cache pairs carried from batch to batch, so the radiance and work
are exactly those of one whole-image packet while memory stays bounded by the batch.
:func:`render_batches` is the loop; it returns what the passes computed
(:class:`Rendered`: radiance, work, the primary AOVs, the photon trace and the gather
tallies). Loading the frame before it and measuring, simulating and writing after it
belong to the experiments (:mod:`tlm.experiments.run`).
"""

from __future__ import annotations

import contextlib
import mmap
import os
import threading
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from tlm.errors import InputError
from tlm.kernels import release_memory, threads
from tlm.kernels.memory import Streams
from tlm.kernels.photons import PhotonTrace
from tlm.kernels.recording import Deferred
from tlm.progress import Redrawn, Ticking, Timer, checkpoint, progress_bar
from tlm.render import checks
from tlm.render.frame import Frame, GBuffer, ImageGBuffer, cast, new_streams, pixel_batches
from tlm.render.passes import PASS_FUNCTIONS, fgather_pass
from tlm.render.planner import WORK_PASSES, plan
from tlm.render.pmap import density_requests, gathered_maps, pmap_pass, radii, trace_photon_map


@dataclass
class Primary:
    """Each pixel's first eye sample (what ``aov/primary.npz`` holds) and the eye-ray counts.

    Filled batch by batch (:meth:`add`), so a render keeps no G-buffer of the whole image.
    """

    origin: np.ndarray  # (pixels, 3)
    direction: np.ndarray  # (pixels, 3)
    t: np.ndarray  # (pixels,)
    triangle: np.ndarray  # (pixels,) int64
    normal: np.ndarray  # (pixels, 3)
    sees_light: np.ndarray  # (pixels,) bool: the first sample sees a light directly
    rays: int = 0
    hits: int = 0
    back: int = 0  # hits on the back of their triangle (all samples)

    @classmethod
    def empty(cls, n: int) -> Primary:
        return cls(np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n), np.zeros(n, dtype=np.int64),
                   np.zeros((n, 3)), np.zeros(n, dtype=bool))

    def add(self, frame: Frame, g: GBuffer, at: slice) -> None:
        """The batch ``g`` of pixels ``at``."""
        self.put(Primary.part(frame, g), at)

    @staticmethod
    def part(frame: Frame, g: GBuffer) -> dict:
        """What :meth:`put` keeps of the batch ``g`` (small: one sample a pixel, and counts)."""
        return {"origin": g.first(g.origin), "direction": g.first(g.direction), "t": g.first(g.t),
                "triangle": g.first(g.triangle), "normal": g.first(g.normal(frame)),
                "sees_light": g.first(g.sees_emitter), "rays": int(g.origin.shape[0]),
                "hits": int((g.triangle >= 0).sum()),
                "back": checks.back_faces(frame.scene, g.triangle, g.direction, frame.kind)}

    def put(self, part: dict, at: slice) -> None:
        """A batch's :meth:`part`, of pixels ``at``."""
        for k in ("origin", "direction", "t", "triangle", "normal", "sees_light"):
            getattr(self, k)[at] = part[k]
        self.rays += part["rays"]
        self.hits += part["hits"]
        self.back += part["back"]


@dataclass
class Rendered:
    """What :func:`render_batches` computed over the whole image.

    ``radiance``: each pass's (H, W, 3) linear radiance (a work-only pass has none);
    ``work``: each pass's (H, W) work counts (int32 where they fit, else int64);
    ``primary``: the AOVs and eye-ray counts;
    ``gbuffer``: the whole image's G-buffer when it was cast as one batch, else an
    :class:`~tlm.render.frame.ImageGBuffer` that casts it again on first use;
    ``photons``: the photon trace, when the pmap pass ran; ``gather_maps``: the pmap
    pass's work per photon map (``pmap_pass``'s ``per_map``), when it ran.
    """

    radiance: dict[str, np.ndarray]  # pass -> (H, W, 3)
    work: dict[str, dict[str, np.ndarray]]  # pass -> count -> (H, W)
    primary: Primary
    gbuffer: GBuffer | ImageGBuffer
    photons: PhotonTrace | None = None
    gather_maps: dict | None = None


def render_batches(frame: Frame, passes: Sequence[str] | None = None, timer: Timer | None = None,
                   progress: bool = False) -> Rendered:
    """Render ``passes`` (by default those the planner runs for the frame's scene and
    config, in order) over the whole image of ``frame``, in batches (the module's
    docstring). ``timer``: gets the stages ``photon_trace``, ``prepare`` (the warm-up before
    batches run at once: :func:`_warm`), ``cast`` and ``pass_<name>``; ``progress``: a bar on
    stderr while the photons are traced and the warm-up runs (its elapsed time), then one whose
    steps are the batches' casts and passes.

    The kernels run on ``render.threads`` threads (null: :func:`~tlm.kernels.threads.default_threads`), with the
    bits of one (:mod:`tlm.kernels.threads`). On one thread the batches run one after the
    other, every pass charging its cache pairs (one :class:`~tlm.kernels.memory.Streams`
    per pass, carried batch to batch). On several, the image is cut into smaller batches
    (:func:`batches_for`; a pixel's results never depend on its batch) and whole batches
    run at once, on the threads' pool (:func:`tlm.kernels.threads.ordered`), or on forked
    worker processes past 8 threads or where asked (:data:`BATCH_WORKERS`, :func:`tlm.kernels.threads.can_fork`):
    each pass charges cold pairs of its own (:class:`~tlm.kernels.recording.Deferred`), and
    the calling thread takes the batches in
    pixel order, settles each pass's charges on the carried pairs (the misses of the
    batches charged in order) and copies the batch into the image, while the next
    batches run; at most a window of batches is in flight, and they are cut so that the
    window holds about ``render.batch_rays`` eye rays, so memory stays bounded by the batch.
    The stages' seconds are then summed over the threads.
    """
    timer = Timer() if timer is None else timer
    names = tuple(plan(frame.scene, frame.cfg).run_names if passes is None else passes)
    with threads.using(frame.cfg.render.threads):
        return _render_batches(frame, names, timer, progress)


def _kept_alive(bar):
    """What redraws the photon trace's and warm-up's bar while they run (its elapsed time): a
    :class:`~tlm.progress.Ticking` thread where the render forks no worker (one thread, or
    :func:`tlm.kernels.threads.can_fork` false), else the photon chunks' checkpoints
    (:class:`~tlm.progress.Redrawn`: the trace forks its workers only where no other thread runs)."""
    if bar.disable:
        return contextlib.nullcontext()
    try:
        may_fork = threads.current() > 1 and threads.can_fork()
    except InputError:  # (a bad TLM_FORK_WORKERS: the trace or the batches say so)
        may_fork = True
    return Redrawn(bar) if may_fork else Ticking(bar)


def _render_batches(frame: Frame, names: tuple[str, ...], timer: Timer, progress: bool) -> Rendered:
    """:func:`render_batches` on the calling thread's kernel threads."""
    w, h = frame.scene.camera.width, frame.scene.camera.height
    batches = batches_for(w * h, frame.spp, frame.cfg.render.batch_rays, threads.current())
    traced = None
    radiance = {name: np.zeros((w * h, 3)) for name in names if name not in WORK_PASSES}
    work: dict[str, dict[str, np.ndarray]] = {}
    streams = {name: new_streams(frame) for name in names}  # each pass's cache pairs, batch to batch
    primary = Primary.empty(w * h)
    whole: GBuffer | None = None
    gather_maps: dict | None = {} if "pmap" in names else None
    concurrent = threads.current() > 1 and len(batches) > 1
    if "pmap" in names or concurrent:
        # (the photon trace and the warm-up: a bar with no steps of its own, so that the batches' bar's rate and
        # time left are the batches' alone; counted as a step of it, a 16 s photon trace read as 16 s a step)
        # (its elapsed time redrawn: _kept_alive)
        with progress_bar(progress, desc="render", total=None, leave=False) as bar, _kept_alive(bar):
            if "pmap" in names:
                bar.set_postfix_str("photon trace")
                with timer.stage("photon_trace"):  # (when batches run at once: with what they read)
                    traced = trace_photon_map(frame, warm=concurrent)
            if concurrent:
                bar.set_postfix_str("prepare")
                with timer.stage("prepare"):  # (its numba compiling, a cold run's: tlm run books it to one_off)
                    _warm(frame, traced)
    release_memory()  # (the photon trace's and the kernels' layout's freed blocks)
    steps = len(batches) * (1 + len(names))  # (each batch's cast and passes)
    with progress_bar(progress, desc="render", total=steps, unit="step", leave=False) as bar:
        forked = concurrent and BATCH_WORKERS == "processes" and threads.can_fork()
        labels = None if bar.disable else _Labels(bar, len(batches), names)  # (made before the workers' fork)

        def one(i: int) -> _Batch:  # (threads share the run's timer, which counts a stage's wall time once)
            return _run_batch(frame, names, batches[i], traced, streams, concurrent, gather_maps is not None,
                              Timer() if forked else timer, None if concurrent else bar, i, labels)

        if forked:
            done_batches = threads.forked(lambda i: _portable(frame, one(i)), range(len(batches)), threads.current())
        else:
            # (weighed by pixels: the last, small pieces run behind a slow batch, in the same memory)
            done_batches = threads.ordered(one, range(len(batches)), weights=[b.stop - b.start for b in batches])
        with contextlib.closing(done_batches):  # (ended here, whatever stops the loop: its workers and lock go with it)
            for i, done in enumerate(done_batches):
                checkpoint()  # (a signal whose interrupt got lost stops the render here, the batches in flight too)
                at, g = batches[i], done.g
                arrays = None
                if done.portable:
                    arrays = {f"{name}.{k}": v for name, (_, wk) in done.out.items() for k, v in wk.items()}
                for name in names:
                    if concurrent:
                        streams[name].settle(done.deferred[name], arrays)
                    rad, wk = done.out[name]
                    if name in radiance:
                        radiance[name][at] = rad
                    counts = work.setdefault(name, {})
                    for k, v in wk.items():
                        _put_counts(counts, k, v, at, w * h)
                _merge_tallies(gather_maps, done.per_map)
                if forked:
                    timer.add_spans([done.timer])  # (the union of the workers' spans: wall time, not a sum)
                if concurrent:
                    bar.update(1 + len(names))
                    if labels is not None:  # (forked workers' stages, read from the board here)
                        labels.show()
                if isinstance(g, dict):  # (a batch from another process: its primary part)
                    primary.put(g, at)
                else:
                    primary.add(frame, g, at)
                if len(batches) == 1:
                    whole = g
                del g, done  # (no release_memory per batch: the batches reuse each other's blocks, and giving
                # them back made the 1080p Refract run 18% slower for the same peak, 2026-11-28)
    radiance = {name: rad.reshape(h, w, 3) for name, rad in radiance.items()}
    work = {name: {k: v.reshape(h, w) for k, v in wk.items()} for name, wk in work.items()}
    gbuffer = whole if whole is not None else ImageGBuffer(frame, w * h)
    return Rendered(radiance, work, primary, gbuffer, traced, gather_maps)


_INT32 = np.iinfo(np.int32)


def _put_counts(counts: dict[str, np.ndarray], key: str, values: np.ndarray, at: slice, n: int) -> None:
    """Copy a batch's counts of ``key`` into the image's (``n`` pixels): int32 while every
    count fits (half the memory of int64: 19 counts a pixel a pass are about 150 MiB a pass
    at 1080p), int64 from the first batch with one that does not (the earlier batches' counts
    widened). The counts are the same integers either way."""
    fits = values.shape[0] == 0 or (int(values.min()) >= _INT32.min and int(values.max()) <= _INT32.max)
    image = counts.get(key)
    if image is None:
        image = counts[key] = np.zeros(n, dtype=np.int32 if fits else np.int64)
    elif not fits and image.dtype != np.int64:
        image = counts[key] = image.astype(np.int64)
    image[at] = values


BATCHES_PER_THREAD = 3  # batches per thread when whole batches run at once: they differ in cost
MIN_BATCH_RAYS = 1024  # ... but none under this many eye rays (a batch's fixed cost in Python)
TAIL_HALVING = True  # ... and the last batches cut in halving pieces, so the threads end together


def batches_for(n_pixels: int, spp: int, batch_rays: int, n_threads: int) -> list[slice]:
    """The render's pixel batches (:func:`~tlm.render.frame.pixel_batches`): of
    ``batch_rays`` eye rays on one thread; on several, smaller ones, about
    :data:`BATCHES_PER_THREAD` per thread and at most ``batch_rays / (2 n_threads)`` eye
    rays (none under :data:`MIN_BATCH_RAYS`), so that whole batches run at once and
    balance, and the batches in flight (twice the threads' worth of batches, weighed by
    their pixels: :func:`tlm.kernels.threads.ordered`) hold about one batch of one
    thread: ``render.batch_rays`` bounds the render's memory whatever the threads. The
    pixels of the last ``n_threads`` batches are cut again, in rounds of one piece per
    thread whose size halves from round to round (none under :data:`MIN_BATCH_RAYS` eye
    rays or a batch, but the last), so that a thread that takes the last piece keeps the
    others waiting for a small one only: the threads finish closer together (guided
    self-scheduling). The cuts never change the results."""
    if n_threads <= 1:
        return pixel_batches(n_pixels, spp, batch_rays)
    share = -(-n_pixels * spp // (BATCHES_PER_THREAD * n_threads))
    batch_rays = min(batch_rays, max(MIN_BATCH_RAYS, min(share, batch_rays // (2 * n_threads))))
    cuts = pixel_batches(n_pixels, spp, batch_rays)
    if not TAIL_HALVING or len(cuts) <= n_threads:
        return cuts
    step = cuts[0].stop - cuts[0].start  # pixels of a batch: no piece is larger
    least = min(step, max(1, -(-MIN_BATCH_RAYS // spp)))  # ... nor smaller, bar the last
    lo, hi = cuts[-n_threads].start, n_pixels
    piece = step
    tail = []
    while lo < hi:
        piece = max(least, piece // 2)
        for _ in range(n_threads):
            take = min(hi - lo, step) if hi - lo < piece + least else piece  # (no sliver left)
            tail.append(slice(lo, lo + take))
            lo += take
            if lo == hi:
                break
    return cuts[:-n_threads] + tail


@dataclass
class _Batch:
    """One batch's G-buffer (from another process: its :meth:`Primary.part`) and passes:
    pass -> (radiance, work); with ``deferred`` pairs, the work's misses as charged on
    cold pairs (settled in the calling thread; ``portable``: naming the arrays
    ``"<pass>.<count>"``, :meth:`~tlm.kernels.recording.Deferred.portable`)."""

    g: GBuffer | dict
    out: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]]
    deferred: dict[str, Deferred] | None
    per_map: dict | None
    timer: Timer
    portable: bool = False


# where whole batches run at once on several threads: "processes" (forked from the render
# after the photon trace: the frame, its BSP and the photon maps are the parent's pages, and
# no interpreter lock is shared) or "threads" (one process; numpy and the compiled kernels
# release the lock, the Python between them does not)
BATCH_WORKERS = "processes"  # (where threads.can_fork: past DEFAULT_MAX_THREADS threads, or TLM_FORK_WORKERS=1)


def _portable(frame: Frame, done: _Batch) -> _Batch:
    """A batch run in a worker process, for the way back: small and named."""
    ids = {id(v): f"{name}.{k}" for name, (_, wk) in done.out.items() for k, v in wk.items()}
    return replace(done, g=Primary.part(frame, done.g), portable=True,
                   deferred={name: d.portable(ids) for name, d in done.deferred.items()})


def _run_batch(frame: Frame, names: tuple[str, ...], at: slice, traced: PhotonTrace | None,
               streams: dict[str, Streams], deferred: bool, tally: bool, timer: Timer, bar, i: int,
               labels: _Labels | None = None) -> _Batch:
    """Cast batch ``at`` and run every pass on it, on the carried ``streams`` or, when
    ``deferred``, on cold :class:`~tlm.kernels.recording.Deferred` pairs like them (a batch on
    a worker thread: its per-map tallies are its own too). ``bar``: counts its steps (on one
    thread); ``i``: its index; ``labels``: told each stage it enters, for the bar's label
    (:class:`_Labels`)."""
    checkpoint()  # (on one thread: a signal whose interrupt got lost stops the render before the batch)
    pairs = {name: Deferred.like(s) for name, s in streams.items()} if deferred else streams
    per_map: dict | None = {} if tally else None
    if labels is not None:
        labels.enter(i, "cast")
    with timer.stage("cast"):
        g = cast(frame, np.arange(at.start, at.stop, dtype=np.int64))
    if bar is not None:
        bar.update()
    out = {}
    for name in names:
        checkpoint()  # (... and before each pass)
        if labels is not None:
            labels.enter(i, name)
        with timer.stage(f"pass_{name}"):
            if name == "pmap":
                out[name] = pmap_pass(frame, g, traced.photons, streams=pairs[name], per_map=per_map,
                                      fg_streams=pairs.get("fgather"))
            elif name == "fgather":
                out[name] = fgather_pass(frame, g)
            else:
                out[name] = PASS_FUNCTIONS[name](frame, g, pairs[name])
        if bar is not None:
            bar.update()
    if labels is not None:
        labels.enter(i, None)
    return _Batch(g, out, pairs if deferred else None, per_map, timer)


class _Labels:
    """The render bar's label while the batches run, ``batch i/n <stage>``: the stage
    (``cast``, then each pass by name) of the first batch not done, the one the calling
    thread takes next. On one thread, the batch that runs. Where batches run at once, each
    writes the stage it enters (or that it is done) to a board, one byte a batch, in shared
    memory (an anonymous mmap, made before the workers are forked: their writes are seen
    here), and the label is redrawn from the board: by a batch's own thread as it enters a
    stage (in this process: on one thread, or on the threads' pool), and by the calling
    thread as it takes each batch (what forked workers did, having no bar of their own).
    The redraws are serialized, so the label shown is the board's latest. Display only: no
    result reads it."""

    DONE = 255  # (0: not begun; 1 + the stage's index: in it)

    def __init__(self, bar, n: int, names: tuple[str, ...]):
        self.bar, self.n = bar, n
        self.stages = ("cast", *names)
        self.board = mmap.mmap(-1, max(n, 1))  # (anonymous: shared with forked children, zeros)
        self.pid = os.getpid()
        self.lock = threading.Lock()
        self.first = 0  # (the batches before it are done)
        self.shown: str | None = None

    def enter(self, i: int, stage: str | None) -> None:
        """Batch ``i`` enters ``stage`` (None: it is done)."""
        self.board[i] = self.DONE if stage is None else 1 + self.stages.index(stage)
        if os.getpid() == self.pid:  # (a forked worker only writes the board)
            self.show()

    def show(self) -> None:
        """Redraw the label from the board, where it changed."""
        with self.lock:
            while self.first < self.n and self.board[self.first] == self.DONE:
                self.first += 1
            if self.first >= self.n or not self.board[self.first]:
                return  # (all done, or the next batch has not begun: the label stays)
            label = f"batch {self.first + 1}/{self.n} {self.stages[self.board[self.first] - 1]}"
            if label != self.shown:
                self.shown = label
                self.bar.set_postfix_str(label)


def _warm(frame: Frame, traced: PhotonTrace | None) -> None:
    """Make what the passes build on first use (the compiled traversal's layout, the photon
    maps they gather in leaf order, the maps' radii) before batches run at once, so no two
    threads build it. Only the maps the frame gathers (:func:`gathered_maps`) are put in
    leaf order: nothing else reads a map's leaf order (with final gathering the indirect map
    is never gathered, without it the global map). A photon trace asked to warm
    (:func:`trace_photon_map`) made the maps' part already, with the trees: then it is only
    looked up here."""
    cast(frame, np.zeros(1, dtype=np.int64))
    if traced is not None:
        photons = traced.photons
        # each gathered map's leaf order and the density radii (where not made yet) at once on the
        # threads (numpy's gathers and scipy's tree build run without the interpreter lock), each by one thread
        tasks = [m.prepared for m in gathered_maps(frame, photons).values()]
        tasks += [(lambda m=m, k=k: m.density_radius(k)) for m, k in density_requests(frame, photons)]
        for _ in threads.ordered(lambda task: task(), tasks):
            pass
        radii(frame, photons)  # (every radius now made: only looked up)


def _merge_tallies(into: dict | None, tallies: dict | None) -> None:
    """Add a batch's per-map gather totals (pmap_pass's ``per_map``) to the render's, in order."""
    if into is None or tallies is None:
        return
    for name, tally in tallies.items():
        dst = into.setdefault(name, {})
        for k, v in tally.items():
            dst[k] = dst.get(k, 0) + v
