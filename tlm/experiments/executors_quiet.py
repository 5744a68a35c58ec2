"""distributed's loggers around a sweep's Dask client (:func:`tlm.experiments.executors.open_executor`): those
that only narrate connections kept below WARNING for the client's whole life (:meth:`Quiet.hush`: a lost scheduler's
"Batched Comm Closed" traceback, logged on distributed's loop thread before the sweep's poll sees the loss, would
precede tlm's one line), all of them silenced once the sweep knows its scheduler is lost or a signal ends it
(:meth:`Quiet.now`), and put back as they were after (on a signal, :data:`QUIET_GRACE` seconds later).
:mod:`tlm.experiments.executors` re-exports these names.
"""

from __future__ import annotations

import logging
import threading
import time


class Quiet:
    """distributed's loggers silenced (:meth:`now`) and put back as they were (:meth:`restore`); those that only
    narrate a connection closing, kept below WARNING (:meth:`hush`) for the sweep client's whole life."""

    left_due = 0.0  # when the loggers left silenced by the latest signal are put back (:func:`put_back_left`)

    def __init__(self) -> None:
        self.levels: dict[str, int] = {}
        self.client = None  # the sweep's Client, once connected (:meth:`before`)

    def now(self) -> None:
        with _LEFT_LOCK:
            for name in ["distributed", *logging.root.manager.loggerDict]:  # (dask's config sets its children's)
                if name == "distributed" or name.startswith("distributed."):
                    # (one left silenced after an earlier signal: its level before that, not the silence; one
                    # hushed: its level before the hush)
                    if name not in self.levels:
                        self.levels[name] = _LEFT_QUIET.pop(name, logging.getLogger(name).level)
                    logging.getLogger(name).setLevel(logging.CRITICAL + 1)

    def hush(self) -> None:
        """The loggers of :data:`NARRATING` (and their children) kept from logging below WARNING until
        :meth:`restore`: distributed's event loop thread logs a connection closed under the client as it happens
        ("Batched Comm Closed" at INFO, with its traceback), before the sweep can know its scheduler is lost and
        say so in one line (:meth:`tlm.experiments.executors.DaskPool.trouble`, then :meth:`now`). Their warnings
        and errors still reach the user; a logger already at WARNING or above (distributed.client's own, by Dask's
        config) is left."""
        with _LEFT_LOCK:
            for name in [*NARRATING, *logging.root.manager.loggerDict]:
                if name in self.levels or not any(name == n or name.startswith(n + ".") for n in NARRATING):
                    continue
                effective = _level_before(name)  # (before the pop: one left silenced, its level before)
                own = _LEFT_QUIET.pop(name, logging.getLogger(name).level)  # (as :meth:`now`)
                if own != logging.NOTSET:
                    level = max(own, logging.WARNING)
                elif name in NARRATING and effective < logging.WARNING:
                    level = logging.WARNING
                else:  # (a child: its parent's, WARNING at least now; a root already above: as it is)
                    level = logging.NOTSET
                self.levels[name] = own
                logging.getLogger(name).setLevel(level)

    def restore(self) -> None:
        for name, level in self.levels.items():
            logging.getLogger(name).setLevel(level)
        self.levels.clear()

    # A signal (SIGINT, SIGTERM, SIGHUP: a KeyboardInterrupt, tlm.cli_signals) ends the command's
    # process: its process group's signal may have killed the --dask local workers first, and
    # distributed's event loop thread, which outlives the cluster's close, then logs each
    # closed connection with its traceback ("Batched Comm Closed") after tlm's one line (the
    # cluster's own silence_logs ends with its close). Its loggers stay silenced from the
    # cluster's close for QUIET_GRACE seconds, then are put back (a Python session that
    # goes on after a Ctrl-C: a notebook's); any other end of the stack puts them back at once.

    def before(self, kind: type[BaseException] | None, *_) -> bool:
        """An ExitStack exit callback entered after the client: silence now on a signal, or where the client has
        lost its scheduler (its close logs the reconnection it cancels, with a traceback, at ERROR)."""
        if _signalled(kind) or getattr(self.client, "status", "running") != "running":
            self.now()
        return False

    def after(self, kind: type[BaseException] | None, *_) -> bool:
        """An ExitStack exit callback entered before the cluster: put the levels back, on a
        signal only :data:`QUIET_GRACE` seconds later."""
        if not _signalled(kind):
            self.restore()
            return False
        self.now()
        with _LEFT_LOCK:
            _LEFT_QUIET.update(self.levels)
            self.levels.clear()
            due = Quiet.left_due = time.monotonic() + QUIET_GRACE  # (an earlier signal's timer: not these)
        later = threading.Timer(QUIET_GRACE, put_back_left, args=(due,))
        later.daemon = True  # (a process that ends meanwhile does not wait for it)
        later.start()
        return False


QUIET_GRACE = 10.0  # seconds distributed's loggers stay silenced after a signal ended a --dask local sweep
NARRATING = ("distributed.batched", "distributed.client", "distributed.comm", "distributed.core")  # distributed's
# loggers whose INFO records, in the sweep's process, narrate connections: opened, closed (with a traceback),
# reconnecting, pooled (:meth:`Quiet.hush`)
_LEFT_QUIET: dict[str, int] = {}  # logger -> its level before the silence, for the loggers left silenced
_LEFT_LOCK = threading.Lock()


def put_back_left(due: float | None = None) -> None:
    """The levels of the loggers left silenced after a signal (:meth:`Quiet.after`), put back; by the timer of
    the signal whose grace ends at ``due``, only where no later signal has left them silenced since (a sweep
    signalled within an earlier one's grace: its grace, whole)."""
    with _LEFT_LOCK:
        if due is not None and due < Quiet.left_due:  # (the later signal's own timer puts them back)
            return
        for name, level in _LEFT_QUIET.items():
            logging.getLogger(name).setLevel(level)
        _LEFT_QUIET.clear()


def _level_before(name: str) -> int:
    """The effective level of the logger ``name`` as it was before tlm silenced any of distributed's (those left
    silenced after a signal, :data:`_LEFT_QUIET`, at their levels before; the caller holds :data:`_LEFT_LOCK`)."""
    while name:
        level = _LEFT_QUIET.get(name, logging.getLogger(name).level)
        if level != logging.NOTSET:
            return level
        name = name.rpartition(".")[0]
    return logging.root.level


def _signalled(kind: type[BaseException] | None) -> bool:
    """Whether an exception of ``kind`` ends the process on a signal (an interrupt, an exit)."""
    return kind is not None and issubclass(kind, (KeyboardInterrupt, SystemExit))
