"""tlm's caches: where they live, the one line said when one cannot be written, and their entries' checks.

* :func:`cache_home` — the folder of every cache (``$TLM_CACHE``, else ``$XDG_CACHE_HOME/tlm``,
  else ``~/.cache/tlm``); :func:`cache_root` — one cache's folder in it (``functional``,
  ``scenes``, ``references``, ``oracle``: :data:`CACHES`); :func:`cache_needed` — the same, for a use
  that needs it (the scene cache's line waits for a mesh file's load: :data:`WAIT_FOR_USE`).
* :func:`cache_failed` — the one line, said once a process per problem, that a cache cannot be written,
  why, and what that costs (speed only, never a result; what it holds is still read where its folder can
  be, a shared cache mounted read-only: the line says so); :func:`cache_warnings` — the lines on the caches
  as they are now, which a run records (a folder fixed since is said no more); :func:`cache_warnings_held` —
  a sweep's point keeps them for its sweep to say. A write that fails under a cache's folder (a full disk, the
  folder replaced by a file since it was first looked at) says its line too (:func:`tlm.storage.on_failed_write`,
  :func:`cache_write_failed`); one that succeeds clears a line only a failed write could tell
  (:func:`cache_written`).
* :func:`file_digest`, :func:`digest_problem` — the size and checksum a cache entry's sidecar keeps
  of a file, and why a file is not the one described; :func:`cached_image` — an image entry read
  back whole, or a damaged one said and removed, so that it is computed again; :func:`fields_problem` —
  why a sidecar lacks a key it must hold, or holds one of another type; :func:`remove_entry` — a
  damaged entry removed (a folder where a file should be too), only inside its cache; :func:`note_use` —
  an entry's file marked used now (``tlm cache prune``'s least recently used), where it can be.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import stat
import threading
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from tlm import storage
from tlm.errors import EnvironmentFailure, InputError, environment_problem
from tlm.storage import on_failed_write, warn


def cache_home() -> Path:
    """The folder of tlm's caches: ``$TLM_CACHE``; else ``$XDG_CACHE_HOME/tlm`` where
    ``XDG_CACHE_HOME`` is set to an absolute path (the XDG spec has a relative one ignored);
    else ``~/.cache/tlm``. An empty variable counts as unset. A relative ``$TLM_CACHE`` is made
    absolute at its first read (:func:`own_cache`), from the working folder then."""
    if own := own_cache():
        return Path(own)
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg and os.path.isabs(xdg):
        return Path(xdg) / "tlm"
    return Path.home() / ".cache" / "tlm"


def own_cache() -> str | None:
    """``$TLM_CACHE`` (None where unset or empty), absolute: a relative one is made absolute the first
    time it is read (as this module is imported, else at the first :func:`cache_home` after it was set),
    from the working folder then, and written back to ``os.environ``, so that a later ``os.chdir``
    (a notebook's, a script's), a sweep's workers (given this process's ``TLM_*`` variables, whatever
    folder they start in) and the processes this one starts all use that one folder."""
    own = os.environ.get("TLM_CACHE")
    if not own:
        return None
    if not os.path.isabs(own):
        try:
            own = os.path.abspath(own)
        except OSError:  # (the working folder removed: none to start from; read as it is, made absolute later)
            return own
        os.environ["TLM_CACHE"] = own
    return own


own_cache()  # (its first read: a relative one from the working folder as tlm's caches are first imported)


# tlm's caches that a run writes to: their names in a warning, and what a cache that cannot be written
# costs where its folder can be read (what it holds is still read: a shared cache mounted read-only, a full
# disk), and where it cannot (none there, a path under a file) (the tracebacks' folder, which falls back to
# the temporary folder, and numba's, which says its own line, are not among them)
_FRAMES = ("the frames it holds are read, but none is added: a frame not in it is rendered again by every run and "
           "sweep point, even points that differ only in arch.*")  # (a sweep of cached frames renders none)
CACHES = {
    "functional": ("functional", _FRAMES, _FRAMES),
    "scenes": ("scene", "the parsed meshes and scene fingerprints it holds are read, but none is added: a large "
               "mesh not in it is parsed again on every load, by each process (a finished sweep's rerun too)",
               "large meshes are parsed again on every load, and no scene's fingerprint is remembered: "
               "each process (a finished sweep's rerun too) parses its mesh scenes again"),
    "references": ("reference", "the references it holds are read, but none is added: a photon-map reference not "
                   "in it is computed again by every run", "photon-map references are computed again by every run"),
    "oracle": ("Mitsuba ground-truth", "the ground truths it holds are read, but none is added: a ground truth not "
               "in it is rendered again by every run", "ground truths are rendered again by every run"),
}
# the caches a use needs before their line is said (cache_needed): the scene cache's remembered fingerprints are
# looked up for every scene, but only a mesh file's load costs what its line says (a scene of no mesh file none)
WAIT_FOR_USE = frozenset({"scenes"})
CACHE_WARNING = "cannot write tlm's "  # how each line of cache_warnings() starts
_CACHE_LOCK = threading.Lock()
_CACHE_CHECKED: set[Path] = set()  # the cache folders looked at in this process
_CACHE_LINES: dict[Path, str] = {}  # a cache folder that cannot be written -> its line, as last found
_CACHE_WRITES: set[Path] = set()  # those of _CACHE_LINES a failed write told, which looking cannot (a full disk)
_CACHE_SAID: set[str] = set()  # the lines said on stderr in this process
_CACHE_HELD = 0  # > 0: the lines are kept, not said (a sweep point: its sweep says them once)
_CACHE_NEEDED: set[Path] = set()  # the folders of WAIT_FOR_USE a use needed in this process (cache_needed)
_CACHE_WAITING: set[Path] = set()  # those of WAIT_FOR_USE the first look found unwritable, not needed yet


def cache_root(kind: str) -> Path:
    """``<cache_home()>/<kind>``: the folder of one of tlm's caches.

    The first call in a process for a cache of :data:`CACHES` checks that the folder can be
    written (or made); where it cannot, one line says so (:func:`cache_failed`): a cache
    that cannot be written costs speed only, never a result, but the user is told which.
    A cache of :data:`WAIT_FOR_USE` (the scene cache) says it once a use needs it (:func:`cache_needed`).
    """
    folder = cache_home() / kind
    if kind in CACHES and folder not in _CACHE_CHECKED:
        with _CACHE_LOCK:
            _CACHE_CHECKED.add(folder)
        why = cache_problem(folder)
        if why is not None:
            with _CACHE_LOCK:
                wait = kind in WAIT_FOR_USE and folder not in _CACHE_NEEDED
                if wait:
                    _CACHE_WAITING.add(folder)
            if not wait:
                cache_failed(folder, why)
    return folder


def cache_needed(kind: str) -> Path:
    """:func:`cache_root` for a use that needs the cache (the scene cache: a mesh file's load,
    :func:`tlm.scenes.cache.cache_dir`): a line its first look found and kept (:data:`WAIT_FOR_USE`: a
    scene of no mesh file loses nothing by it) is said now, where the folder still cannot be written."""
    folder = cache_root(kind)
    with _CACHE_LOCK:
        if folder in _CACHE_NEEDED:
            return folder
        _CACHE_NEEDED.add(folder)
        waited = folder in _CACHE_WAITING
        _CACHE_WAITING.discard(folder)
    if waited and (why := cache_problem(folder)) is not None:
        cache_failed(folder, why)
    return folder


def cache_problem(folder: Path) -> str | None:
    """Why nothing can be written into ``folder`` (nor the folder made), or None. Looked at,
    not tried: nothing is created (``os.access``, which a root user's read-only mount fails too)."""
    p = Path(folder)
    while True:
        try:
            st = p.stat()
            break
        except (FileNotFoundError, NotADirectoryError):
            if p.parent == p:
                return f"{p} does not exist"
            p = p.parent
        except OSError as e:
            return f"{p}: {(e.strerror or str(e)).lower()}"
    if not stat.S_ISDIR(st.st_mode):
        return f"{p} is a file, not a folder"
    if os.access(p, os.W_OK | os.X_OK):
        return None
    try:
        read_only = bool(os.statvfs(p).f_flag & os.ST_RDONLY)
    except OSError:
        read_only = False
    return f"{p} is on a read-only file system" if read_only else f"{p} is not writable (permission denied)"


def cache_failed(path: Path, why: str) -> None:
    """Note that one of tlm's caches (the one ``path`` is in or under) cannot be written, why, and what
    that costs, and say it (once a process per line: :func:`say_cache_warning`); nothing for a path in none.
    ``why`` is a failed write's; where looking at the folder finds why (:func:`cache_problem`: a file in
    its place since it was first looked at), that is the line, the one a fresh process says. A failed write's
    line stands till a write succeeds (:func:`cache_written`) or looking finds why: the next failed write's, of
    another entry (a short write's other sizes), is not a new problem, said again a frame."""
    path = Path(path)
    home = cache_home()
    kind = next((k for k in CACHES if path == home / k or home / k in path.parents), None)
    if kind is None:
        return
    folder = home / kind
    seen = cache_problem(folder)
    line = _cache_line(folder, seen or why)
    with _CACHE_LOCK:
        if _CACHE_LINES.get(folder) == line or (seen is None and folder in _CACHE_WRITES):
            return
        _CACHE_LINES[folder] = line
        if seen is None:
            _CACHE_WRITES.add(folder)
        else:
            _CACHE_WRITES.discard(folder)
        held = _CACHE_HELD > 0
    if not held:
        say_cache_warning(line)


def _cache_line(folder: Path, why: str) -> str:
    """The line on the cache ``folder`` (``<cache_home()>/<kind>``) that cannot be written, and why: what it
    costs where the folder can still be read (what it holds is read) or where it cannot (:data:`CACHES`)."""
    name, read, unread = CACHES[folder.name]
    cost = read if os.path.isdir(folder) and os.access(folder, os.R_OK | os.X_OK) else unread
    return f"{CACHE_WARNING}{name} cache {folder} ({why}): {cost}; set TLM_CACHE to a writable folder"


def say_cache_warning(line: str) -> bool:
    """:func:`warn` a line of :func:`cache_warnings` (this process's or a worker's) unless this
    process said it already (here, or a sweep's ``warn``: :data:`tlm.storage.SAID`); whether it was said now."""
    with _CACHE_LOCK:
        if line in _CACHE_SAID or " ".join(line.split()) in storage.SAID:
            return False
        _CACHE_SAID.add(line)
    warn(line)
    return True


def cache_warnings() -> list[str]:
    """The lines on the caches of :func:`cache_home` this process cannot write (:func:`cache_failed`),
    said or held, as they are now: each folder found unwritable is looked at again (once a call: a run's
    record, a sweep point's, a sweep's; :func:`cache_problem`, a few system calls). One fixed since is
    left out (and looked at afresh by the next :func:`cache_root`), one whose problem changed gets its new
    line; a line a failed write told (a full disk) stays till a write into that cache succeeds
    (:func:`cache_written`). Outside :func:`cache_warnings_held`, a line not said yet in this process (met
    while held: a sweep's point in this process) is said now, as a fresh process says it."""
    home = cache_home()
    with _CACHE_LOCK:
        found = [folder for folder in _CACHE_LINES if folder.parent == home]
    lines = []
    for folder in found:
        why = cache_problem(folder)
        with _CACHE_LOCK:
            if folder not in _CACHE_LINES:  # (cleared meanwhile by another thread's write)
                continue
            if why is not None:
                _CACHE_LINES[folder] = _cache_line(folder, why)
                _CACHE_WRITES.discard(folder)
            elif folder not in _CACHE_WRITES:  # (fixed: said no more)
                del _CACHE_LINES[folder]
                _CACHE_CHECKED.discard(folder)
                continue
            lines.append(_CACHE_LINES[folder])
            held = _CACHE_HELD > 0
        if not held:
            say_cache_warning(lines[-1])
    return lines


def cache_written(path: Path) -> None:
    """A write into one of tlm's caches (the one ``path`` is in or under) succeeded: a line on it that
    only a failed write could tell (a full disk since freed) is said no more."""
    path = Path(path)
    home = cache_home()
    with _CACHE_LOCK:
        for folder in [f for f in _CACHE_WRITES if path == f or f in path.parents]:
            if folder.parent == home:
                _CACHE_WRITES.discard(folder)
                _CACHE_LINES.pop(folder, None)


@contextmanager
def cache_warnings_held() -> Iterator[None]:
    """While the block runs, a cache that cannot be written is noted (:func:`cache_warnings`),
    not said: a sweep's point, whose sweep says each line once for all its workers."""
    global _CACHE_HELD
    with _CACHE_LOCK:
        _CACHE_HELD += 1
    try:
        yield
    finally:
        with _CACHE_LOCK:
            _CACHE_HELD -= 1


def cache_write_failed(path: Path, e: BaseException) -> None:
    """A write under one of the caches failed (:func:`tlm.storage.write_atomic`,
    :func:`tlm.storage.atomic_folder`, which call this on every failed write once this module is
    imported; a cache's writer for the rest of its write, its folder's ``mkdir``): said once (a full disk,
    a folder :func:`cache_problem` could not tell was read-only, a file put in a folder's place since)."""
    if isinstance(e, EnvironmentFailure) and isinstance(e.__cause__, OSError):
        e = e.__cause__  # (tlm.storage's, naming the entry: the machine's words alone, as its hearer was told)
    if isinstance(e, EnvironmentFailure):
        why = str(e)
    elif isinstance(e, OSError):
        why = environment_problem(e, filename=False) or (e.strerror or str(e)).lower()
    elif isinstance(e, InputError):  # (check_destination's: a file, or something else, in the way)
        why = str(e).removeprefix(f"{e.key}: ") if e.key else str(e)
    else:
        return
    cache_failed(path, why)


_note_cache_write = cache_write_failed  # (the name tlm.storage's hearers knew it by)
on_failed_write(_note_cache_write)  # (tlm.storage knows nothing of caches: it tells whoever asked)


def file_digest(path: Path) -> dict:
    """``{"size": bytes, "sha256": hex}`` of a file, for a cache entry's sidecar."""
    h = hashlib.sha256()
    size = 0
    with open(path, "rb") as fh:
        while chunk := fh.read(1 << 20):
            h.update(chunk)
            size += len(chunk)
    return {"size": size, "sha256": h.hexdigest()}


def cached_image(folder: Path, name: str, key: str, what: str, again: str, fields: dict | None = None,
                 optional: dict | None = None):
    """The image ``folder/name`` (an (H, W, 3) float ``.npy``) and ``folder/meta.json`` of
    the cache entry ``key``, or None when there is none. A damaged entry is reported once as a
    warning naming the file (``what``: the entry's kind; ``again``: what computes it again) and
    removed, so it is computed again as if never cached: ``meta.json`` unreadable (a folder too)
    or of another key, without the size and checksum of the image (``npy``: an entry of an older
    tlm, or a damaged one), without a key of ``fields``, or with a key of ``fields`` or ``optional``
    of another type (:func:`fields_problem`; ``height`` and ``width`` whole numbers); the image
    not the file ``meta.json`` describes, by its ``npy`` digest and its ``height`` and ``width``
    where given, or not (H, W, 3) floats.

    Another process (or thread) writing the same entry meanwhile replaces its folder whole
    (:func:`tlm.storage.atomic_folder`: the old one renamed aside and removed, the new one renamed
    into place): files read across that replacement (the ``meta.json`` of one folder and the image
    of the next, or none where the old one was removed) are no damaged entry; the entry is read
    again, and never said damaged nor removed unless the folder found damaged is the one still there."""
    for _ in range(_READS):
        try:  # (held open, the folder read keeps its inode number: it is told from any other one there)
            held = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
        except (FileNotFoundError, NotADirectoryError):
            held = None
        except OSError:  # (a folder this process may not read: judged as it is, as before)
            held = _UNHELD
        try:
            found, bad, why = _read_image(folder, name, key, fields, optional)
            if why is None:
                if found is not None:
                    note_use(folder / "meta.json")
                return found
            if not _still_there(folder, held):
                continue  # (replaced while it was read: read the new one)
            left = remove_entry(folder, folder.parent)
        finally:
            if held not in (None, _UNHELD):
                os.close(held)
        done = "removed" if left is None else f"not removed ({left})"
        warn(f"damaged {what} cache entry {bad} ({why}): {done}; {again}")
        return None
    return None  # (replaced again each time it was read: as if not cached, computed again)


def note_use(path: Path) -> None:
    """Mark a cache entry's file ``path`` used now (its modification time: ``tlm cache prune`` removes the
    least recently used first, and access times are often not kept); nothing where it cannot be (a
    read-only cache, another user's): a read never fails for it."""
    with suppress(OSError, NotImplementedError):  # (a link is not followed: its own time, if any)
        os.utime(path, follow_symlinks=False)


_READS = 5  # times an entry replaced while it is read is read again (cached_image)
_UNHELD = -1  # (cached_image: a folder that could not be opened, not one that was not there)


def _still_there(folder: Path, held: int | None) -> bool:
    """Whether ``folder`` is the folder ``held`` (a descriptor opened on it before it was read,
    or None where there was none then) still: not replaced, nor made, meanwhile."""
    if held == _UNHELD:
        return True
    try:
        now = os.stat(folder)
    except OSError:
        return False  # (gone: being replaced, the new one not yet in place, or removed by another reader)
    if held is None:
        return not stat.S_ISDIR(now.st_mode)
    return os.path.samestat(now, os.fstat(held))


def _read_image(folder: Path, name: str, key: str, fields: dict | None, optional: dict | None):
    """:func:`cached_image`'s reading: ``((image, meta), None, None)``, ``(None, None, None)`` where
    there is no entry, or ``(None, bad, why)``: the damaged file and what is wrong with it."""
    import numpy as np

    npy, side = folder / name, folder / "meta.json"
    if not npy.exists() and not side.exists():  # (a folder in place of either is a damaged entry)
        return None, None, None
    bad, why = side, None
    try:
        meta = json.loads(side.read_text(encoding="utf-8"))
        if not isinstance(meta, dict) or meta.get("key") != key:
            raise ValueError("not the metadata of this entry")
    except (OSError, ValueError) as e:
        why = f"unreadable ({_error_text(e)})"
    if why is None:
        why = fields_problem(meta, fields or {}, {"height": int, "width": int, **(optional or {})})
        if why is None and "npy" not in meta:
            why = f"it has no size and checksum of {name} (an entry of an older tlm, or a damaged one)"
    if why is None:
        bad = npy
        why = digest_problem(npy, meta["npy"])
    if why is None:
        try:
            image = np.load(npy, allow_pickle=False)
            size = (meta.get("height"), meta.get("width"))
            if image.dtype.kind != "f" or image.ndim != 3 or image.shape[-1] != 3:
                raise ValueError(f"an array of {image.dtype} {image.shape}, not (H, W, 3) floats")
            if all(isinstance(n, int) for n in size) and image.shape[:2] != size:
                raise ValueError(f"an image of {image.shape[1]}x{image.shape[0]} pixels, its meta.json says "
                                 f"{size[1]}x{size[0]}")
            return (image, meta), None, None
        except (OSError, ValueError, EOFError) as e:
            why = _error_text(e)
    return None, bad, why


def _error_text(e: BaseException) -> str:
    """``Type: message`` of an error on one line: an OSError's reason without its file name (the
    warning names the file; a name cut short read as a broken quote), any other message cut after
    120 characters with an ellipsis."""
    text = (e.strerror or str(e)) if isinstance(e, OSError) else str(e)
    text = " ".join(text.split())
    return f"{type(e).__name__}: {text if len(text) <= 120 else text[:117] + '...'}"


_KIND_NAMES = {int: "a whole number", float: "a number", str: "a string", bool: "true or false", list: "a list",
               dict: "an object", type(None): "null"}


def fields_problem(meta: dict, fields: dict, optional: dict | None = None) -> str | None:
    """Why ``meta`` (a cache entry's metadata) does not hold each key of ``fields`` as a value of
    its type(s) (``{"rounds": int, "relative_standard_error": (int, float, type(None))}``; true and
    false are no number), or holds a key of ``optional`` of another type than its, or None."""
    for k, kinds in {**(optional or {}), **fields}.items():
        kinds = kinds if isinstance(kinds, tuple) else (kinds,)
        if k not in meta:
            if k in fields:
                return f"it has no {k!r}"
            continue
        v = meta[k]
        if not isinstance(v, kinds) or (isinstance(v, bool) and bool not in kinds):
            shown = json.dumps(v)
            shown = shown if len(shown) <= 40 else shown[:37] + "..."
            return f"its {k!r} is {shown}, not {' or '.join(_KIND_NAMES.get(t, t.__name__) for t in kinds)}"
    return None


def remove_entry(path: Path, root: Path) -> str | None:
    """Remove the cache entry ``path``: a file, a symbolic link (not what it points to), or a
    folder where a file should be (a whole tree); only where it lies in ``root`` (a cache's
    folder, or one below it), never elsewhere. Why it was not removed, or None (removed, or
    gone already)."""
    path = Path(path)
    try:
        here, top = path.parent.resolve(), Path(root).resolve()
        if here != top and top not in here.parents:
            return f"it is not in the cache folder {root}"
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)
    except OSError as e:
        return (e.strerror or str(e)).lower()
    return None


def digest_problem(path: Path, digest: object) -> str | None:
    """Why ``path`` is not the file :func:`file_digest` described (``digest``), or None."""
    if not isinstance(digest, dict) or not isinstance(digest.get("size"), int):
        return "its sidecar has no size and checksum"
    try:
        st = Path(path).stat()
    except OSError as e:
        return f"cannot read it ({e.strerror or e})"
    if stat.S_ISDIR(st.st_mode):  # (not its size: a folder's own bytes)
        return "a folder, not a file"
    size = st.st_size
    if size != digest["size"]:
        return f"{size} bytes, its sidecar says {digest['size']}"
    if file_digest(path)["sha256"] != digest.get("sha256"):
        return "its checksum differs from its sidecar's"
    return None

