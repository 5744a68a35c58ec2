"""A Ctrl-C (SIGINT) that arrives while a module is imported, held until that import is
complete and then raised as the KeyboardInterrupt it would have been.

Python does not undo a half-finished import: a package whose import a KeyboardInterrupt
cut off is removed from ``sys.modules`` while the submodules it had imported stay, and
importing it again makes a package without them (``module 'numba' has no attribute
'core'``), in every later call of the process. :mod:`tlm.api` imports its heavy layers
(numba, scipy, the compiled kernels) when a function first needs them, inside a user's
first call: its public functions are wrapped by :func:`imports_whole`, so that a notebook
user's Ctrl-C in the first seconds of a first render interrupts the call, not the process.
"""

from __future__ import annotations

import _thread
import functools
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

_IMPORT_FILES = ("<frozen importlib._bootstrap>", "<frozen importlib._bootstrap_external>")
_IMPORT_SOURCES = (os.path.join("importlib", "_bootstrap.py"), os.path.join("importlib", "_bootstrap_external.py"))
_LEFT_HALF: set[str] = set()  # the modules an import interrupted in an API call left without their package


def _importing(frame: Any, stop: Any) -> bool:
    """Whether ``frame`` (the main thread's) runs an import that began after ``stop``, the
    frame of the API call (an API call made while a module is imported does not hold every
    Ctrl-C to its end)."""
    while frame is not None and frame is not stop:
        name = frame.f_code.co_filename
        if name in _IMPORT_FILES or name.endswith(_IMPORT_SOURCES):
            return True
        frame = frame.f_back
    return False


def _orphans() -> set[str]:
    """The modules whose package is not imported: what an interrupted import leaves (its
    submodules imported whole stay in ``sys.modules``, the package is removed, and importing
    it again makes a package without them: ``module 'numba' has no attribute 'core'``)."""
    return {name for name in list(sys.modules) if "." in name and name.rpartition(".")[0] not in sys.modules}


class HeldInterrupt:
    """The SIGINT handler during a call of a function :func:`imports_whole` wraps, in the
    main thread. A Ctrl-C outside an import goes at once to the handler it replaced
    (``KeyboardInterrupt``, or the command line's); one during an import is held, and given
    to that handler once the main thread has left the import (a thread watches it) or, at
    the latest, when the call ends. A second Ctrl-C during the same import goes through at
    once (the import is then left half done, which the next API call reports:
    :func:`check_imports`)."""

    def __init__(self, before: Callable, entry: Any):
        self.before = before
        self.entry = entry  # the frame of the API call
        self.main = threading.get_ident()
        self.lock = threading.RLock()  # (reentrant: the handler may run while the main thread holds it)
        self.active = True
        self.held = False
        self.orphans: set[str] | None = None  # before an interrupt went through during an import

    def __call__(self, signum: int, frame: Any) -> None:
        with self.lock:
            if self.active and _importing(frame, self.entry):
                if not self.held:
                    self.held = True
                    # (the low-level start: threading's own start takes a lock the interrupted code may hold)
                    _thread.start_new_thread(self._watch, ())
                    return
                if self.orphans is None:  # (now, the half-imported packages are still in sys.modules)
                    self.orphans = _orphans()
            self.held = False
        self.before(signum, frame)

    def _watch(self) -> None:
        """Give the held Ctrl-C back to the main thread once it is out of the import."""
        while True:
            time.sleep(0.01)
            with self.lock:
                if not (self.active and self.held):
                    return
                frame = sys._current_frames().get(self.main)
                if frame is not None and _importing(frame, self.entry):
                    continue
                self.held = False
                if hasattr(signal, "pthread_kill"):  # (this handler passes it on: no import now)
                    signal.pthread_kill(self.main, signal.SIGINT)
                else:  # (no pthread_kill: the same signal, simulated in the main thread)
                    _thread.interrupt_main(signal.SIGINT)
                return

    def close(self, failed: BaseException | None) -> None:
        """The call ended: the handler it replaced back, the Ctrl-C still held raised now,
        and the modules an interrupt that went through left half imported noted."""
        held = False
        try:
            with self.lock:
                self.active = False
                held, self.held = self.held, False
        finally:  # (the handler put back even if a Ctrl-C lands here; one left behind is found stale: :func:`_outer`)
            if signal.getsignal(signal.SIGINT) is self:
                signal.signal(signal.SIGINT, self.before)
            self.entry = None
        if failed is not None and self.orphans is not None:
            _LEFT_HALF.update(_orphans() - self.orphans)
        if held:
            signal.raise_signal(signal.SIGINT)  # (its handler runs now: the KeyboardInterrupt of the held Ctrl-C)


def check_imports() -> None:
    """A RuntimeError naming the cure where an interrupted import left packages half imported."""
    left = sorted(name for name in _LEFT_HALF if name in sys.modules)
    if left:
        packages = ", ".join(sorted({name.partition(".")[0] for name in left}))
        raise RuntimeError(f"a Ctrl-C (pressed twice) interrupted the import of {packages} in an earlier call and "
                           f"left it half imported ({len(left)} modules without their package), which Python cannot "
                           "import again: restart the Python process (in a notebook, restart its kernel)")


def _outer(handler: HeldInterrupt) -> bool:
    """Whether ``handler`` is an API call's that is still running around this one (its call's
    frame on this thread's stack), not one a Ctrl-C at the wrong moment left installed."""
    frame = sys._getframe(1)
    while frame is not None:
        if frame is handler.entry:
            return handler.active
        frame = frame.f_back
    return False


def imports_whole(function: Callable) -> Callable:
    """``function`` with a Ctrl-C that arrives during an import held to the import's end
    (:class:`HeldInterrupt`; in the main thread, where SIGINT has a Python handler)."""

    @functools.wraps(function)
    def call(*args: Any, **kwargs: Any) -> Any:
        check_imports()
        before = signal.getsignal(signal.SIGINT)
        if isinstance(before, HeldInterrupt) and not _outer(before):  # (left behind: the handler it replaced)
            before = before.before
        if isinstance(before, HeldInterrupt) or not callable(before):  # (an outer API call holds; or no handler)
            return function(*args, **kwargs)
        if threading.current_thread() is not threading.main_thread():  # (a Ctrl-C interrupts the main thread)
            return function(*args, **kwargs)
        held = HeldInterrupt(before, sys._getframe())
        failed = None
        try:
            signal.signal(signal.SIGINT, held)
            return function(*args, **kwargs)
        except BaseException as e:
            failed = e
            raise
        finally:
            held.close(failed)

    return call
