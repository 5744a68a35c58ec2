"""Mesh files (OBJ, PLY, STL, GLB/GLTF) as named parts, loaded with trimesh.

`load_mesh` turns a file into a :class:`~tlm.scenes.model.Geometry`. Nothing is
repaired, merged or dropped: trimesh is called with ``process=False`` so that the
triangles keep the file's face order and winding (polygons are fan-triangulated by
trimesh's readers). A file holding one mesh becomes one part named after the file
stem; a scene (GLB/GLTF, or an OBJ with several ``o`` objects, or several ``g`` groups
when it has no objects) becomes one part per geometry, named by trimesh's geometry
name, with each instance's scene-graph transform applied. Every problem is an
:class:`~tlm.errors.InputError` naming the file.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from tlm.errors import InputError
from tlm.scenes.model import Geometry

__all__ = ["SUPPORTED_EXTENSIONS", "load_mesh"]

SUPPORTED_EXTENSIONS = (".obj", ".ply", ".stl", ".glb", ".gltf")


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def _obj_kwargs(path: Path) -> tuple[dict, list[str]]:
    """Loader options for an OBJ file and the object (or group) names in file order."""
    try:
        text = path.read_text(errors="replace")
    except OSError:
        return {}, []
    objects = re.findall(r"^o[ \t]+(.*?)\s*$", text, flags=re.MULTILINE)
    groups = re.findall(r"^g[ \t]+(.*?)\s*$", text, flags=re.MULTILINE)
    kwargs = {"group_material": False, "maintain_order": True, "skip_materials": True}
    if objects:
        kwargs["split_objects"] = True
        return kwargs, objects
    if groups:
        kwargs["split_groups"] = True
        return kwargs, groups
    # One chunk: split_objects keeps trimesh from splitting at `usemtl` lines.
    kwargs["split_objects"] = True
    return kwargs, []


def _file_rank(name: str, order: list[str]) -> int:
    """Position in the file of the object/group a trimesh geometry name comes from."""
    for i, o in enumerate(order):
        if name == o or re.fullmatch(re.escape(o) + r"_\d+", name):
            return i
    return len(order)


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
            f"infinite coordinates (first: vertex {first}, {vertices[first].tolist()})",
            source=source,
        )
    if faces.min() < 0 or faces.max() >= len(vertices):
        worst = int(faces.min()) if faces.min() < 0 else int(faces.max())
        raise InputError(
            f"{label} has a face referencing vertex {worst} but only {len(vertices)} vertices",
            source=source,
        )


def load_mesh(path: Path) -> Geometry:
    """Load a mesh file into named parts.

    Parameters
    ----------
    path : Path
        An OBJ, PLY, STL, GLB or GLTF file.

    Returns
    -------
    Geometry
        ``triangles`` (n, 3, 3) float64 in the file's face order (scene geometries in
        scene-graph order, OBJ objects in file order), ``part`` (n,) int32.

    Raises
    ------
    InputError
        Missing file, unsupported extension, unparsable file, no faces (empty mesh,
        point cloud, path), non-triangle faces, NaN/inf vertices, bad face indices.
    """
    import trimesh

    path = Path(path)
    src = str(path)
    ext = path.suffix.lower()
    if ext not in SUPPORTED_EXTENSIONS:
        raise InputError(
            f"unsupported mesh extension {path.suffix or '(none)'!r}; supported: "
            f"{', '.join(SUPPORTED_EXTENSIONS)}",
            source=src,
        )
    if not path.is_file():
        raise InputError("mesh file not found", source=src)
    kwargs: dict = {}
    order: list[str] = []
    if ext == ".obj":
        kwargs, order = _obj_kwargs(path)
    try:
        loaded = trimesh.load(str(path), force=None, process=False, **kwargs)
    except Exception as exc:  # trimesh raises anything from ValueError to IndexError
        raise InputError(f"cannot parse the {ext[1:].upper()} file: {_one_line(exc)}",
                         source=src) from None

    # (part name, trimesh geometry, 4x4 transform) per instance.
    items: list[tuple[str, object, np.ndarray]] = []
    if isinstance(loaded, trimesh.Scene):
        nodes = list(loaded.graph.nodes_geometry)
        for node in nodes:
            transform, geom_name = loaded.graph[node]
            items.append((str(geom_name), loaded.geometry[geom_name], np.asarray(transform)))
        if order:
            items.sort(key=lambda it: _file_rank(it[0], order))
    else:
        items.append((path.stem, loaded, np.eye(4)))
    if not items:
        raise InputError("the file holds no geometry (empty mesh)", source=src)

    names: list[str] = []
    chunks: list[np.ndarray] = []
    part_ids: list[np.ndarray] = []
    corner_normals: list[np.ndarray | None] = []
    for name, geom, transform in items:
        label = "the mesh" if len(items) == 1 else f"geometry {name!r}"
        if not isinstance(geom, trimesh.Trimesh):
            kind = type(geom).__name__
            raise InputError(f"{label} is a {kind} without faces, not a triangle mesh",
                             source=src)
        vertices = np.asarray(geom.vertices, dtype=np.float64)
        faces = np.asarray(geom.faces)
        _check_mesh(vertices, faces, label, src)
        tri = vertices[faces]
        nrm = _file_normals(geom, faces)
        if not np.allclose(transform, np.eye(4)):
            tri = tri @ transform[:3, :3].T + transform[:3, 3]
            if nrm is not None:  # normals transform by the inverse transpose
                nrm = nrm @ np.linalg.inv(transform[:3, :3])
            if np.linalg.det(transform[:3, :3]) < 0:  # a mirroring transform flips winding
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
    )


def _file_normals(geom, faces: np.ndarray) -> np.ndarray | None:
    """(f, 3, 3) per-corner normals the file gave (OBJ ``vn``, PLY ``nx ny nz``, glTF
    NORMAL), or None when trimesh would have to compute them (its own would be
    area-weighted without a crease angle: the loader's crease normals are better)."""
    given = geom._cache.cache.get("vertex_normals") if hasattr(geom, "_cache") else None
    if given is None:
        return None
    given = np.asarray(given, dtype=np.float64)
    if given.shape != (len(geom.vertices), 3) or not np.isfinite(given).all():
        return None
    return given[faces]
