"""Host-side progress: wall seconds per stage and the progress bars on stderr.

What a command shows while it works and what ``results.json`` records of the host's
time (``host_seconds``), kept apart from the work that uses them: the render's batch
loop (:mod:`tlm.render.batches`, which books its stages and draws its bar), a run, a
sweep, a study. In the base layer so that every layer may use it. Nothing here changes
a result; a bar is drawn only when asked for and stderr is a terminal.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

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


def progress_bar(enabled: bool, **kwargs):
    """A tqdm bar on stderr, drawn only when ``enabled`` and stderr is a terminal."""
    from tqdm import tqdm

    return tqdm(disable=None if enabled else True, file=sys.stderr, dynamic_ncols=True, **kwargs)


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
