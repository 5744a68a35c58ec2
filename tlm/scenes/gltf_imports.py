"""A glTF's point, spot and directional lights and first perspective camera, placed by the
nodes of its scene (:func:`gltf_imports`): what :func:`tlm.scenes.meshes.load_mesh` gives a
scene as ``Geometry.imports`` (the scene file decides whether they are used:
:mod:`tlm.scenes.loader`), and a line each on what of the file's lights and cameras is not
imported.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from tlm.config_words import listing
from tlm.errors import InputError, quoted
from tlm.scenes.model import Camera, Imported, Light

__all__ = ["check_mesh_nodes", "gltf_imports", "singular", "singular_message"]

_PUNCTUAL = "KHR_lights_punctual"
_SHOWN = 4  # entries a note names before "and N more"


def _listed(items: list[str]) -> str:
    return listing(items, _SHOWN)


def _numbers(value, n: int, where: str, src: str) -> np.ndarray:
    """``n`` finite numbers (a list of them; one number for ``n == 1``), else an InputError
    naming the file and ``where``."""
    seq = value if isinstance(value, list) else [value]
    ok = len(seq) == n and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in seq)
    if not ok:
        what = "a number" if n == 1 else f"a list of {n} numbers"
        raise InputError(f"{where}: {value!r} is not {what}", source=src)
    try:
        out = np.array([float(x) for x in seq], dtype=np.float64)
    except OverflowError:
        out = np.full(n, np.inf)
    if not np.isfinite(out).all():
        raise InputError(f"{where}: {value!r} is not finite", source=src)
    return out


def _node_matrix(node: dict, i: int, src: str) -> np.ndarray:
    """A node's local transform as trimesh composes it for the triangles: ``matrix`` (column
    major), then ``translation``, ``rotation`` (a quaternion x, y, z, w; normalized) and
    ``scale`` (T R S, as the glTF spec has it)."""
    m = np.eye(4)
    if "matrix" in node:
        m = _numbers(node["matrix"], 16, f"nodes[{i}].matrix", src).reshape(4, 4).T
    if "translation" in node:
        t = np.eye(4)
        t[:3, 3] = _numbers(node["translation"], 3, f"nodes[{i}].translation", src)
        m = m @ t
    if "rotation" in node:
        q = _numbers(node["rotation"], 4, f"nodes[{i}].rotation", src)
        norm = float(np.dot(q, q))
        if not norm > 0.0:
            raise InputError(f"nodes[{i}].rotation: {node['rotation']!r} is no rotation (a zero quaternion)",
                             source=src)
        x, y, z, w = q / np.sqrt(norm)
        r = np.eye(4)
        r[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        m = m @ r
    if "scale" in node:
        m = m @ np.diag([*_numbers(node["scale"], 3, f"nodes[{i}].scale", src), 1.0])
    return m


def _scene_walk(header: dict, nodes: list, src: str) -> dict[int, tuple[int, ...]]:
    """The nodes of the glTF's scene (``scene``, else ``scenes[0]``; a file without ``scenes``:
    every node no node names as a child), each with its path from its root (root first), in
    depth-first file order. A node reached twice (a second parent, a cycle) is an error: glTF's
    nodes form trees."""
    scenes = header.get("scenes")
    if isinstance(scenes, list) and scenes:
        k = header.get("scene", 0)
        if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < len(scenes):
            raise InputError(f"scene = {k!r} names no entry of 'scenes' (it has {len(scenes)})", source=src)
        scene = scenes[k] if isinstance(scenes[k], dict) else {}
        roots = scene.get("nodes") or []
        where = f"scenes[{k}].nodes"
    else:
        children = {c for n in nodes if isinstance(n, dict) for c in (n.get("children") or [])
                    if isinstance(c, int)}
        roots = [i for i in range(len(nodes)) if i not in children]
        where = "nodes"
    if not isinstance(roots, list):
        raise InputError(f"{where}: {roots!r} is not a list of node indices", source=src)
    paths: dict[int, tuple[int, ...]] = {}
    stack = [(r, (), where) for r in reversed(roots)]  # (depth first without recursion: a deep rig is no error)
    while stack:
        i, parent, named = stack.pop()
        if isinstance(i, bool) or not isinstance(i, int) or not 0 <= i < len(nodes):
            raise InputError(f"{named} names {i!r}, no entry of 'nodes' (it has {len(nodes)})", source=src)
        if i in paths:
            raise InputError(f"{named} names nodes[{i}], which the scene reaches twice (glTF's nodes form trees)",
                             source=src)
        paths[i] = (*parent, i)
        kids = nodes[i].get("children") if isinstance(nodes[i], dict) else None
        if kids is not None and not isinstance(kids, list):
            raise InputError(f"nodes[{i}].children: {kids!r} is not a list of node indices", source=src)
        stack += [(c, paths[i], f"nodes[{i}].children") for c in reversed(kids or [])]
    return paths


def _world(path: tuple[int, ...], nodes: list, src: str) -> np.ndarray:
    """The world transform of the last node of ``path``: its local transform composed with
    every parent's (root first)."""
    m = np.eye(4)
    for i in path:
        m = m @ _node_matrix(nodes[i] if isinstance(nodes[i], dict) else {}, i, src)
    if not np.isfinite(m).all():
        raise InputError(f"nodes[{path[-1]}]: its world transform (with its parents') is not finite", source=src)
    return m


def singular(m: np.ndarray) -> bool:
    """Whether a 3x3 transform is singular: a zero scale, an all-zero ``matrix``, or scales
    whose product is 0 in floating point (a small but non-zero scale is not)."""
    # each column (an axis's image) to unit length, so that a small but non-zero scale, [1e-9, 1e-9, 1],
    # is no nearer singular than [1, 1, 1]; a zero scale leaves a zero column, or columns that are
    # dependent to rounding (at most ~2e-15 after a chain of rotations and scales)
    big = np.abs(m).max(axis=0)
    det = 0.0
    if (big > 0.0).all():
        unit = m / big  # (scaled to 1 first: no overflow or underflow in the norms)
        unit = unit / np.sqrt(np.sum(unit * unit, axis=0))
        det = float(np.dot(unit[:, 0], np.cross(unit[:, 1], unit[:, 2])))  # (no LAPACK call: meshes.det3)
    return not abs(det) > 1e-12


def singular_message(n: int, mesh, skin=None) -> str:
    """The error for a mesh node whose world transform (or, given ``skin``, its skin's joint
    matrix, which glTF places a skinned mesh by) collapses its mesh's triangles."""
    what = ("its world transform (with its parents')" if skin is None else
            f"its skin's joint matrix (skins[{skin!r}]: a joint's world transform times its inverse bind matrix)")
    return (f"nodes[{n}]: {what} is singular (a zero scale, an all-zero matrix, or scales whose product is 0 in "
            f"floating point): it collapses meshes[{mesh!r}] to a plane, a line or a point")


def _accessor_mat4(header: dict, k, buffer, where: str, src: str) -> np.ndarray:
    """The (count, 4, 4) float matrices of accessor ``k`` (glTF's MAT4 of floats, column major),
    read through ``buffer(i) -> bytes``; an InputError naming ``where`` for anything else (an
    index out of range, a byte offset or stride that is no count of bytes, matrices past their
    buffer view)."""
    def count(x) -> bool:
        return isinstance(x, int) and not isinstance(x, bool) and x >= 0

    accessors = header.get("accessors") if isinstance(header.get("accessors"), list) else []
    views = header.get("bufferViews") if isinstance(header.get("bufferViews"), list) else []
    if not (count(k) and k < len(accessors)):
        raise InputError(f"{where} = {k!r} names no entry of 'accessors' (it has {len(accessors)})", source=src)
    acc = accessors[k]
    if not (isinstance(acc, dict) and acc.get("type") == "MAT4" and acc.get("componentType") == 5126
            and count(acc.get("count")) and "sparse" not in acc
            and count(acc.get("bufferView")) and acc["bufferView"] < len(views)
            and isinstance(views[acc["bufferView"]], dict)):
        raise InputError(f"{where} = {k!r} names no MAT4 accessor of floats that tlm reads (one in a buffer view, "
                         "not sparse)", source=src)
    j = acc["bufferView"]
    view = views[j]
    stride = view.get("byteStride") or 64  # (left out: tightly packed)
    for key, x, least in ((f"bufferViews[{j}].byteStride", stride, 64),
                          (f"bufferViews[{j}].byteOffset", view.get("byteOffset", 0), 0),
                          (f"accessors[{k}].byteOffset", acc.get("byteOffset", 0), 0)):
        if not (count(x) and x >= least):
            raise InputError(f"{where} = {k}: {key} = {x!r} is not a count of bytes"
                             f"{f' of at least {least} (a MAT4 of floats)' if least else ''}", source=src)
    n, offset = acc["count"], acc.get("byteOffset", 0)
    span = stride * (n - 1) + 64 if n else 0
    length = view.get("byteLength")
    if count(length) and offset + span > length:
        raise InputError(f"{where} = {k}: its {n} matrices need {offset + span:,} bytes of bufferViews[{j}], "
                         f"which holds {length:,}", source=src)
    start = view.get("byteOffset", 0) + offset
    data = buffer(view.get("buffer", 0))
    if len(data) < start + span:
        raise InputError(f"{where} = {k}: its accessor needs {start + span:,} bytes of its buffer, which holds "
                         f"{len(data):,}", source=src)
    rows = [np.frombuffer(data, dtype="<f4", count=16, offset=start + i * stride) for i in range(n)]
    return np.array(rows, dtype=np.float64).reshape(n, 4, 4).transpose(0, 2, 1)


def _parents(nodes: list) -> dict[int, int]:
    return {c: i for i, n in enumerate(nodes) if isinstance(n, dict)
            for c in (n.get("children") or []) if isinstance(c, int) and not isinstance(c, bool)}


def _path(i: int, parents: dict[int, int]) -> tuple[int, ...]:
    """A node's path from its root by its parents (a node outside the scene: a skin's joint)."""
    path = [i]
    while path[-1] in parents and len(path) <= len(parents):
        path.append(parents[path[-1]])
    return tuple(reversed(path))


def _joint_world(j: int, nodes: list, parents: dict[int, int], worlds: dict[int, np.ndarray],
                 src: str) -> np.ndarray:
    """:func:`_world` of node ``j`` by its parents (the same products, in the same order), each
    node's kept in ``worlds``: a rig's joints share their parents' (no time quadratic in its depth)."""
    path = _path(j, parents)
    done = len(path)
    while done and path[done - 1] not in worlds:
        done -= 1
    m = worlds[path[done - 1]] if done else np.eye(4)
    for i in path[done:]:
        m = m @ _node_matrix(nodes[i] if isinstance(nodes[i], dict) else {}, i, src)
        worlds[i] = m
    if not np.isfinite(m).all():
        raise InputError(f"nodes[{j}]: its world transform (with its parents') is not finite", source=src)
    return m


def _skin_matrix(header: dict, nodes: list, n: int, buffer, src: str,
                 memo: dict | None = None) -> np.ndarray | None:
    """The one matrix every joint of node ``n``'s skin gives its vertices (each joint's world
    transform times its inverse bind matrix: glTF's joint matrix), None where they differ (a
    posed skin, whose vertices need blending by their weights). ``memo`` keeps each skin's
    (and each node's world transform) for the other nodes of one file."""
    memo = {} if memo is None else memo
    skins = header.get("skins") if isinstance(header.get("skins"), list) else []
    k = nodes[n].get("skin")
    if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < len(skins):
        raise InputError(f"nodes[{n}].skin = {k!r} names no entry of 'skins' (it has {len(skins)})", source=src)
    if not isinstance(skins[k], dict):
        raise InputError(f"skins[{k}]: {skins[k]!r} is not an object (a skin: its joints and inverse bind matrices)",
                         source=src)
    if ("skin", k) in memo:  # (a skin that skins several nodes)
        return memo[("skin", k)]
    joints = skins[k].get("joints")
    if not (isinstance(joints, list) and joints and all(isinstance(j, int) and not isinstance(j, bool)
                                                        and 0 <= j < len(nodes) for j in joints)):
        raise InputError(f"skins[{k}].joints: {joints!r} is not a list of node indices", source=src)
    if "inverseBindMatrices" in skins[k]:
        inverse = _accessor_mat4(header, skins[k]["inverseBindMatrices"], buffer, f"skins[{k}].inverseBindMatrices",
                                 src)
        if len(inverse) < len(joints):
            raise InputError(f"skins[{k}].inverseBindMatrices: {len(inverse)} matrices for {len(joints)} joints",
                             source=src)
    else:
        inverse = np.repeat(np.eye(4)[None], len(joints), axis=0)
    if "parents" not in memo:
        memo["parents"] = _parents(nodes)
    worlds = memo.setdefault("worlds", {})
    got = [_joint_world(j, nodes, memo["parents"], worlds, src) @ inverse[i] for i, j in enumerate(joints)]
    if not np.isfinite(got).all():
        raise InputError(f"skins[{k}]: a joint's matrix (its world transform times its inverse bind matrix) is not "
                         "finite", source=src)
    scale = max(float(np.abs(got[0]).max()), 1e-300)
    rigid = all(np.abs(g - got[0]).max() <= 1e-6 * scale for g in got[1:])  # (float32 inverse bind matrices)
    memo[("skin", k)] = got[0] if rigid else None
    return memo[("skin", k)]


def check_mesh_nodes(header: dict, src: str,
                     buffer=None) -> tuple[dict[int, np.ndarray], frozenset[int], tuple[str, ...]]:
    """The mesh nodes of the glTF's scene whose world transform tlm sets itself (a node's
    world transform is its local transform composed with its parents'), each with the 4x4
    transform its mesh gets; those of them placed by their skin's joint matrix; and a line on
    each skin tlm does not pose:

    * a node whose world transform is singular (a zero scale, an all-zero ``matrix``; a small
      but non-zero scale is not): its world transform, kept where its mesh is flat and the
      transform keeps its triangles (a quad in the XY plane under a scale [1, 1, 0]; checked
      with the triangles, :func:`tlm.scenes.meshes.load_mesh`), else an error naming the node;
    * a skinned mesh's node (``skin``): glTF ignores its transform; its mesh gets its skin's
      joint matrix (each joint's world transform times its inverse bind matrix, read through
      ``buffer(i) -> bytes``) where every joint gives the same one (a skin at rest); a posed
      skin (joint matrices that differ) is not blended: its mesh gets its node's world
      transform, as before, and a line says so.

    An InputError names the first node whose world transform is not finite. A node the scene
    reaches twice (a cycle) is an error."""
    nodes = header.get("nodes") if isinstance(header.get("nodes"), list) else []
    if not any(isinstance(node, dict) and "mesh" in node for node in nodes):
        return {}, frozenset(), ()
    paths = _scene_walk(header, nodes, src)
    out: dict[int, np.ndarray] = {}
    posed: list[str] = []
    skinned: set[int] = set()
    memo: dict = {}  # (each skin's matrix, and the world transforms of its joints, worked out once)
    for n in sorted(paths):
        if not (isinstance(nodes[n], dict) and "mesh" in nodes[n]):
            continue
        if "skin" in nodes[n] and buffer is not None:
            rigid = _skin_matrix(header, nodes, n, buffer, src, memo)
            if rigid is not None:
                out[n] = rigid
                skinned.add(n)
                continue
            posed.append(f"nodes[{n}] (skins[{nodes[n]['skin']}])")
        m = _world(paths[n], nodes, src)
        if singular(m[:3, :3]):
            out[n] = m
    notes = ()
    if posed:
        many = len(posed) > 1
        notes = (f"{src}: its skinned mesh{'es' if many else ''} {_listed(posed)} "
                 f"{'are' if many else 'is'} posed (the joints' matrices differ), drawn unposed: tlm does not "
                 "apply a skin's pose (it does not blend the joints by their weights); placed by "
                 f"{'each' if many else 'the'} node's world transform",)
    return out, frozenset(skinned), notes


def _entries(table, where: str, src: str) -> list[dict]:
    if table is None:
        return []
    if not isinstance(table, list):
        raise InputError(f"{where}: {table!r} is not a list", source=src)
    for i, e in enumerate(table):
        if not isinstance(e, dict):
            raise InputError(f"{where}[{i}]: {e!r} is not an object", source=src)
    return table


def _label(entry: dict, where: str) -> str:
    name = entry.get("name")
    return f"{where} {quoted(name)}" if isinstance(name, str) and name else where


def _light_entry(light: dict, i: int, src: str) -> tuple[str, np.ndarray, tuple[float, float]]:
    """A KHR_lights_punctual light's type, its RGB ``intensity * color`` (candela for a point or
    spot light, lux for a directional one) and a spot's inner and outer cone angles in degrees
    (glTF's defaults 0 and pi / 4; (0, 0) for other kinds); an InputError for a malformed one."""
    where = f"{_PUNCTUAL}.lights[{i}]"
    kind = light.get("type")
    if kind not in ("point", "spot", "directional"):
        raise InputError(f"{where}.type: {kind!r} is not 'point', 'spot' or 'directional'", source=src)
    intensity = _numbers(light.get("intensity", 1.0), 1, f"{where}.intensity", src)[0]
    color = _numbers(light.get("color", [1.0, 1.0, 1.0]), 3, f"{where}.color", src)
    if intensity < 0.0:
        raise InputError(f"{where}.intensity: {light['intensity']!r} is negative", source=src)
    if (color < 0.0).any():
        raise InputError(f"{where}.color: {light['color']!r} has a negative value", source=src)
    if "range" in light and not _numbers(light["range"], 1, f"{where}.range", src)[0] > 0.0:
        raise InputError(f"{where}.range: {light['range']!r} must be > 0", source=src)
    cone = (0.0, 0.0)
    if kind == "spot":
        if "spot" not in light:  # (the extension's spec: "When a light's type is spot, the spot property on the
            # light is required"; its cone angles inside it are optional)
            raise InputError(f"{where}: a spot light needs a 'spot' object (KHR_lights_punctual requires it; "
                             "'spot': {} gives the default cone angles 0 and pi / 4)", source=src)
        spot = light["spot"]
        if not isinstance(spot, dict):
            raise InputError(f"{where}.spot: {spot!r} is not an object", source=src)
        given = spot.get("innerConeAngle", 0.0), spot.get("outerConeAngle", math.pi / 4.0)
        inner = float(_numbers(given[0], 1, f"{where}.spot.innerConeAngle", src)[0])
        outer = float(_numbers(given[1], 1, f"{where}.spot.outerConeAngle", src)[0])
        if not 0.0 < outer <= math.pi / 2.0:
            raise InputError(f"{where}.spot.outerConeAngle: {given[1]!r} must be > 0 and <= pi / 2 (radians)",
                             source=src)
        if not 0.0 <= inner < outer:
            raise InputError(f"{where}.spot.innerConeAngle: {given[0]!r} must be >= 0 and less than outerConeAngle "
                             f"({given[1]!r} radians)", source=src)
        cone = (math.degrees(inner), math.degrees(outer))
        if not math.cos(math.radians(cone[0])) > math.cos(math.radians(cone[1])):
            raise InputError(f"{where}.spot: innerConeAngle {given[0]!r} and outerConeAngle {given[1]!r} are too "
                             "close: their cosines are equal in float64", source=src)
    return kind, intensity * color, cone


def _camera_entry(camera: dict, i: int, src: str) -> tuple[str, float | None, float | None]:
    """A glTF camera's type, and a perspective camera's ``yfov`` (radians) and
    ``aspectRatio`` (None when not given); an InputError for a malformed one."""
    where = f"cameras[{i}]"
    kind = camera.get("type")
    if kind not in ("perspective", "orthographic"):
        raise InputError(f"{where}.type: {kind!r} is not 'perspective' or 'orthographic'", source=src)
    if kind != "perspective":
        return kind, None, None
    p = camera.get("perspective")
    if not isinstance(p, dict):
        raise InputError(f"{where}.perspective: {p!r} is not an object", source=src)
    if "yfov" not in p:
        raise InputError(f"{where}.perspective.yfov: missing (the vertical field of view, radians)", source=src)
    yfov = _numbers(p["yfov"], 1, f"{where}.perspective.yfov", src)[0]
    if not 0.0 < yfov < math.pi:
        raise InputError(f"{where}.perspective.yfov: {p['yfov']!r} must be > 0 and < pi (radians)", source=src)
    aspect = None
    if "aspectRatio" in p:
        aspect = _numbers(p["aspectRatio"], 1, f"{where}.perspective.aspectRatio", src)[0]
        if not aspect > 0.0:
            raise InputError(f"{where}.perspective.aspectRatio: {p['aspectRatio']!r} must be > 0", source=src)
    return kind, float(yfov), aspect


def _colour_notes(header: dict, src: str) -> tuple[str, ...]:
    """A line naming the meshes whose primitives give vertex colours (``COLOR_0``, ...),
    which tlm does not render (none when no primitive does), as
    :func:`tlm.scenes.plyfile.colour_notes` says of a PLY's."""
    meshes = header.get("meshes") if isinstance(header.get("meshes"), list) else []
    names: list[str] = []
    found: list[str] = []
    for i, mesh in enumerate(meshes):
        prims = mesh.get("primitives") if isinstance(mesh, dict) else None
        got = sorted({str(k) for p in (prims if isinstance(prims, list) else []) if isinstance(p, dict)
                      for k in (p.get("attributes") if isinstance(p.get("attributes"), dict) else {})
                      if str(k).startswith("COLOR_")})
        if got:
            names.append(_label(mesh, f"meshes[{i}]"))
            found += [k for k in got if k not in found]
    if not names:
        return ()
    return (f"{src}: its vertex colours ({', '.join(sorted(found))} of {_listed(names)}) are not rendered: a "
            "triangle's material is the glTF's or the scene file's (parts:, materials:, default_material)",)


def gltf_imports(header: dict, src: str) -> tuple[Imported | None, tuple[str, ...]]:
    """A glTF's point, spot and directional lights and first perspective camera
    (:class:`~tlm.scenes.model.Imported`, None when it has neither) and a line each on what of
    its lights and cameras is not imported (a light or camera on no node of the scene,
    orthographic cameras, perspective ones after the first, a point or spot light's ``range``),
    and one on its meshes' vertex colours (``COLOR_0``), which tlm does not render.

    Each node of the scene that names a light gives a tlm light at the node's world position
    (its intensity is in candela for a point or spot light, lux for a directional one):

    * a point light: power ``4 pi * intensity * color`` (``intensity * color`` W/sr);
    * a spot light: the same power (the intensity on its axis), shining down the node's -Z,
      its ``spot.innerConeAngle`` and ``outerConeAngle`` (radians; default 0 and pi / 4) in
      degrees;
    * a directional light: irradiance ``intensity * color`` (W per unit area) travelling down
      the node's -Z; its power is set by the scene's loader (from the scene's bounds).

    A geometry item's transform moves the lights' positions and turns their directions
    (:mod:`tlm.scenes.compose`). The camera is the first node (in ``nodes`` order) of the
    scene with a perspective camera: its eye the node's world position, looking down its -Z
    with +Y up, ``vfov`` = ``yfov`` in degrees. Malformed
    entries (a type, intensity, colour, range, cone angle or yfov that is not a number, NaN,
    negative or out of range, an inner cone angle not below the outer; a node's light or
    camera index out of range; a NaN or zero-quaternion transform on the way to a light or
    camera; a zero scale on the way to a spot or directional light or the camera) are an
    InputError naming the file and the entry."""
    ext = header.get("extensions")
    punctual = ext.get(_PUNCTUAL) if isinstance(ext, dict) else None
    # (an extension that is not an object holds no lights: nothing to import, nothing to say)
    lights = _entries(punctual.get("lights"), f"{_PUNCTUAL}.lights", src) if isinstance(punctual, dict) else []
    cameras = _entries(header.get("cameras"), "cameras", src)
    nodes = header.get("nodes") if isinstance(header.get("nodes"), list) else []
    light_kind = [_light_entry(lt, i, src) for i, lt in enumerate(lights)]
    camera_kind = [_camera_entry(c, i, src) for i, c in enumerate(cameras)]
    on_light: dict[int, int] = {}  # node -> its light
    on_camera: dict[int, int] = {}  # node -> its camera
    for n, node in enumerate(nodes):
        if not isinstance(node, dict):
            continue
        if "camera" in node:
            c = node["camera"]
            if isinstance(c, bool) or not isinstance(c, int) or not 0 <= c < len(cameras):
                raise InputError(f"nodes[{n}].camera = {c!r} names no entry of 'cameras' (it has {len(cameras)})",
                                 source=src)
            on_camera[n] = c
        node_ext = node.get("extensions")
        ref = node_ext.get(_PUNCTUAL) if isinstance(node_ext, dict) else None
        if ref is not None:
            k = ref.get("light") if isinstance(ref, dict) else ref
            if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < len(lights):
                raise InputError(f"nodes[{n}].extensions.{_PUNCTUAL}.light = {k!r} names no entry of "
                                 f"{_PUNCTUAL}.lights (it has {len(lights)})", source=src)
            on_light[n] = k
    colours = _colour_notes(header, src)
    if not lights and not cameras:
        return None, colours
    paths = _scene_walk(header, nodes, src) if on_light or on_camera else {}
    file = Path(src).name
    out: list[Light] = []
    placed: set[int] = set()
    ranged: list[tuple[str, str]] = []  # (the light and its range, its kind)
    for n in sorted(on_light):
        k = on_light[n]
        if n not in paths:
            continue
        placed.add(k)
        kind, radiant, cone = light_kind[k]
        w = _world(paths[n], nodes, src)
        position = tuple(float(x) for x in w[:3, 3])
        label = f"{_label(lights[k], f'{_PUNCTUAL}.lights[{k}]')} at nodes[{n}]"
        name = f"{file} {label}"
        if kind == "point":
            out.append(Light("point", tuple(float(x) for x in 4.0 * math.pi * radiant), position=position, name=name))
        else:
            axis = w[:3, :3] @ [0.0, 0.0, -1.0]  # (the node's -Z: where a spot shines, a directional light travels)
            length = float(np.linalg.norm(axis))
            if not (length > 0.0 and np.isfinite(axis / length).all()):
                raise InputError(f"nodes[{n}]: its world transform (with its parents') leaves the {kind} light "
                                 f"{_label(lights[k], f'lights[{k}]')} no direction (a zero scale)", source=src)
            direction = tuple(float(x) for x in axis / length)
            if kind == "spot":
                out.append(Light("spot", tuple(float(x) for x in 4.0 * math.pi * radiant), position=position,
                                 direction=direction, inner_angle=cone[0], outer_angle=cone[1], name=name))
            else:  # (lux read as W per unit area; its power is set by the scene's loader, from the scene's box)
                out.append(Light("directional", (0.0, 0.0, 0.0), direction=direction,  # (no position: its node's
                                 irradiance=tuple(float(x) for x in radiant), name=name))  # is no field of its kind)
        if "range" in lights[k] and kind != "directional":
            ranged.append((f"{_label(lights[k], f'lights[{k}]')} (range {lights[k]['range']:g})", kind))
    camera, camera_name, aspect = None, "", None
    skipped: list[str] = []
    for n in sorted(on_camera):
        c = on_camera[n]
        kind, yfov, ratio = camera_kind[c]
        label = f"{_label(cameras[c], f'cameras[{c}]')} at nodes[{n}]"
        if n not in paths:
            skipped.append(f"{label} (on no node of the glTF's scene)")
        elif kind != "perspective":
            skipped.append(f"{label} (orthographic: tlm's camera is a pinhole)")
        elif camera is not None:
            skipped.append(f"{label} (a perspective camera after the first)")
        else:
            w = _world(paths[n], nodes, src)
            fwd, up = w[:3, :3] @ [0.0, 0.0, -1.0], w[:3, :3] @ [0.0, 1.0, 0.0]
            lf, lu = np.linalg.norm(fwd), np.linalg.norm(up)
            if not (lf > 0 and lu > 0 and np.linalg.norm(np.cross(fwd, up)) > 1e-12 * lf * lu):
                raise InputError(f"nodes[{n}]: its world transform (with its parents') leaves the camera no view "
                                 "direction and up (a zero scale)", source=src)
            eye = w[:3, 3]
            camera = Camera(tuple(float(x) for x in eye), tuple(float(x) for x in eye + fwd / lf),
                            tuple(float(x) for x in up / lu), math.degrees(yfov), 0, 0)
            camera_name, aspect = label, ratio
    unused = [c for c in range(len(cameras)) if c not in on_camera.values()]
    skipped += [f"{_label(cameras[c], f'cameras[{c}]')} (on no node of the glTF's scene)" for c in unused]
    notes = []
    left = [f"{_label(lights[k], f'lights[{k}]')} ({kind}, on no node of the glTF's scene)"
            for k, (kind, _, _) in enumerate(light_kind) if k not in placed]
    if left:
        notes.append(f"{src}: not imported from its {_PUNCTUAL} lights: {_listed(left)}")
    ranged = list(dict.fromkeys(ranged))  # (a light on two nodes: named once)
    if ranged:
        what = " and ".join(k for k in ("point", "spot") if any(kind == k for _, kind in ranged))
        notes.append(f"{src}: the range of its {what} light{'s' if len(ranged) > 1 else ''} "
                     f"{_listed([r for r, _ in ranged])} is not modelled: a tlm {what.replace(' and ', ' or ')} light "
                     "reaches every distance (falling off as 1/d^2)")
    if skipped:
        notes.append(f"{src}: not imported from its cameras: {_listed(skipped)}")
    notes += colours
    if not out and camera is None:
        return None, tuple(notes)
    return Imported(src, tuple(out), camera, camera_name, aspect), tuple(notes)
