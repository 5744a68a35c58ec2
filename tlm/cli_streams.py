"""The ``tlm`` command's stdout and stderr: guarded, so that a reader that goes away stops nothing.

A reader of stdout that goes away (``tlm params | head -1``) ends a command that only prints at
once, quietly (exit status 141, as if killed by SIGPIPE); one that writes a destination (``tlm run
... | head``: :func:`writes_files`, a claim of its folder) runs to its end, what it prints from
then on dropped, and exits with 141 once its folder is whole. A stdout that cannot be written (a full disk,
``> /dev/full``) is the same but for its end: ``tlm: error: cannot write stdout: ...``, exit status 1
(:func:`stdout_failure`). A reader of stderr that goes away, or a stderr that cannot be written
(``2>/dev/full``, ``2</dev/null``), stops nothing: the command's warnings and lines are lost, to no one, its
work and exit status its own (:class:`_Guarded`, made by :func:`guard_streams` as a command begins). A line
the stream cannot encode (a path of bytes not UTF-8,
``run_\\udcff`` as Python reads it, printed to a stdout that refuses surrogates: a UTF-8 locale other than
``C.UTF-8``, ``PYTHONIOENCODING=utf-8``) is written with the byte escaped, ``run_\\xff`` (:func:`_writable`), where
it raised UnicodeEncodeError and the command ended as an internal error, its files written; stderr writes such a
byte so always (:func:`_bytes_shown`: Python's stderr wrote ``run_\\udcff``). Where stdout or
stderr was closed as the process started (``2>&-``) it is ``/dev/null`` (:func:`no_stream_closed`). How the
command then ends (its exit status, its last line) is :mod:`tlm.cli_signals`', which re-exports these names: a test's
``monkeypatch.setattr(cli_signals, "_writing", ...)`` reaches the code here.

Only the standard library is imported: :mod:`tlm.cli_signals` imports this module before it takes
the command's early signals (:func:`tlm.cli_signals.early_signals`), as the process starts.
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Iterator
from contextlib import contextmanager, suppress


def no_stream_closed() -> None:
    """stdout or stderr closed as the ``tlm`` process started (``2>&-``: Python then has no
    ``sys.stderr``, and the next file the command opened took its file descriptor, with what a
    library writes there) made ``/dev/null``: what is said there is lost, the command goes on."""
    for name, fd in (("stdout", 1), ("stderr", 2)):
        if getattr(sys, name) is not None:
            continue
        try:
            os.fstat(fd)
        except OSError:  # (closed: /dev/null takes its place)
            with suppress(OSError):
                devnull = os.open(os.devnull, os.O_WRONLY)
                if devnull != fd:
                    os.dup2(devnull, fd)
                    os.close(devnull)
        with suppress(OSError):  # (else another file took it already: the stream alone is /dev/null)
            target = fd if os.path.samestat(os.fstat(fd), os.stat(os.devnull)) else os.devnull
            setattr(sys, name, open(target, "w", buffering=1, closefd=target != fd,  # noqa: SIM115
                                    encoding="utf-8", errors="backslashreplace"))



_GONE: dict[str, bool] = {}  # the streams (stdout, stderr) whose reader went away during the command


class _Guarded:
    """stdout or stderr (``name``), whose reader going away (``tlm run ... | head``, ``2>&- | ...``: a
    BrokenPipeError) stops nothing (stdout's: while the command writes a destination, :func:`_writing`;
    else its BrokenPipeError ends the command at once, quietly): what it writes there from then on is dropped
    (its file descriptor now leads to ``/dev/null``, so a library's own writes are dropped too),
    the command runs to its end and writes its files, its report. The stream is noted
    (:data:`_GONE`) and the first BrokenPipeError kept (``error``): a reader of stdout gone ends
    the command with exit status 141 once its work is done, as if SIGPIPE had ended it
    (:func:`tlm.cli_signals.signals`, :func:`tlm.cli_signals._flushed`); one of stderr changes
    nothing (its warnings and lines are lost, to no one). Any other error writing the stream is
    :meth:`_failed`'s: stderr's stops nothing, stdout's ends the command as its reader gone does, but
    with exit status 1 and its line (:func:`stdout_failure`). Text the stream cannot encode is written escaped
    (:func:`_writable`). Anything else is the stream's."""

    def __init__(self, stream, name: str) -> None:
        self._stream = stream
        self._name = name
        self.error: OSError | None = None  # (stdout's first: a BrokenPipeError, or a failure, stdout_failure)

    def _failed(self, e: OSError) -> None:
        """A write (or flush) of the stream that raised ``e``. A reader gone (a BrokenPipeError): :meth:`_gone`.
        Any other error writing stderr (a full disk, ``2>/dev/full``; a file descriptor open for reading,
        ``2</dev/null``) stops nothing either: what it writes from then on is dropped (stderr is the human's
        channel: losing it changes neither the work nor the exit status); one that says a stream set non-blocking
        is full this moment (a BlockingIOError) drops this text alone. One writing stdout is a failure to write
        the command's output (:func:`stdout_failure`, kept in ``error``), stdout dropped from then on. Either
        of stdout's ends a command that only prints (its stdout is its output) at once, raised here, and one that
        writes a destination (:func:`_writing`: its files are its output, its stdout their summary) once its
        work is done, raised by :func:`tlm.cli_signals.signals`."""
        if isinstance(e, BrokenPipeError):
            self._gone(e)
            failed: OSError = e
        elif self._name == "stderr":
            if not isinstance(e, BlockingIOError):
                self._dropped()
            return
        else:
            failed = stdout_failure(e)
            if self.error is None:
                self.error = failed
            self._dropped()
        if self._name == "stdout" and not _writing():
            if failed is e:
                raise e
            raise failed from e

    def _gone(self, e: BrokenPipeError) -> None:
        _GONE[self._name] = True
        if self.error is None:
            self.error = e
        self._dropped()

    def _dropped(self) -> None:
        """What the stream writes from now on dropped: its file descriptor led to ``/dev/null``, what was
        buffered flushed there."""
        with suppress(Exception):
            _to_devnull(self._stream.fileno())
        with suppress(Exception):  # (what was buffered goes to /dev/null now)
            self._stream.flush()

    def write(self, text):
        try:
            try:
                if self._name == "stderr" and isinstance(text, str):  # (a byte of a path not UTF-8 as stdout, a CSV
                    self._stream.write(_bytes_shown(text))  # cell, a figure show it, \xff: not Python's \udcff)
                    return len(text)
                return self._stream.write(text)
            except UnicodeEncodeError:  # (encoded whole before any of it is written: nothing written twice)
                self._stream.write(_writable(text, getattr(self._stream, "encoding", None)))
                return len(text)
        except OSError as e:
            self._failed(e)
            return len(text)

    def writelines(self, lines) -> None:
        for line in lines:
            self.write(line)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except OSError as e:
            self._failed(e)

    def __getattr__(self, name):
        return getattr(self._stream, name)

    def __iter__(self):
        return iter(self._stream)


def stdout_failure(e: OSError) -> OSError:
    """What ``e``, an error writing stdout (not its reader gone), says: ``cannot write stdout: no space left on
    device`` (``> /dev/full``; ``bad file descriptor``: ``1</dev/null``), a :class:`tlm.errors.EnvironmentFailure`
    (the command's line ``tlm: error: ...``, exit status 1), not a bare ``no space left on device`` that named no
    file. ``e`` itself where it says so already. (:mod:`tlm.errors` as :mod:`tlm.cli_signals` imported it, after this
    module: this one imports none of tlm's, see the module's notes; where none is, an OSError of the same words.)"""
    errors = sys.modules.get("tlm.errors")
    if str(e).startswith(STDOUT_FAILED):
        return e
    what = errors is not None and errors.environment_problem(e, filename=False)
    what = what or (e.strerror or str(e) or type(e).__name__).lower()
    return errors.EnvironmentFailure(f"{STDOUT_FAILED}: {what}") if errors is not None else OSError(
        e.errno, f"{STDOUT_FAILED}: {what}")


STDOUT_FAILED = "cannot write stdout"


_WRITES = False  # the command writes files (:func:`writes_files`, set by tlm.cli for its command)


@contextmanager
def writes_files(yes: bool) -> Iterator[None]:
    """While the block runs, the command is one that writes files (``tlm run``, ``sweep``, a study,
    ``scaling``, a report, an export), whatever it holds at the moment: a sweep shares its folder
    (:func:`tlm.claims.sharing`), which :func:`tlm.claims.holding` does not count; a run, a study, ``tlm scaling``
    and a report claim theirs (:func:`tlm.claims.claimed`, from the command or its API function), but only once
    their input is checked, and ``tlm report`` lets its claim go before its ``wrote`` line; an export claims none.
    Each prints its summary before its report; :func:`_writing` reads it."""
    global _WRITES
    before, _WRITES = _WRITES, yes
    try:
        yield
    finally:
        _WRITES = before


def _writing() -> bool:
    """Whether the command is writing a destination (one that writes files, :func:`writes_files`,
    or one holding a destination: :func:`tlm.claims.claimed`, a run's folder, a sweep's, a
    report's): then a reader of stdout that goes away stops nothing, and what it writes is
    finished; a command that only prints (``tlm params | head -1``) stops there."""
    if _WRITES:
        return True
    claims = sys.modules.get("tlm.claims")  # (imported by the commands that write a destination: none held before)
    return claims is not None and claims.holding()


def _writable(text: str, encoding: str | None) -> str:
    """``text`` as a stream of ``encoding`` that refused it writes it: each surrogate of a byte of a file name not
    UTF-8 (``os.fsdecode(b"run_\\xff")`` is ``run_\\udcff``) as ``\\xff``, as :func:`tlm.storage_json.escaped`
    writes it in a CSV cell or a figure (not imported: only the standard library is, see the module's notes), and
    any other character the encoding has not (another lone surrogate, a ``×`` to an ASCII stream) as Python's
    backslash escape (``\\ud800``, ``\\xd7``)."""
    text = _bytes_shown(text)
    encoding = encoding or "utf-8"
    try:
        return text.encode(encoding, "backslashreplace").decode(encoding)
    except LookupError:  # (an encoding Python does not know: ASCII, which every one writes)
        return text.encode("ascii", "backslashreplace").decode("ascii")


_BYTE = re.compile("[\udc80-\udcff]")


def _bytes_shown(text: str) -> str:
    """``text`` with each surrogate of a byte of a file name not UTF-8 as ``\\xff`` (:func:`_writable`); what
    stderr writes of it (Python's own stderr: ``\\udcff``, a backslash escape), as a ``tlm:`` line shows it
    (:func:`tlm.errors.escaped_line`)."""
    if not _BYTE.search(text):  # (a scan in C: a progress bar's many writes)
        return text
    return "".join(f"\\x{ord(c) - 0xDC00:02x}" if "\udc80" <= c <= "\udcff" else c for c in text)


def guard_streams() -> dict[str, _Guarded]:
    """``sys.stdout`` and ``sys.stderr`` made :class:`_Guarded`, each that is not already (and is
    not None); those made now, by name. :data:`_GONE` forgotten (a new command)."""
    _GONE.clear()
    made = {}
    for name in ("stdout", "stderr"):
        stream = getattr(sys, name)
        if stream is not None and not isinstance(stream, _Guarded):
            made[name] = _Guarded(stream, name)
            setattr(sys, name, made[name])
    return made


def _to_devnull(fd: int) -> None:
    """File descriptor ``fd`` led to ``/dev/null`` (its reader went away)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
    except OSError:
        return
    try:
        os.dup2(devnull, fd)
    except OSError:
        pass
    finally:
        os.close(devnull)


def _reader_gone(fd: int) -> bool:
    """Whether file descriptor ``fd`` is a pipe (or socket) whose reader went away: the kernel
    says POLLERR (Linux) or POLLHUP for it; False where it cannot tell (no ``poll``)."""
    import select

    if not hasattr(select, "poll"):
        return False
    try:
        poll = select.poll()
        poll.register(fd, select.POLLOUT)
        return any(ev & (select.POLLERR | select.POLLHUP) for _, ev in poll.poll(0))
    except (OSError, ValueError):
        return False


def _broken_streams() -> list[str]:
    """Of stdout and stderr, those whose reader went away (noted by :class:`_Guarded`, or said by
    the kernel of file descriptors 1 and 2): a BrokenPipeError that reached the command line is
    theirs; one of another pipe (a worker's) is an error of its own (:func:`tlm.cli_failed.exit_status`)."""
    return [name for name, fd in (("stdout", 1), ("stderr", 2)) if _GONE.get(name) or _reader_gone(fd)]

