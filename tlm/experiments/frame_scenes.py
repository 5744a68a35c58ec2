"""What of a scene the functional cache's keys hold (:mod:`tlm.experiments.frames`): its fingerprint, and the
checks that tell the files a load read unchanged.

:func:`scene_fingerprint` hashes the scene's content and what its results say of it: its name and its notes,
each path in a note under the scene's folder or a folder above it (not the file system's root) written as
that folder's distance up (:func:`marked_line`), so that a copy of a project in another folder (the same files,
the same relative layout: a mesh at ``../m/x.obj`` too) gives the same fingerprint and shares its frames, while
two mesh files at other places (``../m/x.obj``, ``../n/x.obj``) never do; a cached frame's warnings are then
moved to the copy's folders by :func:`moved_line` (:func:`tlm.experiments.frames._here`).

:func:`read_checks` says, for each file a scene load read (:func:`tlm.config.noting_reads`), what tells it now and
what it told then, and :func:`unchanged` whether they still tell it: how a remembered fingerprint
(:func:`tlm.experiments.frames.scene_key`) is known to be the one those files give.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import re
from pathlib import Path

import numpy as np

from tlm.caches import file_digest
from tlm.config import read_text, text_digest
from tlm.errors import InputError, path_shown
from tlm.scenes.cache import read_as
from tlm.scenes.loader import resolve_scene_path
from tlm.scenes.meshes import mesh_files


def scene_fingerprint(scene) -> str:
    """16 hex digits of the scene's content (triangles, materials, normals, lights, camera, photons), its name,
    its notes and its materials' origins, their paths said from the scene's folder (:func:`marked_line`): not
    where the project lies."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(scene.triangles, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(scene.material_index).tobytes())
    if scene.normals is not None:
        h.update(np.ascontiguousarray(scene.normals, dtype=np.float64).tobytes())
    h.update(repr((scene.materials, scene.lights, scene.camera, scene.photons)).encode())
    # (what its results say of it: its name, and its files' notes with the paths under its folder or one above it
    # said relative to its folder, as given and as a note shows it (path_shown: a tab as \t), so that a copy of the
    # project in another folder shares the frame: marked_line, frames._here)
    folder = os.path.dirname(scene.source) if scene.source else ""
    notes = [marked_line(str(n), folder, tagged=False) for n in scene.extra.get("notes") or []]
    # (and where each material and light came from, results.json's scene.materials' and scene.lights' from:
    # Material.origin, Light.origin, no part of its value; a copy whose MTL defines it on another line, or whose
    # material or lights: another file of its extends: chain gives, has a frame of its own, which names its own line)
    origins = [marked_line(x.origin, folder, tagged=False) for x in (*scene.materials, *scene.lights)]
    h.update(repr((scene.name, notes, origins)).encode())
    return h.hexdigest()[:16]


def _levels(folder: str) -> list[str]:
    """``folder`` and each folder above it, the deepest first, but the file system's root (a copy of a project
    lies in some folder: the root is the same for both, and a ``/`` in a note's words is no path)."""
    out = []
    while folder and os.path.dirname(folder) != folder:
        out.append(folder)
        folder = os.path.dirname(folder)
    return out


_MARK = re.compile("\0([0-9]+)([sr])\0")  # (a note shows no NUL: path_shown escapes it)


def marked_line(line: str, folder: str, tagged: bool = True) -> str:
    """``line`` (a note, a warning) with each path in it under ``folder`` (the scene's) or a folder above it
    (not the root) starting with a mark of that folder: how many folders up it is, and (``tagged``) whether the
    line shows it as a note does (:func:`~tlm.errors.path_shown`: a tab as ``\\t``) or as it is; the deepest first,
    so a path is marked by the folder it is nearest (``../m/x.obj`` one up from the scene's folder: mark 1 and
    ``m/x.obj``). Two copies of one project in other folders give the same marked lines; a path marked is told
    apart from any other, which is marked otherwise or not at all."""
    for form, mark in _marks(folder, tagged):
        line = line.replace(form, mark)
    return line


@functools.lru_cache(maxsize=64)
def _marks(folder: str, tagged: bool) -> tuple[tuple[str, str], ...]:
    """What :func:`marked_line` replaces in a line, in its order, and by what: made once for a folder (5,000 notes
    of a scene 8 folders deep, each folder shown again per note: 0.32 s, 8x the hash of 300k triangles)."""
    out = []
    for k, f in enumerate(_levels(folder)):
        out.append((path_shown(f) + os.sep, f"\0{k}{'s' if tagged else ''}\0"))
        if path_shown(f) != f:  # (and as it is, where the folder has control characters)
            out.append((f + os.sep, f"\0{k}{'r' if tagged else ''}\0"))
    return tuple(out)


def moved_line(line: str, was: str, now: str) -> str:
    """``line`` of a scene in the folder ``was`` as it reads for its copy in ``now``: each path under ``was`` or
    a folder above it that many folders above ``now``, in the form the line showed it (:func:`marked_line`); one
    higher than ``now`` has folders above it (not the root) is left as it was."""
    levels, old = _levels(now), _levels(was)

    def back(m: re.Match) -> str:
        k, shown = int(m[1]), m[2] == "s"
        if k >= max(len(levels), len(old)):  # (no mark of ours: a NUL in a cached line, a sidecar's, kept)
            return m[0]
        f = levels[k] if k < len(levels) else old[k]
        return (path_shown(f) if shown else f) + os.sep

    return _MARK.sub(back, marked_line(line, was))


def read_checks(reads: list) -> list | None:
    """For each file read that :func:`tlm.config.noting_reads` noted, what tells it now and what it
    told then, as JSON (``[kind, *arguments, then]``: :data:`TELLS` tells it now); None where one
    cannot be told so, or where a mesh's file or one its parse read beside it (an OBJ's material
    library, a glTF's buffer) tells now other bytes than the parse read (saved while the scene loaded:
    what it tells now is not what the fingerprint was parsed from; :func:`tlm.scenes.cache.read_as`)."""
    out, seen = [], set()
    try:
        for read in reads:
            said = repr(read[:4])  # (a file read twice the same: one mesh placed twice)
            if said in seen:
                continue
            seen.add(said)
            if read[0] == "side":  # (a file a mesh's parse read beside it: checked with its mesh's, below)
                continue
            if read[0] == "yaml":  # (its text's digest as it was parsed)
                _, path, digest, extends = read
                out.append(["text", path, digest])
                if extends is not None:
                    found = [extends, str(Path(path).parent), path]
                    out.append(["found", *found, tell(["found", *found, None])])
            elif read[0] == "mesh":
                _, path, digest, names, resolve = read
                if digest is None:
                    return None
                if names is not None:  # (an OBJ: its libraries found again beside it; [] for PLY, STL, GLB)
                    check = ["libraries", path, names, _function_name(resolve)]
                else:  # (a glTF's buffers: tlm.scenes.meshes.mesh_files)
                    check = ["listed", path]
                now = tell([*check, None])
                if now[0] != _plain([path, digest]):  # (the file changed while it was loaded)
                    return None
                if not read_as([(p, d["sha256"]) for p, d in now[1:]], reads):  # (its libraries, buffers: too)
                    return None
                out.append([*check, now])
            else:
                return None
    except (OSError, InputError, ValueError, TypeError, AttributeError, ImportError, KeyError, IndexError):
        return None
    return out


def _plain(value):
    """``value`` as JSON gives it back (tuples as lists): what a check told, here and read from disk alike."""
    return json.loads(json.dumps(value))


def _function_name(f) -> str:
    """``module:qualname`` of a module-level function (one that :func:`_function` finds again), else a ValueError."""
    name = f"{f.__module__}:{f.__qualname__}"
    if _function(name) is not f:
        raise ValueError(f"{name} is not found by its name")
    return name


def _function(name: str):
    """The function of tlm's scene loaders named ``module:qualname`` (a check read from disk calls it:
    a name outside ``tlm.scenes`` is refused, a ValueError)."""
    import importlib

    module, _, qualname = name.partition(":")
    if not module.startswith("tlm.scenes."):
        raise ValueError(f"{name} is not a function of tlm's scene loaders")
    f = importlib.import_module(module)
    for part in qualname.split("."):
        f = getattr(f, part)
    return f


def _text_digest(path: str) -> str:
    return text_digest(read_text(Path(path)))


def _found(ref: str, folder: Path, src: str) -> str:
    """The scene file an ``extends: ref`` in ``src`` finds now (as the loader looks for it)."""
    return str(resolve_scene_path(ref, folder, src, key="extends"))


def _mesh_and_libraries(path: Path, names: list, resolve) -> list:
    return [(str(p), file_digest(p)) for p in (path, *resolve(path, names))]


def _listed(path: Path) -> list:
    return [(str(p), d) for p, d in mesh_files(path)]


# what tells a check's file now, by the check's kind, from its arguments (a check is [kind, *arguments, then])
TELLS = {
    "text": lambda path: _text_digest(path),
    "found": lambda ref, folder, src: _found(ref, Path(folder), src),
    "libraries": lambda path, names, resolve: _mesh_and_libraries(Path(path), names, _function(resolve)),
    "listed": lambda path: _listed(Path(path)),
}


def tell(check: list):
    """What the file of ``check`` tells now (as JSON)."""
    return _plain(TELLS[check[0]](*check[1:-1]))


def unchanged(checks: list) -> bool:
    """Whether every file a remembered load read tells what it told then."""
    try:
        return all(tell(check) == check[-1] for check in checks)
    except (OSError, InputError, ValueError, TypeError, AttributeError, ImportError, KeyError, IndexError):
        return False  # (a file gone or unreadable: the load says so; a check read from disk not understood)
