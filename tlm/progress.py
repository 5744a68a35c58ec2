"""Host-side progress: wall seconds per stage and the progress bars on stderr.

What a command shows while it works and what ``results.json`` records of the host's
time (``host_seconds``), kept apart from the work that uses them: the render's batch
loop (:mod:`tlm.render.batches`, which books its stages and draws its bar), a run, a
sweep, a study. In the base layer so that every layer may use it. Nothing here changes
a result; a bar is drawn only when asked for and stderr is a terminal.

And the long loops' checkpoints (:func:`checkpoint`): where a command whose interrupt got
lost stops, at the top of its next batch, photon chunk or sweep point, rather than running
to its end.
"""

from __future__ import annotations

import bisect
import functools
import math
import os
import sys
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

# the signals the command line's handler took (tlm.cli_signals.on_signal: SIGINT, SIGTERM), each with the
# process that took it, that no checkpoint has raised again: empty outside a command (a notebook's calls)
_TAKEN: list[tuple[int, int]] = []
_STAGES = threading.Lock()  # (a Timer's stages may be entered on several threads at once)
_ENTERED = threading.local()  # per thread: the (timer, stage) it is in, innermost last


def _entered() -> list[tuple[Timer, str]]:
    stack = getattr(_ENTERED, "stack", None)
    if stack is None:
        stack = _ENTERED.stack = []
    return stack


@dataclass
class Timer:
    """Host wall seconds per named stage (a stage entered twice adds up). A stage that
    runs on several threads at once (the render's batches) counts the wall time while any
    of them runs, not the sum of their times: a stage never holds more seconds than
    passed. Part of a stage's block may be booked to another stage instead
    (:func:`booked_apart`)."""

    seconds: dict[str, float] = field(default_factory=dict)
    # each stage's closed spans (perf_counter start, end), kept to merge timers of blocks that
    # ran at once elsewhere (:meth:`add_spans`: a forked worker's batches)
    spans: dict[str, list[tuple[float, float]]] = field(default_factory=dict, repr=False, compare=False)
    _open: dict[str, tuple[int, float]] = field(default_factory=dict, repr=False, compare=False)

    def _enter(self, name: str, now: float) -> None:
        n, since = self._open.get(name, (0, now))
        self._open[name] = (n + 1, since)

    def _leave(self, name: str, now: float) -> None:
        n, since = self._open[name]
        if n > 1:
            self._open[name] = (n - 1, since)
            return
        del self._open[name]
        self.seconds[name] = self.seconds.get(name, 0.0) + now - since
        self.spans.setdefault(name, []).append((since, now))

    def add_spans(self, others: list[Timer]) -> None:
        """Add the stages of timers whose blocks ran at once (forked workers, on the same
        monotonic clock) as the wall time while any of them ran: per stage, the length of
        the union of their spans, less what this timer already counts of it."""
        names = {n for t in others for n in t.spans}
        for name in sorted(names):
            mine = self.spans.get(name, [])
            spans = sorted([*mine, *(sp for t in others for sp in t.spans.get(name, []))])
            total, end = 0.0, -math.inf
            for a, b in spans:
                if b > end:
                    total += b - max(a, end)
                    end = b
            self.seconds[name] = self.seconds.get(name, 0.0) + total - sum(b - a for a, b in _merged(mine))
            self.spans[name] = spans

    def book_apart(self, stage: str, spans: list[tuple[float, float]]) -> None:
        """Book the time ``spans`` cover (``time.perf_counter`` readings, from any thread: the
        spans in which numba compiled or loaded a kernel, or a module was first imported, as
        :class:`~tlm.experiments.error_cost_clock.CompileClock` keeps them) to stage ``stage``,
        out of the others: each stage loses the part of its blocks' time that they cover, and
        ``stage`` gets all the time they cover (overlapping spans counted once), in a stage or
        between stages (a cold run's first compiles: :func:`tlm.experiments.run.run`). A stage
        that kept no spans (one made from seconds alone) keeps its seconds."""
        apart = _merged([(a, b) for a, b in spans if b > a])
        if not apart:
            self.seconds.setdefault(stage, 0.0)
            return
        for name, own in self.spans.items():
            if name != stage and name in self.seconds:
                self.seconds[name] = max(0.0, self.seconds[name] - _overlap(_merged(own), apart))
        self.seconds[stage] = self.seconds.get(stage, 0.0) + sum(b - a for a, b in apart)
        self.spans.setdefault(stage, []).extend(apart)

    def stage(self, name: str):
        """A context manager that adds the wall seconds of its block to stage ``name``."""
        timer = self

        class _Stage:
            def __enter__(self):
                with _STAGES:
                    timer._enter(name, time.perf_counter())
                _entered().append((timer, name))

            def __exit__(self, *exc):
                _entered().pop()
                with _STAGES:
                    timer._leave(name, time.perf_counter())

        return _Stage()


def _merged(spans: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Spans as disjoint ones covering the same time."""
    out: list[tuple[float, float]] = []
    for a, b in sorted(spans):
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def _overlap(a: list[tuple[float, float]], b: list[tuple[float, float]]) -> float:
    """The time two lists of disjoint, sorted spans (:func:`_merged`) have in common."""
    total, i, j = 0.0, 0, 0
    while i < len(a) and j < len(b):
        lo, hi = max(a[i][0], b[j][0]), min(a[i][1], b[j][1])
        total += max(0.0, hi - lo)
        if a[i][1] < b[j][1]:
            i += 1
        else:
            j += 1
    return total


@contextmanager
def booked_apart(stage: str, within: str):
    """A block inside stage ``within`` whose wall seconds go to stage ``stage`` instead.

    When the calling thread's innermost stage (:meth:`Timer.stage`) is ``within``, the
    block leaves it and enters ``stage`` of the same Timer, at one instant, and on the way
    out leaves ``stage`` and enters ``within`` again: the block's time is booked once, to
    ``stage``, and ``within`` keeps the rest (each stage still counts the wall time while
    any of its blocks runs). Elsewhere (no stage, or another one) it does nothing. The
    photon-map pass books its final gathering so (:func:`tlm.render.pmap.pmap_pass`).
    """
    stack = _entered()
    if not stack or stack[-1][1] != within:
        yield
        return
    timer = stack[-1][0]
    with _STAGES:
        now = time.perf_counter()
        timer._leave(within, now)
        timer._enter(stage, now)
    stack.append((timer, stage))
    try:
        yield
    finally:
        stack.pop()
        with _STAGES:
            now = time.perf_counter()
            timer._leave(stage, now)
            timer._enter(within, now)


# the size a bar takes on a terminal that reports none (0 x 0: a pty whose size was never
# set, as under `script` and on some CI runners), where $COLUMNS and $LINES do not give one
FALLBACK_SIZE = (80, 24)
# a sweep's bar shows no time left until this fraction of the points it runs is done, and then
# the time left at the rate of the last half of the time (progress_bar's eta_after): a frame's
# first point renders it, and grid order runs the points of a factor's first value together,
# so the first points' rate says little of the others'
SWEEP_ETA_AFTER = 0.1
# tqdm's default bar, written out (its time left is {remaining})
_BAR = "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}<{remaining}, {rate_fmt}{postfix}]"


def terminal_shape(fp) -> tuple[int | None, int | None]:
    """The (columns, rows) a bar on ``fp`` may use, as tqdm's ``dynamic_ncols`` gives them
    (the terminal's size less one: a full line would wrap), read again at each redraw so
    that the bar follows a resized window. A terminal that reports 0 columns or 0 rows
    takes $COLUMNS / $LINES where they are whole numbers > 0, else :data:`FALLBACK_SIZE`
    (tqdm's own reading takes 0 x 0 as -1 x -1, and draws nothing). (None, None) where
    ``fp`` is no terminal."""
    try:
        size = os.get_terminal_size(fp.fileno())
    except (AttributeError, OSError, ValueError):
        return None, None
    shape = []
    for got, name, fallback in zip(size, ("COLUMNS", "LINES"), FALLBACK_SIZE):
        if got <= 0:
            given = os.environ.get(name, "").strip()
            got = int(given) if given.isdigit() and int(given) > 0 else fallback
        shape.append(got - 1)
    return shape[0], shape[1]


@functools.cache
def _bar_class():
    """tqdm's bar, sized by :func:`terminal_shape`, that may hold back its time left and
    take it from the recent rate (``eta_after``: :func:`progress_bar`)."""
    from tqdm import tqdm

    class Bar(tqdm):
        # no monitor thread: tqdm starts one with the first bar (a disabled one too) and keeps it
        # for the life of the process, taking tqdm's lock every few seconds; a render that forks
        # its workers (tlm.kernels.threads.forked) forks only where no other thread runs. The
        # monitor only lowers a bar's miniters after a stall; these bars' redraws come from
        # their steps (and Ticking's refreshes)
        monitor_interval = 0

        def __init__(self, *args, eta_after: float = 0.0, **kwargs):
            self.eta_after = eta_after
            self.seen: list[tuple[float, float]] = []  # (when, steps done then) at each update
            cols, rows = terminal_shape(kwargs.get("file") or sys.stderr)
            super().__init__(*args, ncols=cols, nrows=rows, dynamic_ncols=False, **kwargs)
            self.dynamic_ncols = terminal_shape  # (read at each redraw, as tqdm's own)

        def update(self, n=1):
            if self.eta_after > 0 and not self.disable:
                # (before tqdm's update, which may redraw with this step; one append: a redraw on
                # another thread reads it)
                self.seen.append((self._time(), self.n + n))
            return super().update(n)

        @property
        def format_dict(self):
            d = super().format_dict
            if self.disable or not self.eta_after > 0 or not self.total:
                return d
            rate = self.recent_rate(d["elapsed"])
            if rate is None:  # (the rate shown: the mean since the bar began)
                d["bar_format"] = (d["bar_format"] or _BAR).replace("{remaining}", "?")
            d["rate"] = rate
            return d

        def recent_rate(self, elapsed: float) -> float | None:
            """Steps per second over the last half of the time since the bar began, once
            ``eta_after`` of its steps are done and a step ended in that half; else None.

            Each step's work is spread evenly over its span (from the step before it, or the
            bar's start, to its end): of a step that ends in the last half, only the part of
            its span in that half counts there, not the whole step (a slow first step
            counted whole gave about twice the rate while it ended in the last half, and half
            the time left). The steps in the half are over the time from its start to the
            last step's end: the step running now goes at that rate, but it has not ended,
            so it adds less than one step; if the time since the last step says so, the
            rate is lower (one more step over the whole half). Steps of equal length give
            their own rate, so the time left shown after each is the time left."""
            done = self.n - self.initial
            if done < max(1, math.ceil(self.eta_after * (self.total - self.initial))) or elapsed <= 0:
                return None
            seen = self.seen
            m = len(seen)  # (a step's update on another thread may append meanwhile)
            if not m:
                return None
            half = self.start_t + elapsed / 2
            t_last, n_last = seen[m - 1]
            if t_last <= half:
                return None  # (no step ended in the last half)
            k = bisect.bisect_right(seen, half, hi=m, key=lambda e: e[0])  # (those that ended in the first half)
            t0, n0 = seen[k - 1] if k else (self.start_t, self.initial)
            t1, n1 = seen[k]
            at_half = n0 + (n1 - n0) * (half - t0) / (t1 - t0) if t1 > t0 else n1
            recent = n_last - at_half
            if recent <= 0:
                return None
            return min(recent / (t_last - half), (recent + 1) / (elapsed / 2))

    return Bar


def progress_bar(enabled: bool, eta_after: float = 0.0, **kwargs):
    """A tqdm bar on stderr, drawn only when ``enabled`` and stderr is a terminal, as wide
    as the terminal (:func:`terminal_shape`: 80 columns where it reports none).

    ``eta_after`` > 0, a fraction of the steps the bar is to count (``total`` less
    ``initial``, the steps done before): until that many are done (at least one) the time
    left reads ``?``; from then on the rate, and the time left (the steps left at that
    rate), are the steps done in the last half of the time since the bar began over that
    half (a step's work spread over its span: ``Bar.recent_rate``; steps of equal length
    give the true time left), not tqdm's moving average of the last few steps. The first steps drop out of it
    as the bar goes on (a sweep's first points render their frames), and one slow step does
    not swing it; while no step was done in the last half, the time left reads ``?``.

    A bar with no ``total`` (a stage that has no steps of its own: loading the scene, building
    the BSP) reads its description and elapsed time, ``build BSP (2604 triangles) [00:01]``,
    not tqdm's count of steps and their rate (``: 0step [00:01, ?step/s]``)."""
    if kwargs.get("total") is None and "bar_format" not in kwargs:
        kwargs["bar_format"] = "{desc} [{elapsed}{postfix}]"
    return _bar_class()(disable=None if enabled else True, file=sys.stderr, eta_after=eta_after, **kwargs)


class Ticking:
    """Redraws a bar every ``every`` seconds (its elapsed time) while a long call runs,
    so that a stage with no steps of its own (a simulation, writing a folder) still
    shows that it is alive."""

    def __init__(self, bar, every: float = 0.5):
        self.bar, self.every = bar, every
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._tick, daemon=True)

    def _tick(self) -> None:
        while not self.stop.wait(self.every):
            self.bar.refresh()

    def __enter__(self):
        if not self.bar.disable:
            self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        if self.thread.is_alive():
            self.thread.join()


class Redrawn:
    """Redraws a bar (its elapsed time) at the checkpoints (:func:`checkpoint`: a photon chunk's, a
    batch's) of the thread and process that entered it, every ``every`` seconds at most, while a long
    call runs: :class:`Ticking` with no thread of its own, for a call that may fork its workers
    (:func:`tlm.kernels.threads.forked` forks only where no other thread runs). A forked worker's
    checkpoints (another process) and other threads' redraw nothing."""

    def __init__(self, bar, every: float = 0.5):
        self.bar, self.every = bar, every
        self.last = time.monotonic()
        self.where = (os.getpid(), threading.get_ident())

    def redraw(self) -> None:
        now = time.monotonic()
        if now - self.last >= self.every and (os.getpid(), threading.get_ident()) == self.where:
            self.last = now
            self.bar.refresh()

    def __enter__(self):
        if not self.bar.disable:
            _REDRAWN.append(self)
        return self

    def __exit__(self, *exc):
        if self in _REDRAWN:
            _REDRAWN.remove(self)


_REDRAWN: list[Redrawn] = []  # the bars the checkpoints redraw (Redrawn)


def signal_taken(signum: int) -> None:
    """The command line's handler took ``signum`` and raises its KeyboardInterrupt now
    (:func:`tlm.cli_signals.on_signal`): the next :func:`checkpoint` raises it again, in case
    CPython dropped it (:func:`checkpoint`)."""
    _TAKEN.append((signum, os.getpid()))


def forget_signals() -> None:
    """No signal taken (a command's start and end: :func:`tlm.cli_signals.signals`)."""
    _TAKEN.clear()


_DEFERRED: list[int] = []  # the pid of each section (:func:`interrupts_deferred`) the main thread is in


@contextmanager
def interrupts_deferred():
    """A section of the main thread that a signal must not cut in two (a pool starting a
    worker process: one the pool does not know yet would outlive the command, and print a
    traceback once the command's semaphores are gone): the command line's handler
    (:func:`tlm.cli_signals.on_signal`) takes a signal that comes meanwhile without raising
    (:func:`deferring`), and its KeyboardInterrupt is raised as the section ends
    (:func:`checkpoint`); one more meanwhile is the same one (``timeout -s INT`` signals the
    process and its group at once), so the section is never cut: it is short (a worker's start,
    at most the fork server's start-up, a claim's file). Nested sections raise at the outermost
    one's end; off the main thread, a plain block. Only a signal taken during the section is
    raised at its end: one taken before it and lost (a command after its last checkpoint, which
    runs to its end and says so) is not made a checkpoint here."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = len(_TAKEN)
    _DEFERRED.append(os.getpid())
    try:
        yield
    finally:
        _DEFERRED.pop()
    if not _DEFERRED and len(_TAKEN) > before:
        checkpoint()


def deferring() -> bool:
    """Whether the main thread of this process is in a section :func:`interrupts_deferred`
    (not a forked child's inherited list)."""
    return (bool(_DEFERRED) and _DEFERRED[-1] == os.getpid()
            and threading.current_thread() is threading.main_thread())


def checkpoint() -> None:
    """The top of a long loop's iteration (a render's batch or pass, a photon chunk, a sweep's
    point): a KeyboardInterrupt where the command line took a signal since the last checkpoint.

    The handler's own KeyboardInterrupt may never have reached the command: raised where
    CPython ignores exceptions (an at-fork hook, an llvmlite ctypes callback during a numba
    compilation, a ``__del__``), it is dropped ("the lost interrupt") and the command goes on.
    Here it stops, as if the interrupt had landed: what it half wrote is removed, and it exits
    130 / 143. Each signal is raised again once at most, and only in the main thread of the
    process that took it (not a worker thread, nor a forked worker, which inherits the list).
    An interrupt that went through by itself ends the command as before: no checkpoint is in a
    clean-up path (only at the top of an iteration). Without the command line's handler (a
    notebook's calls) nothing is taken: nothing happens. Cheap: a list's truth, when empty.

    It also redraws the bars waiting on the loop (:class:`Redrawn`: their elapsed time)."""
    for bar in list(_REDRAWN):
        bar.redraw()
    if not _TAKEN:
        return
    if threading.current_thread() is not threading.main_thread() or _TAKEN[0][1] != os.getpid():
        return
    _TAKEN.clear()
    raise KeyboardInterrupt
