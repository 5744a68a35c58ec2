"""Host-side progress: wall seconds per stage and the progress bars on stderr.

What a command shows while it works and what ``results.json`` records of the host's
time (``host_seconds``), kept apart from the work that uses them: the render's batch
loop (:mod:`tlm.render.batches`, which books its stages and draws its bar), a run, a
sweep, a study. In the base layer so that every layer may use it. Nothing here changes
a result; a bar is drawn only when asked for and stderr is a terminal.
"""

from __future__ import annotations

import sys
import threading
import time
from dataclasses import dataclass, field

_STAGES = threading.Lock()  # (a Timer's stages may be entered on several threads at once)


@dataclass
class Timer:
    """Host wall seconds per named stage (a stage entered twice adds up). A stage that
    runs on several threads at once (the render's batches) counts the wall time while any
    of them runs, not the sum of their times: a stage never holds more seconds than
    passed."""

    seconds: dict[str, float] = field(default_factory=dict)
    _open: dict[str, tuple[int, float]] = field(default_factory=dict, repr=False, compare=False)

    def stage(self, name: str):
        """A context manager that adds the wall seconds of its block to stage ``name``."""
        timer = self

        class _Stage:
            def __enter__(self):
                with _STAGES:
                    n, since = timer._open.get(name, (0, time.perf_counter()))
                    timer._open[name] = (n + 1, since)

            def __exit__(self, *exc):
                with _STAGES:
                    n, since = timer._open[name]
                    if n > 1:
                        timer._open[name] = (n - 1, since)
                        return
                    del timer._open[name]
                    timer.seconds[name] = timer.seconds.get(name, 0.0) + time.perf_counter() - since

        return _Stage()


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
