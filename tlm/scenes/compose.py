"""A scene's ``geometry:``: one item, or a list of items merged into one Geometry.

An *item* is a mapping with exactly one source key:

* ``builder: NAME`` with ``params: {...}`` (the thesis's scenes: ``ring``, ``room``, ``cornell``);
* ``mesh: FILE`` (OBJ, PLY, STL, GLB/glTF, relative to the scene file that names it);
* ``shape: NAME`` with ``params: {...}``, a primitive needing no file (:data:`SHAPES`):
  ``plane`` (a floor), ``quad``, ``box``, ``sphere``, ``cylinder``;

and optionally

* ``transform: {scale, rotate, translate}``: scale (a number or ``[sx, sy, sz]``, no
  zero; a negative one mirrors), then rotate (degrees ``[rx, ry, rz]``: about x, then y,
  then z, right-handed, i.e. ``p' = Rz Ry Rx S p + t``), then translate; shading normals
  from a mesh file follow by the inverse transpose, and a mirroring transform reverses
  each triangle's vertex order so that front faces stay front faces; a glTF's imported
  lights and camera (``Geometry.imports``) move with the triangles: a light's position as a
  vertex, a spot's or directional light's direction by ``M`` alone, made unit length again
  (under a non-uniform scale it turns as the triangles' edges do; its power, a spot's cone
  angles and a directional light's irradiance stay);
* ``name: N``: the item's part names become ``N`` (an item of one part) or ``N.PART``
  (an item of several parts, e.g. a builder's).

``geometry: {...}`` (one item) is what scene files always had; ``geometry: [...]`` merges
the items in list order (triangle ids follow it): triangles, parts, shading normals (an
item without file normals gets crease normals at the default angle, as the loader would
give it: parts never span items), the file materials (two files' equal materials become
one; a different one under a name already used is renamed ``NAME_2``),
``face_material`` (re-indexed, -1 kept) and the files' imported lights and cameras (in
order). A part name that an earlier item already uses is renamed ``PART_2`` (then ``_3``
...) unless the item has a ``name``, in which case it is an error. Every problem is an
:class:`~tlm.errors.InputError` naming the file and the key
(``geometry[1].transform.scale``).
"""

from __future__ import annotations

import inspect
import math
import os
import stat
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from tlm.errors import InputError, did_you_mean, quoted
from tlm.scenes.model import Geometry, Imported, Light, unit_vector
from tlm.scenes.validate import keys as _keys
from tlm.scenes.validate import mapping as _mapping
from tlm.scenes.validate import num, shown, vec

__all__ = ["ITEM_KEYS", "SHAPES", "TRANSFORM_KEYS", "compose_geometry", "item_transform", "listed_part_names",
           "mesh_path", "transform_geometry"]

SOURCES = ("builder", "mesh", "shape")
ITEM_KEYS = ("builder", "mesh", "shape", "params", "transform", "name")
TRANSFORM_KEYS = ("scale", "rotate", "translate")
# shape name -> its params and their defaults (None: required)
SHAPES: dict[str, dict[str, Any]] = {
    "plane": {"size": [1.0, 1.0], "divisions": [1, 1]},
    "quad": {"corner": None, "edge_u": None, "edge_v": None, "divisions": [1, 1]},
    "box": {"min": [-0.5, -0.5, -0.5], "max": [0.5, 0.5, 0.5], "divisions": 1},
    "sphere": {"center": [0.0, 0.0, 0.0], "radius": 1.0, "segments": 32, "rings": 16},
    "cylinder": {"center": [0.0, 0.0, 0.0], "radius": 1.0, "height": 1.0, "segments": 32},
}


def _num(v: Any, src: str, key: str, positive: bool = False) -> float:
    return num(v, src, key, lo=0.0, lo_exclusive=True) if positive else num(v, src, key)


def _vec(v: Any, src: str, key: str, n: int = 3) -> tuple[float, ...]:
    return vec(v, src, key, n=n)


def _whole(v: Any, src: str, key: str, lo: int) -> int:
    if not isinstance(v, int) or isinstance(v, bool) or v < lo:
        raise InputError(f"{shown(v)} must be a whole number >= {lo}", source=src, key=key)
    return int(v)


def _ints(v: Any, src: str, key: str, n: int, lo: int) -> list[int]:
    if not isinstance(v, list) or len(v) != n:
        raise InputError(f"{shown(v)} is not a list of {n} whole numbers", source=src, key=key)
    return [_whole(x, src, key, lo) for x in v]


# ---------------------------------------------------------------- transforms


def _rotation(axis: int, degrees: float) -> np.ndarray:
    """Right-handed rotation about x (0), y (1) or z (2); exact at multiples of 90 degrees."""
    quarter = degrees / 90.0
    if quarter == round(quarter):
        c, s = ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[round(quarter) % 4]
    else:
        c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def item_transform(raw: Any, src: str, key: str) -> tuple[np.ndarray, np.ndarray] | None:
    """``transform: {scale, rotate, translate}`` as ``(M, t)`` with ``p' = M p + t``;
    None when it is absent or the identity."""
    if raw is None:
        return None
    tr = _mapping(raw, src, key)
    _keys(tr, TRANSFORM_KEYS, src, key)
    scale = tr.get("scale", 1.0)
    if isinstance(scale, list):
        s = np.asarray(_vec(scale, src, f"{key}.scale"))
    else:
        s = np.full(3, _num(scale, src, f"{key}.scale"))
    if np.any(s == 0.0):
        raise InputError(f"{scale!r} must be non-zero (a negative scale mirrors)", source=src, key=f"{key}.scale")
    rx, ry, rz = _vec(tr.get("rotate", [0.0, 0.0, 0.0]), src, f"{key}.rotate")
    t = np.asarray(_vec(tr.get("translate", [0.0, 0.0, 0.0]), src, f"{key}.translate"))
    m = _rotation(2, rz) @ _rotation(1, ry) @ _rotation(0, rx) @ np.diag(s)
    if np.array_equal(m, np.eye(3)) and not t.any():
        return None
    return m, t


def transform_geometry(geom: Geometry, m: np.ndarray, t: np.ndarray) -> Geometry:
    """``p' = M p + t`` on the triangles; file normals by the inverse transpose; a
    mirroring ``M`` (negative determinant) reverses each triangle's vertex order. (The inverse
    and the determinant are written out, :func:`~tlm.scenes.meshes.inverse3` and
    :func:`~tlm.scenes.meshes.det3`: no LAPACK call.)"""
    from tlm.scenes.meshes import det3, inverse3  # (as load_mesh: meshes is imported where a scene needs it)

    with np.errstate(over="ignore", invalid="ignore"):  # the caller checks the result is finite
        tri = np.asarray(geom.triangles, dtype=np.float64) @ m.T + t
        normals = geom.normals
        if normals is not None:
            normals = np.asarray(normals, dtype=np.float64) @ inverse3(m)
            length = np.linalg.norm(normals, axis=2, keepdims=True)
            normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
        mirrors = det3(m / np.abs(m).max()) < 0.0
    if mirrors:
        tri = tri[:, [0, 2, 1]]
        normals = None if normals is None else normals[:, [0, 2, 1]]
    imports = tuple(_transform_imported(i, m, t) for i in geom.imports)
    return replace(geom, triangles=np.ascontiguousarray(tri), normals=normals, imports=imports)


def _transform_imported(imp: Imported, m: np.ndarray, t: np.ndarray) -> Imported:
    """A mesh file's lights and camera moved as its triangles are (``p' = M p + t``): a light's
    position and the camera's eye; a spot's or directional light's direction, the view
    direction and up by ``M`` and made unit again (the target one unit in front of the new
    eye). A light's power stays (as the glTF spec has a node's scale leave its light's
    intensity)."""
    def pt(p) -> tuple[float, float, float]:
        with np.errstate(over="ignore", invalid="ignore"):  # (the loader checks the result is finite)
            return tuple(float(x) for x in m @ np.asarray(p, dtype=np.float64) + t)

    def unit(v) -> tuple[float, float, float]:
        with np.errstate(over="ignore", invalid="ignore"):
            d = m @ np.asarray(v, dtype=np.float64)
            return tuple(float(x) for x in d / np.linalg.norm(d))

    def light(lt: Light) -> Light:
        if lt.kind not in ("spot", "directional"):
            return replace(lt, position=pt(lt.position))
        with np.errstate(over="ignore", invalid="ignore"):
            u = unit_vector(m @ np.asarray(lt.direction, dtype=np.float64))
        # (NaN where M leaves it none, which only a product beyond float64 can: the loader names it)
        return replace(lt, position=pt(lt.position) if lt.kind == "spot" else lt.position,  # (a directional
                       direction=(math.nan,) * 3 if u is None else tuple(float(x) for x in u))  # light has none)

    lights = tuple(light(lt) for lt in imp.lights)
    cam = imp.camera
    if cam is not None:
        eye = pt(cam.eye)
        fwd = unit(np.subtract(cam.target, cam.eye))
        cam = replace(cam, eye=eye, target=tuple(float(e + f) for e, f in zip(eye, fwd, strict=True)),
                      up=unit(cam.up))
    return replace(imp, lights=lights, camera=cam)


# ---------------------------------------------------------------- sources


def _params(raw: dict, src: str, key: str) -> dict:
    return _mapping(raw.get("params") or {}, src, f"{key}.params")


def _builder(raw: dict, src: str, key: str) -> Geometry:
    from tlm.scenes.builders import BUILDERS, BuilderParamError

    name = raw["builder"]
    if not isinstance(name, str) or name not in BUILDERS:
        raise InputError(
            f"{quoted(name)} is not a builder ({', '.join(BUILDERS)}){did_you_mean(str(name), BUILDERS)}",
            source=src, key=f"{key}.builder",
        )
    params = _params(raw, src, key)
    builder = BUILDERS[name]
    known = tuple(inspect.signature(builder).parameters)
    for k in params:
        if k not in known:
            raise InputError(f"unknown parameter of builder {name}{did_you_mean(str(k), known)}; its parameters: "
                             f"{', '.join(known)}", source=src, key=f"{key}.params.{k}")
    try:
        return builder(**params)
    except BuilderParamError as e:  # one parameter's refusal: named by its key (geometry[0].params.glass_seg)
        raise InputError(e.reason, source=src, key=f"{key}.params.{e.key}") from None
    except TypeError as e:
        raise InputError(f"bad builder parameter ({e})", source=src, key=f"{key}.params") from None
    except ValueError as e:
        raise InputError(str(e), source=src, key=f"{key}.params") from None


def _mesh(raw: dict, src: str, path: Path, key: str) -> Geometry:
    from tlm.scenes.meshes import load_mesh

    mesh = raw["mesh"]
    if not isinstance(mesh, str) or not mesh:
        raise InputError(f"{quoted(mesh)} is not a file name", source=src, key=f"{key}.mesh")
    if "params" in raw:
        raise InputError("a mesh takes no params (scale, rotate and move it with transform)",
                         source=src, key=f"{key}.params")
    mpath = mesh_path(mesh, path)
    wrong = _not_a_mesh_file(mpath)
    if wrong:
        raise InputError(wrong, source=src, key=f"{key}.mesh")
    return load_mesh(mpath)


def _not_a_mesh_file(mpath: Path) -> str | None:
    """Why the path ``mpath`` names no regular file to read a mesh from (a folder, a device, a pipe, a
    socket, a link to nothing, nothing, a folder on the way that cannot be searched, a name no file can
    have); None where it does."""
    try:
        mode = mpath.stat().st_mode
    except FileNotFoundError:
        if mpath.is_symlink():
            try:
                to = os.readlink(mpath)
            except OSError:  # (removed meanwhile)
                return f"mesh file {quoted(mpath)} not found"
            end = ("itself a link that leads to no file" if os.path.islink(mpath.parent / to) else
                   "which is not there")  # (a chain of links ending in nothing)
            return f"mesh file {quoted(mpath)} is a symbolic link to {quoted(to)}, {end}"
        return f"mesh file {quoted(mpath)} not found"
    except OSError as e:  # (a folder on the way that cannot be searched, a link loop, a name too long)
        return f"mesh file {quoted(mpath)} cannot be read ({e.strerror or e})"
    except ValueError:  # (a NUL character: no file has such a name)
        return f"mesh file {quoted(mpath)} not found (a file name holds no NUL character)"
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return f"{quoted(mpath)} is a folder, not a mesh file"
    kind = ("a character device" if stat.S_ISCHR(mode) else "a block device" if stat.S_ISBLK(mode) else
            "a named pipe" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else "a special file")
    return f"{quoted(mpath)} is {kind}, not a mesh file (a mesh is read from a regular file)"


def mesh_path(mesh: str, path: Path) -> Path:
    """An item's ``mesh:`` file, relative to the scene file ``path`` that names it, without its ``..``
    and ``.`` where the plain name is the same entry (:func:`tlm.scenes.meshes.shown_path`, the one rule of a mesh's
    path): one mesh reached two ways (``a/../m/box.obj``, ``m/box.obj``) is one path, in messages and to whatever
    compares them."""
    from tlm.scenes.meshes import shown_path  # (as load_mesh: meshes is imported where a scene needs it)

    mpath = Path(mesh)
    return shown_path(mpath if mpath.is_absolute() else path.parent / mpath)


def _shape(raw: dict, src: str, key: str) -> Geometry:
    from tlm.scenes import shapes

    kind = raw["shape"]
    if not isinstance(kind, str) or kind not in SHAPES:
        raise InputError(f"{quoted(kind)} is not a shape ({', '.join(SHAPES)}){did_you_mean(str(kind), SHAPES)}",
                         source=src, key=f"{key}.shape")
    pk = f"{key}.params"
    given = _params(raw, src, key)
    _keys(given, tuple(SHAPES[kind]), src, pk)
    p = {**SHAPES[kind], **given}
    for name, value in p.items():
        if value is None:
            raise InputError(f"a {kind} needs {name}", source=src, key=f"{pk}.{name}")
    try:
        tri = _tessellate(shapes, kind, p, src, pk)
    except InputError:
        raise
    except ValueError as e:  # (a tessellation too large for the machine: shapes.check_triangle_count)
        raise InputError(str(e), source=src, key=pk) from None
    tri = np.ascontiguousarray(tri, dtype=np.float64)
    return Geometry(triangles=tri, part=np.zeros(len(tri), dtype=np.int32), part_names=(kind,))


def _tessellate(shapes, kind: str, p: dict, src: str, pk: str) -> np.ndarray:
    """The triangles of shape ``kind`` with its parameters ``p`` (defaults filled in)."""
    if kind == "plane":  # centred on the origin in y = 0, facing +y
        w, d = _vec(p["size"], src, f"{pk}.size", n=2)
        if not (w > 0 and d > 0):
            raise InputError(f"{shown(p['size'])} must be positive", source=src, key=f"{pk}.size")
        nu, nv = _ints(p["divisions"], src, f"{pk}.divisions", 2, 1)
        tri = shapes.quad((-w / 2, 0.0, d / 2), (w, 0.0, 0.0), (0.0, 0.0, -d), nu, nv)
    elif kind == "quad":
        c, u, v = (_vec(p[k], src, f"{pk}.{k}") for k in ("corner", "edge_u", "edge_v"))
        if not np.linalg.norm(np.cross(u, v)) > 1e-12 * np.linalg.norm(u) * np.linalg.norm(v):
            raise InputError("edge_u and edge_v span no area", source=src, key=pk)
        nu, nv = _ints(p["divisions"], src, f"{pk}.divisions", 2, 1)
        tri = shapes.quad(c, u, v, nu, nv)
    elif kind == "box":
        lo, hi = _vec(p["min"], src, f"{pk}.min"), _vec(p["max"], src, f"{pk}.max")
        if not all(b > a for a, b in zip(lo, hi, strict=True)):
            raise InputError(f"max {list(hi)} must exceed min {list(lo)} in x, y and z", source=src, key=pk)
        tri = shapes.aabox(lo, hi, n=_whole(p["divisions"], src, f"{pk}.divisions", 1))
    elif kind == "sphere":
        c = _vec(p["center"], src, f"{pk}.center")
        r = _num(p["radius"], src, f"{pk}.radius", positive=True)
        tri = shapes.uv_sphere(c, r, _whole(p["segments"], src, f"{pk}.segments", 3),
                               _whole(p["rings"], src, f"{pk}.rings", 2))
    else:  # cylinder: base centre, along +y, both caps
        c = _vec(p["center"], src, f"{pk}.center")
        r = _num(p["radius"], src, f"{pk}.radius", positive=True)
        h = _num(p["height"], src, f"{pk}.height", positive=True)
        tri = shapes.cylinder(c, r, h, _whole(p["segments"], src, f"{pk}.segments", 3))
    return tri


def _item(raw: Any, src: str, path: Path, key: str, items: list | None = None) -> tuple[Geometry, str | None]:
    """One item: its geometry, transformed and with its parts renamed, and its ``name``; ``items``, where passed,
    gets what gave the item's parts (:func:`_source`) and their names before its ``name`` renamed them."""
    if not isinstance(raw, dict):
        raise InputError(f"must be a mapping with one of {', '.join(SOURCES)}, got {raw!r}", source=src, key=key)
    _keys(raw, ITEM_KEYS, src, key)
    given = [k for k in SOURCES if k in raw]
    if len(given) != 1:
        raise InputError(f"give exactly one of 'builder', 'mesh' or 'shape' (got {len(given)})",
                         source=src, key=key)
    name = raw.get("name")
    if name is not None and (not isinstance(name, str) or not name.strip()):
        raise InputError(f"{quoted(name)} is not a name", source=src, key=f"{key}.name")
    transform = item_transform(raw.get("transform"), src, f"{key}.transform")
    if "builder" in raw:
        geom = _builder(raw, src, key)
    elif "mesh" in raw:
        geom = _mesh(raw, src, path, key)
    else:
        geom = _shape(raw, src, key)
    if items is not None:
        items.append((_source(raw, path), tuple(geom.part_names)))
    if transform is not None:
        geom = transform_geometry(geom, *transform)
        if not np.isfinite(geom.triangles).all():
            raise InputError("makes vertices non-finite", source=src, key=f"{key}.transform")
    if name is not None:
        geom = replace(geom, part_names=_named(geom.part_names, name))
    return geom, name


def _named(part_names: tuple[str, ...], name: str) -> tuple[str, ...]:
    """An item's part names under its ``name``: ``N`` (one part) or ``N.PART``."""
    return (name,) if len(part_names) == 1 else tuple(f"{name}.{p}" for p in part_names)


def _source(raw: Any, path: Path) -> tuple | None:
    """What gives the parts of the item ``raw`` of the scene file ``path`` (its ``transform`` and ``name`` aside),
    to know it listed again: ``("builder", NAME, PARAMS)``, ``("mesh", FILE)`` (:func:`mesh_path`), ``("shape",
    NAME)``; None for an item that is none of them."""
    if not isinstance(raw, dict) or len([k for k in SOURCES if k in raw]) != 1:
        return None
    if isinstance(raw.get("builder"), str):
        return ("builder", raw["builder"], raw.get("params") or {})
    if isinstance(raw.get("shape"), str):
        return ("shape", raw["shape"])
    if isinstance(raw.get("mesh"), str) and raw["mesh"]:
        try:
            return ("mesh", str(mesh_path(raw["mesh"], path)))
        except (OSError, ValueError):  # (a name no file has: no such item is known)
            return None
    return None


def listed_part_names(raw: Any, path: Path, items: list) -> tuple[str, ...] | None:
    """The part names of the geometry ``raw`` (a ``geometry:`` value of the scene file ``path``, mesh paths
    relative to it), known without building it: a shape's from its kind, a builder's (the same name and params) or
    a mesh file's from the item of another geometry built (``items``: :func:`compose_geometry`'s), each under its
    ``name``, merged as :func:`merge` merges them; None where one item's cannot be known so (a mesh file or a
    builder's params that no built item has) or the geometry is no geometry."""
    listed = raw if isinstance(raw, list) else [raw]
    if not listed:
        return None
    per_item, names = [], []
    for item in listed:
        source = _source(item, path)
        name = item.get("name") if isinstance(item, dict) else None
        if source is None or (name is not None and (not isinstance(name, str) or not name.strip())):
            return None
        if source[0] == "shape":
            own = (source[1],) if source[1] in SHAPES else None
        else:
            own = next((n for s, n in items if s == source), None)
        if own is None:
            return None
        per_item.append(own if name is None else _named(own, name))
        names.append(name)
    if not isinstance(raw, list):
        return per_item[0]
    try:
        return tuple(p for own in _renamed(per_item, names, None) for p in own)
    except InputError:  # (a geometry that is an error: not known)
        return None


# ---------------------------------------------------------------- merging


def compose_geometry(raw: Any, src: str, path: Path, items: list | None = None) -> Geometry:
    """The Geometry of a scene's ``geometry:`` value (one item or a list of items);
    ``src`` and ``path`` are the scene file that names it (mesh paths are relative to it). ``items``, where
    passed, gets each item's source and part names, for :func:`listed_part_names`."""
    if isinstance(raw, dict):
        return _item(raw, src, path, "geometry", items)[0]
    if not isinstance(raw, list):
        raise InputError(f"must be a mapping (builder, mesh or shape) or a list of them, got {raw!r}",
                         source=src, key="geometry")
    if not raw:
        raise InputError("an empty list: give at least one builder, mesh or shape", source=src, key="geometry")
    built = [_item(r, src, path, f"geometry[{i}]", items) for i, r in enumerate(raw)]
    return merge([g for g, _ in built], [n for _, n in built], src)


def _renamed(per_item: list[tuple[str, ...]], names: list[str | None], src: str | None) -> list[tuple[str, ...]]:
    """Each item's part names in the merged geometry (:func:`merge`): a name an earlier item already uses
    renamed ``PART_2`` (then ``_3`` ...), an error where the item has a ``name``."""
    part_names: list[str] = []
    out = []
    for i, (own, item_name) in enumerate(zip(per_item, names, strict=True)):
        local: list[str] = []
        for p in own:
            final, k = p, 2
            while final in part_names or final in local:
                if item_name is not None:
                    raise InputError(f"{quoted(p)} is already a part name of an earlier item; give this item "
                                     "another name",
                                     source=src, key=f"geometry[{i}].name")
                final, k = f"{p}_{k}", k + 1
            local.append(final)
        part_names.extend(local)
        out.append(tuple(local))
    return out


def merge(geoms: list[Geometry], names: list[str | None] | None = None, src: str | None = None) -> Geometry:
    """Concatenate geometries in order: parts (renamed where names repeat), normals,
    file materials and ``face_material`` (offset)."""
    from tlm.scenes.normals import DEFAULT_CREASE_ANGLE, crease_normals

    renamed = _renamed([tuple(g.part_names) for g in geoms], names or [None] * len(geoms), src)
    part_names: list[str] = []
    parts, materials, face_material = [], [], []
    for g, local in zip(geoms, renamed, strict=True):
        parts.append(np.asarray(g.part, dtype=np.int32) + len(part_names))
        part_names.extend(local)
        index = []  # the item's file materials in the merged list: equal ones shared, a name reused renamed
        for m in g.materials:
            same = [j for j, o in enumerate(materials) if o == m]
            if same:  # (what each file's leaves unrendered, together)
                o = materials[same[0]]
                materials[same[0]] = replace(o, ignored=tuple(dict.fromkeys((*o.ignored, *m.ignored))))
                index.append(same[0])
                continue
            taken, k, name = {o.name for o in materials}, 2, m.name
            while name in taken:
                name, k = f"{m.name}_{k}", k + 1
            index.append(len(materials))
            materials.append(replace(m, name=name, alias=m.alias or (m.name if name != m.name else "")))
        fm = (np.full(len(g.triangles), -1, dtype=np.int32) if g.face_material is None
              else np.asarray(g.face_material, dtype=np.int32))
        lookup = np.asarray(index + [-1], dtype=np.int32)  # -1 stays -1
        face_material.append(lookup[np.where(fm >= 0, fm, len(index))])
    normals = None
    if any(g.normals is not None for g in geoms):
        normals = np.concatenate([
            np.asarray(g.normals, dtype=np.float64) if g.normals is not None
            else crease_normals(g.triangles, g.part, DEFAULT_CREASE_ANGLE)
            for g in geoms
        ])
    any_file_materials = any(g.face_material is not None for g in geoms)
    return Geometry(
        triangles=np.ascontiguousarray(np.concatenate([np.asarray(g.triangles, dtype=np.float64) for g in geoms])),
        part=np.concatenate(parts).astype(np.int32),
        part_names=tuple(part_names),
        normals=normals,
        materials=tuple(materials),
        face_material=np.concatenate(face_material) if any_file_materials else None,
        notes=tuple(dict.fromkeys(n for g in geoms for n in g.notes)),
        imports=tuple(i for g in geoms for i in g.imports),
    )
