"""Parsed mesh files and crease normals on disk, so that a large scene is parsed once.

The conference room (331,179 triangles) spends about 1.1 s in tlm's OBJ reader and
0.7 s in its crease normals on every load, on one core: every ``tlm run``, every sweep
point, and again for the key of every cached frame (``benchmarks/bench_load.py``
measures both ways). Both results are kept under ``$TLM_CACHE/scenes`` (default
``~/.cache/tlm/scenes``), keyed by what determines them, bit for bit:

* a **mesh** (:func:`mesh`): tlm's code (:func:`tlm.fingerprint.code_fingerprint`) and
  the name and sha256 of the mesh file. Its sidecar lists every other file the parse
  read (an OBJ's MTL libraries, by their path from the mesh's folder) with their sizes
  and sha256; an entry whose files beside this mesh differ is parsed again and
  replaced. A file whose parse reads files it cannot name (a ``.gltf`` with external
  buffers) is not cached.
* **crease normals** (:func:`crease_normals`): the code, the crease angle and the bytes
  of the world-space triangles and their parts, so a transform, another part map or
  another angle is another entry.

Only geometry of at least :data:`MIN_TRIANGLES` triangles is kept (smaller parses take
less time than the read back). The entries are written atomically (concurrent loads of
one scene leave one whole entry); a damaged entry (cut short, zeroed, overwritten) is
reported once as a warning naming the file, removed and computed again; a cache that
cannot be written (read-only, full) only costs speed.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from contextlib import suppress
from pathlib import Path

import numpy as np

from tlm.fingerprint import code_fingerprint
from tlm.scenes.model import Geometry, Material
from tlm.storage import cache_root, digest_problem, file_digest, warn, write_atomic, write_file

__all__ = ["FORMAT", "MIN_TRIANGLES", "cache_dir", "crease_normals", "mesh"]

FORMAT = "tlm-scene-cache/1"
MIN_TRIANGLES = 20_000  # smaller geometry is parsed (its normals computed) again: it is quicker


def cache_dir() -> Path:
    """``$TLM_CACHE/scenes`` (default ``~/.cache/tlm/scenes``)."""
    return cache_root("scenes")


def _key(*parts: str | np.ndarray) -> str:
    """24 hex digits of sha256 over the parts, each with its length (an array's bytes are
    hashed where they lie, not copied)."""
    h = hashlib.sha256()
    for p in (FORMAT, code_fingerprint(), *parts):
        b = p.encode() if isinstance(p, str) else memoryview(np.ascontiguousarray(p)).cast("B")
        h.update(len(b).to_bytes(8, "little"))
        h.update(b)
    return h.hexdigest()[:24]


def mesh(path: Path, parse: Callable[[Path], tuple[Geometry, list[Path] | None]]) -> Geometry:
    """The :class:`Geometry` of the mesh file ``path``: from the cache when its file and
    every file its parse read are those of the entry, else ``parse(path)`` (which returns
    the geometry and the other files it read, None when it cannot name them), cached."""
    path = Path(path)
    try:
        digest = file_digest(path)
    except OSError:
        return parse(path)[0]  # (the parse says what is wrong with the file)
    key = _key("mesh", path.name, digest["sha256"], str(digest["size"]))  # (the name: a part's, the format)
    npz, side = cache_dir() / f"mesh-{key}.npz", cache_dir() / f"mesh-{key}.json"
    if npz.exists() and side.exists():
        meta = _read_entry(npz, side)
        if meta is not None and _deps_unchanged(path.parent, meta.get("deps")):
            got = _geometry(npz, side, meta)
            if got is not None:
                return got
    geom, deps = parse(path)
    if deps is None or geom.triangles.shape[0] < MIN_TRIANGLES:
        return geom
    try:
        dep_meta = [{"path": os.path.relpath(p, path.parent), **file_digest(Path(p))} for p in deps]
    except OSError:
        return geom
    arrays = {"triangles": geom.triangles, "part": geom.part}
    if geom.normals is not None:
        arrays["normals"] = geom.normals
    if geom.face_material is not None:
        arrays["face_material"] = geom.face_material
    meta = {"part_names": list(geom.part_names), "deps": dep_meta,
            "materials": [{"name": m.name, "kind": m.kind, "albedo": m.albedo, "reflectance": m.reflectance,
                           "ior": m.ior, "transmittance": m.transmittance, "emission": m.emission}
                          for m in geom.materials]}
    _write_entry(npz, side, arrays, meta)
    return geom


def crease_normals(triangles: np.ndarray, part: np.ndarray, crease_angle: float,
                   compute: Callable[[np.ndarray, np.ndarray, float], np.ndarray]) -> np.ndarray:
    """``compute(triangles, part, crease_angle)`` (:func:`tlm.scenes.normals.crease_normals`),
    from the cache when the same triangles, parts and angle were computed before."""
    tri = np.ascontiguousarray(triangles, dtype=np.float64)
    if tri.shape[0] < MIN_TRIANGLES:
        return compute(tri, part, crease_angle)
    part64 = np.ascontiguousarray(part, dtype=np.int64)
    key = _key("crease", repr(float(crease_angle)), repr(tri.shape), tri, part64)
    npz, side = cache_dir() / f"normals-{key}.npz", cache_dir() / f"normals-{key}.json"
    if npz.exists() and side.exists() and _read_entry(npz, side) is not None:
        got = _arrays(npz, side)
        if got is not None and got.get("normals") is not None and got["normals"].shape == tri.shape:
            return got["normals"]
        if got is not None:
            _damaged(npz, side, "it holds no normals of the triangles' shape")
    normals = compute(tri, part, crease_angle)
    _write_entry(npz, side, {"normals": normals}, {})
    return normals


# ------------------------------------------------------------------ entries


def _read_entry(npz: Path, side: Path) -> dict | None:
    """The sidecar's metadata, or None (an older format, quietly; damaged: a warning)."""
    try:
        meta = json.loads(side.read_text())
        if not isinstance(meta, dict):
            raise ValueError("not a JSON object")
    except (OSError, ValueError) as e:
        _damaged(side, npz, f"unreadable sidecar ({type(e).__name__})")
        return None
    if meta.get("format") != FORMAT:
        return None
    problem = digest_problem(npz, meta.get("npz"))
    if problem is not None:
        _damaged(npz, side, problem)
        return None
    return meta


def _deps_unchanged(folder: Path, deps: object) -> bool:
    """Whether every file the entry's parse read (by its path from the mesh's ``folder``)
    is, beside this mesh file, the file it was."""
    if not isinstance(deps, list):
        return False
    return all(isinstance(d, dict) and digest_problem(folder / str(d.get("path")), d) is None for d in deps)


def _arrays(npz: Path, side: Path) -> dict[str, np.ndarray] | None:
    try:
        with np.load(npz, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except Exception as e:  # BadZipFile, EOFError, zlib.error, ValueError: a damaged file
        _damaged(npz, side, f"{type(e).__name__}: {e}")
        return None


def _geometry(npz: Path, side: Path, meta: dict) -> Geometry | None:
    got = _arrays(npz, side)
    if got is None:
        return None
    try:
        tri, part = got["triangles"], got["part"]
        n = tri.shape[0]
        ok = (tri.ndim == 3 and tri.shape[1:] == (3, 3) and part.shape == (n,)
              and all(got[k].shape[0] == n for k in ("normals", "face_material") if k in got))
        materials = tuple(Material(**{k: tuple(v) if isinstance(v, list) else v for k, v in m.items()})
                          for m in meta["materials"])
        names = tuple(str(s) for s in meta["part_names"])
        if not ok:
            raise ValueError("arrays of mismatched shapes")
    except (KeyError, TypeError, ValueError) as e:
        _damaged(npz, side, f"{type(e).__name__}: {e}")
        return None
    return Geometry(triangles=tri, part=part, part_names=names, normals=got.get("normals"),
                    materials=materials, face_material=got.get("face_material"))


def _write_entry(npz: Path, side: Path, arrays: dict[str, np.ndarray], meta: dict) -> None:
    """The arrays, then the sidecar with their size and checksum; nothing on an OSError."""
    try:
        npz.parent.mkdir(parents=True, exist_ok=True)
        with write_atomic(npz, "wb") as fh:
            np.savez(fh, **arrays)
        write_file(side, json.dumps({"format": FORMAT, **meta, "npz": file_digest(npz)}, indent=1) + "\n")
    except OSError:
        pass  # a read-only (or full) cache only costs speed


def _damaged(bad: Path, other: Path, why: str) -> None:
    warn(f"damaged scene cache entry {bad} ({why}): removed, computing it again")
    for f in (bad, other):
        with suppress(OSError):  # (a read-only cache: computed again every time, said every time)
            f.unlink(missing_ok=True)
