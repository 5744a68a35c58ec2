"""Who holds an output folder while it is written: a run's, a study's or a report's destination, a
sweep's folder.

* :func:`claimed` — a run's destination (a study's, a report's), held by one process while it works: a
  second writer of another process is refused at once, naming the first (its host and pid), before it
  does any work; threads of one process share the claim.
* :func:`sharing` — a sweep's folder, held by the processes of one identity (one sweep's points):
  a sweep of other points running into it is refused, naming its holder.
* :func:`refuse_held` — the refusal of a destination another live process holds (its claim, or a sweep
  running in it), which :func:`tlm.storage.check_destination` asks of every writer before its work.
* :func:`holding` — whether this process holds a destination now (:func:`claimed`'s).
* :func:`lock_holder` — the process holding a folder's lock (:func:`tlm.storage.folder_lock`), for
  the line of one that waits for it (``tlm report``).
* :func:`drop_stale` — remove the claim file a killed run left beside its folder, where its holder is
  provably gone (``tlm report`` of the folder; the next :func:`claimed` of it takes it over).

The first two hold a ``flock`` on a file of their own (beside the destination, or in the sweep's folder)
recording the holder's host and pid (:func:`tlm.storage.process_tag`): the lock alone decides
whether a holder is alive (its process ended, the kernel released it), on a folder shared between
machines too; the record only names it in a refusal (:func:`_holder`). Writing the folder itself,
atomically, is :mod:`tlm.storage`'s (which recognises :func:`sharing`'s files in a folder as a tlm
output's).
"""

from __future__ import annotations

import errno
import fcntl
import os
import re
import stat
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from tlm.errors import EnvironmentFailure, InputError, path_shown, quoted
from tlm.progress import interrupts_deferred
from tlm.storage_errors import takes_no_files
from tlm.storage_json import naming
from tlm.storage_live import _GUARD, _RUNNING, pid_alive, process_tag, sibling_stem
from tlm.storage_lock import _host

_RECORD = 64  # bytes of a running file's record of its holder (``<host>-<pid>``, padded)


@contextmanager
def sharing(out: Path, identity: str, what: str = "run", made: str | None = None) -> Iterator[None]:
    """Hold the existing folder ``out`` for the processes of one ``identity`` (a sweep's
    points) while the block runs: an :class:`InputError` if a process of another identity
    holds it. Processes of one identity share it (two runs of one sweep cooperate).

    Each holder keeps a shared ``flock`` on ``.tlm-running-<identity>`` (with its host and
    pid, ``<host>-<pid>``: the folder may be on a disk shared between machines); a newcomer,
    under an exclusive lock on ``.tlm-lock``, tries an exclusive lock on every other
    identity's file: one it gets is stale (its processes ended, the kernel released their
    locks) and is removed; one it cannot get is held, and the refusal names its holder
    (:func:`_holder`). The lock alone decides: a pid is never checked, another machine's
    cannot be from here. The last holder of an identity removes its file on the way out. A folder
    that a live ``tlm run`` or study claims (:func:`claimed`) is refused too (:func:`refuse_held`), leaving
    nothing it made: its guard where this made it, and, ``made`` (the marker file this process made ``out`` with
    just before: :func:`tlm.storage.claim_folder`), that file and the folder (h422)."""
    out = Path(out)
    guard, new = _guard(out)
    mine_path = out / f"{_RUNNING}{identity}"
    mine = None
    try:
        try:
            for other in sorted(out.glob(f"{_RUNNING}*")):
                if other.name != mine_path.name:
                    _claim_stale(other, what)
            with naming(mine_path):  # (os.pwrite's OSError names no file)
                mine = os.open(mine_path, os.O_RDWR | os.O_CREAT, 0o644)
                fcntl.flock(mine, fcntl.LOCK_SH)
                os.pwrite(mine, f"{process_tag():<{_RECORD - 1}}\n".encode(), 0)  # (fixed width: holders overwrite it)
            # (and only then the claim beside the folder looked at: a run or a study that claims it as this sweep
            # comes in finds this sweep's file, or this sweep finds its claim; one of the two is refused)
            try:
                refuse_held(out.resolve(), out, "sweep.yaml", in_place=True)
            except FolderHeld:
                if _unshare(mine, mine_path):  # (this sweep's alone: what it made goes, under the guard still)
                    mine = None
                    _unmake(out, made, new)
                raise
        finally:
            fcntl.flock(guard, fcntl.LOCK_UN)
        yield
    finally:
        if mine is not None:
            fcntl.flock(guard, fcntl.LOCK_EX)
            with suppress(OSError):
                fcntl.flock(mine, fcntl.LOCK_EX | fcntl.LOCK_NB)  # (no other holder of this identity)
                mine_path.unlink(missing_ok=True)
            os.close(mine)
        os.close(guard)


def _guard(out: Path) -> tuple[int, bool]:
    """The guard of the folder ``out`` open and locked (exclusive), and whether this made it (:func:`sharing`).
    One removed as this waited for its lock (a refused sweep's, :func:`_unmake`) is opened again: the lock is
    that of the file ``.tlm-lock`` names, or two sweeps would hold two guards at once (h428)."""
    while True:
        with naming(out / _GUARD):  # (a full disk: one line naming the file, :func:`tlm.storage.naming`)
            try:
                guard, new = os.open(out / _GUARD, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644), True
            except FileExistsError:
                guard, new = os.open(out / _GUARD, os.O_RDWR | os.O_CREAT, 0o644), False
        fcntl.flock(guard, fcntl.LOCK_EX)
        if _same_file(guard, out / _GUARD):
            return guard, new
        os.close(guard)


def _unshare(mine: int, path: Path) -> bool:
    """Whether this process held the running file ``path`` (open as ``mine``) alone: then it is removed and
    closed (:func:`sharing` refused, under its guard); held by another process of its identity, it is left."""
    try:
        fcntl.flock(mine, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    with suppress(OSError):
        path.unlink()
    os.close(mine)
    return True


def _unmake(out: Path, made: str | None, guard: bool) -> None:
    """Remove what a refused :func:`sharing` of the folder ``out`` made, where no sweep runs there: its guard
    (``guard``: this made it), and, ``made``, the marker file this process made the folder with, and the folder,
    where nothing else is in it (a sweep of these points that came in and ended meanwhile left its points and
    that marker: all kept, h428). Under the guard, which ``.tlm-lock`` names still (:func:`_guard`)."""
    if any(out.glob(f"{_RUNNING}*")):
        return
    if made is not None and not set(os.listdir(out)) <= {made, _GUARD}:  # (another's points there: h428)
        made = None
    with suppress(OSError):
        if made is not None:
            (out / made).unlink()
        if guard or made is not None:
            (out / _GUARD).unlink()
        if made is not None:
            out.rmdir()


def _claim_stale(path: Path, what: str) -> None:
    """Remove another identity's running file whose holders ended; an InputError naming
    the process when one still holds it (:func:`sharing`, under its guard)."""
    try:
        fd = os.open(path, os.O_RDWR)
    except FileNotFoundError:
        return
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if _let_go(fd):  # (a claim's look, unguarded, at a dead sweep's file: its lock held a moment, h428)
                path.unlink(missing_ok=True)
                return
            holder = _holder(os.pread(fd, _RECORD, 0).decode("ascii", "replace"))
            raise InputError(f"another {what} of other points is writing into {quoted(path.parent)} "
                             f"({holder}): wait for it to end, or give another folder",
                             key="--out") from None
        path.unlink(missing_ok=True)
    finally:
        os.close(fd)


def _holder(record: str) -> str:
    """The process a running file's ``record`` names, for a refusal: ``process PID on this
    machine, HOST (its command line)`` (:func:`_command`, where it can be read), or ``process PID
    on host HOST, another machine: ...`` (its processes cannot be checked from this one); an older
    tlm's record (its pid alone) as ``process PID``; ``process ?`` for none (not written yet)."""
    line = record.split("\n", 1)[0].strip()  # (a shorter record written over a longer one: its first line)
    m = re.fullmatch(r"(h[A-Za-z0-9]*)-(\d+)", line)
    if m is None:
        return f"process {line if line.isdigit() else '?'}"
    name = m[1][1:]
    if m[1] == _host():
        return f"process {m[2]} on this machine, {name}{_command(int(m[2]))}"
    return f"process {m[2]} on host {name}, another machine: its processes cannot be checked from this one"


def _claim_holder(fd: int, path: Path, wait: float = 0.5) -> str:
    """The holder of the claim file ``path`` (open as ``fd``, its lock held by another), for a
    refusal (:func:`_holder`). Its holder writes its record just after it takes the lock, so a
    record not written yet is waited for a moment; then this machine's kernel is asked who
    holds the lock (:func:`lock_holder`), and ``process ?`` said only where neither tells."""
    deadline = time.monotonic() + wait
    while True:
        record = os.pread(fd, _RECORD, 0).decode("ascii", "replace")
        holder = _holder(record)
        if holder != "process ?" or time.monotonic() >= deadline:
            break
        time.sleep(0.01)
    if holder == "process ?":
        holder = lock_holder(path) or holder
    return holder


def lock_holder(path: Path) -> str | None:
    """The process holding a ``flock`` on ``path`` (a folder's :func:`tlm.storage.folder_lock`: a
    run swapping a new folder in, a report reading it), named as a refusal names a claim's holder
    (``process 4242 on this machine, HOST``) with its command line where it can be read (``(python -m
    tlm run x.yaml --out runs/x)``); None where none is found: this machine's kernel lists its locks
    (``/proc/locks``, Linux), and lists none on ``path`` for another machine's process (a disk shared
    between machines), another container's, or one that let go meanwhile."""
    try:
        st = os.stat(path)
        with open("/proc/locks", encoding="ascii", errors="replace") as f:
            listed = f.read().splitlines()
    except OSError:
        return None
    inode = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    for line in listed:  # ``1: FLOCK  ADVISORY  WRITE 4242 fe:00:3926309 0 EOF`` (a waiter's: ``1: -> FLOCK ...``)
        fields = line.split()
        if len(fields) >= 6 and fields[1] == "FLOCK" and fields[5] == inode and fields[4].isdigit():
            pid = int(fields[4])
            if pid == os.getpid():
                return f"this process ({pid})"
            if pid > 0:
                return f"process {pid} on this machine, {_host()[1:]}{_command(pid)}"
    return None


def _command(pid: int, most: int = 100) -> str:
    """`` (its command line)`` of the process ``pid``, on one line, shortened to ``most`` characters; empty
    where it cannot be read (ended meanwhile, another user's under ``hidepid``)."""
    import shlex

    try:
        words = Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace").rstrip("\0").split("\0")
    except OSError:
        return ""
    if not words or not words[0]:
        return ""
    line = " ".join(shlex.join([Path(words[0]).name, *words[1:]]).split())  # (on one line: a -c program's lines)
    return f" ({line if len(line) <= most else line[:most - 3] + '...'})"


_CLAIMED = ".tlm-running"  # the suffix of a claimed destination's sibling (``.<name>.tlm-running``; a long name's
# prefix and hash, :func:`tlm.storage_live.sibling_stem`, within the file system's NAME_MAX)
# (reentrant: a claim left open, a ``claimed`` block entered and never left, is let go by the garbage collector,
# whose close of its generator takes this lock in whatever thread it runs, one holding it too, as a claim is
# taken: a plain lock waited there for ever, and every later claim of the process with it, h431)
_CLAIMS_LOCK = threading.RLock()
_CLAIMS: dict[str, list] = {}  # the destinations this process holds: path -> [fd, claim file, holders, made]


def holding() -> bool:
    """Whether this process holds a destination now (:func:`claimed`: a run's folder, a sweep's,
    a report's): the command is writing one (read by :func:`tlm.cli_signals._writing`)."""
    return bool(_CLAIMS)


class FolderHeld(InputError):
    """:func:`claimed`'s refusal where another process holds the folder (``--out``), with its parts
    (``held``: what writes, the folder as the caller named it, the holder's words: :func:`_holder`), so
    that a caller says it otherwise (:func:`held_line`) without taking the message apart."""

    held: tuple[str, str, str] = ("", "", "")


def held_line(what: str, folder: str, holder: str, report_folder: bool = False) -> str:
    """The refusal of a folder another process holds: ``another run is writing into 'OUT' (process ...):
    wait for it to end, or give another folder``; ``report_folder``: ``folder`` is the report folder of
    the folder the user gave (``tlm report DIR``, no ``--out``), said so, and ``--out`` named."""
    into, other = ("into its report folder", "another folder with --out") if report_folder else ("into",
                                                                                               "another folder")
    return f"another {what} is writing {into} {quoted(folder)} ({holder}): wait for it to end, or give {other}"


@contextmanager
def claimed(out: Path, what: str = "run") -> Iterator[None]:
    """Hold the destination ``out`` (resolved) for this process while the block runs: an
    :class:`InputError` naming the process when another holds it (``another run is writing
    into 'OUT' (process 4242 on this machine, HOST): ...``), raised before the block does any work.

    The holder keeps an exclusive ``flock`` on ``.<name>.tlm-running`` beside ``out`` (the
    destination may not exist yet, and a run's swap replaces the folder itself), the file
    holding its host and pid (:func:`~tlm.storage.process_tag`, read back by :func:`_holder`);
    the last holder removes it. A file whose process ended is taken over (the kernel released its
    lock), another machine's is respected while its lock is held: the lock alone decides, as for a
    sweep (:func:`sharing`). Threads of one process share the claim (their writes of one folder
    were always safe: the last to finish wins, :func:`~tlm.storage.atomic_folder`). The folders
    made on the way to ``out`` are removed again when the block leaves none of its output in them."""
    given = Path(out)
    out = given.resolve()
    key = os.fsdecode(out)
    taken = None
    try:
        # (a signal while the claim is taken, its file made but not yet held here, left the file
        # behind: the command line's handler raises it once the claim is held, and dropped)
        with interrupts_deferred(), _CLAIMS_LOCK:
            while True:
                held = _CLAIMS.get(key)
                if held is None:
                    held = _CLAIMS[key] = [*_take_claim(out, given, what), 0]
                held[3] += 1
                # (a claim of ``out`` left open, let go by the collector in this thread between the look and the
                # count, the lock reentrant: its file dropped, this count is of nothing; counted anew, h442)
                if _CLAIMS.get(key) is held:
                    break
                held[3] -= 1
            taken = held
        yield
    finally:
        if taken is not None:
            with _CLAIMS_LOCK:
                taken[3] -= 1
                if taken[3] == 0 and _CLAIMS.get(key) is taken:
                    del _CLAIMS[key]
                    _drop_claim(*taken[:3])


def _take_claim(out: Path, given: Path, what: str) -> tuple[int, Path, list[Path]]:
    """The locked claim file of the resolved destination ``out`` (:func:`claimed`; ``given``:
    as the caller named it, for the messages): its descriptor, its path and the folders made
    on the way to it."""
    path = out.parent / f".{sibling_stem(out)}{_CLAIMED}"
    made = [d for d in (out.parent, *out.parent.parents) if not d.exists()][::-1]
    for _ in range(100):
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except FileNotFoundError as e:
            # (the folder the file or a folder on the way was made in: there, it takes no new one, /proc's ENOENT;
            # gone, it was removed meanwhile, another holder's, made and dropped: tried again)
            there = out.parent if e.filename is None or Path(e.filename) == path else Path(e.filename).parent
            if not there.is_dir():
                continue
            _remove_made(made)
            raise EnvironmentFailure(f"cannot write: {takes_no_files(there)}", source=str(given)) from None
        except OSError as e:
            if e.errno in (errno.EACCES, errno.EPERM):  # (another user's file there: its holder's, or a stale one)
                foreign = _foreign(path)
                if foreign is True:  # (stale, removed: a new one taken)
                    continue
                if foreign:
                    _remove_made(made)
                    kind, holder = foreign
                    refused = FolderHeld(held_line(kind or what, str(given), holder), key="--out")
                    refused.held = (kind or what, str(given), holder)
                    raise refused from None
            _remove_made(made)
            if e.errno in (errno.EROFS, errno.EACCES, errno.EPERM):  # (as check_destination and the swap say it)
                raise EnvironmentFailure(f"cannot write into {path_shown(out.parent)} (read-only or not permitted)",
                                         source=str(given)) from None
            raise EnvironmentFailure(f"cannot write beside the output folder ({e.strerror})",
                                     source=str(given)) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as e:
            if not isinstance(e, BlockingIOError):  # (a file system without locks: ENOLCK, EOPNOTSUPP)
                os.close(fd)
                with suppress(OSError):
                    path.unlink()
                _remove_made(made)
                raise EnvironmentFailure(f"cannot lock {path} to claim the output folder ({e.strerror}): "
                                         "the file system takes no locks; give a folder on a local disk",
                                         source=str(given)) from None
            if _being_dropped(fd, path):  # (a dead run's file, drop_stale removing it as this opened it: a new one)
                os.close(fd)
                continue
            if not _let_go(fd):  # (let go: a writer's check that looked at it, its shared lock held a moment)
                holder = _claim_holder(fd, path)
                what = _kind(os.pread(fd, _RECORD, 0).decode("ascii", "replace")) or what  # (the holder's, if said)
                os.close(fd)
                _remove_made(made)
                refused = FolderHeld(held_line(what, str(given), holder), key="--out")
                refused.held = (what, str(given), holder)
                raise refused from None
        taken = _claim_taken(fd, path, made, out, given, what)
        if taken is not None:
            return taken
    _remove_made(made)
    raise EnvironmentFailure(f"cannot claim the output folder: {path} keeps changing", source=str(given))


def _foreign(path: Path) -> tuple[str | None, str] | bool:
    """The claim file ``path`` that this process may not open to write (another user's, left by a run of theirs,
    :func:`_take_claim`): its holder's kind and words (:func:`_held_claim`) where its lock is held; True where
    it is stale (its lock free) and was removed, under an exclusive lock, so that a run of that user taking it the
    while finds it gone (:func:`_claim_taken`) and takes a new one, and two takers never both remove a file, the
    second the first's new claim (both then wrote, h428); True too (looked at again) where another holds that
    lock a moment (a taker, a look). The lock is a shared one only where a file open to read takes no exclusive
    one (NFS: EBADF). False where it is neither (it cannot be read, nor removed: a folder that takes no new files
    of this user's), as the caller says it."""
    held = _held_claim(path)
    if held is not None:
        return held
    fd = _look(path)
    if fd is None:
        return False
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            time.sleep(0.002)
            return True
        except OSError as e:
            if e.errno != errno.EBADF:
                raise
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        if _same_file(fd, path):
            path.unlink()
        return True
    except OSError:
        return False
    finally:
        os.close(fd)


def _claim_taken(fd: int, path: Path, made: list[Path], out: Path, given: Path, what: str
                 ) -> tuple[int, Path, list[Path]] | None:
    """:func:`_take_claim`'s claim file ``path``, open as ``fd`` and locked: its record written and the folder
    looked at for a running sweep; None (``fd`` closed) where ``path`` no longer names the file (its holder
    removed it between the open and the lock: the caller opens it again)."""
    try:
        same = os.path.samestat(os.stat(path), os.fstat(fd))
    except OSError:
        same = False
    if not same:
        os.close(fd)
        return None
    try:
        os.pwrite(fd, _record(what), 0)
    except OSError as e:  # (a full disk: no run could be written there either)
        _drop_claim(fd, path, made)
        raise EnvironmentFailure(f"cannot write beside the output folder ({e.strerror}: {path})",
                                 source=str(given)) from None
    # (then a sweep running in the folder looked for: one that came in as this claim was taken finds it,
    # or is found here, :func:`sharing`)
    sweep = _sweep_holder(out, guarded=False) if out.is_dir() else None
    if sweep is not None:
        _drop_claim(fd, path, made)
        refused = FolderHeld(held_line("sweep", str(given), sweep), key="--out")
        refused.held = ("sweep", str(given), sweep)
        raise refused
    return fd, path, made


def _let_go(fd: int, wait: float = 0.05) -> bool:
    """Whether the lock of the claim file open as ``fd``, held by another, is let go within ``wait`` seconds,
    and taken (exclusive) here: another writer's check of the folder (:func:`_held_claim`'s shared lock, held
    for as long as a look takes), never a claim's holder, which keeps it while it writes."""
    deadline = time.monotonic() + wait
    while time.monotonic() < deadline:
        time.sleep(0.002)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except OSError:
            pass
    return False


def _record(what: str) -> bytes:
    """A claim file's record (:data:`_RECORD` bytes): its holder's host and pid on the first line, as
    :func:`_holder` (and an older tlm) reads it, and what the holder writes (``run``, ``study``,
    ``report``) on the second, which a refusal names (:func:`refuse_held`)."""
    return f"{f'{process_tag()}{chr(10)}{what}'[:_RECORD - 1]:<{_RECORD - 1}}\n".encode()


def _kind(record: str) -> str | None:
    """What the holder of a claim file's ``record`` writes (:func:`_record`'s second line); None for an
    older tlm's record, which says none."""
    lines = record.split("\n")
    word = lines[1].strip() if len(lines) > 2 else ""
    return word if re.fullmatch(r"[a-z][a-z -]*", word) else None


# what an older tlm's claim (its record says nothing of it: :func:`refuse_held`) is of, by the file that marks the
# output the caller writes: a report's folder a report's, any other a ``tlm run``'s (an older tlm's only other claim;
# none of its sweeps or studies took one: h422)
_WRITERS = {"report.html": "report"}


def refuse_held(out: Path, given: Path, marker: str, key: str = "--out", in_place: bool = False) -> None:
    """A :class:`FolderHeld` where another live process writes the destination ``out`` (resolved;
    ``given``: as the caller named it): it holds the claim beside it (:func:`claimed`: a ``tlm run``,
    a study, a report), or, unless ``in_place`` (a sweep's own folder, which runs of one sweep share:
    :func:`sharing`), a sweep runs in it. Called by :func:`tlm.storage.check_destination`, so that
    every writer of a folder (a run, a sweep, a study, a report) is refused at once, before any work,
    naming the holder (``another run is writing into 'OUT' (process 4242 on this machine, HOST (tlm
    run ...))``), not found out at its end, when one output replaces the other's. Its own claims (this
    process's) and stale ones (their process gone: their lock free) are none; the lock alone decides."""
    with _CLAIMS_LOCK:
        if os.fsdecode(out) in _CLAIMS:  # (this process's own: a run's write of the folder it claimed)
            return
    path = out.parent / f".{sibling_stem(out)}{_CLAIMED}"
    held = _held_claim(path)
    what = None
    if held is not None:
        with _CLAIMS_LOCK:  # (this process's own, taken by another thread as this one looked: h422)
            if os.fsdecode(out) in _CLAIMS:
                return
        what, holder = held
        what = what or _WRITERS.get(marker, "run")
    elif not in_place and out.is_dir():
        holder = _sweep_holder(out)
        what = "sweep" if holder is not None else None
    if what is None:
        return
    refused = FolderHeld(held_line(what, str(given), holder), key=key)
    refused.held = (what, str(given), holder)
    raise refused


def _look(path: Path) -> int | None:
    """``path`` open to read for a look at a claim file: not through a link, and never waiting (a FIFO put there
    would block the open); None where it cannot be opened or is not a regular file (closed again)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        if stat.S_ISREG(os.fstat(fd).st_mode):
            return fd
    except OSError:
        pass
    os.close(fd)
    return None


def _held_claim(path: Path) -> tuple[str | None, str] | None:
    """The claim file ``path`` (:func:`claimed`) where another process holds it: what it writes (None: an
    older tlm's record) and who (:func:`_claim_holder`); None where there is none, or it is stale. Looked at
    with a shared lock, let go at once: a run taking the file that instant is refused as by a holder."""
    fd = _look(path)
    if fd is None:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            return None  # (free: none holds it; its lock goes with the descriptor)
        except BlockingIOError:
            pass
        except OSError:  # (a file system without locks: no claim could be held there)
            return None
        if _being_dropped(fd, path):  # (a dead run's, which drop_stale is removing)
            return None
        holder = _claim_holder(fd, path)
        return _kind(os.pread(fd, _RECORD, 0).decode("ascii", "replace")), holder
    finally:
        os.close(fd)


def _sweep_holder(out: Path, guarded: bool = True) -> str | None:
    """The process of a sweep running in the folder ``out`` (:func:`sharing`'s running files, one of them
    held), as a refusal names it (:func:`_holder`); None where none runs there. Looked at under the folder's
    guard, as a sweep coming in looks (nothing made: a folder without a guard has no sweep running); not
    ``guarded``, without it: by :func:`_take_claim`, which holds this process's claims' lock, which a sweep of
    this process coming in asks for under the guard (:func:`refuse_held`: the two threads would wait for each
    other for ever, h422). A sweep that comes in as the claim is taken finds the claim there, its record written
    before this looks: one of the two is refused."""
    if not any(out.glob(f"{_RUNNING}*")):
        return None
    try:
        guard = os.open(out / _GUARD, os.O_RDWR | os.O_CLOEXEC | os.O_NOFOLLOW)
    except OSError:
        return None
    try:
        if guarded:
            fcntl.flock(guard, fcntl.LOCK_EX)
        for path in sorted(out.glob(f"{_RUNNING}*")):
            try:
                fd = os.open(path, os.O_RDWR | os.O_CLOEXEC | os.O_NOFOLLOW)
            except OSError:
                continue
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # (got: stale, left for the next sweep to remove)
            except BlockingIOError:
                return _holder(os.pread(fd, _RECORD, 0).decode("ascii", "replace"))
            except OSError:
                continue
            finally:
                os.close(fd)
        return None
    except OSError:
        return None
    finally:
        os.close(guard)


def _gone(record: str) -> bool:
    """Whether a claim file's ``record`` (``<host>-<pid>``, :func:`_holder`) names a process of this
    machine that is gone; False for a live one, another machine's, an older tlm's (its pid alone) or none."""
    m = re.fullmatch(r"(h[A-Za-z0-9]*)-(\d+)", record.split("\n", 1)[0].strip())
    return m is not None and m[1] == _host() and not pid_alive(int(m[2]))


def _same_file(fd: int, path: Path) -> bool:
    """Whether ``path`` still names the file open as ``fd``."""
    try:
        return os.path.samestat(os.stat(path), os.fstat(fd))
    except OSError:
        return False


def _being_dropped(fd: int, path: Path, wait: float = 0.2) -> bool:
    """Whether the claim file ``path`` (open as ``fd``, its lock held by another) is one that
    :func:`drop_stale` holds to remove: its record names a process of this machine that is gone, and
    within ``wait`` seconds ``path`` no longer names it (the caller takes a new one) or its lock is let go
    (one :func:`drop_stale` could not remove: the caller opens it again). A live holder's file (its record
    its own) is never waited for."""
    if not _gone(os.pread(fd, _RECORD, 0).decode("ascii", "replace")):
        return False
    deadline = time.monotonic() + wait
    while _same_file(fd, path):
        try:  # (let go without removing it, a parent it cannot write: the caller opens it again and takes it)
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except OSError:
            pass
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.005)
    return True


def drop_stale(out: Path) -> bool:
    """Remove the claim file (:func:`claimed`) that a process now gone left beside the destination
    ``out``, ``.<name>.tlm-running`` (a ``tlm run`` killed with SIGKILL while it wrote its report);
    whether one was removed. Only one whose holder is provably gone: its lock is free (the kernel
    released a dead holder's) and its record names a process of this machine that is not alive. One
    held, one of a live process, another machine's or an older tlm's (its pid alone: the next
    :func:`claimed` of ``out`` takes it over), one this process holds, one that is not a plain file
    (a link, a folder, a FIFO) and one that cannot be removed (a read-only copy) are left as they are.
    A run that opened the file meanwhile takes a new one, or this one (:func:`_being_dropped`), never
    refused for it."""
    out = Path(out).resolve()
    path = out.parent / f".{sibling_stem(out, strict=False)}{_CLAIMED}"
    with _CLAIMS_LOCK:
        if os.fsdecode(out) in _CLAIMS:  # (this process's own: held)
            return False
    fd = _look(path)
    if fd is None:
        return False
    try:
        # (read before the lock: one not provably stale, a live or reused pid's, another machine's, an older
        # tlm's, one not written yet, is never locked, so a run claiming it at this moment is not refused for it)
        if not _gone(os.pread(fd, _RECORD, 0).decode("ascii", "replace")):
            return False
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # (held, or a file system without locks: left)
        if not _gone(os.pread(fd, _RECORD, 0).decode("ascii", "replace")) or not _same_file(fd, path):
            return False
        path.unlink()
        return True
    except OSError:
        return False
    finally:
        os.close(fd)  # (the lock with it)


def _drop_claim(fd: int, path: Path, made: list[Path]) -> None:
    """Give up the claim :func:`_take_claim` took: its file removed, its lock released (released
    for forked children too, which hold copies of the descriptor), the folders it made removed
    where they are empty (``out`` was not written)."""
    try:
        with suppress(OSError):
            if os.path.samestat(os.stat(path), os.fstat(fd)):
                path.unlink()
    finally:
        with suppress(OSError):
            fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)
    _remove_made(made)


def _remove_made(made: list[Path]) -> None:
    """Remove the folders in ``made`` (outermost first) that are empty, innermost first."""
    for d in reversed(made):
        try:
            d.rmdir()
        except OSError:
            return


def _forget_claims() -> None:
    """In a forked child: the parent's claims, never unlocked by the child (which would release them)."""
    global _CLAIMS_LOCK
    _CLAIMS_LOCK = threading.RLock()
    _CLAIMS.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_claims)
