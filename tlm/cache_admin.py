"""What tlm's caches hold, and their entries removed whole: ``tlm cache`` (:mod:`tlm.cli_cache`).

* :data:`NAMES` — the caches under :func:`tlm.caches.cache_home`, each a folder of it; :func:`scan` —
  one cache's entries (:class:`Entry`), the writes in progress and the files that are not tlm's;
  :func:`survey` — every cache's (:class:`Cache`); :func:`describe` — what an entry is, and whether a frame is
  **stale**: written by other code (its sidecar's ``code_fingerprint``), under a key this code never reads
  (:mod:`tlm.cache_look`, with :func:`peek`, a look that is no use; another user's frame is not read, nor judged).
* :func:`choose` — the entries a prune removes (last used before a time, then the least recently used
  until the rest fit a size); :func:`remove` — entries removed whole, in an order no reader can mistake
  for a damaged entry; :func:`prune` — both, as ``tlm cache prune``/``clear`` and the API do it
  (:class:`Outcome`: its :meth:`~Outcome.record` is what ``--json`` prints and ``tlm.prune_cache`` returns).
* :func:`duration`, :func:`size`, :func:`cache_names` — the flags' values read (an
  :class:`~tlm.errors.InputError` naming the flag and the value); :func:`human` — bytes as ``48.2M``.

An **entry** is what a cache's reader reads as one: ``functional/<key>.npz`` with its sidecar
``<key>.json`` and a photon-map frame's ``<key>.pmap.npy``; ``scenes/mesh-<key>.npz``,
``normals-<key>.npz`` or a scene's remembered fingerprint ``key-<key>.json``; ``references/<key>/``
and ``oracle/<key>/`` (a folder: the image and its
``meta.json``), and ``references/<key>.partial.npz``, the rounds saved of a reference being computed or
interrupted (:mod:`tlm.experiments.reference_resume`: an entry of its own, a **partial**, which ``tlm cache``
names with the rounds its header says it holds, :func:`partial_state`, and a prune may remove as any other, but
while a live process of this machine computing it saved it under :data:`BUSY_SECONDS` ago: a write in progress,
:func:`partial_computer`);
``tracebacks/tlm-traceback-*.txt``; in ``numba/`` (where numba's own folders cannot be written) a
kernel's index ``<name>.nbi`` with its ``<name>.<n>.nbc``. Its **last use** is the latest
access or modification time of its files; its **size** the apparent bytes of its files (``ls -l``'s, not
``du``'s blocks; a folder itself counts nothing). tlm's reads refresh a file's modification time
(:func:`tlm.caches.note_use`): a frame read, its sidecar ``<key>.json``'s; a mesh or normals entry read
(a mesh's metadata alone too, read for the files its parse names), its ``.npz``'s; a scene's remembered
fingerprint read (a scene key given without a parse), its ``key-<key>.json``'s; a reference or a
ground truth read, its ``meta.json``'s. numba's reads of a kernel, and a traceback read, update only the
access time, where the file system keeps it (``relatime``, Linux's default: once a day at least;
``noatime``: never, and their last use is when they were written).

Never touched: a file or folder that is no entry of tlm's (a user's own file, a link), and a write in
progress: a temporary file or folder (``.<name>.tmp...``, ``.<name>.old-...``, numba's ``*.tmp.*``)
or an entry without its sidecar (the files a writer renames into place before it) under
:data:`BUSY_SECONDS` old, or one a live process of this machine is writing. Older temporaries, left by
a killed writer, are entries of their own (``leftover``).
"""

from __future__ import annotations

import contextlib
import itertools
import json
import math
import os
import re
import stat
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from tlm.cache_look import HEX as _HEX
from tlm.cache_look import PARTIAL as _PARTIAL  # (references/: the rounds saved of a reference, a file)
from tlm.cache_look import describe as describe  # (what an entry is: out of here, h517)
from tlm.cache_look import peek as peek  # (a look that is no use)
from tlm.cache_look import tell_apart as tell_apart  # (what tells frames apart: h527)
from tlm.caches import cache_home, remove_entry
from tlm.errors import EnvironmentFailure, InputError
from tlm.fingerprint import code_fingerprint
from tlm.storage import folder_lock, pid_alive, process_tag
from tlm.storage_live import process_start

NAMES = ("functional", "scenes", "references", "oracle", "tracebacks", "numba")
BUSY_SECONDS = 3600  # a temporary file (or an entry without its sidecar) younger than this is a write in progress

_FUNCTIONAL = re.compile(rf"({_HEX})\.(npz|json|pmap\.npy)")
_SCENES = re.compile(rf"((?:mesh|normals|key)-{_HEX})\.(npz|json)")
_FOLDER_KEY = re.compile(_HEX)
_TRACEBACK = re.compile(r"tlm-traceback-.+\.txt")
_NUMBA = re.compile(r"(.+\.py\d+)\.(nbi|\d+\.nbc)")
# the temporary names of tlm's writers (tlm.storage: write_atomic, atomic_folder, write_files, a kept
# folder) and numba's (``<file>.tmp.<uid>``)
_TEMPORARY = re.compile(r"\..+\.(?:tmp|old|new|claim)-?(?:h[A-Za-z0-9]*-)?\d+(?:-t?\d+)*"
                        r"|.+\.(?:nbi|nbc)\.tmp\.[0-9a-f]+|.+\.unsaved-\d+(?:-t?\d+)*")
_WRITER = re.compile(r"(h[A-Za-z0-9]*)-(\d+)")  # (the host and process a temporary name carries)
_MARKERS = {"functional": ".json", "numba": ".nbi"}  # the file a writer puts in place last
_SIDECAR_FIRST = (".json", ".nbi")  # removed first: an entry without them is no entry to its reader


@dataclass
class Entry:
    """One entry of a cache: its ``files`` (paths in the cache's folder, removed together), their
    ``size`` in bytes and ``last_use`` (seconds since the epoch); ``leftover``: a killed writer's
    temporary file or folder."""

    cache: str
    name: str
    files: list[Path]
    size: int = 0
    last_use: float = 0.0
    leftover: bool = False
    partial: str = ""  # a partial (references/<key>.partial.npz): what it is, ``24 rounds saved by ...``
    rounds: int | None = None  # a partial's rounds (None: unreadable, or no partial)
    kind: str = ""  # what it is: frame, mesh, reference, partial, leftover... (:func:`describe`, as all below)
    about: dict = field(default_factory=dict, compare=False)  # what its sidecar says: scene, resolution, mode...
    stale: bool | None = None  # a frame of other code than this tlm's, never read by it; None: not judged (no frame)
    # a frame's settings its sidecar records (tlm.cache_look.frame_settings: described whole), and those it differs in
    # from frames of the same scene, resolution and mode (tlm.cache_look.tell_apart: tlm cache list's; else none)
    settings: dict = field(default_factory=dict, repr=False, compare=False)
    differs: dict = field(default_factory=dict, compare=False)
    # (of differs, as tlm cache list's table shows it: a source by its shortest distinct tail; --json: differs whole)
    brief: dict = field(default_factory=dict, repr=False, compare=False)
    # (each file's :func:`_fingerprint` as the scan saw it: :func:`remove` removes a file only while it is
    # still that one)
    seen: dict[Path, dict[str, tuple[int, ...]]] = field(default_factory=dict, repr=False, compare=False)

    def shown(self) -> str:
        return f"{self.cache}/{self.name}"

    def what(self) -> str:
        """What it is, in words: ``frame cornell 320x240 pmap``, ``reference 64x64 16000 photons 32 rounds``; and
        what tells a frame from others of the same (:attr:`differs`): ``frame cornell 320x240 pmap [filter=knn]``."""
        a = self.about
        words = [self.kind, a.get("scene"), "x".join(map(str, a["resolution"])) if "resolution" in a else None,
                 a.get("mode"), *(f"{a[k]} {k}" for k in ("photons", "rounds", "spp") if k in a),
                 f"[{' '.join(f'{k}={self.brief.get(k, v)}' for k, v in self.differs.items())}]" if self.differs
                 else None]
        return " ".join(str(w) for w in words if w) or "-"

    def row(self) -> dict:
        """As ``--json`` lists it (a prune's ``removed``, ``tlm cache list --json``'s ``entries``, ``tlm cache
        --json``'s ``partials``): what it is too, and a partial with its ``partial_rounds`` and ``partial`` words."""
        row = {"entry": self.shown(), "bytes": self.size, "last_use": stamp(self.last_use), "kind": self.kind,
               **self.about, "what": self.what(), "stale": self.stale, **({"differs": self.differs} if self.differs
                                                                          else {})}
        return {**row, "partial_rounds": self.rounds, "partial": self.partial} if self.partial else row


@dataclass
class Cache:
    """A cache's folder, its entries, the writes in progress there (``busy``) and what is not tlm's
    (``other``: paths, never removed), with their sizes."""

    name: str
    folder: Path
    entries: list[Entry] = field(default_factory=list)
    busy: list[Path] = field(default_factory=list)
    busy_size: int = 0
    other: list[Path] = field(default_factory=list)
    other_size: int = 0
    partials: list[Entry] = field(default_factory=list)  # (references/: the partials, entries or being written)
    problem: str = ""  # what is wrong with its folder (a link to a path that does not exist: :func:`dangling`)

    @property
    def size(self) -> int:
        return sum(e.size for e in self.entries)

    def record(self) -> dict:
        """As ``tlm cache --json`` prints it."""
        uses = [e.last_use for e in self.entries]
        listed = {id(e) for e in self.entries}  # (a partial not among them: being written)
        stale = [e for e in self.entries if e.stale]
        return {"cache": self.name, "folder": str(self.folder), "entries": len(self.entries), "bytes": self.size,
                "oldest_use": stamp(min(uses)) if uses else None, "newest_use": stamp(max(uses)) if uses else None,
                "leftovers": sum(e.leftover for e in self.entries), "being_written": len(self.busy),
                "being_written_bytes": self.busy_size, "not_tlms": [str(p) for p in self.other],
                "not_tlms_bytes": self.other_size, "problem": self.problem or None,
                **({"stale": len(stale), "stale_bytes": sum(e.size for e in stale), "not_judged": sum(
                    e.kind == "frame" and e.stale is None for e in self.entries)} if self.name == "functional" else {}),
                "partials": [{**e.row(), "being_written": id(e) not in listed} for e in self.partials]}


def _usage(path: Path) -> tuple[int, float, float]:
    """``(bytes, last use, last modification)`` of a file, or of a folder and everything in it (links
    not followed; by lstat); (0, 0, 0) where it is gone."""
    try:
        st = path.lstat()
    except OSError:
        return 0, 0.0, 0.0
    size, used, changed = st.st_size, max(st.st_atime, st.st_mtime), st.st_mtime
    if stat.S_ISDIR(st.st_mode):  # (a folder's access time: its listing, as this scan's own; not a use)
        size, used = 0, st.st_mtime
        try:
            inside = list(path.iterdir())
        except OSError:
            inside = []
        for p in inside:
            s, u, m = _usage(p)
            size, used, changed = size + s, max(used, u), max(changed, m)
    return size, used, changed


def _fingerprint(path: Path) -> dict[str, tuple[int, ...]]:
    """A file's or folder's ``{"": (device, inode, modification time in ns, access time in ns)}``, and a
    folder's files' and folders' the same under their paths in it (lstat; a folder's access time, its
    listing, left out): any write, replacement or (where access times are kept) read changes it; ``{}``
    where it is gone. (A modification time set now may be a few milliseconds behind ``time.time()``, the
    kernel's coarse clock: a use just after a survey is told by this, not by a time.)"""
    try:
        st = path.lstat()
    except OSError:
        return {}
    folder = stat.S_ISDIR(st.st_mode)
    out = {"": (st.st_dev, st.st_ino, st.st_mtime_ns, 0 if folder else st.st_atime_ns)}
    if folder:
        try:
            inside = sorted(path.iterdir())
        except OSError:
            inside = []
        for p in inside:
            out.update({f"{p.name}/{k}" if k else p.name: v for k, v in _fingerprint(p).items()})
    return out


def _live_writer(name: str) -> bool:
    """Whether a temporary's name carries a live process of this machine (its writer at work)."""
    host = process_tag().rsplit("-", 1)[0]
    return any(m[1] == host and pid_alive(int(m[2])) for m in _WRITER.finditer(name))


def scan(name: str, home: Path | None = None, now: float | None = None, whole: bool = False) -> Cache:
    """The cache ``name`` (of :data:`NAMES`) in ``home`` (:func:`~tlm.caches.cache_home`): a
    missing folder is an empty cache (a link to a path that does not exist too, said in its ``problem``); a file
    where its folder should be is not tlm's (``other``); a folder that cannot be read an
    :class:`~tlm.errors.EnvironmentFailure`. Its entries as :func:`describe` finds them (``whole``: what each is)."""
    folder = (cache_home() if home is None else Path(home)) / name
    now = time.time() if now is None else now
    cache = Cache(name, folder, problem=dangling(folder) or "")  # (one: no entries, nothing not tlm's)
    if not cache.problem and (folder.exists() or folder.is_symlink()) and not folder.is_dir():
        cache.other.append(folder)
        cache.other_size += _usage(folder)[0]
        return cache
    groups: dict[str, list[Path]] = {}
    temporaries: list[Path] = []
    for path in _listing(folder, deep=name == "numba"):
        rel = path.relative_to(folder)
        key = _entry_key(name, path)
        if key is not None:
            groups.setdefault(str(rel.parent / key) if rel.parent != Path(".") else key, []).append(path)
        elif _TEMPORARY.fullmatch(path.name) and not path.is_symlink():
            temporaries.append(path)
        else:
            cache.other.append(path)
            cache.other_size += _usage(path)[0]
    for key, files in sorted(groups.items()):
        sizes = [_usage(f) for f in files]
        entry = Entry(name, key, files, sum(s for s, _, _ in sizes), max(u for _, u, _ in sizes),
                      seen=_seen(files))
        marker = _MARKERS.get(name)
        written = max(m for _, _, m in sizes)
        computing = False
        if name == "references" and _PARTIAL.fullmatch(key):
            entry.rounds, entry.partial, computing = partial_state(files[0], written, now)
            cache.partials.append(entry)
        describe(entry, whole)
        # (its writer puts the sidecar in place last; a partial's, a compute at work, saves it again)
        if computing or (marker is not None and not any(f.name.endswith(marker) for f in files)
                         and now - written < BUSY_SECONDS):
            cache.busy.extend(files)
            cache.busy_size += entry.size
        else:
            cache.entries.append(entry)
    for path in temporaries:
        size, used, written = _usage(path)
        if now - written < BUSY_SECONDS or _live_writer(path.name):
            cache.busy.append(path)
            cache.busy_size += size
        else:
            cache.entries.append(Entry(name, str(path.relative_to(folder)), [path], size, used, leftover=True,
                                       kind="leftover", seen=_seen([path])))
    return cache


def dangling(path: Path) -> str | None:
    """``<path> is a link to <target>, which does not exist`` (a cache moved to a disk not mounted now), or None."""
    with contextlib.suppress(OSError):
        if path.is_symlink() and not path.exists():
            return f"{path} is a link to {os.readlink(path)}, which does not exist"
    return None


def partial_info(path: Path) -> dict | None:
    """The header (``info``) of the rounds saved of a reference at ``path`` (``references/<key>.partial.npz``,
    :mod:`tlm.experiments.reference_resume`), or None where there are none, it is no regular file (a FIFO is not
    waited on) or it cannot be read. The one reader of it below the experiments (:func:`partial_state`, and
    :mod:`tlm.experiments.reference_cache` through it). A look at the header is no use of the file: its access
    time is left as it was (``O_NOATIME``, else set back), or ``tlm cache``'s listing, which reads it, made it
    used now (a prune's ``--older-than`` then kept a stale one, and one listed before a prune was kept as "used
    meanwhile")."""
    def read(fh) -> object:
        import numpy as np  # (tlm cache's other commands do without it)

        with np.load(fh, allow_pickle=False) as z:
            return json.loads(str(z["info"][()]))

    info = peek(path, read)
    return info if isinstance(info, dict) else None


def partial_rounds(info: dict | None) -> int:
    """The rounds that saved rounds' header ``info`` (:func:`partial_info`) says they hold: its cycles times its
    rounds a cycle; 0 where it says no whole positive numbers (none, or a damaged header)."""
    k, strata = (info or {}).get("k"), (info or {}).get("strata")
    return k * strata if type(k) is int and type(strata) is int and k > 0 and strata > 0 else 0


def partial_state(path: Path, written: float, now: float) -> tuple[int | None, str, bool]:
    """What the rounds saved of a reference (``references/<key>.partial.npz``, last written at ``written``) are,
    by their header (:func:`partial_info`): ``(rounds, words, computing)``: the rounds it holds (its cycles times
    their rounds; None where it cannot be read: a damaged file, or another tlm's layout), what ``tlm cache`` says of
    it after ``partial:`` (``24 rounds saved by an interrupted compute``), and whether a live process of this
    machine other than this one, computing it (:func:`partial_computer`), saved it under :data:`BUSY_SECONDS` ago
    (``now``): a compute at work, whose file is a write in progress (the compute saves it again at its next save)."""
    info = partial_info(path) or {}
    rounds = partial_rounds(info)
    if not rounds:
        return None, ("its rounds cannot be read (a damaged file, or another tlm's: the next compute of its key says "
                      "which)"), False
    pid = partial_computer(info) if now - written < BUSY_SECONDS else None
    if pid is not None:
        return rounds, f"{rounds} rounds saved so far by process {pid}, computing it now", True
    return rounds, f"{rounds} rounds saved by an interrupted compute", False


def partial_computer(info: dict) -> str | None:
    """The id of the process computing now the rounds saved of header ``info`` (:func:`partial_info`): its
    ``writer`` (``h<host>-<pid>``), a live process of this machine other than this one, that has not left them
    (no ``stopped``: the last save of a compute that leaves its rounds, an interrupt or an error, says it, as the
    process may live on: a notebook, a service) and that its ``started`` (:func:`~tlm.storage_live.process_start`,
    where ``/proc`` tells) says is the one that saved them, not a later one given its id. None for none (a
    reference interrupted earlier). A header of an older tlm's (neither field) is read by its writer alone."""
    writer = info.get("writer")
    if not isinstance(writer, str) or writer == process_tag() or info.get("stopped") is True:
        return None
    host, _, pid = writer.rpartition("-")
    if host != process_tag().rpartition("-")[0] or not pid.isdigit() or not pid_alive(int(pid)):
        return None
    started = info.get("started")
    if type(started) is int and process_start(int(pid)) not in (None, started):
        return None  # (another process, given the id of the one that saved them)
    return pid


def _seen(files: list[Path]) -> dict[Path, dict[str, tuple[int, ...]]]:
    """:attr:`Entry.seen`: each of ``files``' :func:`_fingerprint` (those gone already left out)."""
    return {f: i for f in files if (i := _fingerprint(f))}


def _listing(folder: Path, deep: bool) -> list[Path]:
    """What ``folder`` holds (``deep``: the files of its folders, numba's per-source folders, too)."""
    try:
        top = sorted(folder.iterdir())
    except FileNotFoundError:  # (no folder: an empty cache)
        return []
    except OSError as e:
        raise EnvironmentFailure(f"cannot read the cache folder {folder}: {(e.strerror or str(e)).lower()}") from None
    if not deep:
        return top
    out = []
    for p in top:
        if p.is_dir() and not p.is_symlink() and not _TEMPORARY.fullmatch(p.name):
            out.extend(_listing(p, True))
        else:
            out.append(p)
    return out


def _entry_key(name: str, path: Path) -> str | None:
    """The entry of cache ``name`` the path ``path`` is a file of (its key), or None: not tlm's."""
    if path.is_symlink():
        return None
    n = path.name
    if name == "functional":
        m = _FUNCTIONAL.fullmatch(n)
    elif name == "scenes":
        m = _SCENES.fullmatch(n)
    elif name in ("references", "oracle"):
        if name == "references" and _PARTIAL.fullmatch(n):
            return n if path.is_file() else None
        return n if _FOLDER_KEY.fullmatch(n) and path.is_dir() else None
    elif name == "tracebacks":
        return n if _TRACEBACK.fullmatch(n) and path.is_file() else None
    else:
        m = _NUMBA.fullmatch(n)
    return m[1] if m else None


def survey(names: Iterable[str] = NAMES, home: Path | None = None, whole: bool = False) -> list[Cache]:
    """:func:`scan` of each cache of ``names``, after :func:`check_home` (``whole``: what each entry is too)."""
    home = check_home(home)
    now = time.time()
    return [scan(n, home, now, whole) for n in names]


def check_home(home: Path | None = None) -> Path:
    """The cache folder (``home``, else :func:`~tlm.caches.cache_home`), checked: one that does not exist
    holds empty caches; a file (or anything not a folder), or a path under a file, is an
    :class:`~tlm.errors.InputError` naming the setting it came from (``TLM_CACHE: /x is a file, not a
    folder``, ``XDG_CACHE_HOME: /x/tlm: /x is a file, not a folder``), one that cannot be looked
    at an :class:`~tlm.errors.EnvironmentFailure`."""
    home = cache_home() if home is None else Path(home)
    try:
        st = home.stat()
    except FileNotFoundError:
        return home
    except NotADirectoryError:  # (a file above it: XDG_CACHE_HOME=/etc/passwd, the folder /etc/passwd/tlm)
        above = next((p for p in home.parents if p.exists() and not p.is_dir()), None)
        if above is None:
            raise EnvironmentFailure(f"cannot read the cache folder {home}: not a directory") from None
        raise InputError(f"{home}: {_not_a_folder(above, above.stat().st_mode)}", key=_setting(home)) from None
    except OSError as e:
        raise EnvironmentFailure(f"cannot read the cache folder {home}: {(e.strerror or str(e)).lower()}") from None
    if not stat.S_ISDIR(st.st_mode):
        raise InputError(_not_a_folder(home, st.st_mode), key=_setting(home))
    return home


def _not_a_folder(path: Path, mode: int) -> str:
    return f"{path} is a file, not a folder" if stat.S_ISREG(mode) else f"{path} is not a folder"


def _setting(home: Path) -> str:
    """The setting the cache folder ``home`` came from, as an error names it."""
    if home == cache_home():
        if os.environ.get("TLM_CACHE"):
            return "TLM_CACHE"
        if os.path.isabs(os.environ.get("XDG_CACHE_HOME") or ""):
            return "XDG_CACHE_HOME"
    return "tlm's cache folder"


def folder_size(home: Path | None = None) -> int:
    """The bytes of everything in the cache folder (entries, writes in progress, what is not tlm's)."""
    return _usage(cache_home() if home is None else Path(home))[0]


def choose(caches: Iterable[Cache], older_than: float | None = None, max_size: int | None = None,
           now: float | None = None, stale: bool = False) -> list[Entry]:
    """The entries of ``caches`` a prune removes, least recently used first: the ``stale`` frames
    (:attr:`Entry.stale`) where asked, and those last used more than ``older_than`` seconds ago, then the least
    recently used of the rest until what stays is at most ``max_size`` bytes."""
    now = time.time() if now is None else now
    entries = sorted((e for c in caches for e in c.entries), key=lambda e: (e.last_use, e.cache, e.name))
    gone = [e for e in entries if (stale and e.stale) or (older_than is not None and e.last_use < now - older_than)]
    if max_size is not None:
        taken = {id(e) for e in gone}  # (by identity: a list's ``in`` compares entries field by field, n² of them)
        left = sum(e.size for e in entries) - sum(e.size for e in gone)
        for e in entries:
            if left <= max_size:
                break
            if id(e) not in taken:
                gone.append(e)
                taken.add(id(e))
                left -= e.size
    return sorted(gone, key=lambda e: (e.last_use, e.cache, e.name))


_ASIDE = itertools.count()
USED = "used meanwhile"  # why an entry read, written or replaced since its scan is kept


def remove(entries: Iterable[Entry], home: Path | None = None, unused_since: float | None = None
           ) -> tuple[list[Entry], list[tuple[Entry, str]]]:
    """Remove each entry whole: ``(removed, [(not removed, why)])``. An entry used (read or written)
    after ``unused_since`` (the scan's time), or a file of it that is no longer the one its scan saw
    (another file or folder put in its place: :attr:`Entry.seen`; with ``unused_since``, one written, or
    read where access times are kept, since), is left, as :data:`USED`: checked before each file goes, a
    folder's inside its :func:`~tlm.storage.folder_lock` (a writer swapping a new one in waits, or is waited
    for and then kept). Files are removed only inside their cache's folder (a cache's folder that is a link, a cache
    moved to another disk, is followed); a sidecar first (its reader then sees no entry, not a damaged
    one), and a folder renamed aside first (a reader holding it reads it again and finds none; a killed
    prune leaves a temporary name that the next one removes)."""
    base = cache_home() if home is None else Path(home)
    done, failed = [], []
    try:
        for e in entries:
            root = base / e.cache
            if not all(_unchanged(e, f, unused_since) for f in e.files):
                failed.append((e, USED))
                continue
            why = None
            for f in sorted(e.files, key=lambda f: not f.name.endswith(_SIDECAR_FIRST)):
                said = _remove_one(f, root, e.leftover, lambda e=e, f=f: _unchanged(e, f, unused_since))
                if said == USED:  # (the files after it are kept: a writer's, or one a reader just used)
                    why = USED
                    break
                why = said or why
            (failed.append((e, why)) if why else done.append(e))
    except KeyboardInterrupt as e:  # (Ctrl-C, SIGTERM: what went by then, said)
        raise RemovalInterrupted(done) from e
    return done, failed


class RemovalInterrupted(KeyboardInterrupt):
    """The KeyboardInterrupt (Ctrl-C, SIGTERM) that came while :func:`remove` (:func:`prune`) removed
    entries: ``removed``, the entries removed whole before it (``tlm cache prune`` says them)."""

    def __init__(self, removed: list[Entry]) -> None:
        super().__init__(f"removed {len(removed)} entries before the interrupt")
        self.removed = removed


def _unchanged(e: Entry, path: Path, unused_since: float | None) -> bool:
    """Whether the file (or folder) ``path`` of the entry ``e`` is still what its scan saw: the same file
    (:attr:`Entry.seen`), and where ``unused_since`` is given unchanged since (its :func:`_fingerprint`) and
    not used after it; one gone meanwhile is (there is nothing left of it to keep)."""
    seen = e.seen.get(path)
    if seen is not None:
        now = _fingerprint(path)
        if not now:
            return True
        if now[""][:2] != seen[""][:2] or (unused_since is not None and now != seen):
            return False
    return unused_since is None or _usage(path)[1] <= unused_since


@dataclass
class Outcome:
    """A prune's or clear's: the ``caches`` surveyed, the entries ``chosen``, those ``removed`` (a ``dry_run``:
    the chosen, none really) and those ``failed`` (with why: :data:`USED`, or the system's words)."""

    caches: list[Cache]
    chosen: list[Entry]
    removed: list[Entry]
    failed: list[tuple[Entry, str]]
    dry_run: bool = False

    @property
    def kept(self) -> list[Entry]:
        """Every entry not removed: not chosen, used meanwhile, or that could not be removed."""
        gone = {id(e) for e in self.removed}
        return [e for c in self.caches for e in c.entries if id(e) not in gone]

    def record(self) -> dict:
        """What ``tlm cache prune --json`` prints and :func:`tlm.prune_cache` returns."""
        kept = self.kept
        return {"dry_run": self.dry_run, "removed": [e.row() for e in self.removed],
                "not_removed": [{**e.row(), "why": why} for e, why in self.failed],
                "kept": len(kept), "kept_bytes": sum(e.size for e in kept)}


def prune(names: Iterable[str], older_than: float | None = None, max_size: int | None = None, *,
          clear: bool = False, dry_run: bool = False, home: Path | None = None, stale: bool = False) -> Outcome:
    """``tlm cache prune`` (``clear``: ``tlm cache clear``, every entry) of the caches ``names``: :func:`survey`,
    :func:`choose` (``stale``: the stale frames too), and (unless ``dry_run``) :func:`remove`; a prune leaves an entry
    used since its survey. A KeyboardInterrupt during the removal is a :class:`RemovalInterrupted` naming those gone."""
    start = time.time()
    caches = survey(names, home, whole=True)
    chosen = choose(caches, -math.inf if clear else older_than, None if clear else max_size, start, stale and not clear)
    if dry_run:
        return Outcome(caches, chosen, chosen, [], dry_run=True)
    done, failed = remove(chosen, home, unused_since=None if clear else start)
    return Outcome(caches, chosen, done, failed)


def _remove_one(path: Path, root: Path, leftover: bool, unchanged=None) -> str | None:
    """Remove one file (or folder) of an entry; why not (:data:`USED` where ``unchanged()``, asked just
    before, a folder's inside its lock, says it is no longer what was chosen), or None."""
    if path.is_dir() and not path.is_symlink() and not leftover:
        aside = path.with_name(f".{path.name}.old-{process_tag()}-{next(_ASIDE) + 10_000}")
        try:
            with folder_lock(path):  # (not while a writer swaps a new one in for it)
                if unchanged is not None and not unchanged():  # (a new one swapped in while this waited)
                    return USED
                path.rename(aside)
        except FileNotFoundError:
            return None  # (gone already: another prune, or a reader that found it damaged)
        except OSError as e:
            return (e.strerror or str(e)).lower()
        path = aside
    elif unchanged is not None and not unchanged():
        return USED
    return remove_entry(path, root)


# ------------------------------------------------------------------ the flags' values

_UNITS = {"s": 1, "m": 60, "h": 3600, "d": 86400, "w": 7 * 86400}
_SIZES = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}


# (a value past these is refused as too large, not read as "no limit": 1000 years, 1 EiB)
MAX_DURATION = 1000 * 365.25 * 86400
MAX_SIZE = 1 << 60


def duration(text: str, key: str = "--older-than") -> float:
    """``30d``, ``12h``, ``90m``, ``45s``, ``2w`` (any case; ``M`` is minutes): seconds, at most
    :data:`MAX_DURATION`."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([smhdw])\s*", text, re.I)
    if not m:
        raise InputError(f"{text!r} is not a duration: a number and s, m, h, d or w (30d, 12h)", key=key)
    return too_large(float(m[1]) * _UNITS[m[2].lower()], text, key, True)


def size(text: str, key: str = "--max-size") -> int:
    """``500M``, ``2G``, ``1.5G``, ``800K``, ``2GiB``, ``2gb``, a number of bytes (any case): bytes (K, M, G,
    T: powers of 1024), at most :data:`MAX_SIZE`."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*(?:([kmgt])(?:i?b)?|b)?\s*", text, re.I)
    if not m:
        raise InputError(f"{text!r} is not a size: a number of bytes, or one with K, M, G or T (500M, 2G)", key=key)
    return int(too_large(float(m[1]) * _SIZES[(m[2] or "").lower()], text, key, False))


def too_large(value: float, given: object, key: str, seconds: bool) -> float:
    """``value`` (``key``'s, a duration's seconds or, not ``seconds``, a size's bytes, read from ``given``),
    or an :class:`~tlm.errors.InputError` where it is past :data:`MAX_DURATION` or :data:`MAX_SIZE` (or
    infinite)."""
    if value <= (MAX_DURATION if seconds else MAX_SIZE):
        return value
    text = str(given)
    shown = f"{text[:20]}... ({len(text)} characters)" if len(text) > 40 else repr(given) if isinstance(
        given, str) else text
    what = "a duration: at most 1000 years" if seconds else "a size: at most 1 EiB (1048576T)"
    raise InputError(f"{shown} is too large for {what}", key=key)


def cache_names(given: list[str] | None, key: str = "--cache") -> list[str]:
    """The caches named (each once, in :data:`NAMES`' order); all where ``given`` is None (an empty list:
    none)."""
    for n in given or []:
        if n not in NAMES:
            raise InputError(f"{n!r} is not one of tlm's caches ({', '.join(NAMES)})", key=key)
    return [n for n in NAMES if given is None or n in given]


def human(n: float) -> str:
    """Bytes as ``du -h`` says them: ``512B``, ``48.2K``, ``1.1G`` (powers of 1024)."""
    for unit in ("B", "K", "M", "G", "T"):
        if abs(n) < 1024 or unit == "T":
            return f"{int(n)}{unit}" if unit == "B" else f"{n:.1f}{unit}"
        n /= 1024
    return f"{n:.1f}T"


def stamp(t: float) -> str:
    """A time as local ISO 8601 to the second, with its offset."""
    import datetime

    return datetime.datetime.fromtimestamp(t).astimezone().isoformat(timespec="seconds")


def as_json(caches: list[Cache], home: Path) -> str:
    """``tlm cache --json``."""
    return json.dumps({"folder": str(home), "bytes": folder_size(home), "code_fingerprint": code_fingerprint(),
                       "problem": dangling(home), "caches": [c.record() for c in caches]}, indent=1)

