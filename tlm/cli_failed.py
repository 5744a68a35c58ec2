"""A command that raised: its one line on stderr and its exit status (:func:`exit_status`).

Split out of :mod:`tlm.cli_signals`, which keeps the signals and the process's exit; the names
of that module this one calls are looked up on it at each call (``cli_signals._line``), so that
what replaces one there (a test's stand-in) is what runs here too.

A command that ran out of memory (a MemoryError: ``tlm: error: out of memory: ...``) and is the
process's own ends at once after its line (:func:`_memory_end`): what the failed work held is
let go, the exit handlers run, and the process ends before the interpreter joins its threads.
That join, and the exit handlers after it, allocate: with the memory still short (under
``ulimit -v``) they printed their own MemoryError tracebacks after tlm's line ("Exception ignored
in: <module 'threading'>"), and a pool's worker thread left waiting for work that its
wake-up could no longer be queued for kept the join, and the process, waiting for ever."""

from __future__ import annotations

import gc
import os
import signal
import sys
import threading
import traceback
from contextlib import suppress
from typing import TYPE_CHECKING

from tlm import cli_signals, cli_streams
from tlm.errors import (
    ERROR_CHARS,
    InputError,
    environment_problem,
    error_line,
    interrupted_by,
    memory_problem,
    thread_problem,
)

if TYPE_CHECKING:  # (imported where used: tlm.api is the heavy part of a command's imports)
    from tlm.api import Deadlock

__all__ = ["deadlock_line", "exit_status"]


def deadlock_line(e: Deadlock) -> str:
    """A model that could not finish, on one line (``tlm: deadlock: ...``; a cap hit,
    :class:`MaxEventsReached`, said as such): its blocked units bounded to a few hundred
    characters (10 KB at 64 pipelines), the whole message kept in the traceback file the line
    names (:func:`~tlm.cli_signals.save_traceback`; where none can be written, the line says so)."""
    from tlm.api import MaxEventsReached

    text = cli_signals.one_line(e)
    if len(text) > ERROR_CHARS:
        kept = cli_signals.save_traceback(e)
        text = error_line(text, "no file could be written" if kept is None else str(kept))
    return f"tlm: {text}" if isinstance(e, MaxEventsReached) else f"tlm: deadlock: {text}"


def exit_status(e: Exception | KeyboardInterrupt, argv: list[str] | None) -> int:
    """The exit status of a command that raised ``e``, once its one line is on stderr
    (``argv``: the command's, None for the process's own). The process's own command that failed
    (exit status 1 or 2) is ended as one that returned is: a signal until the process exits
    says that the command ran to its end and the exit status is 128 + it
    (:func:`~tlm.cli_signals.until_exit`); one that ran out of memory ends now (:func:`_memory_end`)."""
    try:
        status = _failed(e, argv)
    except MemoryError:  # (under ``ulimit -v``, too little left even to say it: the shortest line, no traceback)
        with suppress(OSError):
            os.write(2, b"tlm: error: out of memory\n")
        status = 1
    if argv is not None:
        return status
    status = cli_signals.until_exit(status)
    if status == 1 and cli_signals._EXIT and threading.current_thread() is threading.main_thread() \
            and _out_of_memory(e):  # (the process's own, on its main thread: until_exit registered the end)
        _memory_end(e)
    return status


def _out_of_memory(e: BaseException) -> bool:
    """Whether ``e`` is a shortage of memory (its line says ``out of memory``) or of threads (``no new
    thread could be started``: under ``ulimit -v`` a thread's stack that could not be mapped; the pool's
    calls still in flight, joined at the interpreter's exit, went on loading kernels and ended the
    process after tlm's line in LLVM's abort or a segmentation fault)."""
    try:
        return isinstance(e, MemoryError) or memory_problem(e) is not None or thread_problem(e) is not None
    except MemoryError:
        return True


def _memory_end(e: BaseException) -> None:
    """End the process's own command that ran out of memory, now: the frames its error passed
    through let go (their arrays), a collection, then :func:`tlm.cli_signals._end` (the exit
    handlers, stdout and stderr flushed, ``os._exit`` with the command's status) before the
    interpreter's exit joins the threads. Where that cannot be done, the interpreter's exit as
    at any end."""
    with suppress(BaseException):
        traceback.clear_frames(e.__traceback__)  # (the frames still running are left: the command's own)
        for linked in (e.__cause__, e.__context__):
            if linked is not None:
                traceback.clear_frames(linked.__traceback__)
        gc.collect()
    cli_signals._end()  # (never returns where it can run the handlers; else leaves the exit to the interpreter)


def _failed(e: Exception | KeyboardInterrupt, argv: list[str] | None) -> int:
    """:func:`exit_status`, but for a signal until the process exits."""
    from tlm.api import Deadlock

    line = cli_signals._line
    if isinstance(e, InputError):
        line(f"tlm: error: {cli_signals.one_line(e)}")
        return 2
    if isinstance(e, Deadlock):  # the model could not finish: nothing is written, no partial numbers
        line(deadlock_line(e))
        return 1
    if isinstance(e, KeyboardInterrupt):
        return cli_signals.interrupted(argv, kept=getattr(e, "kept", None))
    broken = cli_streams._broken_streams() if isinstance(e, BrokenPipeError) else []
    if broken:  # the reader of stdout (or stderr) went away (``| head``): nothing more to say
        for name in broken:  # so that the exit's flush does not fail again
            with suppress(Exception):
                cli_streams._to_devnull(getattr(sys, name).fileno())
        return 128 + signal.SIGPIPE
    if interrupted_by(e) is not None:  # (Ctrl-C inside a compiled kernel's callback: a SystemError; inside
        # a C extension's call into Python, one that made it an error of its own: nanobind's TypeError)
        return cli_signals.interrupted(argv)
    what = environment_problem(e) or memory_problem(e) or thread_problem(e)
    if what is not None:  # the machine's fault: a full disk, a read-only destination, too little memory, no thread
        line(f"tlm: error: {cli_signals.escaped(what)}")  # (a path of the user's in it: its control characters escaped)
        return 1
    try:
        saved = cli_signals.save_traceback(e)
    except MemoryError as m:  # (under ``ulimit -v``: the traceback's text, tlm's version read from its metadata)
        line(f"tlm: error: {memory_problem(m)}, as the command ended with {type(e).__name__}: "
             f"{cli_signals.one_line(e)}")
        return 1
    where = f"full traceback in {saved}" if saved else "the traceback could not be saved"
    line(f"tlm: internal error: {type(e).__name__}: {cli_signals.one_line(e)} ({where})")
    return 1
