"""Mesh files (OBJ, PLY, STL, GLB/GLTF, plain or compressed) as named parts with materials.

`load_mesh` turns a file into a :class:`~tlm.scenes.model.Geometry`. Nothing is
repaired, merged or dropped: the triangles keep the file's face order and winding,
polygons are fan-triangulated from their first corner.

* **OBJ** is read by tlm's own vectorized reader (:mod:`tlm.scenes.objfile`): one part
  per ``o`` object when the file has any, else one per ``g`` group, else one part named
  after the file stem (parts in file order, parts of the same name merged); its
  ``mtllib`` libraries give ``Geometry.materials`` and each face's ``usemtl`` its
  ``face_material`` (:mod:`tlm.scenes.materials`). A polygon its fan does not cover (a
  concave face: one fan triangle faces back) is named in ``Geometry.notes``, which the
  run warns of. A library sits beside the OBJ, plain
  or compressed like it; a missing library is an error. A ``usemtl`` naming a material
  no library defines (McGuire's ``CornellBox-Glossy`` names a ``light`` its MTL lacks)
  gives a placeholder material whose ``Material.undefined`` says so: the scene file
  supplies it (a ``materials:`` entry of that name, or ``default_material``), or loading
  the scene is that error. A file without ``mtllib`` has no materials (its ``usemtl``
  lines are ignored).
* **PLY, STL, GLB/GLTF** are read with trimesh (``process=False``). A file holding one
  mesh becomes one part named after the file stem; a scene (GLB/GLTF) one part per
  geometry, named by trimesh's geometry name, with each instance's scene-graph
  transform applied (a skinned mesh's its skin's joint matrix, not its node's; a singular one
  where it keeps a flat mesh's triangles: :func:`tlm.scenes.gltf_imports.check_mesh_nodes`,
  :func:`tlm.scenes.mat3.keeps_triangles`). glTF materials come from the file's JSON (extensions included)
  and map to tlm's kinds by :func:`tlm.scenes.materials.gltf_material`. Its
  ``KHR_lights_punctual`` point, spot and directional lights and its first perspective
  camera, placed by the nodes of its scene, are ``Geometry.imports``
  (:func:`tlm.scenes.gltf_imports.gltf_imports`; the scene file decides whether they are
  used: :mod:`tlm.scenes.loader`); what of its lights and cameras is not imported (lights and
  cameras on no node of its scene, orthographic cameras, ...) is named in ``Geometry.notes``. A PLY whose
  faces are triangle strips (element ``tristrips``, ``-1`` restarting a strip) is
  decoded with alternating winding; the degenerate triangles that stitch strips are
  dropped. A PLY's face property ``material`` (or ``material_index``) gives each face's
  material, a placeholder named by the file's header or by its index that the scene file
  supplies; a PLY's polygons are fanned from their first corner in file order; its colours
  are named in ``Geometry.notes`` (:mod:`tlm.scenes.plyfile`).
* A file ending in ``.gz``, ``.xz`` or ``.bz2`` after its format's suffix
  (``conference.obj.xz``) is decompressed first (all but ``.gltf``).

The checks of a file's bytes and of the files it names that run before trimesh reads it (an ASCII
STL's facets, a glTF's buffer URIs, the resolver that notes the buffers it reads) are
:mod:`tlm.scenes.mesh_checks`.

Shading normals come from the file (OBJ ``vn`` when every corner has one, PLY
``nx ny nz``, glTF ``NORMAL``) or are None. No library warning reaches the terminal:
loading runs under ``warnings.catch_warnings`` and ``np.errstate``. Every problem is an
:class:`~tlm.errors.InputError` naming the file (and, for OBJ and MTL, the line).
"""

from __future__ import annotations

import io
import os
import re
import warnings
from pathlib import Path

import numpy as np

from tlm.config_words import listing
from tlm.errors import InputError, did_you_mean, quoted
from tlm.scenes.gltf_imports import check_mesh_nodes, gltf_imports, singular, singular_message
from tlm.scenes.mat3 import _cross, adjugate3, det3, inverse3  # noqa: F401  (the old names, importable here)
from tlm.scenes.mat3 import keeps_triangles as _keeps_triangles
from tlm.scenes.mesh_checks import absolute_uri as _absolute_uri  # noqa: F401  (the old names, still importable)
from tlm.scenes.mesh_checks import buffer_files as _buffer_files
from tlm.scenes.mesh_checks import buffer_reader as _buffer_reader
from tlm.scenes.mesh_checks import check_ascii_stl as _check_ascii_stl
from tlm.scenes.mesh_checks import glb_binary as _glb_binary
from tlm.scenes.mesh_checks import noting_resolver as _noting_resolver
from tlm.scenes.mesh_checks import noting_resolver_class as _noting_resolver_class  # noqa: F401
from tlm.scenes.model import Geometry, Imported, Material

__all__ = ["COMPRESSED_EXTENSIONS", "SUPPORTED_EXTENSIONS", "load_mesh", "mesh_files", "mesh_format"]

SUPPORTED_EXTENSIONS = (".obj", ".ply", ".stl", ".glb", ".gltf")
COMPRESSED_EXTENSIONS = (".gz", ".xz", ".bz2")
_TAG = "tlm-material-"  # the names given to a glTF file's materials while trimesh reads it
_NODE_TAG = "tlm-node-"  # the names given to the mesh nodes whose transform tlm sets (check_mesh_nodes)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def _check_mesh(vertices: np.ndarray, faces: np.ndarray, label: str, source: str) -> None:
    if faces.ndim != 2 or faces.shape[1] != 3:
        width = faces.shape[1] if faces.ndim == 2 else "mixed"
        raise InputError(
            f"{label} has faces with {width} vertices after loading, expected triangles",
            source=source,
        )
    if len(faces) == 0:
        raise InputError(f"{label} has no faces (empty mesh)", source=source)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise InputError(f"{label} vertices have shape {vertices.shape}, expected (n, 3)",
                         source=source)
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        count = int(bad.sum())
        raise InputError(
            f"{label} has {count} {'vertex' if count == 1 else 'vertices'} with NaN or "
            f"infinite coordinates (first: vertex {first} counting from 0, {vertices[first].tolist()})",
            source=source,
        )
    if faces.min() < 0 or faces.max() >= len(vertices):
        worst = int(faces.min()) if faces.min() < 0 else int(faces.max())
        raise InputError(
            f"{label} has a face referencing vertex {worst} but only {len(vertices)} vertices",
            source=source,
        )


def mesh_format(path: Path) -> tuple[str, str]:
    """``(format suffix, compression suffix or "")`` of a mesh file name, e.g.
    ``(".obj", ".xz")`` for ``conference.obj.xz``; an InputError for anything else."""
    path = Path(path)
    ext = path.suffix.lower()
    zext = ""
    if ext in COMPRESSED_EXTENSIONS:
        zext, ext = ext, Path(path.stem).suffix.lower()
    if ext not in SUPPORTED_EXTENSIONS or (zext and ext == ".gltf"):
        shown = (ext + zext) if zext else (path.suffix or "(none)")
        raise InputError(
            f"unsupported mesh extension {quoted(shown)}; supported: {', '.join(SUPPORTED_EXTENSIONS)} "
            f"(all but .gltf also compressed: {', '.join(COMPRESSED_EXTENSIONS)})",
            source=str(path),
        )
    return ext, zext


def load_mesh(path: Path) -> Geometry:
    """Load a mesh file into named parts, with the materials the file defines.

    Parameters
    ----------
    path : Path
        An OBJ, PLY, STL, GLB or GLTF file, or one of the first four compressed
        (``.gz``, ``.xz``, ``.bz2`` after the format's suffix); named in messages and
        notes without its ``..`` (:func:`shown_path`).

    Returns
    -------
    Geometry
        ``triangles`` (n, 3, 3) float64 in the file's face order (scene geometries in
        scene-graph order, OBJ objects in file order), ``part`` (n,) int32, ``normals``
        from the file or None, ``materials`` (the file's, mapped to tlm's kinds) and
        ``face_material`` (n,) int32 into them (-1: the face has none; None when the
        file defines no materials).

    Raises
    ------
    InputError
        Missing file, unsupported extension, unparsable file, no faces (empty mesh,
        point cloud, path), non-triangle faces, NaN/inf vertices, bad face indices, a
        missing or bad material library, an undefined material.
    """
    path = shown_path(Path(path))
    mesh_format(path)  # (an unsupported suffix is an error before anything is read)
    if not path.is_file():
        raise InputError("mesh file not found", source=str(path))
    from tlm.scenes import cache

    return cache.mesh(path, _parse, _libraries)


def shown_path(path: Path) -> Path:
    """``path`` as messages name it and whatever compares paths reads it: without its ``..`` and ``.``
    (:func:`os.path.normpath`, not ``resolve``: a symbolic link keeps its name) where that names the same
    entry, the same name in the same folder (``scenes/../cb/box.obj`` as ``cb/box.obj``), whether the file
    is there or not (a missing file's message names it plainly too). Kept as given where the folders
    differ (a ``..`` after a symbolic link to a folder leads elsewhere than the name without it) or where
    a folder on the way is not there. The one rule of a mesh's path (:func:`tlm.scenes.compose.mesh_path`
    applies it)."""
    norm = Path(os.path.normpath(path))
    if norm == path:
        return path
    if norm.name != path.name:  # (a path ending in .. or .: a folder's; the same entry where the two are one)
        try:
            return norm if os.path.samefile(norm, path) else path
        except (OSError, ValueError):
            return path
    try:
        return norm if os.path.samefile(norm.parent, path.parent) else path
    except (OSError, ValueError):  # (a folder on the way not there; a NUL in a name: no such folder)
        return path


def _parse(path: Path) -> tuple[Geometry, list | None]:
    """The file's geometry and what names the other files its parse read, for
    :func:`tlm.scenes.cache.mesh`: an OBJ's ``mtllib`` statements (``[text, line]``),
    ``[]`` for a file that reads no other, None where the parse can read files that
    :func:`_libraries` cannot name (a ``.gltf``'s buffers, a ``.glb`` with external ones)."""
    src = str(path)
    ext, zext = mesh_format(path)
    stem = Path(path.stem).stem if zext else path.stem
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        if ext == ".obj":
            return _load_obj(path, stem, zext, src)
        geom = _load_trimesh(path, ext, zext, stem, src)
    if ext == ".gltf" or (ext == ".glb" and _external_buffers(path)):
        return geom, None
    return geom, []


def mesh_files(path: Path) -> list[tuple[Path, dict]]:
    """The files a load of the mesh file ``path`` reads, each with its
    :func:`~tlm.caches.file_digest` (the digest the scene cache keys a mesh by): the file,
    then an OBJ's material libraries (found as :func:`load_mesh` finds them:
    :func:`tlm.scenes.cache.mesh_files`) or a glTF's buffer files. A glTF's images (textures)
    are not among them: tlm does not render them. An :class:`~tlm.errors.InputError` or an
    OSError where one cannot be read."""
    from tlm.caches import file_digest

    path = Path(path)
    ext = mesh_format(path)[0]
    if ext == ".obj":
        from tlm.scenes import cache

        return cache.mesh_files(path, _parse, _libraries)
    out = [(path, file_digest(path))]
    if ext in (".glb", ".gltf"):
        from urllib.parse import unquote

        from tlm.scenes.materials import gltf_json
        from tlm.scenes.objfile import read_bytes

        for b in gltf_json(path, read_bytes(path)).get("buffers") or []:
            uri = b.get("uri") if isinstance(b, dict) else None
            if isinstance(uri, str) and not uri.startswith("data:"):
                file = path.parent / uri
                file = file if file.is_file() else path.parent / unquote(uri)  # (as the load finds it: _buffer_files)
                out.append((file, file_digest(file)))
    return out


def _external_buffers(path: Path) -> bool:
    """Whether a GLB's JSON names a buffer or an image by a URI (a file beside it)."""
    from tlm.scenes.materials import gltf_json
    from tlm.scenes.objfile import read_bytes

    header = gltf_json(path, read_bytes(path))
    return any(isinstance(x, dict) and "uri" in x for key in ("buffers", "images") for x in header.get(key) or [])


def _libraries(path: Path, names: list) -> list[Path]:
    """The material libraries an OBJ's ``mtllib`` statements (``[text, line]``) name beside
    it, in the order :func:`_obj_materials` reads them (an InputError when one is missing)."""
    zext = mesh_format(path)[1]
    out: list[Path] = []
    for text, line in names:
        for mtl in _library_paths(path, text, line, zext, str(path)):
            if mtl not in out:
                out.append(mtl)
    return out


# ------------------------------------------------------------------ OBJ


def _load_obj(path: Path, stem: str, zext: str, src: str) -> tuple[Geometry, list]:
    from tlm.scenes.objfile import colour_notes, read_obj

    obj = read_obj(path, stem)
    _check_mesh(obj.vertices, obj.faces, "the mesh", src)
    tri = obj.vertices[obj.faces]
    normals = None
    if obj.corner_normals is not None:
        normals = obj.vertex_normals[obj.corner_normals]
        normals = _unit_or_none(normals)
    materials, face_material, mtl_notes = _obj_materials(path, obj, src)
    return Geometry(
        triangles=np.ascontiguousarray(tri, dtype=np.float64),
        part=obj.part,
        part_names=obj.part_names,
        normals=normals,
        materials=materials,
        face_material=face_material,
        notes=_concave_note(tri, obj.face_line, src) + colour_notes(obj, src) + mtl_notes,
    ), [[text, line] for text, line in obj.mtllibs]


def _concave_note(tri: np.ndarray, face_line: np.ndarray, src: str) -> tuple[str, ...]:
    """A line naming the polygons (faces of more than 3 corners) that their fan from the
    first corner does not cover: one of its triangles faces against the polygon's vector
    area (a concave polygon, a U or an L, whose fan overlaps itself and fills its notch)."""
    line = np.asarray(face_line)
    if line.shape[0] < 2:
        return ()
    poly = np.flatnonzero(np.r_[line[1:] == line[:-1], False] | np.r_[False, line[1:] == line[:-1]])
    if poly.shape[0] == 0:
        return ()
    t = np.asarray(tri[poly], dtype=np.float64)
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])  # twice each fan triangle's vector area
    lines, which = np.unique(line[poly], return_inverse=True)
    area = np.zeros((lines.shape[0], 3))
    np.add.at(area, which, n)  # twice the polygon's vector area (the fan's sum)
    a = area[which]
    dot = np.einsum("ij,ij->i", n, a)
    back = dot < -1e-6 * np.einsum("ij,ij->i", a, a)  # (against the face's area: a sliver's sign is noise)
    if not back.any():
        return ()
    bad = np.unique(line[poly][back])
    k = bad.shape[0]
    return (f"{src}: {k} polygon{'s are' if k > 1 else ' is'} not convex (first at line {int(bad[0])}): fanned from "
            f"{'their' if k > 1 else 'its'} first corner, {'they cover' if k > 1 else 'it covers'} another area "
            "than the face, with triangles facing back; split such faces into triangles in the file",)


def _unit_or_none(normals: np.ndarray) -> np.ndarray | None:
    """Unit per-corner normals, or None when the file's are not finite (the loader then
    computes crease normals)."""
    if not np.isfinite(normals).all():
        return None
    length = np.linalg.norm(normals, axis=2, keepdims=True)
    return np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)


def _library_paths(obj_path: Path, text: str, line: int, zext: str, src: str) -> list[Path]:
    """The files an ``mtllib`` statement names, found beside the OBJ (plain first, then
    compressed like the OBJ): its whole text as one name (exporters write a name with spaces so),
    else the names its spaces separate (the OBJ spec's several libraries). A missing one is an
    error naming the OBJ, the whole text and each file looked for, and a file beside it whose
    name differs only in letter case."""
    folder = obj_path.parent

    def find(name: str) -> Path | None:
        name = name.replace("\\", "/")
        for candidate in ([name, name + zext] if zext else [name]):
            p = folder / candidate
            if p.is_file():
                return p
        return None

    whole = find(text) if text else None
    if whole is not None:
        return [whole]
    words = text.split()
    if not words:
        raise InputError(f"line {line}: 'mtllib' names no file", source=src)
    found = [find(word) for word in words]
    if all(p is not None for p in found):
        return found

    def looked(name: str) -> str:
        at = folder / name.replace("\\", "/")
        return f"{at} or {at}{zext}" if zext else str(at)

    missing = [w for w, p in zip(words, found, strict=True) if p is None]
    dirs = list(dict.fromkeys(str(folder / n.replace("\\", "/")) for n in [text, *missing]
                              if (folder / n.replace("\\", "/")).is_dir()))  # (`mtllib sub`: a folder of that name)
    if dirs and len(words) == 1:
        raise InputError(f"line {line}: the material library {quoted(text)} (mtllib) is a folder, not a file: {dirs[0]}"
                         + (f" (nor is there {dirs[0]}{zext})" if zext else ""), source=src)
    tried = f"no file {looked(text)}"
    if len(words) > 1:
        there = ", ".join(w for w, p in zip(words, found, strict=True) if p is not None)
        tried += (f", nor {listing(map(looked, missing))} (of the names its spaces separate, as the OBJ "
                  f"spec reads several libraries{f'; {there} found' if there else ''})")
    tried += f" ({listing(dirs)}: {'a folder' if len(dirs) == 1 else 'folders'})" if dirs else ""
    raise InputError(f"line {line}: the material library {quoted(text)} (mtllib) is missing: {tried}"
                     f"{_case_hint(folder, [text, *missing])}", source=src)


def _case_hint(folder: Path, names: list[str]) -> str:
    """``" (box.MTL is there: names differ in letter case ...)"``: the files beside the OBJ whose
    names differ from one of ``names`` only in letter case, else ``""``."""
    try:
        there = {n.lower(): n for n in sorted(os.listdir(folder))}
    except OSError:
        return ""
    near = list(dict.fromkeys(there[n.lower()] for n in names if n.lower() in there and there[n.lower()] != n))
    if not near:
        return ""
    return (f" ({listing(map(quoted, near))} {'is' if len(near) == 1 else 'are'} there: the name differs in "
            "letter case, which this file system tells apart; write it as the file is named)")


def _obj_materials(path: Path, obj, src: str) -> tuple[tuple[Material, ...], np.ndarray | None, tuple[str, ...]]:
    """The OBJ's materials, each face's index into them, and the notes of its libraries
    (:func:`~tlm.scenes.materials.parse_mtl`'s, and a material a later library defines again)."""
    from tlm.scenes.materials import LIBRARY_WINS, mtl_text, parse_mtl
    from tlm.scenes.objfile import read_bytes

    odd = [(n, line) for n, line in zip(obj.material_names, obj.material_lines, strict=True) if "\ufffd" in n]
    notes: list[str] = [f"{src}: line {odd[0][1]}: usemtl {odd[0][0]!r}: bytes that are not UTF-8, read as U+FFFD"
                        f"{f' ({len(odd)} usemtl names)' if len(odd) > 1 else ''}: a scene file's `materials:` entry "
                        "spelled otherwise does not name it (save the file as UTF-8)"] if odd else []
    if not obj.mtllibs:
        return (), None, tuple(notes)
    library: dict[str, Material] = {}
    first: dict[str, tuple[Path, int]] = {}  # (a material's library and the line of its newmtl there)
    files = _libraries(path, obj.mtllibs)  # (the lookup the scene cache reruns: tlm.scenes.cache)
    for mtl in files:
        lines: dict[str, int] = {}
        # (its read noted with the bytes' sha256: what a memo of the parse checks the library by)
        for m in parse_mtl(mtl_text(read_bytes(mtl, side=True), str(mtl), notes), str(mtl), notes, lines):
            if m.name in library and first[m.name][0] != mtl:
                notes.append(f"{mtl}: line {lines[m.name]}: newmtl {m.name!r} is defined by {first[m.name][0]} too "
                             f"(line {first[m.name][1]}), which the mtllib names first: {LIBRARY_WINS}")
            # (where its values come from, for results.json's scene.materials: Material.origin)
            library.setdefault(m.name, m.with_origin(f"{mtl}:{lines[m.name]}"))
            first.setdefault(m.name, (mtl, lines[m.name]))
    materials = tuple(library.values())
    index = {m.name: i for i, m in enumerate(materials)}
    table = np.full(len(obj.material_names) + 1, -1, dtype=np.int32)  # the last: "no usemtl"
    for k, (name, line) in enumerate(zip(obj.material_names, obj.material_lines, strict=True)):
        if name not in index:  # (a placeholder the scene file may replace: tlm.scenes.loader)
            libs = ", ".join(Path(f).name for f in files)
            why = f"{src}: line {line}: usemtl {name!r}: no material of that name in {libs}{did_you_mean(name, index)}"
            index[name] = len(materials)
            materials = (*materials, Material(name, "lambertian", albedo=(0.8, 0.8, 0.8), undefined=why))
        table[k] = index[name]
    return materials, table[obj.material], tuple(dict.fromkeys(notes))


# ------------------------------------------------------------------ PLY, STL, glTF (trimesh)


def _load_trimesh(path: Path, ext: str, zext: str, stem: str, src: str) -> Geometry:
    import trimesh

    from tlm.scenes.materials import (
        check_gltf,
        check_gltf_buffers,
        glb_length_notes,
        gltf_buffer_sizes,
        gltf_json,
        gltf_materials,
        write_glb,
    )
    from tlm.scenes.objfile import read_bytes

    file_materials: tuple[Material, ...] = ()
    header: dict | None = None  # (a glTF's JSON)
    imported: Imported | None = None  # (a glTF's lights and camera)
    placed: dict[int, np.ndarray] = {}  # (a glTF's mesh nodes whose transform tlm sets: check_mesh_nodes)
    skinned: frozenset[int] = frozenset()  # (those of them placed by their skin's joint matrix)
    notes: tuple[str, ...] = ()
    source: object = str(path)
    kwargs: dict = {}
    data: bytes | None = None
    if zext or ext in (".glb", ".gltf"):
        data = read_bytes(path)
        if zext:
            source = io.BytesIO(data)
            kwargs = {"file_type": ext[1:]}
        if ext in (".glb", ".gltf") and not data.strip():  # (trimesh: "index 0 is out of bounds")
            raise InputError(f"the file is empty ({len(data):,} bytes{', all whitespace' if data else ''}): no "
                             f"{'binary ' if ext == '.glb' else ''}glTF to read (cut short, or not written yet?)",
                             source=src)
        if ext in (".glb", ".gltf"):
            header = gltf_json(path, data)
            check_gltf(header, src)
            imported, notes = gltf_imports(header, src)
            file_materials = tuple(gltf_materials(header, src))
            buffers = _buffer_files(header, path, src)
            binary = _glb_binary(data, ext, src)
            notes += check_gltf_buffers(header, gltf_buffer_sizes(header, path, binary, src), src)
            notes += glb_length_notes(data, src) if ext == ".glb" else ()
            placed, skinned, posed = check_mesh_nodes(header, src, _buffer_reader(header, path, binary, src))
            notes += posed
            if buffers is not None:  # (read from the JSON with the buffers' file names decoded)
                header = {**header, "buffers": buffers}
            nodes = header.get("nodes") if isinstance(header.get("nodes"), list) else []
            cameras = any(isinstance(n, dict) and "camera" in n for n in nodes)
            if file_materials or buffers is not None or cameras or placed:
                # name each material by its index, so that each geometry's says which it is
                from tlm.scenes.materials import glb_chunks

                header = dict(header)
                if file_materials:
                    header["materials"] = [dict(m, name=f"{_TAG}{i}") for i, m in enumerate(header["materials"])]
                if cameras:  # (trimesh drops the mesh of a camera's node, of every one up to its first perspective
                    # camera's; tlm reads the cameras itself: gltf_imports)
                    header["nodes"] = [{k: v for k, v in n.items() if k != "camera"} if isinstance(n, dict) else n
                                       for n in nodes]
                if placed:  # (each named by its index, so that trimesh's frame of its mesh says which it is; a
                    # node named like that already loses its name, which tlm does not use)
                    header["nodes"] = [
                        dict(n, name=f"{_NODE_TAG}{i}") if i in placed
                        else {k: v for k, v in n.items() if k != "name"}
                        if isinstance(n, dict) and str(n.get("name", "")).startswith(_NODE_TAG) else n
                        for i, n in enumerate(header["nodes"])]
                if ext == ".glb":
                    source = io.BytesIO(write_glb(header, glb_chunks(data, src)[1]))
                else:
                    import json

                    source = io.BytesIO(json.dumps(header).encode())
                    kwargs["resolver"] = _noting_resolver(str(path))
                kwargs["file_type"] = ext[1:]
    if ext == ".stl":
        _check_ascii_stl(path, data, src)
    if ext == ".ply":  # (an ASCII one's rows against its header: trimesh reads a wrong list count as something else)
        from tlm.scenes import plyfile

        head = plyfile.header(path, data)
        if b"format ascii" in head:
            plyfile.check_ascii(head, data if data is not None else path.read_bytes(), src)
    if ext in (".glb", ".gltf") and isinstance(source, str):  # (trimesh's own resolver of the file, noting)
        kwargs["resolver"] = _noting_resolver(str(path))
    try:
        loaded = trimesh.load(source, force=None, process=False, **kwargs)
    except Exception as exc:  # trimesh raises anything from ValueError to IndexError
        if ext == ".ply" and "unexpected length" in str(exc):  # (trimesh's "PLY is unexpected length!")
            raise InputError("the binary PLY file's data is not the length its header gives (cut short, bytes added, "
                             "or a count wrong)",
                             source=src) from None
        raise InputError(f"cannot parse the {ext[1:].upper()} file: {_one_line(exc)}",
                         source=src) from None

    # (part name, trimesh geometry, 4x4 transform, the glTF node whose transform tlm sets or None) per instance.
    items: list[tuple[str, object, np.ndarray, int | None]] = []
    if isinstance(loaded, trimesh.Scene):
        for node in loaded.graph.nodes_geometry:
            transform, geom_name = loaded.graph[node]
            tagged = re.match(rf"{_NODE_TAG}(\d+)(?:_\w+)?$", str(node)) if placed else None
            n = int(tagged.group(1)) if tagged and int(tagged.group(1)) in placed else None
            items.append((str(geom_name), loaded.geometry[geom_name],
                          np.asarray(transform) if n is None else placed[n], n))
    else:
        items.append((stem, loaded, np.eye(4), None))
    if not items:
        raise InputError("the file holds no geometry (empty mesh)", source=src)
    # (whether each item's node's transform is singular: a flat mesh its node's zero scale keeps; judged once an item)
    flats = [node is not None and singular(transform[:3, :3]) for _, _, transform, node in items]
    for n in sorted({node for (_, _, _, node), flat in zip(items, flats) if flat}):
        # (a singular transform, judged by all the triangles of the node's mesh, its primitives together: two
        # flat layers are no flat mesh)
        tri = [np.asarray(geom.vertices, dtype=np.float64)[np.asarray(geom.faces)] for _, geom, _, node in items
               if node == n and isinstance(geom, trimesh.Trimesh) and len(geom.faces) > 0
               and np.min(geom.faces) >= 0 and np.max(geom.faces) < len(geom.vertices)]  # (else: _check_mesh)
        judged = np.concatenate(tri) if tri else None
        # (a NaN or infinite corner is not judged here: _check_mesh names its vertex below)
        if judged is not None and np.isfinite(judged).all() and not _keeps_triangles(judged, placed[n][:3, :3]):
            raise InputError(singular_message(n, header["nodes"][n].get("mesh"),
                                              header["nodes"][n].get("skin") if n in skinned else None), source=src)

    if ext == ".ply":
        from tlm.scenes import plyfile

        head = plyfile.header(path, data)
    names: list[str] = []
    chunks: list[np.ndarray] = []
    part_ids: list[np.ndarray] = []
    mat_ids: list[np.ndarray] = []
    corner_normals: list[np.ndarray | None] = []
    for (name, geom, transform, _), flat in zip(items, flats):
        label = "the mesh" if len(items) == 1 else f"geometry {quoted(name)}"
        has_faces = isinstance(geom, trimesh.Trimesh) and len(geom.faces) > 0
        strips = _ply_strips(geom) if ext == ".ply" and not has_faces else None
        polys = plyfile.polygons(geom, src) if ext == ".ply" and has_faces else None
        face_of = None  # (a PLY's face of each triangle: None, triangle i is face i)
        if strips is not None:
            vertices, faces, nrm = strips
        elif polys is not None:
            vertices, faces, nrm, face_of, short = polys
            notes += short
        else:
            if not isinstance(geom, trimesh.Trimesh):
                kind = type(geom).__name__
                raise InputError(f"{label} is a {kind} without faces, not a triangle mesh",
                                 source=src)
            vertices = np.asarray(geom.vertices, dtype=np.float64)
            faces = np.asarray(geom.faces)
            nrm = None
        _check_mesh(vertices, faces, label, src)
        tri = vertices[faces]
        if strips is None and polys is None:
            nrm = _file_normals(geom, faces)
        if ext == ".ply" and nrm is not None:  # (a unit normal read as written, as an OBJ's vn: an export's)
            from tlm.scenes.objfile import unit_as_written

            nrm = unit_as_written(nrm.reshape(-1, 3)).reshape(nrm.shape)
        if not np.allclose(transform, np.eye(4)):
            tri = tri @ transform[:3, :3].T + transform[:3, 3]
            if nrm is not None:  # normals transform by the inverse transpose (a singular one: by the adjugate)
                nrm = nrm @ (adjugate3 if flat else inverse3)(transform[:3, :3])  # (written out: no LAPACK call)
            with np.errstate(divide="ignore", invalid="ignore"):  # (scaled to 1: no overflow; an all-zero one, NaN)
                # (a singular transform turns no winding: its determinant, 0, is not negative)
                mirrors = not flat and det3(transform[:3, :3] / np.abs(transform[:3, :3]).max()) < 0
            if mirrors:  # a mirroring transform flips winding
                tri = tri[:, [0, 2, 1]]
                nrm = None if nrm is None else nrm[:, [0, 2, 1]]
        corner_normals.append(nrm)
        if not np.isfinite(tri).all():
            raise InputError(f"{label} has a scene transform that makes vertices non-finite",
                             source=src)
        if name not in names:
            names.append(name)
        chunks.append(tri)
        part_ids.append(np.full(len(tri), names.index(name), dtype=np.int32))
        mat_ids.append(np.full(len(tri), _gltf_index(geom, len(file_materials)), dtype=np.int32))
        if ext == ".ply":  # (one mesh: its faces' materials, and what it holds that tlm does not render)
            notes += plyfile.colour_notes(geom, src)
            got = plyfile.face_materials(geom, src, head, face_of) if has_faces else None
            if got is not None:
                file_materials, mat_ids[-1] = got
    normals = None
    if all(c is not None for c in corner_normals):  # the file gives every geometry's normals
        normals = np.concatenate(corner_normals)
        length = np.linalg.norm(normals, axis=2, keepdims=True)
        normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    return Geometry(
        triangles=np.ascontiguousarray(np.concatenate(chunks), dtype=np.float64),
        part=np.concatenate(part_ids),
        part_names=tuple(names),
        normals=normals,
        materials=file_materials,
        face_material=np.concatenate(mat_ids) if file_materials else None,
        notes=notes,
        imports=() if imported is None else (imported,),
    )


def _gltf_index(geom, n_materials: int) -> int:
    """Index of the glTF material a trimesh geometry carries (named by ``_TAG``), -1: none."""
    material = getattr(getattr(geom, "visual", None), "material", None)
    name = str(getattr(material, "name", None) or "")
    match = re.fullmatch(re.escape(_TAG) + r"(\d+)", name)
    if match and int(match.group(1)) < n_materials:
        return int(match.group(1))
    return -1


def _ply_strips(geom) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | None:
    """(vertices, faces, corner normals or None) of a PLY whose faces are triangle strips
    (element ``tristrips``, property ``vertex_indices``, -1 restarting a strip); None
    for any other PLY. A strip ``v0 v1 v2 v3 ...`` gives ``(v0 v1 v2), (v2 v1 v3),
    (v2 v3 v4), ...`` (every other one flipped, so all keep one winding); triangles with
    a repeated vertex (the stitches between strips) are dropped."""
    raw = (getattr(geom, "metadata", None) or {}).get("_ply_raw") or {}
    strips = (raw.get("tristrips") or {}).get("data")
    data = (raw.get("vertex") or {}).get("data")
    lists = _ply_field(strips, "vertex_indices")
    xyz = [_ply_field(data, k) for k in "xyz"]
    if lists is None or any(c is None for c in xyz):
        return None
    vertices = np.stack([np.asarray(c, dtype=np.float64).reshape(-1) for c in xyz], axis=1)
    lists = np.asarray(lists) if not isinstance(lists, list) else lists
    if getattr(getattr(lists, "dtype", None), "names", None):  # binary: (count, values) records
        count, values = lists[lists.dtype.names[0]], lists[lists.dtype.names[1]]
        seqs = [np.asarray(values[i]).reshape(-1)[: int(count[i])] for i in range(len(count))]
    elif isinstance(lists, np.ndarray) and lists.dtype != object:
        seqs = [np.asarray(row).reshape(-1) for row in lists.reshape(lists.shape[0], -1)]
    else:
        seqs = [np.asarray(row).reshape(-1) for row in lists]
    flat = np.concatenate([np.r_[s.astype(np.int64), -1] for s in seqs]) if seqs else np.zeros(0, np.int64)
    # every window of three inside one strip (no -1 among them)
    faces = np.zeros((0, 3), dtype=np.int64)
    if flat.shape[0] >= 3:
        win = np.stack([flat[:-2], flat[1:-1], flat[2:]], axis=1)
        ok = (win >= 0).all(axis=1)
        restart = np.flatnonzero(flat < 0)
        # position of each window within its strip: flip every other one
        strip_start = np.r_[0, restart + 1]
        pos = np.arange(win.shape[0]) - strip_start[np.searchsorted(strip_start, np.arange(win.shape[0]),
                                                                    side="right") - 1]
        odd = (pos % 2) == 1
        win[odd] = win[odd][:, [1, 0, 2]]
        keep = ok & (win[:, 0] != win[:, 1]) & (win[:, 1] != win[:, 2]) & (win[:, 0] != win[:, 2])
        faces = win[keep]
    normals = None
    nxyz = [_ply_field(data, k) for k in ("nx", "ny", "nz")]
    if all(c is not None for c in nxyz):
        n = np.stack([np.asarray(c, dtype=np.float64).reshape(-1) for c in nxyz], axis=1)
        if n.shape == vertices.shape and np.isfinite(n).all() and faces.shape[0] and faces.max() < len(n):
            normals = n[faces]
    return vertices, faces, normals


def _ply_field(data, key: str):
    """A property of a PLY element as trimesh keeps it (:func:`tlm.scenes.plyfile.field`)."""
    from tlm.scenes.plyfile import field

    return field(data, key)


def _file_normals(geom, faces: np.ndarray) -> np.ndarray | None:
    """(f, 3, 3) per-corner normals the file gave (PLY ``nx ny nz``, glTF NORMAL), or
    None when trimesh would have to compute them (its own would be area-weighted
    without a crease angle: the loader's crease normals are better)."""
    given = geom._cache.cache.get("vertex_normals") if hasattr(geom, "_cache") else None
    if given is None:
        return None
    given = np.asarray(given, dtype=np.float64)
    if given.shape != (len(geom.vertices), 3) or not np.isfinite(given).all():
        return None
    return given[faces]
