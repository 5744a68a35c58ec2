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


@dataclass
class Timer:
    """Host wall seconds per named stage (a stage entered twice adds up)."""

    seconds: dict[str, float] = field(default_factory=dict)

    def stage(self, name: str):
        """A context manager that adds the wall seconds of its block to stage ``name``."""
        timer = self

        class _Stage:
            def __enter__(self):
                self.t0 = time.perf_counter()

            def __exit__(self, *exc):
                timer.seconds[name] = timer.seconds.get(name, 0.0) + time.perf_counter() - self.t0

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
