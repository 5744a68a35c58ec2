"""The scene's part of a functional-cache key (:mod:`tlm.experiments.frames`): :func:`scene_key` loads a scene once in
a process and remembers its fingerprint (:func:`~tlm.experiments.frame_scenes.scene_fingerprint`) while the files the
load read are unchanged (:func:`~tlm.experiments.frame_scenes.unchanged`), so the points of a sweep that differ only in
``arch`` do not load it again each; a scene with mesh files on disk too (``scenes/key-<hash>.json`` in tlm's cache:
:func:`_kept_key`, :func:`keep_key`), so that another process (a rerun of a sweep whose points are done) parses no
mesh for it; a dry run's read of it is a look, not a use (:func:`looked`: the file's times as they were, which
``tlm cache prune`` reads). Out of :mod:`tlm.experiments.frames` (h487), which re-exports :func:`scene_key` and
:data:`MEMO_SIZE` (and :func:`scene_key_loaded` and :func:`keep_key` by their old names there, ``_scene_key`` and
``_keep_key``).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import threading
from collections import OrderedDict
from pathlib import Path

from tlm.cache_look import unmarked
from tlm.caches import cache_root, cache_write_failed, cache_written, note_use, remove_entry
from tlm.config import decoded, noting_reads, read_bytes, text_digest
from tlm.errors import InputError
from tlm.experiments.frame_scenes import TELLS, read_checks, scene_fingerprint, unchanged
from tlm.experiments.provenance import scene_identity
from tlm.fingerprint import code_fingerprint
from tlm.progress import Timer
from tlm.scenes.cache import parse_versions, writable
from tlm.scenes.loader import load_scene, resolve_scene_path
from tlm.scenes.model import Scene
from tlm.storage import write_atomic

MEMO_SIZE = 8  # the scenes whose fingerprint one process remembers (the least recently used goes)
_SCENE_KEYS: OrderedDict[tuple, tuple] = OrderedDict()  # inputs -> (fingerprint, checks, scene digest, _yaml_bytes)
_MEMO_LOCK = threading.Lock()


def scene_key(ref, base: Path | None = None, resolution: list[int] | None = None, source: str | None = None
              ) -> str:
    """:func:`~tlm.experiments.frame_scenes.scene_fingerprint` of :func:`~tlm.scenes.loader.load_scene` ``(ref, base,
    resolution, source)``, remembered: the points of a sweep that differ only in ``arch``
    share a frame, and its key no longer loads the scene at each point.

    It is remembered (:data:`MEMO_SIZE` scenes, the least recently used forgotten) by the
    arguments but ``source`` (which only names the config in an error), the working folder,
    the scene file they name and the code (:func:`~tlm.fingerprint.code_fingerprint`), with
    every file the load read (:func:`tlm.config.noting_reads`): the scene file and its
    ``extends:`` chain by the sha256 of their text and the file each ``extends:`` finds now,
    each mesh file with the files its load read beside it (an OBJ's material libraries, as the
    load finds them now; a glTF's buffers) by their sha256, which must be that of the bytes the
    parse read (a load during which one was saved is not remembered). A remembered fingerprint is given
    again only while all of them are as they were, so a file edited between two sweeps of one
    process (even to the same size and modification time) is read again. A load that read a
    file it cannot check this way is not remembered. Only the fingerprint (a string) is kept,
    not the :class:`~tlm.scenes.model.Scene`, so no caller can change what is remembered."""
    return scene_key_loaded(ref, base, resolution, source)[0]


def scene_key_loaded(ref, base: Path | None, resolution: list[int] | None, source: str | None,
               timer: Timer | None = None) -> tuple[str, Scene | None, str | None]:
    """:func:`scene_key` with the scene it loaded, or None where it gave the remembered
    fingerprint (a caller that renders next uses this one: the scene loaded once), and the scene's
    digest (``results.json``'s ``scene_digest``, as :func:`tlm.experiments.run.render` records a run's:
    :func:`~tlm.experiments.provenance.scene_identity` of the files that load read, from the digests it
    computed), remembered with the fingerprint (in this process and on disk) while those files are
    unchanged and its YAML files keep their bytes (:func:`_yaml_bytes`: the checks tell their text): a sweep's points
    of one scene digest it once (an entry on disk of a tlm before it, none: its files digested once, and kept).

    A fingerprint is remembered in this process and, for a scene with mesh files (their parse is the
    cost), on disk too (:func:`_kept_key`: ``scenes/key-<hash>.json`` in tlm's cache), under the same key
    and checks: another process (a rerun of a sweep whose points are done, a sweep's worker) gives it
    without loading the scene while every file the load read is as it was (each file's sha256: the
    mesh parsed from the same bytes by the same code gives the same fingerprint), so a rerun that
    computes nothing parses no mesh, nor writes a pruned mesh entry back. The key is the parsed
    scene's fingerprint as ever: what is remembered is only which one those files give."""
    timer = Timer() if timer is None else timer
    path = resolve_scene_path(ref, base, source)  # (a missing scene: load_scene's own error)
    # (not ``source``: it names the config in a load's errors, and a remembered load had none)
    key = (os.fspath(ref), None if base is None else str(base),
           None if resolution is None else tuple(resolution), os.getcwd(), str(path), code_fingerprint())
    try:
        hash(key)
    except TypeError:  # (a resolution of other items than numbers: load_scene says what is wrong)
        with timer.stage("load_scene"), noting_reads() as reads:
            scene = load_scene(ref, base, resolution, source)
            digest = scene_identity(scene.source, reads) if scene.source else None
        return scene_fingerprint(scene), scene, digest
    with _MEMO_LOCK:
        hit = _SCENE_KEYS.get(key)
    if hit is None:
        hit = _kept_key(key)
    now = None if hit is None else _told(hit[1])  # (before the digest: a file saved between is digested again next)
    if now is not None:
        if hit[2] is None or now != hit[3]:  # (an entry of a tlm before the digest; a YAML file's bytes not those
            # digested, its text the same (its line ends: the checks' text is in universal newlines): digested now)
            hit = (hit[0], hit[1], scene_identity(path), now)
            if any(c[0] in ("libraries", "listed") for c in hit[1]):  # (kept on disk: once, not once a process)
                keep_key(key, *hit)
        with _MEMO_LOCK:
            _SCENE_KEYS[key] = hit
            _SCENE_KEYS.move_to_end(key)
            while len(_SCENE_KEYS) > MEMO_SIZE:
                _SCENE_KEYS.popitem(last=False)
        return hit[0], None, hit[2]
    with noting_reads() as reads, timer.stage("load_scene"):
        scene = load_scene(ref, base, resolution, source)
    fingerprint = scene_fingerprint(scene)
    checks = read_checks(reads)  # (the load's reads alone: not the digest's own read of the scene's YAML)
    now = None if checks is None else _yaml_bytes(checks)
    with timer.stage("load_scene"):  # (of the load's stage, as a run's: its files' digests, most of them the load's)
        digest = scene_identity(scene.source, reads) if scene.source else None
    with _MEMO_LOCK:
        _SCENE_KEYS.pop(key, None)
        if checks is not None:
            _SCENE_KEYS[key] = (fingerprint, checks, digest, now)
            while len(_SCENE_KEYS) > MEMO_SIZE:
                _SCENE_KEYS.popitem(last=False)
    if checks is not None and any(c[0] in ("libraries", "listed") for c in checks):  # (a mesh parsed: the cost)
        keep_key(key, fingerprint, checks, digest, now)
    return fingerprint, scene, digest


def _told(checks: list) -> list | None:
    """:func:`_yaml_bytes` of a remembered load's ``checks`` where every file tells what it told then
    (:func:`~tlm.experiments.frame_scenes.unchanged`, in their order), else None: each YAML file read once, its
    ``text`` check's text (:func:`tlm.config.read_text`) and its bytes' sha256 from one read."""
    sums = []
    try:
        for check in checks:
            if check[0] != "text" or len(check) != 3:  # (a text check of other arguments: unchanged's TypeError)
                if not unchanged([check]):
                    return None
                continue
            data = read_bytes(Path(check[1]))
            if text_digest(decoded(data, Path(check[1]))) != check[-1]:
                return None
            sums.append(hashlib.sha256(data).hexdigest())
    except (OSError, InputError, ValueError, TypeError, AttributeError, KeyError, IndexError):
        return None  # (as unchanged: a file gone or unreadable, a check read from disk not understood)
    return sums


def _yaml_bytes(checks: list) -> list | None:
    """The sha256 of the bytes of each YAML file of a load's ``checks`` (its ``text`` ones: the scene file and its
    ``extends:`` chain), which the scene's digest hashes and those checks do not tell (their text is in universal
    newlines: a file saved with CRLF line ends is the same text, other bytes); None where one is not read."""
    try:
        return [hashlib.sha256(Path(c[1]).read_bytes()).hexdigest() for c in checks if c[0] == "text"]
    except (OSError, TypeError, ValueError):
        return None


SCENE_KEY_FORMAT = "tlm-scene-key/1"  # the "tlm" field of a remembered scene fingerprint (scenes/key-<hash>.json)
_DIGEST = re.compile("sha256 [0-9a-f]{16}")  # (a scene digest of a scene file that loaded: scene_identity's)


def _key_file(key: tuple) -> tuple[Path, list] | None:
    """The file that remembers the fingerprint of the scene load ``key`` (a :func:`scene_key_loaded` key) on
    disk, with the key as JSON; None where the key is no JSON."""
    try:
        plain = json.loads(json.dumps([*key, parse_versions()]))  # (a parse's libraries: the mesh cache's too)
    except (TypeError, ValueError):
        return None
    name = hashlib.sha256(json.dumps(plain).encode()).hexdigest()[:24]
    return cache_root("scenes") / f"key-{name}.json", plain


def _kept_key(key: tuple) -> tuple[str, list, str | None, list | None] | None:
    """The fingerprint, checks, scene digest and its YAML files' bytes' sha256 (:func:`_yaml_bytes`) remembered on disk
    for ``key`` (:func:`keep_key`; the digest and bytes None where a tlm before them kept the entry, or either is
    damaged: the files digested again), or None: none kept,
    or one not read whole (its checks then run as a load's would: a damaged one costs a load, quietly)."""
    found = _key_file(key)
    if found is None:
        return None
    path, plain = found
    try:  # (a dry run's read is a look, not a use: the file's times as they were)
        kept = json.loads(path.read_text(encoding="utf-8") if writable() else looked(path).decode("utf-8"))
        if (not isinstance(kept, dict) or kept.get("tlm") != SCENE_KEY_FORMAT or kept.get("key") != plain
                or not isinstance(kept.get("fingerprint"), str) or not isinstance(kept.get("checks"), list)
                or not all(isinstance(c, list) and c and c[0] in TELLS for c in kept["checks"])):
            return None
    except (OSError, ValueError):
        return None
    if writable():  # (not inside tlm.scenes.cache.read_only: a dry run)
        note_use(path)  # (tlm cache prune keeps the fingerprints in use)
    digest, digested = kept.get("digest"), kept.get("digested")  # (either damaged or not there: digested again)
    if not (isinstance(digest, str) and _DIGEST.fullmatch(digest) and isinstance(digested, list)
            and all(isinstance(d, str) for d in digested)):
        digest = digested = None
    return kept["fingerprint"], kept["checks"], digest, digested


def keep_key(key: tuple, fingerprint: str, checks: list, digest: str | None = None,
              digested: list | None = None) -> None:
    """Remember ``fingerprint`` of the scene load ``key`` with its ``checks`` (and the scene's ``digest``, its
    ``scene_digest``) on disk (speed only: a cache
    that cannot be written is left as it is; nothing inside :func:`tlm.scenes.cache.read_only`, a dry run). A
    folder where the file should be is a damaged entry (:func:`_kept_key` read none): removed, the file written."""
    found = _key_file(key) if writable() else None
    if found is None:
        return
    path, plain = found
    body = {"tlm": SCENE_KEY_FORMAT, "key": plain, "fingerprint": fingerprint, "checks": checks, "digest": digest,
            "digested": digested}  # (the sha256 of the bytes of its YAML files that digest is of: _yaml_bytes)
    try:
        text = json.dumps(body)
    except (TypeError, ValueError):
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.is_dir() and not path.is_symlink():  # (not the whole cache that cannot be written: this entry)
            remove_entry(path, path.parent)
        with write_atomic(path) as f:
            f.write(text)
    except OSError as e:  # (said once, as any failed write into a cache: its folder's mkdir's too)
        cache_write_failed(path, e)
    else:
        cache_written(path)


def looked(path: Path, digest: bool = False) -> bytes | dict:
    """The bytes of ``path`` (with ``digest``: their size and sha256, as :func:`~tlm.caches.file_digest` gives them,
    read a MiB at a time), read without changing its access time (:func:`tlm.cache_look.unmarked`); OSError where it
    cannot be read. A look at a cache entry that is not a use of it (``tlm sweep --dry-run``:
    :func:`tlm.experiments.frames.is_cached`, :func:`_kept_key`)."""
    return unmarked(path, _digest if digest else (lambda fh: fh.read()))


def _digest(fh) -> dict:
    """``{"size", "sha256"}`` of what the open file ``fh`` holds, read a MiB at a time."""
    h, size = hashlib.sha256(), 0
    while chunk := fh.read(1 << 20):
        h.update(chunk)
        size += len(chunk)
    return {"size": size, "sha256": h.hexdigest()}
