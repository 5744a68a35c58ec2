"""A look at a cache entry that is no use of it (:func:`peek`: its access time left as it was), and what the entry is
(:func:`describe`: its kind, what its sidecar says, and whether a frame is **stale**, written by other code than this
tlm's), and what tells frames of one scene, resolution and mode apart (:func:`tell_apart`: the settings their
sidecars record, :func:`frame_settings`, where they differ; h527). Out of :mod:`tlm.cache_admin` (h517), which
re-exports the first two: ``tlm cache``'s survey, listing and prune read
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
        if whole:
            e.settings = frame_settings(got)
    elif whole and e.kind in ("reference", "ground truth"):
        meta = v if isinstance(v := _sidecar(e.files[0] / "meta.json", True), dict) else {}
        head = peek(e.files[0] / ("reference.npy" if e.kind == "reference" else "image.npy"), lambda f: f.read(512),
                    own=True)
        m = re.search(rb"'shape': \((\d+), (\d+), 3\)", head if isinstance(head, bytes) else b"")
        e.about = {"scene": meta.get("scene"), "resolution": [int(m[2]), int(m[1])] if m else None,
                   **{k: meta.get(k) for k in (("photons", "rounds") if e.kind == "reference" else ("spp",))}}
    e.about = {k: v for k, v in e.about.items() if (isinstance(v, list) and len(v) == 2 and all(
        type(x) is int for x in v) if k == "resolution" else isinstance(v, (str, int)) and not isinstance(v, bool))}


def frame_settings(side: dict) -> dict:
    """What a frame's sidecar ``side`` records of its settings beside its scene, resolution and mode (which the key
    holds with the rest, the seed among them, unrecorded): ``spp``; a photon-map frame's ``photons`` (emitted),
    ``filter``, ``final_gather``, each radius given (``radius``, ``caustic_radius``, ``global_radius``: 4 digits) or
    its photons where the density gives it, and its reference's ``reference_photons`` and ``k_nearest``; the scene's
    ``source`` file and ``triangles`` (a scene file changed: a cheap sign of it; a digest of all the sidecar says of
    the scene cost ``tlm cache list`` of 5,000 frames a tenth more time); ``code`` (its ``code_fingerprint``). Only
    what is there, as text or a whole number (:func:`tell_apart`)."""
    scene, primary, photons, pmap = (v if isinstance(v := side.get(k), dict) else {}
                                     for k in ("scene", "primary", "photons", "pmap"))
    got = {"spp": primary.get("spp"), "photons": photons.get("emitted"), "filter": photons.get("filter"),
           "final_gather": photons.get("final_gather")}
    for r in ("radius", "caustic_radius", "global_radius"):
        rule, value = photons.get(f"{r}_rule"), photons.get(r)
        if rule == "density":
            got[f"{r}_photons"] = photons.get(f"{r}_photons")
        elif rule is not None and isinstance(value, (int, float)) and not isinstance(value, bool):
            got[r] = f"{value:.4g}"
    got.update(reference_photons=pmap.get("photons"), k_nearest=pmap.get("k_nearest"), source=scene.get("source"),
               triangles=scene.get("triangles"), code=side.get("code_fingerprint"))
    return {k: v for k, v in got.items() if type(v) in (str, int)}


def tell_apart(entries) -> None:
    """Set each frame's :attr:`~tlm.cache_admin.Entry.differs` among ``entries`` (described ``whole``): where frames
    of one cache, scene, resolution and mode differ in a setting their sidecars record (:func:`frame_settings`),
    each's value of those (where it records one); where two still read the same (a seed, a setting no sidecar
    records), ``other``: the start of each's key (8 hex digits, more where needed), which holds every setting. A frame
    alone of its kind: none. One pass over the entries and a set per setting: 5,000 frames in a few hundredths of a
    second."""
    groups: dict[tuple, list] = {}
    for e in entries:
        if e.kind == "frame":
            a = e.about
            what = (e.cache, a.get("scene"), tuple(a.get("resolution") or ()), a.get("mode"))
            groups.setdefault(what, []).append(e)
    for group in groups.values():
        if len(group) < 2:
            continue
        for e in group:
            e.differs = {}
        for same in _alike(group, recorded=True):  # (a value recorded by some, not by others: said only where needed)
            for alike in _alike(same, recorded=False):
                n = next((n for n in range(8, 65) if len({e.name[:n] for e in alike}) == len(alike)), None)
                for e in alike:
                    e.differs["other"] = e.name[:n]
        short = _shortest({e.differs["source"] for e in group if isinstance(e.differs.get("source"), str)})
        for e in group:  # (in the order of frame_settings, other last; a source shown by its shortest distinct tail)
            e.differs = {k: e.differs[k] for k in sorted(e.differs, key=lambda k: _ORDER.get(k, len(_ORDER)))}
            e.brief = {"source": short[e.differs["source"]]} if e.differs.get("source") in short else {}


def _shortest(sources: set) -> dict:
    """Each of the paths ``sources`` (a group's scene files, which differ) as ``tlm cache list`` shows it: its
    fewest trailing parts that no other one's as many parts are (its file name where that is its own;
    ``a/room.yaml`` beside ``b/room.yaml``), and the whole path where one is the other's tail. No two are shown
    alike: a tail of k parts is no other one's of k, nor one of other parts (k - 1 separators)."""
    parts = {s: Path(s).parts for s in sources}
    out = {}
    for s, mine in parts.items():
        k = next((k for k in range(1, len(mine)) if all(p[-k:] != mine[-k:] for o, p in parts.items() if o != s)),
                 len(mine))
        out[s] = str(Path(*mine[-k:])) if mine else s
    return out


def _alike(group: list, recorded: bool) -> list[list]:
    """The frames of ``group`` that still read the same once each's ``differs`` has the settings the group differs
    in (those with two values or more; not ``recorded``: or recorded by some, not by others): those of two or more."""
    names = sorted({k for e in group for k in e.settings}, key=lambda k: _ORDER.get(k, len(_ORDER)))
    differ = [k for k in names if len({e.settings.get(k) for e in group if k in e.settings or not recorded}) > 1]
    alike: dict[tuple, list] = {}
    for e in group:
        e.differs.update((k, e.settings[k]) for k in differ if k in e.settings)
        alike.setdefault(tuple(e.differs.items()), []).append(e)
    return [same for same in alike.values() if len(same) > 1]


# (the order a frame's settings are said in: frame_settings')
_ORDER = {k: i for i, k in enumerate(("spp", "photons", "filter", "final_gather", "radius", "radius_photons",
                                      "caustic_radius", "caustic_radius_photons", "global_radius",
                                      "global_radius_photons", "reference_photons", "k_nearest", "source", "triangles",
                                      "code"))}


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
