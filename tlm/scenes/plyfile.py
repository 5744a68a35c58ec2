"""What tlm reads of a PLY file besides the triangles trimesh gives (:mod:`tlm.scenes.meshes`).

* **Each face's material.** A face property ``material`` (or ``material_index``), one
  whole number per face, gives the face's material: ``-1`` none (the part's material or
  ``default_material``, as an OBJ face before any ``usemtl``), ``k >= 0`` material ``k``.
  A PLY holds no material's values, so each material is a placeholder
  (``Material.undefined``) that the scene file supplies by name under ``materials:``
  (or ``default_material``), as it supplies an OBJ's ``usemtl`` that no MTL defines.
  The name is the one the file's header gives (``comment tlm material K "NAME"``, the
  name as a JSON string: what ``tlm scene export`` writes, :mod:`tlm.scenes.export`),
  else the index itself (``materials: {3: ...}``). An index that the header's names do
  not cover, a negative one other than ``-1``, a fraction, or a list property is an
  :class:`~tlm.errors.InputError` naming the file and the first such face.
* **Polygons.** trimesh groups a PLY's faces by their corner count (its triangles, then
  its quads' first halves, then their second halves, then larger polygons), so a file
  with any face of more than three corners is triangulated here instead: each face
  fanned from its first corner, ``(0, i, i + 1)``, in file order, as an OBJ is. A face of
  fewer than three corners among polygons gives no triangle, and a line says so.
* **Colours.** Vertex or face colours (``red``, ``green``, ``blue``, ...) are not
  rendered (a triangle's material is the scene file's): a line says so, as it does of a
  ``material`` property of triangle strips (element ``tristrips``), which is not read.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from tlm.errors import InputError
from tlm.scenes.model import Material

__all__ = ["MATERIAL_PROPERTIES", "NAME_COMMENT", "check_ascii", "colour_notes", "face_materials", "field", "header",
           "material_names", "polygons"]

MATERIAL_PROPERTIES = ("material", "material_index")  # a face's material index, the first of these present
NAME_COMMENT = "comment tlm material "  # + index + the name as a JSON string: a material's name in the header
COLOURS = ("red", "green", "blue", "alpha", "diffuse_red", "diffuse_green", "diffuse_blue")
PLACEHOLDER = (0.8, 0.8, 0.8)  # a placeholder's albedo (never rendered: the scene file replaces it, or it is an error)


def field(data, key: str):
    """A property of a PLY element as trimesh keeps it (a dict of arrays for ASCII, a
    structured array for binary files); None if absent."""
    if isinstance(data, dict):
        return data.get(key)
    names = getattr(getattr(data, "dtype", None), "names", None) or ()
    return data[key] if key in names else None


def _element(geom, name: str):
    raw = (getattr(geom, "metadata", None) or {}).get("_ply_raw") or {}
    return (raw.get(name) or {}).get("data")


def _properties(data) -> tuple[str, ...]:
    if isinstance(data, dict):
        return tuple(data)
    return tuple(getattr(getattr(data, "dtype", None), "names", None) or ())


def header(path: Path, data: bytes | None = None) -> bytes:
    """The file's header, up to ``end_header`` (``data``: the file's bytes, decompressed,
    when they were read already)."""
    mark = b"end_header"
    if data is not None:
        end = data.find(mark)
        return data if end < 0 else data[: end + len(mark)]
    head = b""
    with open(path, "rb") as f:
        while (chunk := f.read(1 << 16)) and mark not in head:
            head += chunk
    end = head.find(mark)
    return head if end < 0 else head[: end + len(mark)]


def material_names(head: bytes, src: str) -> dict[int, str]:
    """The material names the header gives (``comment tlm material K "NAME"``), by index."""
    out: dict[int, str] = {}
    for line in head.decode("ascii", "replace").splitlines():
        line = line.rstrip("\r")
        if not line.startswith(NAME_COMMENT):
            continue
        index, _, text = line[len(NAME_COMMENT):].partition(" ")
        try:
            k, name = int(index), json.loads(text)
        except ValueError:
            k, name = -1, None
        if k < 0 or not isinstance(name, str) or not name:
            raise InputError(f"header line {line!r}: expected '{NAME_COMMENT}K \"NAME\"' (K a whole number >= 0, "
                             "the name a JSON string)", source=src)
        if k in out or name in out.values():
            raise InputError(f"header line {line!r}: material {k if k in out else repr(name)} is named twice",
                             source=src)
        out[k] = name
    return out


def _declared_list(head: bytes, element: str, prop: str) -> bool:
    """Whether the header declares ``element``'s property ``prop`` as a list
    (``property list COUNT_TYPE TYPE NAME``), not one number (``property TYPE NAME``)."""
    inside = False
    for line in head.decode("ascii", "replace").splitlines():
        words = line.split()
        if words[:1] == ["element"]:
            inside = words[1:2] == [element]
        elif inside and words[:1] == ["property"] and words[-1:] == [prop]:
            return words[1:2] == ["list"]
    return False


def _sequences(lists) -> tuple[np.ndarray | None, list[np.ndarray] | None]:
    """A face element's ``vertex_indices`` as an (n, k) array when every face has k
    corners, else as one array per face."""
    if getattr(getattr(lists, "dtype", None), "names", None):  # binary: (count, values) records
        count, values = lists[lists.dtype.names[0]], np.asarray(lists[lists.dtype.names[1]])
        if values.ndim == 2 and (np.asarray(count) == values.shape[1]).all():
            return values, None
        return None, [np.asarray(values[i]).reshape(-1)[: int(count[i])] for i in range(len(count))]
    if isinstance(lists, np.ndarray) and lists.dtype != object and lists.ndim == 2:
        return lists, None
    return None, [np.asarray(row).reshape(-1) for row in lists]


def polygons(geom, src: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray, tuple[str, ...]] | None:
    """``(vertices, faces, corner normals or None, the face of each triangle, notes)`` of a
    PLY with a face of more than three corners, fanned in file order; None when every face
    is a triangle (trimesh's faces are then the file's) or a face has fewer than three
    corners in a file whose faces all have as many (trimesh's shape says so)."""
    data = _element(geom, "face")
    lists = next((v for k in ("vertex_indices", "vertex_index") if (v := field(data, k)) is not None), None)
    vdata = _element(geom, "vertex")
    xyz = [field(vdata, k) for k in "xyz"]
    if lists is None or any(c is None for c in xyz):
        return None
    even, seqs = _sequences(lists)
    if even is not None:
        if even.shape[1] <= 3:
            return None
        flat, counts = np.asarray(even, dtype=np.int64).reshape(-1), np.full(even.shape[0], even.shape[1])
    else:
        counts = np.array([s.shape[0] for s in seqs], dtype=np.int64)
        if (counts == 3).all():
            return None
        flat = np.concatenate(seqs).astype(np.int64) if seqs else np.zeros(0, np.int64)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    fans = np.maximum(counts - 2, 0)
    face_of = np.repeat(np.arange(counts.shape[0]), fans)
    j = np.arange(face_of.shape[0]) - np.repeat(np.cumsum(fans) - fans, fans) + 1  # (corner i of the fan (0, i, i + 1))
    first = starts[face_of]
    faces = np.stack([flat[first], flat[first + j], flat[first + j + 1]], axis=1)
    vertices = np.stack([np.asarray(c, dtype=np.float64).reshape(-1) for c in xyz], axis=1)
    normals = None
    nxyz = [field(vdata, k) for k in ("nx", "ny", "nz")]
    if all(c is not None for c in nxyz):
        n = np.stack([np.asarray(c, dtype=np.float64).reshape(-1) for c in nxyz], axis=1)
        inside = faces.shape[0] and faces.min() >= 0 and faces.max() < len(n)  # (else _check_mesh's error)
        if n.shape == vertices.shape and np.isfinite(n).all() and inside:
            normals = n[faces]
    notes: tuple[str, ...] = ()
    short = np.flatnonzero(counts < 3)
    if short.shape[0]:
        k = short.shape[0]
        notes = (f"{src}: {k} face{'s' if k > 1 else ''} of fewer than 3 corners (first: face {int(short[0])}) "
                 f"{'are' if k > 1 else 'is'} not a triangle: left out",)
    return vertices, faces, normals, face_of, notes


def face_materials(geom, src: str, head: bytes, face_of: np.ndarray | None
                   ) -> tuple[tuple[Material, ...], np.ndarray] | None:
    """The file's materials (placeholders, named by the header or by their index) and each
    triangle's index into them (-1: none), from the face property ``material`` (or
    ``material_index``); ``face_of``: the face of each triangle (None: triangle i is face i).
    None when the faces have no such property."""
    data = _element(geom, "face")
    prop = next((k for k in MATERIAL_PROPERTIES if field(data, k) is not None), None)
    if prop is None:
        return None
    values = field(data, prop)
    values = values if isinstance(values, np.ndarray) else np.asarray(values)
    if values.ndim == 2 and values.shape[1] == 1 and not _declared_list(head, "face", prop):
        values = values[:, 0]  # (trimesh keeps an ASCII file's scalar property as an (n, 1) column)
    if values.dtype.names or values.dtype == object or values.ndim != 1 or _declared_list(head, "face", prop):
        raise InputError(f"face property {prop!r} is a list; tlm reads one whole number per face (the index of "
                         "its material, -1: none)", source=src)
    if values.dtype.kind == "f":
        bad = np.flatnonzero(~np.isfinite(values) | (values != np.round(values)))
        if bad.shape[0]:
            i = int(bad[0])
            raise InputError(f"face {i}: {prop} {float(values[i])!r} is not a whole number (the index of its material, "
                             "-1: none)", source=src)
    elif values.dtype.kind not in "iu":
        raise InputError(f"face property {prop!r} is of type {values.dtype}; tlm reads a whole number per face",
                         source=src)
    index = values.astype(np.int64)
    names = material_names(head, src)
    if names:
        known = np.array(sorted(names), dtype=np.int64)
        bad = np.flatnonzero((index != -1) & ~np.isin(index, known))
        said = (f"material {known[0]}" if known.shape[0] == 1 else f"materials {known[0]} to {known[-1]}"
                if known[-1] - known[0] + 1 == known.shape[0] else f"materials {', '.join(str(k) for k in known)}")
        why = f"names no material: the file's '{NAME_COMMENT.strip()}' lines name {said} (-1: none)"
    else:
        bad = np.flatnonzero(index < -1)
        why = "is negative: a material index is 0 or more (-1: none)"
    if bad.shape[0]:
        i = int(bad[0])
        k = bad.shape[0]
        more = f"; {k} faces have such an index" if k > 1 else ""
        raise InputError(f"face {i}: {prop} {int(index[i])} {why}{more}", source=src)
    on = index if face_of is None else index[face_of]  # (each triangle's)
    used = np.unique(on[on >= 0])
    first = {int(k): int(i) for k, i in zip(*np.unique(index, return_index=True), strict=True)}
    materials = []
    for k in used.tolist():
        if k in names:
            name, whence = names[k], f"named {names[k]!r} by the header"
        else:
            name, whence = str(k), f"unnamed: the file has no '{NAME_COMMENT.strip()}' lines, so its name is '{k}'"
        why = (f"{src}: face {first[k]}: {prop} {k} ({whence}): a PLY file gives no material's values")
        materials.append(Material(name, "lambertian", albedo=PLACEHOLDER, undefined=why))
    lookup = np.full(int(used[-1]) + 2 if used.shape[0] else 1, -1, dtype=np.int32)  # (the last: -1 stays -1)
    lookup[used] = np.arange(used.shape[0], dtype=np.int32)
    return tuple(materials), lookup[on]


def colour_notes(geom, src: str) -> tuple[str, ...]:
    """A line per element (vertex, face) whose colours the file gives: tlm does not render them;
    and one for a material property of triangle strips, which tlm does not read."""
    out = []
    for element in ("vertex", "face"):
        got = [p for p in _properties(_element(geom, element)) if p in COLOURS]
        if got:
            out.append(f"{src}: its {element} colours ({', '.join(got)}) are not rendered: a triangle's material "
                       "is the scene file's (parts:, materials:, default_material)")
    got = [p for p in _properties(_element(geom, "tristrips")) if p in MATERIAL_PROPERTIES]
    if got:
        out.append(f"{src}: its triangle strips' {got[0]} property is not read (tlm reads a face element's): a "
                   "triangle's material is the scene file's (parts:, materials:, default_material)")
    return tuple(out)


def check_ascii(head: bytes, data: bytes, src: str) -> None:
    """An ASCII PLY's data against its header, before trimesh reads it (which reads a list's
    count of 255 over three numbers, or a file cut short, as something else, or fails with
    "faces with mixed vertices"): an InputError names the first element row whose line does not
    hold the numbers its properties need (a list shorter or longer than its count), or the
    elements the data falls short of (cut short, or a header's count too large). A file that
    does not put one element row per line (the spec allows it; no common writer does) is
    checked by its count of numbers only."""
    elements: list[tuple[str, int, list[bool]]] = []  # (name, count, each property: a list?)
    for line in head.decode("ascii", "replace").splitlines():
        words = line.split()
        if words[:1] == ["format"] and words[1:2] != ["ascii"]:
            return
        if words[:1] == ["element"] and len(words) >= 3:
            try:
                elements.append((words[1], int(words[2]), []))
            except ValueError:
                return  # (trimesh's message)
        elif words[:1] == ["property"] and elements:
            elements[-1][2].append(words[1:2] == ["list"])
    body = data[data.find(b"end_header") + len(b"end_header"):].split(b"\n", 1)[-1]
    first = head.count(b"\n") + 2  # the data's first line's number in the file
    buf = np.frombuffer(body, dtype=np.uint8)
    blank = (buf == 32) | (buf == 9) | (buf == 10) | (buf == 13) | (buf == 11) | (buf == 12)
    starts = np.flatnonzero(~blank & np.r_[True, blank[:-1]])  # each number's first byte
    line_of = np.searchsorted(np.flatnonzero(buf == 10), starts, side="right")  # (its line in the data, from 0)
    new_line = np.flatnonzero(np.r_[True, line_of[1:] != line_of[:-1]]) if line_of.shape[0] else line_of
    used = line_of[new_line]  # the lines that hold numbers, and how many each
    per_line = np.diff(np.r_[new_line, line_of.shape[0]])
    values = None
    total = int(starts.shape[0])
    rows = sum(count for _, count, _ in elements)
    least = sum(count * len(props) for _, count, props in elements)  # (a list: its count at least)
    shown = ", ".join(f"{name} {count:,}" for name, count, _ in elements)
    if total < least:
        raise InputError(f"the ASCII PLY's data holds {total:,} numbers, fewer than its header's elements need "
                         f"({shown}: at least {least:,}): cut short, or a count in the header too large", source=src)
    if used.shape[0] != rows:  # (not a row a line: trimesh reads it by its numbers)
        return
    head_token = np.cumsum(per_line) - per_line  # each line's first number's index
    at = 0
    for name, count, props in elements:
        have = per_line[at:at + count]
        need = np.full(count, len(props), dtype=np.int64)
        lists = [p for p, is_list in enumerate(props) if is_list]
        if len(lists) == 1 and count:  # (the list's count: the number at its place in the line)
            p = lists[0]
            ok = have > p
            if values is None:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # (numpy's DeprecationWarning on a word it cannot read)
                    values = np.fromstring(body, dtype=np.float64, sep=" ")
            if values.shape[0] != total:
                return  # (a word that is not a number: trimesh's message)
            n = values[head_token[at:at + count][ok] + p]
            if not np.isfinite(n).all():
                return  # (a count that is NaN: trimesh's message)
            need[ok] += np.clip(n, 0, 1 << 40).astype(np.int64)
        elif lists:
            return  # (two lists in one row: trimesh's reading)
        bad = np.flatnonzero(have != need)
        if bad.shape[0]:
            row = int(bad[0])
            raise InputError(f"line {first + int(used[at + row])}: element {name!r} row {row} (from 0) holds "
                             f"{int(have[row])} numbers where its properties (a list: its count, then that many) need "
                             f"{int(need[row])}: a list's count wrong, or the line cut short", source=src)
        at += count

