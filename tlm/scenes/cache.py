"""Parsed mesh files and crease normals on disk, so that a large scene is parsed once.

The conference room (331,179 triangles) spends about 1.1 s in tlm's OBJ reader and
0.7 s in its crease normals on every load, on one core: every ``tlm run``, every render
of a sweep, and the key of a cached frame in each process of a sweep (a process remembers
it after: :func:`tlm.experiments.frames.scene_key`) (``benchmarks/bench_load.py``
measures both ways). Both results are kept in ``scenes/`` of tlm's cache folder
(``$TLM_CACHE``, else ``$XDG_CACHE_HOME/tlm``, else ``~/.cache/tlm``:
:func:`tlm.caches.cache_home`), keyed by what determines them, bit for bit:

* a **mesh** (:func:`mesh`): tlm's code (:func:`tlm.fingerprint.code_fingerprint`), the
  versions of numpy and trimesh (which parses PLY, STL and GLB), and the name and sha256
  of the mesh file. The entry keeps the file's notes and a glTF's imported point, spot and
  directional lights and camera (``Geometry.imports``, read back as the file's they are read for), and what names
  the other files the parse read (an OBJ's ``mtllib`` statements) and those files' paths
  and sha256 (of the bytes the parse read: none is written where a file was saved while it
  was parsed, :func:`read_as`): before an entry is used, the
  lookup of those files runs again beside this mesh (so a library that appeared where the
  lookup looks first, or one that changed or went missing, means a new parse). A file
  whose parse can read files the lookup cannot name (any ``.gltf``, a ``.glb`` with
  external buffers) is not cached. :func:`mesh_files` names the files a load reads, with
  their digests, from the entry's names (a parse, kept, where there is none), for a scene
  file's identity (:func:`tlm.experiments.provenance.scene_identity`).
* **crease normals** (:func:`crease_normals`): the code, the crease angle and the bytes
  of the world-space triangles and their parts, so a transform, another part map or
  another angle is another entry.

Only geometry of at least :data:`MIN_TRIANGLES` triangles is kept (smaller parses take
less time than the read back). An entry is one ``.npz`` (its arrays and a ``meta``
member, JSON), written atomically, so concurrent loads of one scene leave one whole entry
of one writer; a damaged entry (cut short, zeroed, overwritten: the zip's CRC-32 of every
member, the arrays' shapes, the metadata) is reported as a warning naming the file,
removed and computed again (one removed under its reader, by ``tlm cache prune`` or another
process, is computed again quietly); a read marks its entry used, for ``tlm cache prune``; a cache
that cannot be written (read-only, full) only costs speed. Inside :func:`read_only` (``tlm sweep --dry-run``)
the cache is read and nothing else: no entry written, marked used or removed (a damaged one is said and
parsed past).
"""

from __future__ import annotations

import contextvars
import functools
import hashlib
import json
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from tlm.caches import (
    cache_needed,
    cache_write_failed,
    cache_written,
    digest_problem,
    file_digest,
    note_use,
    remove_entry,
)
from tlm.config import note_read, noting_reads
from tlm.errors import InputError
from tlm.fingerprint import code_fingerprint
from tlm.scenes.model import Camera, Geometry, Imported, Light, Material
from tlm.storage import warn, write_atomic

__all__ = ["FORMAT", "MIN_TRIANGLES", "cache_dir", "crease_normals", "mesh", "mesh_files", "read_as", "read_only",
           "writable"]

FORMAT = "tlm-scene-cache/3"  # /2: one file an entry (its metadata inside); /3: imported lights of every kind
MIN_TRIANGLES = 20_000  # smaller geometry is parsed (its normals computed) again: it is quicker


_READ_ONLY: contextvars.ContextVar[bool] = contextvars.ContextVar("tlm_scene_cache_read_only", default=False)


@contextmanager
def read_only() -> Iterator[None]:
    """Inside (this thread, this context), tlm's scene cache and what is kept beside it is read only: a parse
    or normals computed are not kept, an entry read is not marked used, a damaged one is not removed
    (``tlm sweep --dry-run`` writes nothing; :func:`writable`)."""
    token = _READ_ONLY.set(True)
    try:
        yield
    finally:
        _READ_ONLY.reset(token)


def writable() -> bool:
    """Whether the scene cache may be written here (not inside :func:`read_only`)."""
    return not _READ_ONLY.get()


def cache_dir() -> Path:
    """``scenes`` in tlm's cache folder (:func:`tlm.caches.cache_home`); a mesh file's load needs it: a line that it
    cannot be written is said then (:func:`~tlm.caches.cache_needed`; a scene of no mesh file loses nothing by it)."""
    return cache_needed("scenes")


@functools.cache
def parse_versions() -> str:
    """The versions of the libraries a parse runs (numpy; trimesh for PLY, STL, GLB)."""
    from importlib.metadata import PackageNotFoundError, version

    out = []
    for name in ("numpy", "trimesh"):
        try:
            out.append(f"{name}={version(name)}")
        except PackageNotFoundError:
            out.append(f"{name}=none")
    return " ".join(out)


def _key(*parts: str | np.ndarray) -> str:
    """24 hex digits of sha256 over the parts, each with its length (an array's bytes are
    hashed where they lie, not copied)."""
    h = hashlib.sha256()
    for p in (FORMAT, code_fingerprint(), *parts):
        b = p.encode() if isinstance(p, str) else memoryview(np.ascontiguousarray(p)).cast("B")
        h.update(len(b).to_bytes(8, "little"))
        h.update(b)
    return h.hexdigest()[:24]


Parse = Callable[[Path], tuple[Geometry, list | None]]
Resolve = Callable[[Path, list], list[Path]]


def mesh(path: Path, parse: Parse, resolve: Resolve) -> Geometry:
    """The :class:`Geometry` of the mesh file ``path``: from the cache when the entry's
    other files are still what ``resolve`` finds beside this file, unchanged; else
    ``parse(path)``, cached. Inside :func:`tlm.config.noting_reads` the load is noted as
    ``("mesh", path, its digest, what names its other files, resolve)``.

    parse : the geometry and what names the other files its parse reads (JSON-able: an
        OBJ's ``mtllib`` statements; ``[]``: none), or None when it cannot name them all.
    resolve : ``resolve(path, names)``, the files ``names`` means beside ``path``, in the
        order the parse reads them (an :class:`~tlm.errors.InputError` when one is missing).
    """
    path = Path(path)
    try:
        digest = file_digest(path)
    except OSError:
        note_read(("mesh", str(path), None, None, resolve))  # (not to be remembered)
        return parse(path)[0]  # (the parse says what is wrong with the file)
    entry = _mesh_entry(path, digest)
    if entry.exists():
        got = _read(entry)
        libraries = None if got is None else _libraries_unchanged(path, got[1], resolve)
        if libraries is not None:
            geom = _geometry(entry, *got, path=path)
            if geom is not None:
                for p, sha, size in libraries:  # (the bytes it was parsed from, checked: "read" as they were)
                    note_read(("side", str(p), sha, size))
                note_read(("mesh", str(path), digest, got[1].get("names"), resolve))
                return geom
    geom, names = _kept(path, parse, resolve, digest, entry)
    note_read(("mesh", str(path), digest, names, resolve))
    return geom


def _kept(path: Path, parse: Parse, resolve: Resolve, digest: dict, entry: Path) -> tuple[Geometry, list | None]:
    """``parse(path)``, kept as the entry ``entry`` when it is large enough and names its other files, and
    each file is still what the parse read (the mesh file the bytes of ``digest``, taken before it; its
    other files the bytes their reads returned, :func:`read_as`): a file saved while it was parsed leaves
    no entry that holds the old parse under the new file's digest."""
    with noting_reads() as reads:  # (a scope of its own: the outer one, a scene load's, notes them too)
        geom, names = parse(path)
    if names is None or geom.triangles.shape[0] < MIN_TRIANGLES:
        return geom, names
    try:
        files = [(Path(p), file_digest(Path(p))) for p in resolve(path, names)]
        if file_digest(path) != digest or not read_as([(p, d["sha256"]) for p, d in files], reads):
            return geom, names  # (a file changed while it was parsed: not kept under its new digest)
        deps = [{"path": os.path.relpath(p, path.parent), **d} for p, d in files]
    except (OSError, InputError):
        return geom, names
    arrays = {"triangles": geom.triangles, "part": geom.part}
    if geom.normals is not None:
        arrays["normals"] = geom.normals
    if geom.face_material is not None:
        arrays["face_material"] = geom.face_material
    here = str(path)  # (the lines that name the file name it as {mesh}: the entry serves a copy elsewhere too)
    meta = {"part_names": list(geom.part_names), "names": names, "deps": deps,
            "notes": [n.replace(here, _HERE) for n in geom.notes],
            "materials": [{"name": m.name, "kind": m.kind, "albedo": m.albedo, "reflectance": m.reflectance,
                           "ior": m.ior, "transmittance": m.transmittance, "emission": m.emission,
                           "ignored": m.ignored, "alias": m.alias, "undefined": m.undefined.replace(here, _HERE),
                           # (an MTL's path beside the mesh as {dir}: the entry serves a copy elsewhere too)
                           "origin": _origin_kept(m.origin, path)}
                          for m in geom.materials],
            # (a file's own lights and camera: its source is the file read, so it is not kept)
            "imports": [{"lights": [_light_record(lt) for lt in i.lights],
                         "camera": None if i.camera is None else {k: getattr(i.camera, k)
                                                                  for k in ("eye", "target", "up", "vfov")},
                         "camera_name": i.camera_name, "aspect": i.aspect}
                        for i in geom.imports]}
    _write(entry, arrays, meta)
    return geom, names


def _mesh_entry(path: Path, digest: dict) -> Path:
    """Where the entry of the mesh file ``path`` (of :func:`~tlm.caches.file_digest` ``digest``) is."""
    # (the name: a part's, the format's)
    key = _key("mesh", parse_versions(), path.name, digest["sha256"], str(digest["size"]))
    return cache_dir() / f"mesh-{key}.npz"


def mesh_files(path: Path, parse: Parse, resolve: Resolve) -> list[tuple[Path, dict]]:
    """The mesh file ``path`` and the other files a load of it reads (``resolve`` of what names
    them: from its entry when it has one, else from ``parse``), each with its
    :func:`~tlm.caches.file_digest`, the digest an entry is keyed by and checks its other files
    by. An OSError or :class:`~tlm.errors.InputError` where a file cannot be read; a ValueError
    where the parse cannot name them (:func:`mesh`'s ``parse``)."""
    path = Path(path)
    digest = file_digest(path)
    entry = _mesh_entry(path, digest)
    names = _names(entry)
    if names is None:  # (parsed, and kept as a load keeps it: the next time, and the next load, read the entry)
        names = _kept(path, parse, resolve, digest, entry)[1]
    if names is None:
        raise ValueError(f"{path}: its parse cannot name the files it reads")
    return [(path, digest), *((Path(p), file_digest(Path(p))) for p in resolve(path, names))]


def _names(entry: Path) -> list | None:
    """What names the other files of a mesh entry's parse (its metadata alone is read); None
    where there is no entry or it cannot be read (a load reports a damaged one)."""
    try:
        with np.load(entry, allow_pickle=False) as z:
            meta = json.loads(z["meta"].tobytes().decode())
    except Exception:  # (FileNotFoundError, BadZipFile, KeyError, ValueError, ...)
        return None
    ok = isinstance(meta, dict) and meta.get("format") == FORMAT and isinstance(meta.get("names"), list)
    if ok and writable():
        note_use(entry)  # (a use too: it spares a parse)
    return meta["names"] if ok else None


def crease_normals(triangles: np.ndarray, part: np.ndarray, crease_angle: float,
                   compute: Callable[[np.ndarray, np.ndarray, float], np.ndarray]) -> np.ndarray:
    """``compute(triangles, part, crease_angle)`` (:func:`tlm.scenes.normals.crease_normals`),
    from the cache when the same triangles, parts and angle were computed before."""
    tri = np.ascontiguousarray(triangles, dtype=np.float64)
    if tri.shape[0] < MIN_TRIANGLES:
        return compute(tri, part, crease_angle)
    part64 = np.ascontiguousarray(part, dtype=np.int64)
    key = _key("crease", repr(float(crease_angle)), repr(tri.shape), tri, part64)
    entry = cache_dir() / f"normals-{key}.npz"
    if entry.exists():
        got = _read(entry)
        if got is not None:
            normals = got[0].get("normals")
            if normals is not None and normals.shape == tri.shape and normals.dtype == np.float64:
                return normals
            _damaged(entry, "it holds no normals of the triangles' shape")
    normals = compute(tri, part, crease_angle)
    _write(entry, {"normals": normals}, {})
    return normals


# ------------------------------------------------------------------ entries


def _read(entry: Path) -> tuple[dict[str, np.ndarray], dict] | None:
    """An entry's arrays and metadata, or None: of an older format or gone (removed since it was
    found: ``tlm cache prune``, another process), quietly, or damaged (a warning; removed). An entry
    read is marked used (:func:`tlm.caches.note_use`: its time, which no digest checks), so that
    ``tlm cache prune`` removes entries by their last use where access times are not kept."""
    try:
        with np.load(entry, allow_pickle=False) as z:  # (zip: every member's CRC-32 is checked as it is read)
            arrays = {k: z[k] for k in z.files}
        meta = json.loads(arrays.pop("meta").tobytes().decode())
        if not isinstance(meta, dict):
            raise ValueError("its metadata is not a JSON object")
    except (FileNotFoundError, NotADirectoryError):
        return None  # (a miss: computed again)
    except IsADirectoryError:
        _damaged(entry, "a folder, not a file")
        return None
    except Exception as e:  # BadZipFile, EOFError, zlib.error, KeyError, ValueError: a damaged file
        _damaged(entry, f"{type(e).__name__}: {e}")
        return None
    if meta.get("format") != FORMAT:
        return None  # (another format cannot be under this key: the key hashes FORMAT)
    if writable():
        note_use(entry)
    return arrays, meta


def _libraries_unchanged(path: Path, meta: dict, resolve: Resolve) -> list[tuple[Path, str, int]] | None:
    """Where the lookup of the entry's other files beside ``path`` finds the same paths, and each
    is the file it was: those files, each with the sha256 and size of the bytes the entry was parsed from;
    else None."""
    deps = meta.get("deps")
    try:
        found = [Path(p) for p in resolve(path, meta.get("names") or [])]
        now = [os.path.relpath(p, path.parent) for p in found]
    except (InputError, OSError, TypeError, ValueError):
        return None  # (a library missing now: the parse says so)
    if not isinstance(deps, list) or now != [d.get("path") if isinstance(d, dict) else None for d in deps]:
        return None
    if not all(digest_problem(path.parent / d["path"], d) is None for d in deps):
        return None
    return [(p, d["sha256"], d["size"]) for p, d in zip(found, deps, strict=True)]


def read_as(files: list[tuple[Path | str, str]], reads: list) -> bool:
    """Whether each of ``files`` (a path and a sha256: what it holds now) is what the parse that noted
    ``reads`` (:func:`tlm.config.noting_reads`) read of it: its reads (``("side", path, sha256 of the
    bytes read)``, :func:`tlm.scenes.objfile.read_bytes`, a glTF's resolver) returned those bytes, every
    one (a file by its real path). False for a file whose read was not noted, or that two reads found
    different: a file saved while the parse ran is not taken for the one it read."""
    got: dict[str, set] = {}
    for read in reads:
        if read[0] == "side":
            got.setdefault(os.path.realpath(read[1]), set()).add(read[2])
    return all(got.get(os.path.realpath(p)) == {sha} for p, sha in files)


_HERE = "{mesh}"  # a cached line's place for the path of the file it was read for
_DIR = "{dir}"  # a cached material origin's place for the folder of that file (an MTL beside it)


def _origin_kept(origin: str, path: Path) -> str:
    """A material's origin (``Material.origin``) as an entry for the mesh file ``path`` keeps it: that file as
    {mesh}, a file in its folder (its MTL) as ``{dir}/NAME``."""
    folder = os.path.join(str(path.parent), "")
    return origin.replace(str(path), _HERE) if origin.startswith(str(path)) else (
        _DIR + os.sep + origin[len(folder):] if origin.startswith(folder) else origin)


def _geometry(entry: Path, got: dict[str, np.ndarray], meta: dict, path: Path | None = None) -> Geometry | None:
    try:
        tri, part = got["triangles"], got["part"]
        n = tri.shape[0]
        ok = (tri.ndim == 3 and tri.shape[1:] == (3, 3) and part.shape == (n,)
              and all(got[k].shape[0] == n for k in ("normals", "face_material") if k in got))
        here = str(path) if path is not None else _HERE
        folder = str(path.parent) if path is not None else _DIR
        materials = tuple(Material(**{k: tuple(v) if isinstance(v, list) else v.replace(_HERE, here)
                                      if k == "undefined" else v.replace(_HERE, here).replace(_DIR, folder)
                                      if k == "origin" else v for k, v in m.items()})
                          for m in meta["materials"])
        names = tuple(str(s) for s in meta["part_names"])
        imports = tuple(_imported(i, str(path) if path is not None else _HERE) for i in meta.get("imports", []))
        if not ok:
            raise ValueError("arrays of mismatched shapes")
    except (AttributeError, IndexError, KeyError, TypeError, ValueError) as e:
        _damaged(entry, f"{type(e).__name__}: {e}")
        return None
    notes = meta.get("notes", [])
    if not (isinstance(notes, list) and all(isinstance(n, str) for n in notes)):
        _damaged(entry, "notes: not a list of lines")
        return None
    notes = [n.replace(_HERE, str(path) if path is not None else _HERE) for n in notes]
    return Geometry(triangles=tri, part=part, part_names=names, normals=got.get("normals"), notes=tuple(notes),
                    materials=materials, face_material=got.get("face_material"), imports=imports)


_IMPORTED_KINDS = ("point", "spot", "directional")  # what Imported.lights holds


def _light_record(lt: Light) -> dict:
    """An imported light's fields as JSON (:func:`_imported` reads them back)."""
    return {"kind": lt.kind, "power": lt.power, "position": lt.position, "name": lt.name,
            "direction": lt.direction, "inner_angle": lt.inner_angle, "outer_angle": lt.outer_angle,
            "irradiance": lt.irradiance}


def _imported(meta: dict, source: str) -> Imported:
    """A cached file's lights and camera (a KeyError, TypeError or ValueError where the entry
    does not hold them as :func:`mesh` writes them)."""
    def vec(v) -> tuple[float, float, float]:
        if not (isinstance(v, list) and len(v) == 3):
            raise ValueError(f"{v!r} is not 3 numbers")
        return tuple(float(x) for x in v)

    def light(lt: dict) -> Light:
        kind = str(lt["kind"])
        if kind not in _IMPORTED_KINDS:
            raise ValueError(f"light kind {kind!r} is not one a glTF's import gives")
        return Light(kind, vec(lt["power"]), position=vec(lt["position"]), name=str(lt["name"]),
                     direction=vec(lt["direction"]), inner_angle=float(lt["inner_angle"]),
                     outer_angle=float(lt["outer_angle"]), irradiance=vec(lt["irradiance"]))

    lights = tuple(light(lt) for lt in meta["lights"])
    cam = meta["camera"]
    camera = None if cam is None else Camera(vec(cam["eye"]), vec(cam["target"]), vec(cam["up"]),
                                             float(cam["vfov"]), 0, 0)
    aspect = meta["aspect"]
    return Imported(source, lights, camera, str(meta["camera_name"]), None if aspect is None else float(aspect))


def _write(entry: Path, arrays: dict[str, np.ndarray], meta: dict) -> None:
    """The arrays and the metadata as one file, atomically; nothing inside :func:`read_only`. A write that fails
    (its folder's ``mkdir`` too: a file put in its place since this process first looked at it) is said once
    (:func:`~tlm.caches.cache_write_failed`), one that succeeds clears a full disk's line
    (:func:`~tlm.caches.cache_written`)."""
    if not writable():
        return
    blob = np.frombuffer(json.dumps({"format": FORMAT, **meta}).encode(), dtype=np.uint8)
    if entry.is_dir():  # (one no read looked at first: mesh_files reads its metadata alone, quietly)
        _damaged(entry, "a folder, not a file")
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        with write_atomic(entry, "wb") as fh:
            np.savez(fh, meta=blob, **arrays)
    except OSError as e:  # a read-only (or full) cache only costs speed
        cache_write_failed(entry, e)
    else:
        cache_written(entry)


def _damaged(entry: Path, why: str) -> None:
    """Say the damaged entry and remove it (a folder where the file should be too, only inside the
    cache: :func:`~tlm.caches.remove_entry`), so that the entry computed again can be written."""
    if not writable():  # (a dry run: said, and left as it is)
        warn(f"damaged scene cache entry {entry} ({why}): computing it again (kept: nothing is written here)")
        return
    left = remove_entry(entry, cache_dir())  # (a read-only cache: computed again every time, said every time)
    done = "removed, computing it again" if left is None else f"computing it again (it could not be removed: {left})"
    warn(f"damaged scene cache entry {entry} ({why}): {done}")
