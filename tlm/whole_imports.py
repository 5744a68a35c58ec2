"""A Ctrl-C (SIGINT) that arrives while a module is imported, held until that import is
complete and then raised as the KeyboardInterrupt it would have been; and a SIGTERM the
same way, where a Python handler takes it.

Python does not undo a half-finished import: a package whose import a KeyboardInterrupt
cut off is removed from ``sys.modules`` while the submodules it had imported stay, and
importing it again makes a package without them (``module 'numba' has no attribute
'core'``), in every later call of the process. :mod:`tlm.api` imports its heavy layers
(numba, scipy, the compiled kernels) when a function first needs them, inside a user's
first call: its public functions are wrapped by :func:`imports_whole`, so that a notebook
user's Ctrl-C in the first seconds of a first render interrupts the call, not the process.
``tlm.<name>`` (the package's ``__getattr__``) imports :mod:`tlm.api` itself so, on first use.

SIGTERM is held only where a Python handler takes it: that handler runs in the main thread
between two bytecodes, as SIGINT's does, and where it raises (``tlm``'s command line turns
SIGTERM into the KeyboardInterrupt that removes what a command half wrote) it cuts an import
short as a Ctrl-C does. Its default action (and an ignored SIGTERM) is the kernel's, not
Python's: nothing to hold, and a SIGTERM that ends the process is never delayed. SIGHUP (a
closed terminal's) and SIGALRM (a timeout's: ``signal.setitimer`` and a handler that raises, as
notebooks' timeouts do; it cut numba's import as a Ctrl-C did) are held the same way.

An interrupt that nothing holds (another signal's handler that raises, an asynchronous exception
from another thread) may still cut an import short: the outermost API call of a thread notes what
its failure left (:class:`_Imports`: packages half imported, a module left half run in
``sys.modules``), and the next call raises the RuntimeError that says to restart (:func:`check_imports`).

numba's install of a registry (a typing or target context's ``install_registry``, run by every
compile's refresh of its contexts, the first one around the imports of numba's own modules) is
held the same way: a KeyboardInterrupt in one leaves that registry's loader broken for the
process (its generator of the registry's new entries, ``numba.core.utils.stream_list``, is
finished by an exception raised in it: every later compile fails with ``generator raised
StopIteration``; cut between two entries, the rest are skipped), and a Ctrl-C held to an
import's end was raised in the refresh around it about one time in six. A signal is not given
in a finalizer either (a ``__del__``: llvmlite's, during a compile), where Python would drop its
KeyboardInterrupt and the call would run on. Nor while numba or llvmlite runs Python code (a compile,
or a compiled function loaded from numba's cache): llvmlite hands LLVM objects from one owner to another
in two steps, a C call and then a Python line that records it (``link_modules``' ``src.detach()``,
``add_module``'s ``module._owned = True``), and a signal that arrives during the C call has its handler
run as the call returns, between the two: the KeyboardInterrupt left a module that LLVM had destroyed
(or that the execution engine owns) for llvmlite to dispose of again when it was collected: a segfault
or "free(): double free" later in the process (SIGINTs at random moments of numba compiles crashed about
one process in two of 150; the likely cause of a clean-clone CI run's exit status -11 in
``test_api_interrupt[tlm.kernels._jit_bsp]``, whose held Ctrl-C is given back during the first compile).
"""

from __future__ import annotations

import _thread
import contextlib
import functools
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

_IMPORT_FILES = ("<frozen importlib._bootstrap>", "<frozen importlib._bootstrap_external>")
_IMPORT_SOURCES = (os.path.join("importlib", "_bootstrap.py"), os.path.join("importlib", "_bootstrap_external.py"))
_NUMBA_CORE = os.sep + os.path.join("numba", "core", "")  # (its contexts' install_registry, typing and target)
COMPILERS = ("numba", "llvmlite")  # the packages whose Python code a signal must not cut short (:func:`_uncuttable`)
# the signals held to an import's end, where a Python handler takes them (the command line's:
# tlm.cli_signals.TAKEN, SIGHUP a closed terminal's; SIGALRM a timeout's, as a notebook's ``signal.setitimer``
# and a handler that raises; none on Windows)
HELD = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP", "SIGALRM") if hasattr(signal, n))
# the timers' signals: no one insisting, so one that comes while another signal is held is held too (and a repeat
# of one held dropped, as the kernel merges a pending signal's), where a second Ctrl-C goes through
_TIMERS = tuple(getattr(signal, n) for n in ("SIGALRM",) if hasattr(signal, n))
_LEFT_HALF: dict[str, int | str] = {}  # the modules an import interrupted in an API call left without their
# package, with the signal that cut it short (or the name of the exception, where no held signal did)
_HALF_RUN: dict[str, tuple[Any, str]] = {}  # the modules an exception in an API call left in sys.modules half
# run (their spec still ``_initializing``: "partially initialized module"), with the module and that exception
_CALLS = threading.local()  # ``open``: an API call of this thread is running (the outermost watches its imports)
_CUT_REGISTRIES: set[int] = set()  # the signals that cut numba's install of a registry short in an API call


def _compiler_folders() -> tuple[str, ...]:
    """The folders of numba's and llvmlite's code, of those imported (none before: then no frame
    of theirs can run but their import's, which is held as an import)."""
    folders = []
    for name in COMPILERS:
        file = getattr(sys.modules.get(name), "__file__", None)
        if file:
            folders.append(os.path.join(os.path.dirname(os.path.abspath(file)), ""))
    return tuple(folders)


def _uncuttable(frame: Any, stop: Any) -> set[str]:
    """What ``frame`` (the main thread's) runs, begun after ``stop`` (the frame of the API call),
    that a signal must not cut short: ``"import"`` (a module's), ``"registry"`` (numba's install of
    a registry), ``"compile"`` (numba's or llvmlite's Python code: a compile, a load from numba's
    cache, where llvmlite hands LLVM objects over in a C call and a Python line after it),
    ``"finalizer"`` (a ``__del__``, where Python drops the KeyboardInterrupt of a Ctrl-C given back
    there: "Exception ignored in ...", and the call goes on); empty if nothing (an API call made
    while a module is imported does not hold every Ctrl-C to its end)."""
    found = set()
    compilers = _compiler_folders()
    while frame is not None and frame is not stop:
        code = frame.f_code
        if code.co_filename in _IMPORT_FILES or code.co_filename.endswith(_IMPORT_SOURCES):
            found.add("import")
        elif code.co_name == "install_registry" and _NUMBA_CORE in code.co_filename:
            found.add("registry")
        elif code.co_name == "__del__":
            found.add("finalizer")
        if compilers and code.co_filename.startswith(compilers):
            found.add("compile")
        frame = frame.f_back
    return found


def _orphans() -> set[str]:
    """The modules whose package is not imported: what an interrupted import leaves (its
    submodules imported whole stay in ``sys.modules``, the package is removed, and importing
    it again makes a package without them: ``module 'numba' has no attribute 'core'``)."""
    return {name for name in list(sys.modules) if "." in name and name.rpartition(".")[0] not in sys.modules}


class HeldInterrupt:
    """The SIGINT (and SIGTERM, SIGHUP, SIGALRM) handler during a call of a function :func:`imports_whole`
    wraps, in the main thread. A signal outside an import goes at once to the handler it
    replaced (``KeyboardInterrupt``, or the command line's); one during an import (or numba's
    install of a registry, or numba's or llvmlite's Python code: a compile) is held, and given to
    that handler once the main thread has left it (a thread watches it; not in a finalizer, which
    would drop it) or, at the latest, when the
    call ends. A second signal during the same import goes through at once (the import is then
    left half done, or the registry's loader broken, which the next API call reports:
    :func:`check_imports`), but for a timer's (:data:`_TIMERS`), held too, and a first one after a
    timer's: those are held after the first (:attr:`late`).

    ``before``: the handler replaced, of SIGINT, or ``{signal: handler}`` of the signals held."""

    def __init__(self, before: Callable | Mapping[int, Callable], entry: Any):
        self.before = dict(before) if isinstance(before, Mapping) else {signal.SIGINT: before}
        self.entry = entry  # the frame of the API call
        self.main = threading.get_ident()
        self.lock = threading.RLock()  # (reentrant: the handler may run while the main thread holds it)
        self.active = True
        self.held: int | None = None  # the signal held
        self.late: list[int] = []  # the signals held after it (a timer's; a first one after a timer's)
        self.orphans: set[str] | None = None  # before a signal went through during an import
        self.cut_by = signal.SIGINT  # the signal that went through
        self.cut_registry = False  # whether it went through during numba's install of a registry

    def __call__(self, signum: int, frame: Any) -> None:
        with self.lock:
            if self.active and (uncuttable := _uncuttable(frame, self.entry)):
                if self.held is None:
                    self.held = signum
                    # (the low-level start: threading's own start takes a lock the interrupted code may hold)
                    _thread.start_new_thread(self._watch, ())
                    return
                if signum in _TIMERS or (self.held in _TIMERS and signum not in self.late):
                    # (a timer's signal is no one insisting: held too, a repeat dropped; a first Ctrl-C after a
                    # timer's is a first one, held; the Ctrl-C after it goes through)
                    if signum != self.held and signum not in self.late:
                        self.late.append(signum)
                    return
                if "finalizer" in uncuttable and uncuttable <= {"finalizer", "compile"}:  # (llvmlite's __del__ too)
                    # a second signal in a finalizer goes through, the first still held: Python drops the
                    # exception there, but it ends the __del__ (one that hangs can still be stopped), and the
                    # held one is given when the finalizer has returned
                    self.before[signum](signum, frame)
                    return
                if self.orphans is None:  # (now, the half-imported packages are still in sys.modules)
                    self.orphans, self.cut_by = _orphans(), signum
                    self.cut_registry = "registry" in uncuttable
            self.held = None
        self.before[signum](signum, frame)

    def _watch(self) -> None:
        """Give the held signal back to the main thread once it is out of the import (its handler,
        :meth:`__call__`, holds it again if the main thread has entered another meanwhile)."""
        while True:
            time.sleep(0.01)
            with self.lock:
                if not self.active or self.held is None:
                    return
                frame = sys._current_frames().get(self.main)
                if frame is not None and _uncuttable(frame, self.entry):
                    continue
                given = [self.held, *self.late]
                self.held, self.late = None, []
                for signum in given:
                    if hasattr(signal, "pthread_kill"):  # (this handler passes it on: no import now)
                        signal.pthread_kill(self.main, signum)
                    else:  # (no pthread_kill: the same signal, simulated in the main thread)
                        _thread.interrupt_main(signum)
                return

    def close(self, failed: BaseException | None) -> None:
        """The call ended: the handlers it replaced back, the signal still held raised now,
        and the modules a signal that went through left half imported noted."""
        held: list[int] = []
        try:
            with self.lock:
                self.active = False
                held = [self.held, *self.late] if self.held is not None else []
                self.held, self.late = None, []
        finally:  # (the handlers put back even if a signal lands here; one left behind is found stale: :func:`_outer`)
            for signum, before in self.before.items():
                if signal.getsignal(signum) is self:
                    signal.signal(signum, before)
            self.entry = None
        if failed is not None and self.orphans is not None:
            _LEFT_HALF.update(dict.fromkeys(_orphans() - self.orphans, self.cut_by))
            if self.cut_registry:
                _CUT_REGISTRIES.add(self.cut_by)
        _give(held)


def _give(signums: list[int]) -> None:
    """Each signal raised in turn (its handler runs now: a held Ctrl-C's KeyboardInterrupt), every
    handler run though an earlier one raised (the last one's exception goes on, the others its context)."""
    if signums:
        try:
            signal.raise_signal(signums[0])
        finally:
            _give(signums[1:])


def _initializing() -> set[str]:
    """The modules in ``sys.modules`` whose import has not finished (their spec's ``_initializing``:
    those being imported now, or one an exception left there half run)."""
    return {name for name, module in list(sys.modules.items())
            if getattr(getattr(module, "__spec__", None), "_initializing", False) is True}


def _running_imports() -> set[str]:
    """The modules whose own code (``<module>``) some thread runs now: imports under way."""
    names = set()
    for frame in sys._current_frames().values():
        while frame is not None:
            if frame.f_code.co_name == "<module>":
                names.add(frame.f_globals.get("__name__"))
            frame = frame.f_back
    return names


def _handlers_codes() -> set[Any]:
    """The code of each Python signal handler installed now, of :class:`HeldInterrupt`'s, and of the
    handlers an installed HeldInterrupt passes a signal to (its ``before``)."""
    codes = {HeldInterrupt.__call__.__code__}
    for signum in signal.valid_signals() if hasattr(signal, "valid_signals") else HELD:
        handler = signal.getsignal(signum)
        before = getattr(handler, "before", None)
        for h in (handler, *(before.values() if isinstance(before, dict) else ())):
            code = getattr(getattr(h, "__func__", h), "__code__", None)
            if code is not None:
                codes.add(code)
    return codes


def raised_by_handler(error: BaseException, handled: BaseException | None = None) -> bool:
    """Whether a Python signal handler raised ``error``, or an exception it came from (its cause, its
    context): the code of one (:func:`_handlers_codes`) among the frames of their tracebacks, or a
    KeyboardInterrupt among them (Python's own SIGINT handler raises it from C: no frame of its own; a Ctrl-C
    whatever raised it). ``handled``: the exception being handled as the work began (``sys.exc_info()``),
    which it and those it came from are older than (an error raised in an ``except`` block has it for its
    context: a timeout caught, then a retry), so none of the work's. What tells an interrupt that cut an
    import short (:func:`_interrupt`) and one that cut the load of a cached kernel
    (:func:`tlm.kernels._numba_cache._damage_safe`: not the files' damage) from an error of their own."""
    chain = _chain(error, handled)
    if any(isinstance(e, KeyboardInterrupt) for e in chain):
        return True
    codes = _handlers_codes()
    return any(frame.f_code in codes for frame in _chain_frames(chain))


def _chain(failed: BaseException, handled: BaseException | None = None) -> list[BaseException]:
    """``failed`` and the exceptions it came from (its cause, its context), each once (a loop of contexts
    ends), but ``handled`` and those it came from (older: :func:`raised_by_handler`)."""
    seen = {id(e) for e in _chain(handled)} if handled is not None else set()  # (ids: held by ``found``, ``handled``)
    found: list[BaseException] = []
    todo: list[BaseException | None] = [failed]
    while todo:
        e = todo.pop()
        if e is not None and id(e) not in seen:
            seen.add(id(e))
            found.append(e)
            todo += [e.__cause__, e.__context__]
    return found


def _frames(failed: BaseException, handled: BaseException | None = None) -> list[Any]:
    """The frames the tracebacks of ``failed`` and of the exceptions it came from (but ``handled``'s:
    :func:`_chain`) pass through."""
    return _chain_frames(_chain(failed, handled))


def _chain_frames(chain: list[BaseException]) -> list[Any]:
    """The frames the tracebacks of the exceptions ``chain`` pass through."""
    frames = []
    for e in chain:
        tb = e.__traceback__
        while tb is not None:
            frames.append(tb.tb_frame)
            tb = tb.tb_next
    return frames


def _cut_imports(frames: list[Any]) -> set[str]:
    """The modules whose import an exception cut short on its way out of ``frames`` (its traceback's):
    those whose own code (``<module>``) or whose import by importlib's code it passed through. Empty
    where it came from no import (a Ctrl-C during a render)."""
    names = set()
    for frame in frames:
        code = frame.f_code
        if code.co_name == "<module>":
            names.add(frame.f_globals.get("__name__"))
        elif code.co_filename in _IMPORT_FILES or code.co_filename.endswith(_IMPORT_SOURCES):
            local = frame.f_locals
            names.add(local.get("name") if isinstance(local.get("name"), str)
                      else getattr(local.get("spec"), "name", None))
    return {name for name in names if isinstance(name, str)}


def _interrupt(failed: BaseException, handled: BaseException | None = None) -> bool:
    """Whether ``failed`` ends a call as an interrupt: not an Exception (KeyboardInterrupt, SystemExit,
    another thread's asynchronous exception), or one a signal's handler raised, or that came of one
    (:func:`raised_by_handler`; ``handled``: the exception handled as the call began, not the call's).
    An Exception of the call's own code (an ImportError: an import that fails of itself) is none."""
    return not isinstance(failed, Exception) or raised_by_handler(failed, handled)


class _Imports:
    """What the imports of an API call left (the outermost of its thread): the packages an interrupt
    cut off half imported, whatever raised it (a signal tlm does not hold, another thread's
    asynchronous exception), noted for :func:`check_imports`, as :class:`HeldInterrupt` notes those of
    a second signal that went through. Nothing is kept before the call (no copy of ``sys.modules``:
    a call costs nothing more); what an interrupt cut is told by its traceback (:func:`_cut_imports`):
    the modules without their package in the packages it cut, and the modules left half run. A package
    that an import which failed of itself left half imported (an ImportError tlm caught: numba's, where
    it runs on numpy) is not said for a Ctrl-C that ends a later render."""

    def __init__(self) -> None:
        self.handled = sys.exc_info()[1]  # (a call made in an ``except`` block: that exception is not the call's)

    def note(self, failed: BaseException) -> None:
        if not _interrupt(failed, self.handled):
            return
        cut = _cut_imports(_frames(failed, self.handled))
        if not cut:  # (it cut no import: a render's, a callback's)
            return
        cause = type(failed).__name__
        packages = {name.partition(".")[0] for name in cut}
        for name in _orphans():
            if name.partition(".")[0] in packages:
                _LEFT_HALF.setdefault(name, cause)
        for name in _initializing() - _running_imports():  # (not another thread's import, nor this one's caller)
            _HALF_RUN.setdefault(name, (sys.modules.get(name), cause))


def check_imports() -> None:
    """A RuntimeError naming the cure where an interrupted import left packages half imported (or a
    module half run), or an interrupted install of one of numba's registries left its loader broken."""
    left = sorted(name for name in _LEFT_HALF if name in sys.modules)
    half = sorted(name for name, (module, _) in _HALF_RUN.items() if sys.modules.get(name) is module
                  and getattr(getattr(module, "__spec__", None), "_initializing", False) is True)
    if not left and not half and not _CUT_REGISTRIES:
        return
    if half and not left:
        names = ", ".join(half)
        raise RuntimeError(f"an exception ({', '.join(sorted({_HALF_RUN[n][1] for n in half}))}) interrupted the "
                           f"import of {names} in an earlier call and left it half run, which Python does not run "
                           "again: restart the Python process (in a notebook, restart its kernel)")
    cut = sorted({_LEFT_HALF[name] for name in left} if left else _CUT_REGISTRIES, key=str)
    if not all(isinstance(c, int) for c in cut):  # (an exception no held signal raised)
        what = f"an exception ({', '.join(str(signal.Signals(c).name if isinstance(c, int) else c) for c in cut)})"
    else:
        what = ("a Ctrl-C (pressed twice)" if cut == [signal.SIGINT] else
                f"a second signal ({', '.join(signal.Signals(s).name for s in cut)})")
    if left:
        packages = ", ".join(sorted({name.partition(".")[0] for name in left}))
        done = (f"the import of {packages} in an earlier call and left it half imported ({len(left)} modules "
                "without their package), which Python cannot import again")
    else:
        done = ("numba's install of its registries in an earlier call and left them incomplete (every later "
                "compile fails or misses functions), which numba cannot resume")
    raise RuntimeError(f"{what} interrupted {done}: restart the Python process (in a notebook, restart its kernel)")


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
    """``function`` with a Ctrl-C (or a SIGTERM, a SIGHUP, a SIGALRM) that arrives during an import held
    to the import's end (:class:`HeldInterrupt`; in the main thread, for each signal of :data:`HELD`
    that a Python handler takes); and what an interrupt that cut an import short left noted
    (:class:`_Imports`), in any thread, so that the next call says to restart (:func:`check_imports`)."""

    @functools.wraps(function)
    def call(*args: Any, **kwargs: Any) -> Any:
        check_imports()
        if getattr(_CALLS, "open", False):  # (an outer API call of this thread watches)
            return held_call(*args, **kwargs)
        imports = _Imports()
        _CALLS.open = True
        try:
            return held_call(*args, **kwargs)
        except BaseException as e:
            with contextlib.suppress(Exception):  # (never in place of the call's own exception)
                imports.note(e)  # (an interrupt's that cut an import: KeyboardInterrupt, SystemExit, a handler's raise)
            raise
        finally:
            _CALLS.open = False

    def held_call(*args: Any, **kwargs: Any) -> Any:
        if threading.current_thread() is not threading.main_thread():  # (a signal interrupts the main thread)
            return function(*args, **kwargs)
        before = {}
        for signum in HELD:
            handler = signal.getsignal(signum)
            if isinstance(handler, HeldInterrupt):
                if _outer(handler):  # (an outer API call holds)
                    return function(*args, **kwargs)
                handler = handler.before.get(signum)  # (left behind: the handler it replaced)
            if callable(handler):  # (not the default action, nor ignored)
                before[signum] = handler
        if not before:
            return function(*args, **kwargs)
        held = HeldInterrupt(before, sys._getframe())
        failed = None
        try:
            for signum in before:
                signal.signal(signum, held)
            return function(*args, **kwargs)
        except BaseException as e:
            failed = e
            raise
        finally:
            held.close(failed)

    return call
