"""Errors that reach the user.

`InputError` is raised for anything the user wrote wrong: a config, a scene file, a
mesh, a command-line value. The command line catches it, prints its one-line message
and exits with status 2; it never shows a traceback. The message always names the
file, the key and the offending value, so that the line alone says what to fix.
`EnvironmentFailure` is the machine's fault (a full disk, a read-only destination): one
line, exit status 1; so is a MemoryError (:func:`memory_problem`: ``out of memory: ...``) and
a thread the system refused (:func:`thread_problem`: ``no new thread could be started: ...``).
"""

from __future__ import annotations

import contextlib
import difflib
import errno
import os
import re
from collections.abc import Iterable, Iterator
from typing import Any

try:  # (imported now: under a small ``ulimit -v`` loading it later, as a command fails, may fail too)
    import resource
except ImportError:  # (not Unix)
    resource = None


# the control characters a line shows escaped (NUL, ESC, DEL, C1: \xNN; a tab, a newline, a carriage return as
# Python writes them, \t, \n, \r), so that a path or a name with one in it is shown, not obeyed by the terminal,
# dropped by it, or shown as a space (accents and CJK are shown as they are)
LINE_ESCAPES = {c: f"\\x{c:02x}" for c in (*range(0x20), *range(0x7f, 0xa0))} | {9: "\\t", 10: "\\n", 13: "\\r"}


def path_shown(path: object) -> str:
    """A path (or a name) the user gave, as a line names it: its control characters escaped
    (:data:`LINE_ESCAPES`: ``a\\tb.yaml``, ``\\x1b[31m``), its spaces as they are. A message that
    puts a path in a line without ``!r`` names it through this (:class:`InputError`'s ``source``, a
    failed write's folder), since :func:`escaped_line` makes a line's whitespace one space."""
    return os.fsdecode(path).translate(LINE_ESCAPES) if isinstance(path, (str, bytes, os.PathLike)) else \
        str(path).translate(LINE_ESCAPES)


_REPR_SURROGATE = re.compile(r"\\(\\|udc([89a-f][0-9a-f]))")  # (a repr's ``\\``, taken whole, or a byte's ``\udcff``)


def quoted(value: object) -> str:
    """A path or a name the user gave, quoted as a message names it: its ``repr`` (``'my runs/a.yaml'``, a
    tab as ``\\t``; a path object as its text, not ``PosixPath(...)``), a byte of a name not UTF-8 as
    ``\\xff`` (``'dir_\\xff/out'``), as a ``tlm:`` line, stdout and a CSV cell show it
    (:func:`surrogates_escaped`), not as Python's ``\\udcff``. A folder literally named with a backslash,
    ``dir_\\xff``, is ``'dir_\\\\xff'``, as ``repr`` writes it. Anything else: its ``repr``, a surrogate
    in a string of it (a list of paths) shown so too."""
    try:
        text = repr(os.fspath(value) if isinstance(value, os.PathLike) else value)
    except Exception:  # (a path object whose __fspath__ fails or gives no text: a message names it, never raises)
        text = repr(value)
    return _REPR_SURROGATE.sub(lambda m: "\\\\" if m.group(2) is None else f"\\x{m.group(2)}", text)


def escaped_line(text: str) -> str:
    """``text`` on one line (its whitespace one space), its control characters escaped
    (:data:`LINE_ESCAPES`): what ``tlm: error:``, ``tlm: warning:`` and ``tlm: plots:`` lines print
    (:func:`tlm.cli_signals.escaped`), so that a value from a file or the command line (an escape
    sequence in a scene's or a folder's name) is shown, not obeyed by the terminal. A byte of a path not
    UTF-8 is ``\\xff`` (:func:`surrogates_escaped`), as stdout, a CSV cell and a figure show it."""
    return surrogates_escaped(" ".join(text.split()).translate(LINE_ESCAPES))


_SURROGATE = re.compile("[\ud800-\udfff]")


def surrogates_escaped(text: str) -> str:
    """``text`` with each surrogate as an escape: a byte that a file name of bytes not UTF-8 holds
    (``os.fsdecode(b"run_\\xff")`` is ``run_\\udcff``) as ``\\xff``, any other lone surrogate as ``\\ud800``:
    text that UTF-8 writes (a surrogate raises UnicodeEncodeError) and a font draws. Text without one is as it
    is. (:func:`tlm.storage_json.escaped`, a CSV cell's, a figure's; a ``tlm:`` line's on stderr. A JSON or YAML
    file keeps the surrogate as its own escape instead, ``\\udcff``, read back as the same path.)"""
    # (a scan in C, text without one given back as it is; a Python call for each surrogate alone: a report page
    # of 1 MB naming such a folder, 7 ms, where a join over its characters took 170 ms)
    return _SURROGATE.sub(_surrogate_escape, text)


def _surrogate_escape(match: re.Match) -> str:
    """The escape of one surrogate (:func:`surrogates_escaped`): ``\\xff`` for a byte's, ``\\ud800`` for another."""
    code = ord(match.group())
    return f"\\x{code - 0xDC00:02x}" if 0xDC80 <= code <= 0xDCFF else f"\\u{code:04x}"


def shell_word(word: str) -> str:
    """``word`` (a path, a ``--set`` value) quoted for bash, in a command tlm prints for its user to run as
    printed: as :func:`shlex.quote` quotes it (``'my runs/a.yaml'``), but where ``shlex.quote``'s word would not
    give the word back once printed, bash's ANSI-C form, ``$'dir_\\xff/sw.yaml'``, with its ``\\`` and ``'``
    escaped: a byte not UTF-8 (Python's surrogate, ``dir_\\udcff``, which a ``tlm:`` line or stdout shows as
    ``\\xff``: :func:`surrogates_escaped`), a control character or whitespace other than a space (which
    :func:`escaped_line` escapes or makes one space), two spaces in a row (made one), each such character as its
    bytes, ``\\xHH``. (``$'...'`` is bash's, zsh's and ksh's, not a plain POSIX sh's.)"""
    import shlex

    if not any(_shown_otherwise(word, i) for i in range(len(word))):
        return shlex.quote(word)
    out = []
    for i, c in enumerate(word):
        if c in "\\'":
            out.append("\\" + c)
        elif _shown_otherwise(word, i):
            try:
                raw = os.fsencode(c)
            except UnicodeEncodeError:  # (a lone surrogate of no byte, in no file name: its UTF-8)
                raw = c.encode("utf-8", "surrogatepass")
            out.extend(f"\\x{b:02x}" for b in raw)
        else:
            out.append(c)
    return "$'" + "".join(out) + "'"


def _shown_otherwise(word: str, i: int) -> bool:
    """Whether a line shows ``word[i]`` as another text than the character (:func:`shell_word`): a surrogate, a
    control character, whitespace other than a space, a space after a space."""
    c = word[i]
    if c == " ":
        return i > 0 and word[i - 1] == " "
    return c.isspace() or ord(c) in LINE_ESCAPES or "\ud800" <= c <= "\udfff"


_KEPT = object()  # (a field of :meth:`InputError.replaced` not given: kept)


class InputError(ValueError):
    """Bad user input: one line naming the file, the key and the value. ``source`` (kept as
    given) is named as :func:`path_shown` shows a path: a tab in a file's name is ``\\t``, not a space."""

    def __init__(self, message: str, *, source: str | None = None, key: str | None = None):
        self.source = source
        self.key = key
        self.message = message
        where = ""
        if source:
            where = f"{path_shown(source)}: "
        if key:
            where += f"{key}: "
        super().__init__(f"{where}{message}")

    def under(self, section: str) -> InputError:
        """The same error, its key named below ``section`` (``base.render.spp``: a key of a run
        config given inline under ``base:``, as checked alone)."""
        return self.replaced(key=f"{section}.{self.key}" if self.key else section)

    def replaced(self, *, message: Any = _KEPT, source: Any = _KEPT, key: Any = _KEPT) -> InputError:
        """A new error like this one, the fields given replaced (``None``: no source, no key) and the
        others kept, its line made again from them as :class:`InputError` makes it (no caller takes
        the line apart by hand): of the same class, so an InputError still (exit status 2; its own
        attributes kept: :class:`tlm.claims.FolderHeld`'s ``held``), with no traceback of its own."""
        new = type(self).__new__(type(self))
        new.__dict__.update(self.__dict__)
        InputError.__init__(new, self.message if message is _KEPT else message,
                            source=self.source if source is _KEPT else source, key=self.key if key is _KEPT else key)
        return new


class EnvironmentFailure(OSError):
    """The machine, not the input, stopped the command: a full disk, a read-only or busy
    destination. The command line prints its one line and exits with status 1."""

    def __init__(self, message: str, *, source: str | None = None):
        self.source = source
        super().__init__(f"{path_shown(source)}: {message}" if source else message)

    def __str__(self) -> str:
        return self.args[0]


def check_numba_threads() -> None:
    """``NUMBA_NUM_THREADS``, checked before numba is imported, which a whole number below 1 makes
    fail (``ValueError: Number of threads specified must be > 0``): an InputError naming the variable
    (exit status 2), as a bad ``TLM_KERNELS`` or ``TLM_FORK_WORKERS`` is. One that is no number is
    numba's to warn of (it takes its default). tlm runs numba's kernels on threads of its own
    (``render.threads``): the variable is numba's, which tlm sets no default for."""
    raw = os.environ.get("NUMBA_NUM_THREADS")
    try:
        count = 1 if raw is None else int(raw)
    except ValueError:
        return
    if count < 1:
        raise InputError(f"{raw!r} is below 1: numba cannot start with it (unset it: numba's threads are the "
                         "CPUs; tlm's kernels run on render.threads)", source="environment", key="NUMBA_NUM_THREADS")


# errors of the machine, not of the input or of tlm: the disk, the file system, the limits
ENVIRONMENT_ERRNOS = frozenset(getattr(errno, n) for n in (
    "ENOSPC", "EDQUOT", "EROFS", "EACCES", "EPERM", "EBUSY", "EIO", "EMFILE", "ENFILE", "ENOMEM", "EFBIG",
    "ETXTBSY", "ENAMETOOLONG", "ESTALE") if hasattr(errno, n))


def environment_problem(e: BaseException, filename: bool = True) -> str | None:
    """What an OSError says about the machine in a few words (``no space left on device``),
    or None when it is not the machine's fault. numpy's short write (``N requested and M
    written``, no errno) is a full disk. ``filename``: with the file the OSError names."""
    if not isinstance(e, OSError):
        return None
    if isinstance(e, EnvironmentFailure):
        return str(e)
    if e.errno in ENVIRONMENT_ERRNOS:
        what = (e.strerror or os.strerror(e.errno)).lower()
        return f"{what}: {path_shown(e.filename)}" if e.filename and filename else what
    text = str(e)
    if e.errno is None and "requested and" in text and "written" in text:
        return f"a write was cut short ({text}): no space left on device?"
    return None


def chain(e: BaseException | None) -> Iterator[BaseException]:
    """``e``'s chain of causes and contexts, ``e`` first: each exception, then its ``__cause__`` or, where it has
    none, its ``__context__``, and so on, each once: the walk stops where the chain ends (``None``) or comes back
    to an exception it gave (a loop of contexts). ``e`` None gives none. The next link is read as the walk goes on
    past an exception, after its caller's turn with it (:func:`settle_landed` marks each as it comes)."""
    seen: set[int] = set()
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        yield e
        e = e.__cause__ or e.__context__


BROKEN_POOL = "BrokenProcessPool"  # concurrent.futures.process': a worker of a process pool ended abruptly
UNMAPPED = "failed to map segment from shared object"  # the dynamic loader's words for a library it could not map


def memory_problem(e: BaseException | None) -> str | None:
    """``out of memory: ...`` where a MemoryError is in ``e``'s chain of causes and contexts (a
    numba kernel's, wrapped), with what the failed allocation needed where it says (numpy's
    ``Unable to allocate 8.24 MiB for an array ...``) and the limit on the address space where one
    is set (``ulimit -v``); under such a limit, a library that could not be mapped as it was loaded
    (an ImportError or ctypes' OSError: ``... failed to map segment from shared object``, a
    module imported late, as matplotlib's for a report) is out of memory too, and so is a forked
    worker process that ended abruptly (concurrent.futures' BrokenProcessPool: numba's LLVM aborts,
    a C allocation fails, where the parent's limit is the workers' too). None where the chain holds
    none. The machine's fault, not tlm's: one line, exit status 1, as a full disk."""
    limit = address_space_limit()
    e = next((c for c in chain(e) if isinstance(c, MemoryError) or (limit is not None and (
        (isinstance(c, (ImportError, OSError)) and UNMAPPED in str(c)) or type(c).__name__ == BROKEN_POOL))), None)
    if e is None:
        return None
    text = " ".join(str(e).split())
    if type(e).__name__ == BROKEN_POOL:  # (its own words name no memory: a worker "terminated abruptly")
        text = f"a forked worker process ended abruptly ({text})"
    line = f"out of memory: {text}" if text else "out of memory"
    if limit is not None:
        line += f" (the address space of this process is limited to {limit / 2**20:.0f} MiB: ulimit -v)"
    return line


THREAD_REFUSED = "can't start new thread"  # threading's RuntimeError where the system gives no more threads


def thread_problem(e: BaseException | None) -> str | None:
    """``no new thread could be started: ...`` where threading's RuntimeError (``can't start new
    thread``) is in ``e``'s chain of causes and contexts (a render's threads, a pool's), with the
    limits that can refuse one where they are set: the address space (``ulimit -v``: each thread's
    stack is mapped in it) and the user's processes and threads (``ulimit -u``); None where the
    chain holds none. The machine's fault, not tlm's: one line, exit status 1, as out of memory."""
    if not any(isinstance(c, RuntimeError) and str(c) == THREAD_REFUSED for c in chain(e)):
        return None
    limits = []
    space = address_space_limit()
    if space is not None:
        limits.append(f"the address space of this process is limited to {space / 2**20:.0f} MiB: ulimit -v")
    threads = _limit("RLIMIT_NPROC")
    if threads is not None:
        limits.append(f"this user may run {threads} processes and threads: ulimit -u")
    said = f" ({'; '.join(limits)})" if limits else ""
    return f"no new thread could be started: {THREAD_REFUSED}{said}"


def address_space_limit() -> int | None:
    """The limit on this process's address space in bytes (``ulimit -v``, RLIMIT_AS), None where
    none is set or it cannot be read (not Unix)."""
    return _limit("RLIMIT_AS")


def _limit(name: str) -> int | None:
    """The soft limit ``name`` of ``resource`` (``RLIMIT_AS``), None where none is set or it
    cannot be read (not Unix, or a limit this system lacks)."""
    try:
        soft = resource.getrlimit(getattr(resource, name))[0]
    except (AttributeError, OSError, ValueError):  # (no resource module: AttributeError)
        return None
    return None if soft == resource.RLIM_INFINITY else soft


_LANDED: list = []  # the Python frame each signal's KeyboardInterrupt was raised in (signal_landed)
_MARK = "_tlm_interrupt"  # set on an exception found, as its command ended, to be an interrupt (settle_landed)


def signal_landed(frame) -> None:
    """The command line's signal handler raises its KeyboardInterrupt in ``frame`` (the Python frame that
    ran as the signal came: :func:`tlm.cli_signals.on_signal`), kept until :func:`forget_landed`, so that an
    exception that code outside Python made of that interrupt is known for it (:func:`interrupted_by`)."""
    if frame is not None:
        _LANDED.append(frame)


def forget_landed() -> None:
    """No signal landed (a command's start and end: :func:`tlm.cli_signals.signals`): the frames let go, and
    with them every local of the command's calls they held."""
    _LANDED.clear()


def settle_landed(e: BaseException | None) -> None:
    """As a command's block ends with ``e`` (:func:`tlm.cli_signals.signals`), before its frames are let go
    (:func:`forget_landed`): each exception of ``e``'s chain that is a signal's interrupt made into an error of
    its own (:func:`_made_of_interrupt`) is marked so, for :func:`interrupted_by` after the block."""
    for c in chain(e):
        if _made_of_interrupt(c):
            with contextlib.suppress(AttributeError, TypeError):  # (an exception that takes no attribute)
                setattr(c, _MARK, True)


def _made_of_interrupt(e: BaseException) -> bool:
    """Whether ``e`` is a signal's interrupt that code outside Python made an error of its own: it carries
    the interrupt (its ``__context__`` is one, or its text names ``KeyboardInterrupt``, as nanobind's
    ``TypeError: could not export nb::ndarray: ... KeyboardInterrupt`` does) and was raised by a call running
    when the interrupt was raised (:func:`_raised_where_landed`). A bug raised in a caller after a library
    swallowed the interrupt carries none: it is the bug."""
    if not _LANDED:
        return False
    try:
        carries = isinstance(e.__context__, KeyboardInterrupt) or "KeyboardInterrupt" in str(e)
    except Exception:  # (an exception whose str fails)
        return False
    return carries and _raised_where_landed(e)


def _raised_where_landed(e: BaseException) -> bool:
    """Whether ``e`` was raised by a call that was running when a signal's interrupt was raised
    (:func:`signal_landed`): the innermost frame of its traceback (where it was raised, or the Python
    frame that called the C function that raised it) is the frame the signal landed in or one of its
    callers. An exception raised before the signal came, and being handled when it came, is not:
    its innermost frame had ended by then."""
    tb = e.__traceback__
    if tb is None or not _LANDED:
        return False
    while tb.tb_next is not None:
        tb = tb.tb_next
    for frame in _LANDED:
        while frame is not None:
            if frame is tb.tb_frame:
                return True
            frame = frame.f_back
    return False


def interrupted_by(e: BaseException | None) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt (Ctrl-C, or SIGTERM, which the command line turns into one) in
    ``e``'s chain of causes and contexts, where something wrapped it: a signal that arrives
    while a compiled numba kernel calls back into Python ends as a ``SystemError`` caused by
    the interrupt. An exception of the chain that a C extension made of the interrupt
    (:func:`_made_of_interrupt`: it carries the interrupt, in its text or context, and was raised by
    a call running when the command line's handler raised it; marked so where the command's block
    ended first, :func:`settle_landed`) is that interrupt too, though it does not hold it: a C
    extension that calls back into Python may turn the interrupt into an error of its own, with the
    interrupt only in its message (nanobind's ``TypeError: could not export nb::ndarray: ...
    KeyboardInterrupt``, FLIP's ``evaluate`` importing a module); a new KeyboardInterrupt is
    returned for it. None where the chain holds neither: ``e`` is an error of its own."""
    for c in chain(e):
        if isinstance(c, KeyboardInterrupt):
            return c
        if getattr(c, _MARK, False) is True or _made_of_interrupt(c):
            return KeyboardInterrupt()
    return None


def values_text(values: Iterable, most: int = 8) -> str:
    """Values as a line says them, without Python's brackets: ``1, 2, 4, 8`` (more than
    ``most``: the first three, ``...`` and the last, ``1, 2, 3, ..., 64 (12 values)``)."""
    shown = [str(v) for v in values]
    if len(shown) > most:
        return f"{', '.join(shown[:3])}, ..., {shown[-1]} ({len(shown)} values)"
    return ", ".join(shown)


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """Return ' (did you mean X?)' when a close match exists, else ''."""
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


class StepsFailed(Exception):
    """Steps exited with status 1 (their results report failures); the report was written
    all the same, to ``page``."""

    def __init__(self, page, steps: list[str]):
        self.page = page
        self.steps = steps
        super().__init__(f"step{'s' if len(steps) > 1 else ''} {', '.join(steps)} reported failures (exit status 1, "
                         f"see above); the report was written all the same: {page}")


ERROR_CHARS = 400  # about the longest error a row holds (sweep.csv, sweep.jsonl, the sweep's failure lines)
ERROR_ITEMS = "; "  # what parts of a message are cut between (a Deadlock's blocked units)


def error_line(text: str, whole: str, limit: int = ERROR_CHARS) -> str:
    """``text`` on one line, of about ``limit`` characters at most: a longer one (a deadlock at
    64 pipelines names every blocked unit, some 10 KB) keeps its first parts (cut between
    :data:`ERROR_ITEMS`, else between characters) and says how many more ``whole`` holds (where
    the whole message is: a sweep point's ``error.json``, the file of a command's traceback)."""
    text = text.replace("\n", " ")
    if len(text) <= limit:
        return text
    parts = text.split(ERROR_ITEMS)
    if len(parts) > 1 and len(parts[0]) <= limit:
        kept = 1
        while kept < len(parts) and len(ERROR_ITEMS.join(parts[:kept + 1])) <= limit:
            kept += 1
        rest = len(parts) - kept
        return f"{ERROR_ITEMS.join(parts[:kept])}; ... and {rest} more (the whole message: {whole})"
    return f"{text[:limit]}... and {len(text) - limit} more characters (the whole message: {whole})"
