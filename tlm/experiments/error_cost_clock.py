"""The host seconds a study charges to no row (:mod:`tlm.experiments.error_cost`'s one-off work):
the spans in which numba compiled a kernel or loaded one from its on-disk cache, or a module was
imported for the first time, from any thread (:class:`CompileClock`); a window's share of them is
taken out of a row's timed trace and gather and said as its ``one_off_seconds``.
"""

from __future__ import annotations

import sys
import threading
import time
from contextlib import contextmanager
from importlib.util import resolve_name


class CompileClock:
    """The spans of host time in which numba compiled a kernel or loaded one from its on-disk
    cache (its global compiler lock asked for and held: numba's ``numba:compiler_lock`` event),
    or an ``import`` statement imported a module not imported before (its first import, with
    what that imports), from any thread, while :meth:`running`; :meth:`within` gives the
    seconds of a window that any of them covered (overlapping spans counted once)."""

    def __init__(self):
        self._lock = threading.Lock()
        self._depth = 0
        self._since = 0.0
        self.spans: list[tuple[float, float]] = []

    def _start(self) -> None:
        with self._lock:
            if self._depth == 0:
                self._since = time.perf_counter()
            self._depth += 1

    def _end(self) -> None:
        with self._lock:
            self._depth -= 1
            if self._depth == 0:
                self.spans.append((self._since, time.perf_counter()))

    @contextmanager
    def running(self):
        import builtins

        from numba.core import event

        clock = self

        class Listener(event.Listener):
            def on_start(self, _event):
                clock._start()

            def on_end(self, _event):
                clock._end()

        real = builtins.__import__

        def timed_import(name, globals=None, locals=None, fromlist=(), level=0):  # noqa: A002 (__import__'s)
            try:
                first = _first_import(name, globals, fromlist, level)
            except Exception:  # (a module's own __getattr__ that fails: the import itself says so)
                first = True
            if not first:
                return real(name, globals, locals, fromlist, level)
            self._start()
            try:
                return real(name, globals, locals, fromlist, level)
            finally:
                self._end()

        builtins.__import__ = timed_import
        try:
            with event.install_listener("numba:compiler_lock", Listener()):
                yield self
        finally:
            if builtins.__import__ is timed_import:
                builtins.__import__ = real

    def within(self, start: float, end: float) -> float:
        """Seconds between ``start`` and ``end`` (``time.perf_counter()`` readings) in which numba
        compiled or a module was imported for the first time."""
        with self._lock:
            spans = list(self.spans) + ([(self._since, end)] if self._depth else [])
        return sum(max(0.0, min(end, b) - max(start, a)) for a, b in spans)


def _first_import(name: str, scope: dict | None, fromlist, level: int) -> bool:
    """Whether an ``import`` statement's call of ``__import__`` may import a module that is not
    imported yet (a module, or a submodule its ``from ... import`` names, not in ``sys.modules``;
    ``scope``: the importing module's globals). It imports nothing itself: it runs inside
    ``__import__``."""
    if level:
        try:
            name = resolve_name("." * level + name, (scope or {}).get("__package__") or None)
        except (ImportError, ValueError, TypeError):
            return True
    module = sys.modules.get(name)
    if module is None:
        return True
    return any(not hasattr(module, f) and f"{name}.{f}" not in sys.modules for f in fromlist or () if f != "*")
