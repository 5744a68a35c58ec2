"""The ``tlm`` command's stdout and stderr: guarded, so that a reader that goes away stops nothing.

A reader of stdout that goes away (``tlm params | head -1``) ends a command that only prints at
once, quietly (exit status 141, as if killed by SIGPIPE); one that writes a destination (``tlm run
... | head``: :func:`writes_files`, a claim of its folder) runs to its end, what it prints from
then on dropped, and exits with 141 once its folder is whole. A reader of stderr that goes away
stops nothing: the command's warnings and lines are lost, to no one (:class:`_Guarded`, made by
:func:`guard_streams` as a command begins). A line the stream cannot encode (a path of bytes not UTF-8,
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
    nothing (its warnings and lines are lost, to no one). Text the stream cannot encode is written escaped
    (:func:`_writable`). Anything else is the stream's."""

    def __init__(self, stream, name: str) -> None:
        self._stream = stream
        self._name = name
        self.error: BrokenPipeError | None = None

    def _gone(self, e: BrokenPipeError) -> None:
        _GONE[self._name] = True
        if self.error is None:
            self.error = e
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
        except BrokenPipeError as e:
            self._gone(e)
            if self._name == "stdout" and not _writing():
                raise
            return len(text)

    def writelines(self, lines) -> None:
        for line in lines:
            self.write(line)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError as e:
            self._gone(e)
            if self._name == "stdout" and not _writing():
                raise

    def __getattr__(self, name):
        return getattr(self._stream, name)

    def __iter__(self):
        return iter(self._stream)


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

