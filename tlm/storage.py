"""Files and folders that appear whole or not at all: the one place tlm writes atomically.

* :func:`write_atomic` — one file, written beside its destination and renamed onto it;
  :func:`write_file` the same for a ready ``str`` or ``bytes``; :func:`write_files` several files, all or none.
* :func:`atomic_folder` — an output folder (a run, a sweep, a study); :func:`write_into`, a file put
  into one under its lock.
* :func:`write_rows` — the one writer of result rows: ``<name>.jsonl`` and ``<name>.csv``.
* :func:`naming` — a write that names no file (``os.pwrite``, a flush) named by its path when it fails (a
  full disk: one line naming the file); :func:`appending` a file appended to, its failures so named (both
  :mod:`tlm.storage_json`'s, imported from here too).
* :func:`json_text` — the JSON text of every file tlm writes for its user: strict JSON, a
  number that is not finite (inf, nan) written as null, never as ``Infinity`` or ``NaN``; and
  :func:`read_jsonl`, rows read back (both :mod:`tlm.storage_json`'s, imported from here too).
* :func:`on_failed_write` — who is told of a write that failed (:mod:`tlm.caches`, which says
  once that one of tlm's caches cannot be written); :func:`warn` — a one-line warning.

For a folder, everything is written into a temporary sibling folder, which is renamed onto the
destination only when the block finished; on any error (or Ctrl-C) the temporary
folder is removed and an earlier folder of the same name is left as it was. An earlier folder is
swapped for the new one in one call where the file system can (:func:`tlm.storage_lock.exchange`), so
the destination is never missing meanwhile; elsewhere (NFS, another OS) it is renamed aside first.
An output that keeps what its user put in its folder (a run's, a study's: ``owned``) lists what it wrote
there (:data:`LISTING`, where it holds a folder), so that a rerun tells the user's files inside the output's
own folders (a run's ``images/``) from the output's, and carries them over (:mod:`tlm.storage_carry`); a path
of the user's that the new output writes itself is the output's, and said (a warning).

An existing destination is replaced only if it is an earlier output of the same kind:
a folder holding the ``marker`` file (``results.json`` for a run folder), or an empty
folder. Anything else — a file, a folder of other things, the current folder or one of
its parents, a mount point (but for a sweep's folder, written in place: :data:`IN_PLACE`) — is
refused with an :class:`~tlm.errors.InputError`, so ``--out .`` can never delete a checkout. A
destination whose parent cannot be written (a read-only file system) is an
:class:`~tlm.errors.EnvironmentFailure`, found before any work. A destination that
turns into such a thing while the block runs (another program's folder, a file) keeps the finished
output beside it, in a folder of its own (``OUT.unsaved-<pid>``, else ``-2``, ``-3``, ...), which the
error names (:func:`_keep_beside`).

A run holds its destination while it works (:func:`tlm.claims.claimed`), as a study command and a report
do theirs: any writer of another process into it (a run, a study, a sweep, a report) is refused at once,
naming the first (:func:`check_destination`, through :func:`tlm.claims.refuse_held`), as a run, a study or a
report into a folder a sweep is running in is. Concurrent writers of one destination that
remain (two threads of one process calling ``tlm.run`` into one folder, two runs of one sweep
writing one point) never see each other's temporary folders: each has its own
(``.<name>.tmp-<host>-<pid>-<n>``, ``n`` counting the writers of the process); the swap of the
old folder for the new one holds a lock on the old one (:func:`folder_lock`, from :mod:`tlm.storage_lock`); the last
to finish wins; and what a killed process left (its temporary folder, or the old folder it was swapping out)
is removed by the next writer once that process is gone. A process never removes a temporary
folder one of its own writers is using (:func:`clean_stale`).
"""

from __future__ import annotations

import csv
import errno
import os
import re
import shutil
import socket  # noqa: F401  (storage.socket.gethostname: what _host, tlm.storage_lock's, asks)
import stat
import sys
from collections.abc import Callable, Collection, Iterable, Iterator, Sequence
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, cast

from tlm import storage_live, storage_lock
from tlm.errors import EnvironmentFailure, InputError, escaped_line, quoted
from tlm.storage_carry import LISTING, carry_over, lost_line, put_back, unlisted_line, write_listing  # noqa: F401
from tlm.storage_errors import raise_environmental as _raise_environmental
from tlm.storage_errors import write_problem  # noqa: F401  (re-exported: storage.write_problem)
from tlm.storage_files import write_files as _write_files
from tlm.storage_json import appending, escaped, finite, json_text, naming, read_jsonl  # noqa: F401  (re-exported)
from tlm.storage_live import (  # noqa: F401  (re-exported)
    _CLEANED,
    _FILES,
    _GUARD,
    _LIVE,
    _RUNNING,
    _WRITERS,
    _forget_live,
    _hold,
    _release,
    _thread_tag,
    _writer,
    hold,
    left_by_the_gone,
    name_max,
    new_writer,
    pid_alive,
    process_tag,
    release,
    sibling_stem,
)
from tlm.storage_lock import _host, folder_lock  # (_host: storage._host, tlm.claims's; _left_by_the_gone asks it)
from tlm.storage_swap import mounted as _mounted
from tlm.storage_swap import swap_in as _swap_in
from tlm.storage_swap import swap_tries as _swap_tries  # noqa: F401  (kept importable from here)

_LIVE_LOCK = storage_live._LIVE_LOCK  # (storage_live's, made anew in a forked child: this name follows, _same_lock)


def _same_lock() -> None:
    """In a forked child: :data:`_LIVE_LOCK` the child's new one (made by ``storage_live._forget_live``, first)."""
    global _LIVE_LOCK
    _LIVE_LOCK = storage_live._LIVE_LOCK


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_same_lock)


def check_destination(out: str | os.PathLike, marker: str, key: str = "--out", also: Collection[str] = ()) -> Path:
    """The resolved destination, or an InputError saying why it may not be written
    (an EnvironmentFailure when its parent folder cannot be written). ``also``: other files that mark an
    earlier output it may replace (a sweep point's ``error.json``, beside ``results.json``). An empty
    path is named as given (``''``), not as the ``'.'`` it becomes. A destination another live process
    writes (a run's, a study's or a report's claim beside it, a sweep running in it: :func:`tlm.claims.refuse_held`)
    is refused first, naming that process (:class:`tlm.claims.FolderHeld`): every writer is refused at once."""
    if os.fspath(out) in ("", b""):
        raise InputError("'' is the current folder (an empty path); name a new folder", key=key)
    out = Path(out)
    resolved = out.resolve()
    cwd = Path.cwd().resolve()
    if resolved == cwd or resolved in cwd.parents:
        raise InputError(f"{quoted(out)} is the current folder or one of its parents; name a new folder",
                         key=key)
    from tlm import claims  # (which imports this module)

    claims.refuse_held(resolved, out, marker, key, in_place=marker in IN_PLACE)
    if resolved.exists():
        _check_existing(out, resolved, marker, key, also)
    # (an existing folder written in place, a sweep's: written inside, never swapped, so it and not its
    # parent must be writable, a mount point in a folder of root's, /media, among them)
    parent = resolved if marker in IN_PLACE and resolved.is_dir() else resolved.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():  # (a file where a folder on the way should be: the user's path, not the machine)
        raise InputError(f"{quoted(out)} cannot be made: {quoted(parent)} is a file, not a folder", key=key)
    if not os.access(parent, os.W_OK | os.X_OK):
        raise EnvironmentFailure(f"cannot write into {parent} (read-only or not permitted)", source=str(out))
    return resolved


def _check_existing(out: Path, resolved: Path, marker: str, key: str, also: Collection[str] = ()) -> None:
    """An InputError where the existing ``resolved`` may not be replaced (not a folder, a mount
    point, a folder that is no earlier tlm output and not being claimed). Nothing where it
    vanished while it was looked at: another writer of the same output (a thread or a process) that
    cannot swap the two folders in one call (:func:`tlm.storage_lock.exchange`: NFS, an older tlm)
    renames the old folder aside and its own into place, and between the two there is none. A refusal
    is told from one listing of one folder: where the marker was looked for between those two renames
    (no folder), the entries of the folder renamed into place next (its marker among them) are
    another folder's, not a folder without its marker."""
    try:
        if not stat.S_ISDIR(resolved.stat().st_mode):
            raise InputError(f"{quoted(out)} exists and is not a folder", key=key)
        if is_mount(resolved) and marker not in IN_PLACE:
            raise InputError(_mounted(out), key=key)
        if any((resolved / m).is_file() for m in (marker, *also)):
            return
        with os.scandir(resolved) as listing:  # (one listing, of one folder: the marker may have come meanwhile)
            entries = list(listing)
    except FileNotFoundError:
        return
    held = [e.name for e in entries if not any(_claiming(e.name, m) for m in (marker, *also))]
    if not any(e.name in (marker, *also) and e.is_file() for e in entries) and held:
        # (what to do, said: a log written into the folder, `> OUT/tlm.log` as Snakemake's log: puts there, is
        # the usual one; a folder tlm wrote carries what is added to it into its next output, not a report's)
        names = ", ".join(quoted(n) for n in sorted(held)[:2]) + (f" and {len(held) - 2} more" if len(held) > 2 else "")
        kept = "" if marker == "report.html" else ", and a folder tlm wrote keeps files added to it"
        raise InputError(f"{quoted(out)} exists and is not an earlier tlm output (no {marker}; it holds {names}: "
                         f"write a log beside it, {quoted(f'{os.fspath(out)}.log')}, not in it; a new or an empty "
                         f"folder is taken{kept}); refusing to replace it", key=key)


# the markers of the outputs written into their folder in place, never replacing it (a sweep's ``sweep.yaml``:
# its points, rows and report go inside, :func:`tlm.experiments.sweep.run_sweep`): such a folder may be a mount point
IN_PLACE = frozenset({"sweep.yaml"})


def is_mount(path: Path) -> bool:
    """Whether the folder ``path`` (resolved) is a mount point: :func:`os.path.ismount`, which
    compares devices and so misses a bind mount of a folder of the same file system (``mount
    --bind D D``), or one of the mount points ``/proc/self/mountinfo`` lists. A mount point
    cannot be renamed (EBUSY), so an output there could never take its place."""
    return os.path.ismount(path) or os.fsencode(path) in _mount_points()


def _mount_points() -> frozenset[bytes]:
    """The mount points of this process's mount namespace (``/proc/self/mountinfo``'s fifth
    field, its octal escapes undone: ``\\040`` for a space); none where it cannot be read."""
    try:
        with open("/proc/self/mountinfo", "rb") as fh:
            lines = fh.read().splitlines()
    except OSError:
        return frozenset()
    unescape = re.compile(rb"\\([0-7]{3})")
    return frozenset(unescape.sub(lambda m: bytes([int(m[1], 8)]), fields[4])
                     for fields in map(bytes.split, lines) if len(fields) > 4)


def _claiming(name: str, marker: str) -> bool:
    """Whether ``name`` is the temporary file of a marker being written (another tlm
    process claiming the folder this instant, :func:`claim_folder`: ``.<marker>.tmp<host>-<pid>``,
    or an older tlm's ``.<marker>.tmp<pid>``), or a lock file of :func:`tlm.claims.sharing` (a sweep
    refused, or killed, before it wrote its marker leaves one)."""
    return name.startswith((f".{marker}.tmp", _RUNNING)) or name == _GUARD


def claim_folder(out: Path, marker: str, data: str, existing: bool = True) -> bool:
    """Make ``out`` a tlm output: the folder with ``marker`` in it, atomically.

    A missing folder is created whole, marker inside, by renaming a prepared sibling onto
    it, so another process never sees it without its marker; a folder that exists (which
    :func:`check_destination` accepted) gets the marker by an atomic write. Two processes
    claiming one folder at once both succeed: the second finds the first's marker.
    ``existing=False``: a folder that exists (or that another process made first) is left
    as it is, its marker the caller's to write (:func:`tlm.claims.sharing`). Whether this made it.
    The prepared sibling, ``.<name>.claim<host>-<pid>`` (and the thread's tag), is this writer's
    alone, on a folder shared between machines too: what is left at its name (by an earlier process
    of this id on this machine) is removed first, never another machine's sibling.
    """
    out = Path(out)
    if not out.exists():
        tmp = out.with_name(f".{sibling_stem(out)}.claim{process_tag()}{_thread_tag()}")
        shutil.rmtree(tmp, ignore_errors=True)
        try:  # (a failure names the folder and its marker, not the prepared sibling, which is gone)
            with naming(out):
                tmp.mkdir(parents=True)
            with naming(out / marker):
                write_file(tmp / marker, data)
            with naming(out):
                os.rename(tmp, out)
            return True
        except OSError:
            if not out.is_dir():  # not a lost race: a real failure
                raise
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    if existing:
        write_file(out / marker, data)
    return False


def distinct_folders(dirs: Iterable[str | Path], notes: list[str] | None = None) -> list[Path]:
    """``dirs`` with a folder given twice (or by two paths) kept once, in order; ``notes``
    gets a line for each repeat."""
    unique: dict[Path, Path] = {}
    for d in map(Path, dirs):
        first = unique.setdefault(d.resolve(), d)
        if first is not d and notes is not None:
            notes.append(f"{d}: given twice (the same folder as {first}): read once")
    return list(unique.values())



def clean_stale(folder: Path, name: str = ".+") -> None:
    """Remove the temporary folders (``.<name>.tmp-<host>-<pid>-<n>``, ``.<name>.old-<host>-<pid>-<n>-<m>``)
    that processes of this machine now gone left in ``folder``: a killed writer cannot
    remove its own. Another machine's (a shared disk) are left alone: its process ids are
    not this machine's to check. Names without a host (older writers) count as this machine's.
    Of this process's own names, those none of its writers is using now are removed (left by an
    earlier process of the same id); one a writer (another thread) is using is never touched."""
    for d in stale_folders(folder, name):
        shutil.rmtree(d, ignore_errors=True)


def stale_folders(folder: Path, name: str = ".+") -> list[Path]:
    """The temporary folders :func:`clean_stale` would remove from ``folder`` now (``tlm sweep --dry-run``)."""
    pattern = re.compile(rf"\.{name}\.(?:tmp|old)-(?:(h[A-Za-z0-9]*)-)?(\d+)(?:-\d+)*")
    return _left_by_the_gone(folder, pattern, Path.is_dir, lambda d: d.name in _LIVE)


def clean_stale_files(folder: Path, name: str = ".+") -> None:
    """Remove the temporary files of :func:`write_atomic` (``.<name>.tmp<host>-<pid>``, a thread's
    ``-t<id>`` and a count added) that processes of this machine now gone left in ``folder``: one
    killed, or ended at once by a second signal, while it wrote. Another machine's, a live
    process's and those this process's writers are writing now are left alone."""
    for f in stale_files(folder, name):
        with suppress(OSError):
            f.unlink()


def stale_files(folder: Path, name: str = ".+") -> list[Path]:
    """The temporary files :func:`clean_stale_files` would remove from ``folder`` now (``tlm sweep --dry-run``)."""
    pattern = re.compile(rf"\.{name}\.tmp(?:(h[A-Za-z0-9]*)-)?(\d+)(?:-t\d+)?(?:-\d+)?")
    return _left_by_the_gone(folder, pattern, Path.is_file, lambda f: os.path.abspath(f) in _FILES)


def _left_by_the_gone(folder: Path, pattern: re.Pattern, kind: Callable[[Path], bool],
                      in_use: Callable[[Path], bool]) -> list[Path]:
    """:func:`tlm.storage_live.left_by_the_gone`, asking this module's :func:`pid_alive` whether a process runs and
    its ``_host`` this machine's name (both what a test replaces: storage.pid_alive, storage._host)."""
    return left_by_the_gone(folder, pattern, kind, in_use, pid_alive, _host)


_WHOLE = object()  # atomic_folder's owned left out: an output replaced whole, which keeps no listing


@contextmanager
def atomic_folder(out: Path, marker: str, owned: Collection[str] | object | None = _WHOLE,
                  clean_once: bool = False, into: Callable[[Path], bool] | None = None,
                  replaces: Collection[str] = (), finished: bool = False) -> Iterator[Path]:
    """Yield a fresh temporary folder that replaces ``out`` when the block succeeds.

    ``marker`` is the file that marks an earlier output of this kind (it may be
    replaced); the block must write it. ``owned``: the names such an output may hold;
    where given, whatever else an earlier ``out`` holds (a user's notes, an analysis
    folder) is carried into the new one, not removed with the old output, and what it holds in its own folders
    that the old output did not write (:data:`LISTING`, which such an output keeps:
    :func:`tlm.storage_carry.carry_over`). None: an output that carries nothing this time (a study's whose
    earlier folder has no record of its names) but keeps
    its listing all the same; left out: one replaced whole (a report's, a cache's), with no listing.
    Before it, the temporary folders that killed writers of ``out`` left beside it are removed
    (:func:`clean_stale`, which lists the whole of ``out``'s parent); ``clean_once``: only at this
    process's first write into that parent (a sweep's points: the sweep cleans its ``points/`` at its
    start and its end, and a listing of N points' folder at each of N points is N² work).
    ``into``: where ``out`` is, at the swap (asked under its lock), a folder that ``into(out)`` keeps (one another
    writer swapped in meanwhile: a failed point's error beside a concurrent sweep's good results of the same
    point), the block's ``marker`` file is renamed into it instead, the rest of the block's folder dropped; such
    a folder found as this starts is not refused. ``replaces``: other files than ``marker`` that mark an earlier
    output this may replace (a point's ``results.json`` over its failed try's ``error.json``, a concurrent sweep's).
    ``finished``: the block writes what was computed before it (a run's end, :func:`tlm.experiments.run.write_run`):
    a destination refused as this starts (another program's folder put there meanwhile) is written all the same,
    and the output kept beside it (``OUT.unsaved-<pid>``) as one refused at the swap, the refusal saying so.
    """
    try:
        out = check_destination(out, marker, also=replaces)
    except (InputError, EnvironmentFailure) as e:  # (a cache's folder: said once, tlm.caches)
        kept_there = into is not None and _kept(Path(out), into)  # (a concurrent sweep's point, kept)
        if not isinstance(e, InputError) or not (kept_there or (finished and _beside_possible(Path(out)))):
            _failed_write(out, e)
            raise
        out = Path(out).resolve()  # (asked again under the lock at the swap)
    writer = _writer()
    tmp = out.parent / f".{sibling_stem(out)}.tmp-{writer}"
    _hold(tmp.name)  # (before it exists: no other thread's clean_stale may take it for a leftover)
    try:
        names = None if owned is _WHOLE else cast("Collection[str] | None", owned)
        yield from _atomic_folder(out, marker, names, tmp, writer, clean_once, into, replaces,
                                  listing=owned is not _WHOLE)
    finally:
        _release(tmp.name)


def _beside_possible(out: Path) -> bool:
    """Whether a refused ``out`` can have an output kept beside it (:func:`atomic_folder`'s ``finished``):
    its parent is a folder, and it is neither the current folder nor one above it."""
    resolved, cwd = out.resolve(), Path.cwd().resolve()
    return resolved.parent.is_dir() and resolved != cwd and resolved not in cwd.parents


def _kept(out: Path, into: Callable[[Path], bool]) -> bool:
    """Whether ``out`` is a folder (not a link to one) that ``into`` keeps (:func:`atomic_folder`)."""
    return out.is_dir() and not out.is_symlink() and into(out)


def _atomic_folder(out: Path, marker: str, owned: Collection[str] | None, tmp: Path,
                   writer: str, clean_once: bool = False,
                   into: Callable[[Path], bool] | None = None, replaces: Collection[str] = (),
                   listing: bool = False) -> Iterator[Path]:
    """:func:`atomic_folder`'s body, into the temporary folder ``tmp`` of ``writer``; ``listing``: its
    :data:`LISTING` written."""
    leave = False  # (the temporary folder holds a user's files that could be kept nowhere else)
    moved: list[str] = []  # (the user's paths carried into tmp, until they are back or tmp took out's place)
    lost: list[str] = []  # (the user's paths that the new output's own take: said once it took out's place)
    unlisted: list[str] = []  # (the paths kept from the own folders of an out with no listing: said so too)
    new: os.stat_result | None = None  # (tmp's, to tell whether it took out's place)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        if not clean_once or _first_clean(out.parent):
            clean_stale(out.parent, re.escape(sibling_stem(out, strict=False)) if not clean_once else ".+")
        shutil.rmtree(tmp, ignore_errors=True)  # (an earlier process's of the same id and number)
        tmp.mkdir()
    except OSError as e:
        _failed_write(out, e)
        raise EnvironmentFailure(f"cannot create the output folder ({e.strerror})", source=str(out)) from None
    try:
        yield tmp
        if not (tmp / marker).is_file():
            raise RuntimeError(f"an output folder was written without its {marker}")
        if listing:
            write_listing(tmp, write_file)  # (before any file of the user's comes in: what this output wrote)
        with folder_lock(out):
            if into is not None and _kept(out, into):  # (the marker into it, under the lock: nothing swaps in between)
                os.replace(tmp / marker, out / marker)
                shutil.rmtree(tmp, ignore_errors=True)
                return
            try:  # another writer may have put something else there meanwhile, or claimed it (a live run's)
                if out.exists():
                    check_destination(out, marker, also=replaces)
                else:
                    from tlm import claims

                    claims.refuse_held(out, out, marker, in_place=marker in IN_PLACE)
            except InputError as refused:  # the finished output is kept beside it, not thrown away
                kept = _keep_beside(tmp, out)
                if kept is None:
                    raise refused from None
                raise InputError(f"{refused}; this run's output is kept in {quoted(kept)}") from None
            new = os.lstat(tmp)
            swapping = False
            try:
                if owned is not None and out.is_dir():
                    unlisted = carry_over(out, tmp, owned, moved, lost)
                swapping = True
                _swap_in(tmp, out, writer)
            except BaseException as e:  # (the user's files go back where they were)
                if storage_lock.is_at(out, new):  # (swapped in, then a signal: it stays; the old one goes with tmp)
                    moved.clear()
                    raise
                stuck = put_back(tmp, out, moved)
                if not swapping and isinstance(e, OSError):  # a file of the user's that cannot be moved
                    kept = _keep_beside(tmp, out)
                    leave = kept is None and bool(stuck)
                    moved.clear()  # (kept beside or left, and said)
                    if kept is None:
                        _stuck_said(out, tmp, kept, stuck)
                        raise
                    raise EnvironmentFailure(
                        f"cannot carry {quoted(e.filename)} into the new output ({e.strerror}), so the folder is "
                        f"left as it was{_stuck_text(stuck)}; this run's output is kept in {quoted(kept)}",
                        source=str(out)) from None
                if stuck:  # (never removed with the temporary folder: it is kept beside, whole, and named)
                    kept = _keep_beside(tmp, out)
                    leave = kept is None
                    moved.clear()
                    _stuck_said(out, tmp, kept, stuck)
                raise
            moved.clear()
        if lost:
            warn(lost_line(out, lost))
        if unlisted:
            warn(unlisted_line(out, unlisted))
    except BaseException as e:
        if moved and not (new is not None and storage_lock.is_at(out, new)):  # (a signal as they went back: the
            leave = True  # temporary folder holds some, never removed, said)
            _stuck_said(out, tmp, _keep_beside(tmp, out) if tmp.is_dir() else None, moved)
        if not leave:
            shutil.rmtree(tmp, ignore_errors=True)
        _failed_write(out, e)
        _raise_environmental(e, out)
        raise


def _stuck_text(stuck: list[str]) -> str:
    """The clause of a carry's refusal on the user's files that could not be moved back (none: '')."""
    return f" but for {', '.join(map(quoted, stuck))}, which could not be moved back" if stuck else ""


def _stuck_said(out: Path, tmp: Path, kept: Path | None, stuck: list[str]) -> None:
    """Say where the user's files ``stuck`` in the new output's ``tmp`` (not moved back into ``out``) are."""
    if not stuck:
        return
    where = f"kept in {quoted(kept)}" if kept is not None else \
        f"left in {quoted(tmp)}, which the next output written to {quoted(out)} removes"
    warn(f"{out}: the new output could not take its place and {', '.join(map(quoted, stuck))} "
         f"could not be moved back into it: they and this run's output are {where}")


def _first_clean(folder: Path) -> bool:
    """Whether this process has not yet looked for leftovers in ``folder`` (noted now: it will)."""
    key = os.path.abspath(folder)
    with storage_live._LIVE_LOCK:
        if key in _CLEANED:
            return False
        _CLEANED.add(key)
        return True


def _keep_beside(tmp: Path, out: Path) -> Path | None:
    """Rename the finished temporary folder ``tmp`` to a name of its own beside ``out`` (kept,
    not removed, when it cannot take ``out``'s place): ``OUT.unsaved-PID`` (``-t<id>`` added in
    a thread other than the main one), else the first of ``OUT.unsaved-PID-2``, ``-3``, ... that
    is free: a name is taken by making it (an empty folder, which the rename then replaces), so
    an earlier kept output, or anything else of that name, is never replaced. Its path, or None."""
    base = f"{sibling_stem(out, strict=False)}.unsaved-{os.getpid()}{_thread_tag()}"
    for n in range(1, 10_000):
        kept = out.parent / (base if n == 1 else f"{base}-{n}")
        try:
            kept.mkdir()
        except FileExistsError:
            continue  # (kept earlier, or someone else's)
        except OSError:
            return None
        try:
            tmp.rename(kept)
        except OSError as e:
            with suppress(OSError):
                kept.rmdir()
            if e.errno in (errno.ENOTEMPTY, errno.EEXIST):
                continue  # (filled meanwhile by someone else)
            return None
        return kept
    return None


@contextmanager
def write_atomic(path: Path, mode: str = "w", **open_kw) -> Iterator[IO]:
    """An open file that replaces ``path`` when the block succeeds.

    The data go to a hidden sibling (``.<name>.tmp<host>-<pid>``, ``-t<id>`` added in a thread
    other than the main one, ``-<n>`` added while another block of this process writes that one (a
    block within a block, or two generators of one thread), so concurrent writers of one path,
    threads or processes, of one machine or of two sharing a folder, never share it) that is
    renamed onto ``path`` at the end; on any error the sibling is removed and ``path`` is left as it was.
    A text file is UTF-8 (``encoding``, unless given), whatever the locale's encoding: a non-ASCII cell of
    ``sweep.csv`` (a worker's host name) under ``LC_ALL=C`` or a Latin-1 locale is written, as is.
    """
    path = Path(path)
    if "b" not in mode:
        open_kw.setdefault("encoding", "utf-8")
    tmp = _temporary_file(path)
    try:
        with open(tmp, mode, **open_kw) as fh:
            yield fh
        os.replace(tmp, path)
    except BaseException as e:
        with suppress(OSError):
            tmp.unlink(missing_ok=True)
        _failed_write(path, e)
        _raise_environmental(e, path)
        raise
    finally:
        with storage_live._LIVE_LOCK:
            _FILES.discard(os.path.abspath(tmp))


def _temporary_file(path: Path) -> Path:
    """The temporary file of a :func:`write_atomic` of ``path``: the first of ``.<name>.tmp<host>-<pid>``
    (and its thread's tag), ``...-2``, ``-3``, ... that no block of this process is writing now. The
    host (:func:`process_tag`): on a folder shared between machines a process id alone names no process."""
    base = f".{sibling_stem(path)}.tmp{process_tag()}{_thread_tag()}"
    with storage_live._LIVE_LOCK:
        tmp, n = path.with_name(base), 1
        while os.path.abspath(tmp) in _FILES:
            n += 1
            tmp = path.with_name(f"{base}-{n}")
        _FILES.add(os.path.abspath(tmp))
    return tmp


def write_file(path: Path, data: str | bytes) -> None:
    """``data`` as the whole of ``path``, atomically (:func:`write_atomic`)."""
    with write_atomic(path, "wb" if isinstance(data, bytes) else "w") as fh:
        fh.write(data)


def write_into(folder: Path, name: str, data: str | bytes, keep: Callable[[Path], bool]) -> bool:
    """``data`` as the whole of the file ``name`` in the output folder ``folder`` as it is, where ``keep(folder)``
    says so, both under the folder's lock (:func:`folder_lock`): True where written, False (nothing written) where
    ``keep`` says no or there is no folder. A writer swapping a new folder in for it (:func:`atomic_folder`, a
    concurrent sweep of the same points) waits for the lock, so that the file goes into the folder ``keep`` was
    asked about (a failed point's ``error.json`` beside the results it keeps), never into the new one: nothing
    swaps in between the question and the write."""
    folder = Path(folder)
    with folder_lock(folder):
        if not folder.is_dir() or not keep(folder):
            return False
        write_file(folder / name, data)
    return True


def write_rows(folder: Path, name: str, rows: Iterable[dict], columns: Iterable[str] = ()) -> None:
    """Result rows as ``folder/<name>.jsonl`` (one JSON object a line) and ``<name>.csv``.

    The CSV's columns are ``columns`` first (a column no row has is there too, its cells
    empty), then every other key of the rows in the order it first appears; a list or mapping
    value is written as JSON in its cell, text with a surrogate escaped (:func:`_cell`). The JSON is
    strict (:func:`json_text`: a number that is not finite is null), and such a number's CSV cell is
    empty, as null's. Both files are written atomically.
    """
    rows = list(rows)
    cols = list(columns)
    for r in rows:
        cols.extend(k for k in r if k not in cols)
    folder = Path(folder)
    write_file(folder / f"{name}.jsonl", "".join(json_text(r) + "\n" for r in rows))
    with write_atomic(folder / f"{name}.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: _cell(v) for k, v in r.items()})


def _cell(value):
    """``value`` as its CSV cell (:func:`write_rows`): a list or mapping as JSON, a number that is not finite
    None, text with each surrogate escaped (:func:`tlm.storage_json.escaped`: a path of bytes not UTF-8 in an
    error a row holds, ``dir_\\xff``, where UTF-8 raised UnicodeEncodeError and nothing was written). The JSON
    keeps the surrogate as its own escape (``\\udcff``), the path read back as it is."""
    cell = json_text(value) if isinstance(value, (list, dict)) else finite(value)
    return escaped(cell) if isinstance(cell, str) else cell


def write_files(files: Sequence[tuple[Path, str | bytes]]) -> None:
    """Each ``(path, data)`` of ``files`` as the whole of ``path``: all of them, or none
    (:func:`tlm.storage_files.write_files`, with this module's :func:`write_file`)."""
    _write_files(files, lambda path, data: write_file(path, data), process_tag)


_HEARERS: list[Callable[[Path, BaseException], None]] = []  # told of each failed write (on_failed_write)


def on_failed_write(hear: Callable[[Path, BaseException], None]) -> None:
    """Have ``hear(path, error)`` called when a write of this module fails: :func:`write_atomic`
    of ``path``, :func:`atomic_folder` of ``path`` (a destination refused or that cannot be made
    too), before the error goes on. :mod:`tlm.caches` hears so, to say once that a cache cannot be
    written (a full disk), without this module knowing of caches. Asked twice, called once."""
    if hear not in _HEARERS:
        _HEARERS.append(hear)


def _failed_write(path: Path, e: BaseException) -> None:
    """Tell each of :func:`on_failed_write`'s hearers that writing ``path`` failed with ``e``."""
    for hear in _HEARERS:
        hear(path, e)


SAID: set[str] = set()  # the lines warn() said (a command clears it, to print a run's warnings once)


def warn(message: str) -> None:
    """A one-line warning on stderr (``tlm: warning: ...``), recorded in :data:`SAID`."""
    line = " ".join(message.split())
    SAID.add(line)
    sys.stderr.write(f"tlm: warning: {escaped_line(line)}\n")  # (a name in it: its control characters shown)
    sys.stderr.flush()
