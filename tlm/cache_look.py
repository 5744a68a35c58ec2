"""A look at a cache entry that is no use of it (:func:`peek`: its access time left as it was), and what the entry is
(:func:`describe`: its kind, what its sidecar says, and whether a frame is **stale**, written by other code than this
tlm's). Out of :mod:`tlm.cache_admin` (h517), which re-exports both: ``tlm cache``'s survey, listing and prune read
every frame's sidecar through them, so a look by a user who does not own the file (a shared cache: reading it would
set its access time, which only its owner may set back) is not made, and leaves the entry's last use as it was.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import stat
from pathlib import Path

from tlm.fingerprint import code_fingerprint

HEX = r"[0-9a-f]{16,64}"  # (a cache key, as tlm.cache_admin reads entries' names)
PARTIAL = re.compile(rf"{HEX}\.partial\.npz")  # (references/: the rounds saved of a reference, a file)
UNREAD = type("Unread", (), {"__repr__": lambda self: "UNREAD"})()  # (peek's: a file it did not look at, own=True)
# what an entry is (:attr:`Entry.kind`), by its cache (a scenes entry: by its name's start)
_KINDS = {"functional": "frame", "references": "reference", "oracle": "ground truth", "tracebacks": "traceback",
          "numba": "kernel", "mesh": "mesh", "normals": "crease normals", "key": "scene key"}
_CODE_LINE = re.compile(rb'\n "code_fingerprint": "([0-9a-f]+)"[,\n]')  # (a sidecar's, as frames writes it)


def describe(e, whole: bool = False) -> None:
    """Set what the entry ``e`` is: its :attr:`~Entry.kind`; a frame's :attr:`~Entry.stale` (its sidecar's
    ``code_fingerprint`` not :func:`~tlm.fingerprint.code_fingerprint`); ``whole``: its :attr:`~Entry.about` too,
    from a frame's sidecar (scene, resolution, mode) or a reference's or ground truth's ``meta.json`` and image's
    header. A look is no use: access times are left as they were (:func:`peek`), and a file this process may not
    look at so (another user's: reading it marks it used, its access time the owner's alone to set back) is not
    read: such a frame is not judged (its ``stale`` None, as :func:`~tlm.cache_admin.prune` leaves it)."""
    e.kind = "partial" if PARTIAL.fullmatch(e.name) else _KINDS.get(e.name.split("-")[0] if e.cache == "scenes"
                                                                     else e.cache, "")
    if e.kind == "frame":
        side = next((f for f in e.files if f.name.endswith(".json")), None)
        got = _sidecar(side, whole) if side else None
        if got is UNREAD:
            return
        got = got or {}
        e.stale = got.get("code_fingerprint") != code_fingerprint()
        scene, plan = (v if isinstance(v := got.get(k), dict) else {} for k in ("scene", "plan"))
        reasons = v if isinstance(v := plan.get("reasons"), dict) else {}  # (the plan's: "mode 'pmap' asks ...")
        modes = [m[1] for r in reasons.values() if isinstance(r, str) and (m := re.match(r"mode '(\w+)'", r))]
        e.about = {"scene": scene.get("name"), "resolution": scene.get("resolution"),
                   "mode": got.get("mode") or ("pmap" if "fgather" in reasons else modes[0] if modes else None)}
    elif whole and e.kind in ("reference", "ground truth"):
        meta = v if isinstance(v := _sidecar(e.files[0] / "meta.json", True), dict) else {}
        head = peek(e.files[0] / ("reference.npy" if e.kind == "reference" else "image.npy"), lambda f: f.read(512),
                    own=True)
        m = re.search(rb"'shape': \((\d+), (\d+), 3\)", head if isinstance(head, bytes) else b"")
        e.about = {"scene": meta.get("scene"), "resolution": [int(m[2]), int(m[1])] if m else None,
                   **{k: meta.get(k) for k in (("photons", "rounds") if e.kind == "reference" else ("spp",))}}
    e.about = {k: v for k, v in e.about.items() if (isinstance(v, list) and len(v) == 2 and all(
        type(x) is int for x in v) if k == "resolution" else isinstance(v, (str, int)) and not isinstance(v, bool))}


def _sidecar(path: Path, whole: bool):
    """The JSON object in the file ``path``, or None (:data:`UNREAD`: not looked at, :func:`peek`); not ``whole``:
    its top-level ``code_fingerprint`` alone where its line says it, by a regular expression, not a parse (``tlm
    cache`` of 5,000 frames: 0.04 s, not 0.3)."""
    data = peek(path, own=True)
    if data is UNREAD:
        return UNREAD
    if data is not None and not whole:
        if m := _CODE_LINE.search(data):
            return {"code_fingerprint": m[1].decode()}
        if b'"code_fingerprint"' not in data:
            return {}  # (none: a frame of a tlm before the field)
    with contextlib.suppress(ValueError, RecursionError, TypeError):
        return v if isinstance(v := json.loads(data), dict) else None
    return None


def unmarked(path: Path, read=lambda fh: fh.read(), own: bool = False):
    """``read(fh)`` of the file ``path`` (its bytes), its access time left as it was: opened ``O_NOATIME`` where this
    process may (the file's owner), else set back after the read where it changed (its modification time as it is
    then: a reader's mark of use meanwhile kept). An OSError where it cannot be read or is no regular file (a FIFO is
    not waited on). ``own``: :data:`UNREAD` where ``O_NOATIME`` is refused (another user's file, whose access time
    this process cannot set back either). A look at a cache entry that is no use of it, which ``tlm cache prune``
    would otherwise take for one (the later of a file's access and modification times): :func:`peek`,
    :func:`tlm.experiments.frame_keys.looked`."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags | getattr(os, "O_NOATIME", 0))
    except PermissionError:  # (O_NOATIME: the owner's alone)
        if own:
            return UNREAD
        fd = os.open(path, flags)
    try:
        before = os.fstat(fd)
        if not stat.S_ISREG(before.st_mode):
            raise OSError(errno.EINVAL, "not a regular file", os.fspath(path))
        with open(fd, "rb", closefd=False) as fh:
            got = read(fh)
        if (after := os.fstat(fd)).st_atime_ns != before.st_atime_ns and os.utime in os.supports_fd:
            with contextlib.suppress(OSError):  # (not the owner's: its access time is the system's)
                os.utime(fd, ns=(before.st_atime_ns, after.st_mtime_ns))
        return got
    finally:
        os.close(fd)


def peek(path: Path, read=lambda fh: fh.read(), own: bool = False):
    """:func:`unmarked`'s ``read(fh)`` of ``path``, or None where it cannot be read or is no regular file
    (whatever numpy or json say too)."""
    try:
        return unmarked(path, read, own)
    except Exception:
        return None
