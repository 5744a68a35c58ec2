"""How a ``tlm`` command ends: its signals, its one line on stderr and its exit status.

Bad input of any kind ends with one line on stderr (``tlm: error: ...``) and exit
status 2, never a traceback; a model that cannot finish (:class:`~tlm.arch.units.Deadlock`,
naming each blocked unit) ends with its message on one line, cut to a few hundred characters (the
whole message in the traceback file it names: :func:`tlm.cli_failed.deadlock_line`), and exit status 1,
and so does a failure of the machine (a full disk, a read-only destination: :class:`~tlm.errors.EnvironmentFailure`).
Ctrl-C (SIGINT) exits with 130, SIGTERM with 143 and SIGHUP (a terminal closed) with 129, after the
command removed what it had half written (a signal the process inherited ignored stays ignored); a
second signal during that clean-up ends the process at once, with one line of its own (and none from
multiprocessing: its semaphores are released first). A signal whose interrupt got lost (raised where
Python ignores exceptions: an at-fork hook, a ctypes callback) stops the command at its next
checkpoint (the top of a render's batch, a photon chunk, a sweep's point:
:func:`tlm.progress.checkpoint`) as if it had landed; one lost after the last checkpoint, or that
came as the command ended, exits with 130 / 143 all the same, saying that the command ran to its
end: what it wrote is whole, and kept; so does one that comes later, while the process exits (its
pools' clean-up, its threads joined: :func:`until_exit`). Anything else (a bug) prints one line and
the path of a file holding the full traceback, exit 1. A reader of stdout that goes away (``tlm
params | head -1``) ends the command quietly (status 141, as if killed by SIGPIPE), once it has
finished the folder it writes, if it writes one; a reader of stderr that goes away stops nothing
(:func:`tlm.cli_streams.guard_streams`). A MemoryError is ``tlm: error: out of memory: ...``, exit 1
(:func:`tlm.errors.memory_problem`), and so is a thread the system refused (``tlm: error: no new
thread could be started: ...``, :func:`tlm.errors.thread_problem`); OpenBLAS runs on one thread
(:func:`one_blas_thread`), its buffers mapped as a command that writes files begins
(:func:`blas_buffer_mapped`), and a MemoryError that Python ignored prints no traceback
(:func:`_without_lost_interrupts`). SIGQUIT is left to Python's default (the process ends at once, no
clean-up). A signal that comes before the command begins (while the ``tlm`` process imports its
modules and builds its parser, a second or more under load) is the command's too, from this module's
import on (:func:`early_signals`: tlm.cli and tlm.__main__ import it first, and it installs its
handler before its own imports): the command stops as it begins, with the same line and exit status,
not a traceback of a half-finished import.
"""

# ruff: noqa: E402  (the early handler is installed before this module's other imports: see early_signals)

from __future__ import annotations

import os
import signal
import sys
from contextlib import contextmanager, suppress

from tlm import cli_streams  # (the standard library's alone: no import of tlm's runs before early_signals)
from tlm.cli_streams import guard_streams, no_stream_closed, writes_files  # noqa: F401  (writes_files: tlm.cli's)

_SIGNALS: list[int] = []  # the signals received by this command, the first one first
# the signals the command takes (SIGHUP: its terminal closed, its ssh dropped; none on Windows), each with
# Python's default handler for it
_TAKEN = tuple((getattr(signal, n), signal.default_int_handler if n == "SIGINT" else signal.SIG_DFL)
               for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n))
TAKEN = tuple(s for s, _ in _TAKEN)
# the names its line gives each one (tlm: interrupted, tlm: terminated (SIGTERM), tlm: hung up (SIGHUP))
_SAID = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated (SIGTERM)"}
if hasattr(signal, "SIGHUP"):
    _SAID[signal.SIGHUP] = "hung up (SIGHUP)"
BLAS_THREADS = "OPENBLAS_NUM_THREADS"  # OpenBLAS's threads (numpy's, scipy's), read as its library is loaded


def _early_signal(signum, frame) -> None:
    """SIGINT / SIGTERM / SIGHUP in the ``tlm`` process before its command began (:func:`early_signals`):
    the first is noted, and raised as the command begins (:func:`signals`: its line, 130 / 143 / 129),
    so that no import is cut in two and no traceback is printed; a second ends the process at
    once, as during a command's clean-up (:func:`on_signal`; nothing has begun that needs one)."""
    if _SIGNALS:
        line = b"tlm: interrupted again: stopping now\n"
        with suppress(OSError):
            os.write(2, b"\n" + line if os.isatty(2) else line)
        os._exit(128 + _SIGNALS[0])
    _SIGNALS.append(signum)


def command_process() -> bool:
    """Whether this process is a ``tlm`` command's own: its main module is the ``tlm`` script
    (``[project.scripts]``: a file of that name, less what the script itself strips, ``-script.pyw``
    or ``.exe``; on Windows a zip of that name runs its ``__main__.py``), ``tlm.__main__``
    (``python -m tlm``) or ``tlm.cli`` (``python -m tlm.cli``). Not a process that imports tlm
    (a notebook, a test), nor a child of the command (a sweep's worker, Dask's: multiprocessing's
    spawn runs the parent's main file as ``__mp_main__``, under a main module of its own that has
    no file, though with the parent's ``sys.argv``)."""
    main = sys.modules.get("__main__")
    if main is None or getattr(main, "__name__", None) != "__main__":
        return False
    mp = sys.modules.get("multiprocessing")
    if mp is not None and mp.parent_process() is not None:
        return False
    spec = getattr(main, "__spec__", None)
    if spec is not None and spec.name != "__main__":
        return spec.name in ("tlm.__main__", "tlm.cli")
    path = getattr(main, "__file__", None)
    if not isinstance(path, str):
        return False
    if spec is not None:  # (a zip run as a script, its __main__.py inside)
        path = os.path.dirname(path)
    name = os.path.basename(path)
    for end in ("-script.pyw", ".exe"):
        if name.endswith(end):
            name = name[:-len(end)]
            break
    return name == "tlm"


def early_signals() -> None:
    """The ``tlm`` process's SIGINT, SIGTERM and SIGHUP handled from now on (:func:`_early_signal`), where
    Python's defaults still take them (an ignored one, as ``nohup`` leaves SIGHUP and a shell's
    background job ``&`` SIGINT, stays ignored, by the command's own handler too: :func:`signals`).
    Before, a Ctrl-C during the imports and the parser's making (the first second, under load)
    printed a KeyboardInterrupt's traceback, and a SIGTERM killed the process without a line.
    Called as this module is imported, in the command's process alone (:func:`command_process`),
    before its other imports: tlm.cli and tlm.__main__ import it first. Only Python's start (its
    ``site``) and the package's ``__init__`` come before. Main thread only."""
    for s, default in _TAKEN:
        try:
            if signal.getsignal(s) is default:
                signal.signal(s, _early_signal)
        except ValueError:  # not the main thread
            return


def one_blas_thread() -> None:
    """OpenBLAS (numpy's, and scipy's that numba loads to check for BLAS as it compiles a kernel)
    on one thread in the ``tlm`` process, unless its environment says otherwise (``OPENBLAS_NUM_THREADS``,
    read as each library is loaded: set before numpy is imported). Its threads serve nothing of tlm's (no
    product of large matrices; the kernels run on tlm's own threads, :mod:`tlm.kernels.threads`), and
    starting them takes a buffer for each: under a limit on the address space (``ulimit -v``) that
    allocation failed, and OpenBLAS retried it for ever (a hang that ignored SIGTERM) or ended the
    process with its own line (``OpenBLAS error: Memory allocation still failed ...``, exit 1). With
    one thread an allocation that fails is a MemoryError, said as ``tlm: error: out of memory: ...``
    (:func:`tlm.cli_failed.exit_status`). Inherited by the command's workers (a sweep's)."""
    os.environ.setdefault(BLAS_THREADS, "1")


BLAS_ROOM = 128 << 20  # the address space checked free before OpenBLAS's buffers (32 MiB each) and scipy's library
BLAS_ROWS = 1024  # the rows of the product that maps numpy's (OpenBLAS's gemv takes its buffer past some 250 rows)


def blas_buffer_mapped() -> None:
    """OpenBLAS's buffers mapped now, as a command that writes files begins (``tlm run``, a sweep, a
    report: its figures), while the address space is free; under a small ``ulimit -v`` (the render's
    memory taken) OpenBLAS cannot map one later, and no line of tlm's says it. numpy's OpenBLAS maps
    its buffer (32 MiB) at a thread's first product of more than some 250 rows (the image's exposure,
    the report's figures), keeps it for the thread's later products, and where it cannot, ends the
    process itself (``OpenBLAS error: Memory allocation still failed after 10 retries``, exit 1): here
    a product of :data:`BLAS_ROWS` rows on this (the main) thread maps it. scipy's own OpenBLAS
    (loaded by numba as it first loads a kernel, to check for BLAS: ``scipy.linalg``) maps its buffer
    as its library is loaded, and where it cannot, retries for ever (a hang that SIGTERM does not end):
    here its library is loaded first (:func:`_scipy_blas`). :data:`BLAS_ROOM` is mapped and unmapped
    before either, and where it cannot be the command ends as out of memory (a MemoryError: ``tlm: error:
    out of memory: ...``, :func:`tlm.cli_failed.exit_status`), before any work. A few milliseconds, numpy imported."""
    import mmap

    import numpy as np

    try:
        room = mmap.mmap(-1, BLAS_ROOM)
    except OSError as e:  # (ENOMEM)
        raise MemoryError(f"no room for OpenBLAS's buffers: {BLAS_ROOM >> 20} MiB of address space "
                          "could not be mapped") from e
    room.close()
    np.ones((BLAS_ROWS, 3)) @ np.ones(3)
    _scipy_blas()


def _scipy_blas() -> None:
    """scipy's OpenBLAS library (``scipy.libs/libscipy_openblas*.so`` of a wheel) loaded, without scipy
    (a few milliseconds, not the second that ``import scipy.linalg`` takes): scipy's modules that
    load it later find it loaded. None where scipy is not installed, or not from a wheel that bundles
    it. One that cannot be mapped is ctypes' OSError (``failed to map segment from shared object``:
    out of memory under a limit, :func:`tlm.errors.memory_problem`)."""
    import ctypes
    from importlib.util import find_spec

    try:
        spec = find_spec("scipy")
    except (ImportError, ValueError):
        return
    for place in (spec.submodule_search_locations or []) if spec is not None else []:
        for lib in sorted((Path(place).parent / "scipy.libs").glob("libscipy_openblas*.so*")):
            ctypes.CDLL(str(lib))


if command_process():
    no_stream_closed()
    one_blas_thread()
    early_signals()

import atexit
import threading
import time
import traceback
import weakref
from pathlib import Path

from tlm import progress
from tlm.errors import (
    escaped_line,
    forget_landed,
    signal_landed,
    surrogates_escaped,
)

_BARS: list[weakref.ref] = []  # the progress bars on the screen when the first signal came
_EXIT: list[int] = []  # the exit status of the process's own command, once it ended (until_exit)


def _line(text: str) -> None:
    """A line on stderr (the command's last); none where its reader went away or it cannot be written
    (``2>/dev/full``, ``2</dev/null``: the exit status is the command's all the same)."""
    with suppress(OSError):  # (a byte of a path not UTF-8 as \xff, as stdout shows it: not \udcff)
        sys.stderr.write(f"{surrogates_escaped(text)}\n")


def version() -> str:
    """``tlm X.Y.Z (Python A.B.C)``: the version of the code that runs
    (:func:`tlm.experiments.provenance.tlm_version`: a checkout's own, not an installed copy's)."""
    from tlm.api import tlm_version

    return f"tlm {tlm_version()} (Python {sys.version.split()[0]})"


def bars_drawn() -> list:
    """The progress bars (tqdm's) drawn and not yet closed: a closed or disabled bar is ``disable``."""
    tqdm_std = sys.modules.get("tqdm.std")  # (none before a command made one)
    if tqdm_std is None:
        return []
    try:
        return [b for b in list(tqdm_std.tqdm._instances) if not b.disable]
    except Exception:  # (the set changed while copied: a bar made or closed on another thread)
        return []


def on_signal(signum, frame) -> None:
    """SIGINT and SIGTERM: the first raises KeyboardInterrupt, so that what is half written
    is removed; a second one, during that clean-up, ends the process at once, with its one
    line (at a terminal, a line of its own), once its multiprocessing semaphores are
    released (else the resource tracker reports them leaked, on the same stderr); a third,
    during that release, ends it without waiting for the release. In a section that must not
    be cut in two (:func:`tlm.progress.interrupts_deferred`: a pool starting a worker) the first
    is noted and its KeyboardInterrupt raised as the section ends, and one more meanwhile is the
    same (``timeout -s INT`` signals the process, then its group: two at once)."""
    if progress.deferring():
        if not _SIGNALS:
            _SIGNALS.append(signum)
            _BARS[:] = [weakref.ref(b) for b in bars_drawn()]
            progress.signal_taken(signum)  # (raised at the section's end)
        return
    if len(_SIGNALS) > 1:
        os._exit(128 + _SIGNALS[0])
    if _SIGNALS:
        _SIGNALS.append(signum)
        line = b"tlm: interrupted again: stopping now\n"
        with suppress(OSError):  # (at a terminal on a line of its own, not after the ^C echoed or a progress bar)
            os.write(2, b"\n" + line if os.isatty(2) else line)
        executors = sys.modules.get("tlm.experiments.executors")  # (imported by a sweep, with its pools)
        if executors is not None:
            with suppress(Exception):
                executors.release_semaphores()
        os._exit(128 + _SIGNALS[0])
    _SIGNALS.append(signum)
    _BARS[:] = [weakref.ref(b) for b in bars_drawn()]
    progress.signal_taken(signum)  # (raised again at the next checkpoint, in case CPython drops this one)
    signal_landed(frame)  # (an error a C extension makes of it is known for it: tlm.errors.interrupted_by)
    raise KeyboardInterrupt


@contextmanager
def signals():
    """SIGTERM and SIGHUP handled as SIGINT is, while the command runs (main thread only); a signal whose
    interrupt got lost is raised again at the command's next checkpoint (:func:`on_signal`). In
    the process's own command, one that came before it began (:func:`early_signals`) stops it
    here, before any work: a KeyboardInterrupt as the block begins. A signal ignored when the block
    begins stays ignored (``nohup`` ignores SIGHUP, a shell's background job ``&`` SIGINT: the
    command is meant to outlive them). A reader of stdout or stderr that goes away stops nothing
    (:func:`tlm.cli_streams.guard_streams`, in the main thread): the command runs to its end, and where it was
    stdout's, its BrokenPipeError is raised as the block ends (exit status 141, :func:`tlm.cli_failed.exit_status`);
    so is a stdout that could not be written (``> /dev/full``: ``cannot write stdout: ...``, exit status 1,
    :func:`tlm.cli_streams.stdout_failure`). A stderr that cannot be written stops nothing either."""
    early = any(signal.getsignal(s) is _early_signal for s in TAKEN)
    if not early:  # (else the signal the early handler noted, if one came, is this command's)
        _SIGNALS.clear()
        _BARS.clear()
        forget_landed()
    progress.forget_signals()
    guarded = guard_streams() if threading.current_thread() is threading.main_thread() else {}
    try:
        before = {s: signal.signal(s, on_signal) for s in TAKEN if signal.getsignal(s) is not signal.SIG_IGN}
    except ValueError:  # not the main thread
        before = {}
    hook = sys.unraisablehook
    if before:
        sys.unraisablehook = quiet = _without_lost_interrupts(hook)
    try:
        if _SIGNALS:  # (noted by the early handler: the command stops before any work)
            raise KeyboardInterrupt
        yield
        out = guarded.get("stdout")
        if out is not None and out.error is not None:  # (its reader went away, or it could not be written: the
            # command ran on, to its end)
            raise out.error
    except BaseException as e:
        from tlm.errors import settle_landed

        out = guarded.get("stdout")
        if isinstance(e, SystemExit) and e.code in (0, None) and out is not None and out.error is not None:
            # (--help, --version: argparse's _print_message swallows the OSError of its write, then exits 0)
            raise out.error from None
        settle_landed(e)  # (an error a C extension made of a signal's interrupt: known for it after the block,
        raise  # whose frames the signals landed in, with every caller's locals, are let go as it ends)
    finally:
        forget_landed()  # (the frames the signals landed in, and every caller's locals: not kept past the command)
        if not command_process():  # (the process's own keeps them to its exit, which flushes them: _flushed)
            for name, stream in guarded.items():
                if getattr(sys, name) is stream:
                    setattr(sys, name, stream._stream)
        for s, h in before.items():
            if signal.getsignal(s) is not _late_signal:  # (else the process's own command ended: until_exit)
                # (the early handler's place is the late one's: the process's own command ended, until_exit follows)
                signal.signal(s, _late_signal if h is _early_signal else h)
        progress.forget_signals()  # (a checkpoint after the command, a notebook's call, raises nothing)
        if before and sys.unraisablehook is quiet:
            sys.unraisablehook = hook


def _without_lost_interrupts(hook):
    """``sys.unraisablehook`` less the KeyboardInterrupt of a signal that CPython ignored
    (raised in an at-fork hook, a ctypes callback: "Exception ignored in ..." and its traceback
    on stderr): the command's exit says it (:func:`interrupted`), in its one line. Less a
    MemoryError too (one in matplotlib's ``read_from_file_callback`` under ``ulimit -v``, FreeType
    reading a font): the call that made the callback fails in its turn, and the command's line
    says it (``tlm: error: out of memory: ...``), not a traceback above it."""
    def quiet(unraisable) -> None:
        if _SIGNALS and isinstance(unraisable.exc_value, KeyboardInterrupt):
            return
        if isinstance(unraisable.exc_value, MemoryError):
            return
        hook(unraisable)
    return quiet


def save_traceback(exc: BaseException) -> Path | None:
    """The full traceback of an unexpected exception in a file (the cache's ``tracebacks/``,
    else the temporary folder), ``tlm-traceback-<time>-<host>-<pid>.txt``: the cache may be
    shared between machines, where a pid alone names no process. Its path, or None when
    neither can be written. The file is made new, for this user alone (0600): a file or link
    already at its name (another user's, in the shared temporary folder) is not written through.
    A second error of the process in the same second gets a name of its own, ``...-<pid>-2.txt``
    (``-3``, ...: :func:`_traceback_name`), the first's file kept."""
    from tlm import storage
    from tlm.caches import cache_root

    text = surrogates_escaped(f"{version()}\ncommand: {' '.join(sys.argv)}\ncwd: {os.getcwd()}\n\n"
                              + "".join(traceback.format_exception(exc)))  # (a byte not UTF-8: \xff, as stderr's)
    name = _traceback_name(f"tlm-traceback-{time.strftime('%Y%m%d-%H%M%S')}-{storage.process_tag()}")  # <host>-<pid>
    import tempfile

    for folder in (cache_root("tracebacks"), Path(tempfile.gettempdir())):
        try:
            folder.mkdir(parents=True, exist_ok=True)
            fd = os.open(folder / name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o600)
        except OSError:
            continue
        try:
            with os.fdopen(fd, "w", encoding="utf-8", errors="backslashreplace") as f:  # (a non-ASCII message
                # or path, whatever the locale; a path of bytes not UTF-8, a surrogate, escaped)
                f.write(text)
            return folder / name
        except OSError:  # (a full disk: made, not written; no empty or cut-off traceback is left behind)
            with suppress(OSError):
                os.unlink(folder / name)
            continue
    return None


_NAMED = ["", 0]  # the last traceback file's name less its suffix, and how many of this process's it named
_NAMED_LOCK = threading.Lock()


def _traceback_name(stem: str) -> str:
    """``<stem>.txt`` for this process's first traceback file of ``stem`` (of one second), ``<stem>-2.txt`` for its
    second, ...: two errors of one second (two threads' internal errors, a deadlock's line and the error after it)
    get a file each, not the second's a name taken (it went to the temporary folder, a third's nowhere)."""
    with _NAMED_LOCK:
        _NAMED[:] = [stem, _NAMED[1] + 1 if _NAMED[0] == stem else 1]
        n = _NAMED[1]
    return f"{stem}.txt" if n == 1 else f"{stem}-{n}.txt"




def one_line(e: BaseException) -> str:
    """An exception's message on one line (its type's name where it has none), its control
    characters escaped (a NUL byte of a file's name as ``\\x00``, an escape sequence as ``\\x1b[...``):
    what a line of the command names, from a file or the command line, is shown, not obeyed by the
    terminal or dropped by it."""
    return escaped(str(e)) or type(e).__name__


def escaped(text: str) -> str:
    """``text`` on one line (its whitespace one space), its control characters escaped as
    :func:`one_line`'s are (:func:`tlm.errors.escaped_line`): a line that names a path or a value the
    user gave (an ``--out`` with an escape sequence in its name, in a machine's error such as ``cannot
    write``; a scene's name in a warning) shows it. ``tlm: error:``, ``tlm: warning:`` and ``tlm: plots:``
    lines alike."""
    return escaped_line(text)


def signalled() -> int | None:
    """The first signal (SIGINT or SIGTERM) the running command received, None if none. Its
    KeyboardInterrupt may never have reached the command: raised where CPython ignores
    exceptions (an at-fork hook, an llvmlite ctypes callback during a compilation, a
    ``__del__``), it is dropped and the command goes on, to its next checkpoint
    (:func:`tlm.progress.checkpoint`), where it stops; or, lost after the last one, to its end,
    and its exit says so (:func:`interrupted`)."""
    return _SIGNALS[0] if _SIGNALS else None


class Interrupted(KeyboardInterrupt):
    """A signal's interrupt that says what the command kept: ``kept``, the rest of its one line
    (``tlm: terminated (SIGTERM) while writing the report: the run in runs/x is kept, whole; ...``,
    :func:`interrupted`). Raised from the KeyboardInterrupt of a stage whose output is apart from
    what the command wrote before it (the report a run, sweep or study writes at its end: the line
    says what is kept and what to type to write the report, :func:`tlm.cli._report_interrupted`)."""

    def __init__(self, kept: str) -> None:
        super().__init__(kept)
        self.kept = kept


def interrupted(argv: list[str] | None, finished: bool = False, kept: str | None = None) -> int:
    """The command was interrupted (SIGINT or SIGTERM): its line, and 128 + the signal.
    ``finished``: the command ran to its end all the same (its interrupt was lost, or came as
    it returned), so what it wrote is whole and stays: the line says so. ``kept``: what the
    command kept, and how to finish it, said after the signal (:class:`Interrupted`)."""
    sig = _SIGNALS[0] if _SIGNALS else signal.SIGINT
    if argv is None and _SIGNALS:  # the process's own command: a second signal during the
        until_exit(128 + sig)  # interpreter's exit (its pools' clean-up) ends it at once
    _line(_interrupted_line(sig, finished, kept))
    return 128 + sig


def _interrupted_line(sig: int, finished: bool, kept: str | None = None) -> str:
    line = f"tlm: {_SAID.get(sig, f'terminated ({signal.Signals(sig).name})')}"
    if kept:
        line += f" {kept}"
    elif finished:
        line += ", but the command ran to its end: its output is complete"
    return line_break(sig) + line


def until_exit(status: int) -> int:
    """The process's own command (``tlm``, ``python -m tlm``: :func:`tlm.cli.main` with no argv)
    ended with ``status``: from now until the process exits, a SIGINT / SIGTERM is still the
    command's. The interpreter's exit takes a while (its threads joined, its pools' workers
    ended by the exit handlers, then its modules' teardown, where CPython has put the default
    handlers back: a signal there killed the process, with no line): a first signal now says
    that the command ran to its end (its output is complete) and the exit status is 128 + it,
    once that clean-up is done (:func:`_late_signal`); a second ends the process at once, as
    during a command's clean-up (:func:`on_signal`). The process ends when the interpreter's
    exit handlers have run, its stdout and stderr flushed, before the modules' teardown
    (:func:`_end`). ``status``, returned. Never for a library call (``tlm.api``, or ``main``
    given its argv): no handler of the whole process outlives the call there."""
    try:
        for s in TAKEN:
            if signal.getsignal(s) is not signal.SIG_IGN:  # (ignored by the command: still, signals)
                signal.signal(s, _late_signal)
    except ValueError:  # not the main thread: the interpreter's exit is not this command's
        return status
    if not _EXIT:
        atexit.register(_end)  # (the last registered: the first run, before those of the command's pools)
    _EXIT[:] = [status]
    return status


def _late_signal(signum, frame) -> None:
    """SIGINT / SIGTERM once the process's own command ended (:func:`until_exit`): the first
    is noted (the exit status is 128 + it) and said, the clean-up goes on; a later one is a
    second signal (:func:`on_signal`: the process ends at once)."""
    if _SIGNALS:
        on_signal(signum, frame)  # (a second: never returns)
    _SIGNALS.append(signum)
    _say(_interrupted_line(signum, finished=True))


def _say(text: str) -> None:
    """A line on stderr from a signal handler: through ``sys.stderr``, else (a write to it was
    under way where the signal landed: a reentrant call) straight to its file descriptor."""
    try:
        _line(text)
        sys.stderr.flush()
    except Exception:
        with suppress(OSError):
            os.write(2, f"{surrogates_escaped(text)}\n".encode())  # (a surrogate escaped, \xff, as stderr does)


def _end() -> None:
    """The process's own command ended (:func:`until_exit`): its exit, at the interpreter's exit
    handlers (this one registered last, so run first). It runs the others (the pools'
    clean-up, the workers ended: the signal handler of :func:`until_exit` still in place),
    flushes stdout and stderr, and ends the process with the command's exit status (128 + the
    signal that came meanwhile, if one did), leaving out the modules' teardown, where a signal
    could only kill the process (the interpreter has put the default handlers back by then).
    Where it cannot run each of the others once (:func:`_others_once`) it leaves them, and the
    exit, to the interpreter."""
    if not _others_once():
        atexit.unregister(_end)
        return
    status = _EXIT[0] if isinstance(_EXIT[0], int) else int(_EXIT[0] is not None)  # (as sys.exit takes it)
    try:
        with suppress(BaseException):  # (each handler's exception is reported, as at any exit)
            atexit._run_exitfuncs()  # (private: see _others_once)
        status = _flushed(status)
        signals = {s for s in TAKEN if signal.getsignal(s) is not signal.SIG_IGN}
        with suppress(ValueError, OSError):  # from here a signal waits (pending), to be taken below
            signal.pthread_sigmask(signal.SIG_BLOCK, signals)
        pending = sorted(signal.sigpending() & signals)
        if pending and not _SIGNALS:
            _SIGNALS.append(pending[0])
            _say(_interrupted_line(pending[0], finished=True))
        elif pending:  # (a second signal: the process is ending anyway)
            _say("tlm: interrupted again: stopping now")
        with suppress(Exception):
            sys.stderr.flush()
    finally:
        os._exit(128 + _SIGNALS[0] if _SIGNALS else status)  # (no handler runs between this test and the exit)


class _Seen:
    """Equal to nothing, it notes each exit handler ``atexit.unregister`` compares with it: the
    handlers registered, in the order they were (it compares with ``==``, as documented; a
    function's own ``==`` gives way to this one's)."""

    __hash__ = None

    def __init__(self) -> None:
        self.handlers: list = []

    def __eq__(self, other) -> bool:
        self.handlers.append(other)
        return False


def _others_once() -> bool:
    """Whether :func:`_end` can run the other exit handlers now, each once, and end the process
    before the modules' teardown: then :func:`_end` is unregistered, and so is each handler
    registered after it, which the interpreter has run already (it runs the last registered
    first, and unregisters none as it goes: a handler registered once the command ended, as a
    ``weakref.finalize`` made then registers one, ran twice). No public call runs the exit
    handlers (the ``atexit`` module registers and unregisters them; only the interpreter's
    exit runs them, and its modules' teardown follows, where a signal can only kill the
    process), so :func:`_end` calls ``atexit._run_exitfuncs``, the one the interpreter's exit
    calls, which every CPython 3 has. False (the interpreter runs them, each once, and the
    teardown, as at any exit) where it is missing, or where a function registered after
    :func:`_end` was registered before it too (``atexit.unregister`` unregisters a function's
    every registration, and the earlier one has not run yet)."""
    if not callable(getattr(atexit, "_run_exitfuncs", None)):
        return False
    seen = _Seen()
    atexit.unregister(seen)  # (compares each handler with it, unregistering none)
    mine = [i for i, f in enumerate(seen.handlers) if f is _end]
    before, after = (seen.handlers[:mine[-1]], seen.handlers[mine[-1] + 1:]) if mine else (seen.handlers, [])
    try:
        if any(f == g for f in after for g in before):  # (as atexit.unregister compares them)
            return False
    except Exception:  # (a handler's own == that fails)
        return False
    atexit.unregister(_end)
    for f in after:
        atexit.unregister(f)
    return True


def _flushed(status: int) -> int:
    """``status`` once stdout and stderr are flushed (what the interpreter's exit would do,
    left out by :func:`_end`): 141 where the reader of stdout went away (as for ``tlm params |
    head -1``, :func:`tlm.cli_failed.exit_status`), 1 with its line where it could not be written (a full disk:
    ``tlm: error: cannot write stdout: no space left on device``, :func:`tlm.cli_streams.stdout_failure`)."""
    if cli_streams._GONE.get("stdout") and status == 0:  # (its reader went away during the command: guard_streams)
        status = 128 + signal.SIGPIPE
    streams = [sys.stdout, sys.__stdout__, sys.stderr, sys.__stderr__]
    for stream in dict.fromkeys(s for s in streams if s is not None):
        try:
            stream.flush()
        except BrokenPipeError:
            if stream in (sys.stdout, sys.__stdout__) and status == 0:
                status = 128 + signal.SIGPIPE
            with suppress(Exception):  # (the interpreter's own flush at the exit: nothing left to fail)
                cli_streams._to_devnull(stream.fileno())
        except OSError as e:
            if stream in (sys.stdout, sys.__stdout__) and status == 0:
                _say(f"tlm: error: {escaped(str(cli_streams.stdout_failure(e)))}")
                status = 1
        except Exception:  # (a closed stream: nothing to flush)
            pass
    return status



def forget_lost_interrupt() -> None:
    """Called just before ``python -m tlm`` exits: its exit status is the one ``main``
    returned. A KeyboardInterrupt that left an ``exec`` of a string (dataclasses', namedtuple's
    and numba's generated source: a signal landing there) sets CPython's "unhandled
    KeyboardInterrupt" flag (pythonrun.c ``run_eval_code_obj``), which the command's catching
    the interrupt later does not clear; ``python -m`` (``Py_RunMain``) then ends the
    process with ``kill(getpid(), SIGINT)`` whatever ``sys.exit`` said: 130 after a SIGTERM,
    killed by SIGINT rather than exiting 130 after a Ctrl-C. Each ``exec`` of a string resets
    the flag first, so one that runs to its end clears it. (The installed ``tlm`` script
    exits through ``Py_Exit``, which never reads the flag: the two ways now end alike, a
    Ctrl-C with exit status 130, as before where the interrupt passed through no ``exec``.) Where
    too little memory is left to compile that string (a MemoryError, or under ``ulimit -v`` a SystemError,
    ``exec`` returned NULL without setting an exception), the flag stays as it is: the command has ended,
    and its exit is not to be a traceback."""
    with suppress(MemoryError, SystemError):
        exec("None")


def line_break(sig: int) -> str:
    """``"\n"`` where stderr is a terminal and its cursor is not at the start of a line, so
    that the interrupted line is a line of its own: after the ``^C`` the terminal echoed
    (SIGINT), or after a progress bar still drawn. Nothing where a bar drawn when the signal
    came has been closed since (its close ends its line: tqdm writes ``\n``, or ``\r`` after
    clearing it), and nothing through a pipe or into a file."""
    try:
        if not sys.stderr.isatty():
            return ""
    except (AttributeError, ValueError):  # (no stderr, or a closed one)
        return ""
    if bars_drawn():
        return "\n"
    if any((bar := ref()) is None or bar.disable for ref in _BARS):  # (one collected was closed by its __del__)
        return ""
    return "\n" if sig == signal.SIGINT else ""
