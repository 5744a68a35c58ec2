"""The host seconds a study charges to no row (:mod:`tlm.experiments.error_cost`'s one-off work):
the spans in which numba compiled a kernel or loaded one from its on-disk cache, or a module was
imported for the first time, from any thread (:class:`CompileClock`); a window's share of them is
taken out of a row's timed trace and gather and said as its ``one_off_seconds``.

The hooks are the process's, one of each, shared by every clock that runs (:func:`_hooks_on`):
the import statement's (``builtins.__import__`` wrapped while any clock runs, restored when the
last one stops, whatever order they stop in) and numba's ``numba:compiler_lock`` listener, only
put on where numba is imported already, or as soon as its first import ends while a clock runs
(:func:`_wants_numba`): a clock imports no numba itself, so a process that runs no kernel (numba
not imported: ``TLM_KERNELS=numpy``, numba missing, a sweep whose frames are all cached) never
imports it, and numba compiles nothing before it is imported.
"""

from __future__ import annotations

import builtins
import contextvars
import sys
import threading
import time
from contextlib import contextmanager, suppress
from importlib.util import resolve_name

# whose work a span is: the token of :meth:`CompileClock.owned` in the context of the thread that
# began it (the kernels' pool threads run their calls in a copy of the caller's context:
# tlm.kernels.threads.ordered), None where no one's
# (the state below kept where the module is loaded again, importlib.reload, IPython's %autoreload: a clock
# running then keeps its tokens, and the hook in place the import statement it wraps: it was a RecursionError)
_OWNER: contextvars.ContextVar[object | None] = globals().get("_OWNER") or contextvars.ContextVar(
    "tlm_one_off_owner", default=None)


class Span(tuple):
    """A span ``(start, end)`` (``time.perf_counter`` readings) that also says whose work it
    was (``owner``: :meth:`CompileClock.owned`'s token, None where no one's) and its thread."""

    def __new__(cls, start: float, end: float, owner: object | None = None, thread: int = 0):
        span = super().__new__(cls, (start, end))
        span.owner, span.thread = owner, thread
        return span


class CompileClock:
    """The spans of host time in which numba compiled a kernel or loaded one from its on-disk
    cache (its global compiler lock asked for and held: numba's ``numba:compiler_lock`` event),
    or an ``import`` statement imported a module not imported before (its first import, with
    what that imports), from any thread, while :meth:`running`; :meth:`within` gives the
    seconds of a window that any of them covered (overlapping spans counted once).

    Each thread's spans are its own (one thread's nested events one span), each one tagged with
    the :meth:`owned` token of the context it began in: :meth:`spans_of` gives one owner's (a
    run's, on its thread and the kernels' pool threads working for it), a span still open cut
    at the window's end."""

    def __init__(self):
        self._lock = threading.Lock()
        self._local = threading.local()  # .stack: the thread's open events, [(owner, start), ...]
        self._open: dict[tuple[int, object | None], float] = {}  # (thread, owner) -> start of its open span
        self._running = 0
        self._run = 0  # (which run of the clock: a thread's stack of an earlier one is forgotten)
        self.spans: list[tuple[float, float]] = []  # (Span, closed; a list others may clear)

    def _stack(self) -> list:
        """The thread's open events of this run of the clock (``self._lock`` held): those of an earlier
        run (an event whose end never came: its listener gone, a Ctrl-C) forgotten."""
        local = self._local.__dict__
        if local.get("run") != self._run:
            local["run"], local["stack"] = self._run, []
        return local["stack"]

    def _start(self) -> None:
        owner, now = _OWNER.get(), time.perf_counter()
        with self._lock:
            stack = self._stack()
            if all(o is not owner for o, _ in stack):  # (the thread's outermost event of that owner)
                self._open[(threading.get_ident(), owner)] = now
            stack.append((owner, now))

    def _end(self) -> None:
        with self._lock:
            stack = self._stack()
            if not stack:  # (begun before this run of the clock)
                return
            owner, _ = stack.pop()
            if all(o is not owner for o, _ in stack):
                key = (threading.get_ident(), owner)
                since = self._open.pop(key, None)
                if since is not None:
                    self.spans.append(Span(since, time.perf_counter(), owner, key[0]))

    def _new_run(self) -> None:
        """``self._lock`` held: the spans still open closed now (an end that will never come: numba's
        listener gone as the last clock stopped, a Ctrl-C inside the hook), every thread's stack forgotten."""
        now = time.perf_counter()
        self.spans += [Span(a, now, owner, thread) for (thread, owner), a in self._open.items()]
        self._open.clear()
        self._run += 1

    @contextmanager
    def running(self):
        """Record while the block runs (the process's hooks on while any clock runs: :func:`_hooks_on`).
        A clock may run on several threads at once; its spans are cleared as it starts from none, and
        those still open closed as it stops (an end never heard: each thread's events forgotten)."""
        with self._lock:
            if self._running == 0:
                self._new_run()
                self.spans.clear()
            self._running += 1
        try:
            _hooks_on(self)  # (as it was, if it raises: a Ctrl-C while numba imports)
            try:
                yield self
            finally:
                _hooks_off(self)
        finally:
            with self._lock:
                self._running -= 1
                if self._running == 0:
                    self._new_run()

    @contextmanager
    def owned(self):
        """A token for the block's work: the spans begun in its context (its thread's, and the
        kernel pool's calls it makes) are tagged with it (:meth:`spans_of`); forgotten after."""
        token = object()
        reset = _OWNER.set(token)
        try:
            yield token
        finally:
            _OWNER.reset(reset)
            with self._lock:
                self.spans[:] = [s for s in self.spans if getattr(s, "owner", None) is not token]

    def spans_of(self, owner: object, start: float, end: float) -> list[tuple[float, float]]:
        """``owner``'s spans cut to ``start`` .. ``end`` (those still open: up to ``end``)."""
        with self._lock:
            mine = [(s[0], s[1]) for s in self.spans if getattr(s, "owner", None) is owner]
            mine += [(a, end) for (_, o), a in self._open.items() if o is owner]
        return [(max(a, start), min(b, end)) for a, b in mine if min(b, end) > max(a, start)]

    def within(self, start: float, end: float) -> float:
        """Seconds between ``start`` and ``end`` (``time.perf_counter()`` readings) in which numba
        compiled or a module was imported for the first time (any thread's: overlaps counted once)."""
        with self._lock:
            spans = [(a, b) for a, b in self.spans] + [(a, end) for a in self._open.values()]
        return covered(spans, start, end)

    @contextmanager
    def running_own(self):
        """:meth:`running` for the block's own work (:meth:`owned`): yields an :class:`OwnSpans`, whose
        ``within(start, end)`` counts the spans the block's work began (on its thread, and on the
        kernels' pool threads working for it), not another thread's first import or compile meanwhile
        (another sweep point's in a thread of the same Dask worker): a sweep point's one-off clock, as
        ``tlm run``'s (:func:`tlm.experiments.run.one_off_clock`)."""
        with self.owned() as token, self.running():
            yield OwnSpans(self, token)


class OwnSpans:
    """One owner's share of a running :class:`CompileClock` (:meth:`CompileClock.running_own`)."""

    def __init__(self, clock: CompileClock, owner: object):
        self.clock, self.owner = clock, owner

    def spans(self, start: float, end: float) -> list[tuple[float, float]]:
        """The owner's spans cut to ``start`` .. ``end`` (:meth:`CompileClock.spans_of`)."""
        return self.clock.spans_of(self.owner, start, end)

    def within(self, start: float, end: float) -> float:
        """Seconds between ``start`` and ``end`` that the owner's spans cover (overlaps counted once)."""
        return covered(self.spans(start, end), start, end)


def covered(spans: list[tuple[float, float]], start: float, end: float) -> float:
    """Seconds between ``start`` and ``end`` that ``spans`` cover (overlapping spans counted once)."""
    cut = sorted((max(a, start), min(b, end)) for a, b in spans if min(b, end) > max(a, start))
    total, reach = 0.0, start
    for a, b in cut:
        if b > reach:
            total += b - max(a, reach)
            reach = b
    return total


# the process's hooks, shared by the clocks that run (a clock running twice: listed twice); a reload of
# the module keeps them as they are (the hook in place, an earlier load's function, reads them by name)
_HOOKS_LOCK = globals().get("_HOOKS_LOCK") or threading.Lock()
_ACTIVE: tuple[CompileClock, ...] = globals().get("_ACTIVE", ())
_REAL_IMPORT = globals().get("_REAL_IMPORT")  # builtins.__import__ as it was when the hook went on
_LISTENER = globals().get("_LISTENER")  # numba's listener, while registered
_HOOK = "_tlm_one_off_hook"  # the attribute that marks this module's import hook (of this load or an earlier one)


def _is_hook(function) -> bool:
    """Whether ``function`` is this module's import hook (:func:`_timed_import`, this load's or one of an earlier
    load in the same module, :func:`importlib.reload`; a module imported afresh, a new one, wraps another's hook)."""
    return getattr(function, _HOOK, False) is True and getattr(function, "__globals__", None) is globals()


def _timed_import(name, globals=None, locals=None, fromlist=(), level=0):  # noqa: A002 (__import__'s)
    real = _REAL_IMPORT if _REAL_IMPORT is not None else _builtin_import
    clocks = _ACTIVE
    if not clocks:  # (left in place under another hook that wrapped it: passes through)
        return real(name, globals, locals, fromlist, level)
    if _LISTENER is None and _wants_numba():  # (numba imported where this hook did not see it end)
        _listen_now()
    try:
        first = _first_import(name, globals, fromlist, level)
    except Exception:  # (a module's own __getattr__ that fails: the import itself says so)
        first = True
    if not first:
        return real(name, globals, locals, fromlist, level)
    try:  # (the starts inside: a Ctrl-C among them still ends them)
        for clock in clocks:
            clock._start()
        return real(name, globals, locals, fromlist, level)
    finally:
        for clock in clocks:
            clock._end()
        if _LISTENER is None and _wants_numba():  # (numba's first import just ended: its listener on)
            _listen_now()


setattr(_timed_import, _HOOK, True)
# the import statement as it was before any hook of this module (loaded again: the first load's; never the hook)
_builtin_import = globals().get("_builtin_import") or builtins.__import__
if getattr(_builtin_import, _HOOK, False) is True:  # (imported afresh under another's hook: the statement it wraps)
    _builtin_import = _builtin_import.__globals__["_builtin_import"]


def _wants_numba() -> bool:
    """Whether numba is imported, its first import ended (not one still running its module's code, in
    which numba's listener could not be put yet): the listener then goes on (:func:`_hooks_on`,
    :func:`_listen_now`). Nothing is imported for it."""
    module = sys.modules.get("numba")
    spec = getattr(module, "__spec__", None)
    return module is not None and not getattr(spec, "_initializing", False)


def _listen_now() -> None:
    """numba's listener on, where numba's first import has just ended while a clock runs and the hooks'
    lock is free (held: :func:`_hooks_on` or :func:`_hooks_off` is at work, and puts it on or has no
    clock left to time it for); a numba that fails as the listener goes on leaves the import hook alone."""
    global _LISTENER
    if not _HOOKS_LOCK.acquire(blocking=False):
        return
    try:
        if _LISTENER is None and _ACTIVE:
            with suppress(Exception):
                _LISTENER = _numba_listener()
    finally:
        _HOOKS_LOCK.release()


def _numba_listener():
    """A listener of numba's ``numba:compiler_lock`` event that times it on every running clock."""
    from numba.core import event

    began = threading.local()  # .stack: the clocks each open event of the thread began on

    class Listener(event.Listener):
        def on_start(self, _event):
            clocks = _ACTIVE
            began.__dict__.setdefault("stack", []).append(clocks)
            for clock in clocks:
                clock._start()

        def on_end(self, _event):
            stack = began.__dict__.get("stack")
            for clock in stack.pop() if stack else ():  # (those its start began on: a clock since started has none)
                clock._end()

    listener = Listener()
    event.register("numba:compiler_lock", listener)
    return listener


def _hooks_on(clock: CompileClock) -> None:
    """``clock`` running: the import hook on with the first clock, numba's listener where wanted."""
    global _ACTIVE, _REAL_IMPORT, _LISTENER
    with _HOOKS_LOCK:
        before = _ACTIVE
        try:  # (whatever it raises, a Ctrl-C while numba's first import runs: the hooks as they were)
            _ACTIVE = (*before, clock)
            # (wrapped; again where the import statement is what this hook called, a library's hook put
            # over it since taken off: not where another hook may still call this one under it)
            now = builtins.__import__
            if not _is_hook(now) and (_REAL_IMPORT is None or now is _REAL_IMPORT):
                _REAL_IMPORT, builtins.__import__ = now, _timed_import
            if _LISTENER is None and _wants_numba():  # (else on as numba's first import ends: _timed_import)
                with suppress(ImportError):  # (numba does not import: the import hook alone)
                    _LISTENER = _numba_listener()
        except BaseException:
            _ACTIVE = before
            if not before:
                _unhook()
            raise


def _hooks_off(clock: CompileClock) -> None:
    """``clock`` stopped: with the last one, the hooks off (the import statement's as it was; a
    hook another library put over it since stays, and this one under it passes calls through)."""
    global _ACTIVE
    with _HOOKS_LOCK:
        left = list(_ACTIVE)
        left.remove(clock)
        _ACTIVE = tuple(left)
        if not _ACTIVE:
            _unhook()


def _unhook() -> None:
    """The hooks off, no clock running (``_HOOKS_LOCK`` held)."""
    global _REAL_IMPORT, _LISTENER
    if _LISTENER is not None:
        from numba.core import event

        event.unregister("numba:compiler_lock", _LISTENER)
        _LISTENER = None
    if _is_hook(builtins.__import__):  # (this load's hook, or an earlier load's)
        builtins.__import__, _REAL_IMPORT = _REAL_IMPORT or _builtin_import, None


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
