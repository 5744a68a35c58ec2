"""Export a scene's world-space triangles, in triangle-id order, as PLY or OBJ, or the
whole scene as a scene file (``.yaml`` or ``.yml``) with its OBJ and MTL beside it.

The PLY file also carries each face's material index (property ``material``) and each
material's name (a header line ``comment tlm material K "NAME"``, the name as a JSON
string), so that tlm reads it back with each face's material named, for the scene file's
``materials:`` to give (a PLY holds no material's values: :mod:`tlm.scenes.plyfile`). The OBJ
file carries the parts (``o``), the shading normals (``vn``, one per triangle corner:
the normals the renderer uses, so that a re-read file needs no crease angle) and the
materials (``usemtl``, in an MTL library of the same stem written beside it: ``Kd`` for
a Lambertian material, ``Ks`` and ``illum 3`` for a mirror, ``Ni``, ``Tf`` and ``illum
7`` for a dielectric, ``Ke`` for emission), so that tlm reads the OBJ back as the same
triangles, parts and materials, and the normals to the bit (a unit ``vn`` is read as
written: :func:`tlm.scenes.objfile.unit_as_written`), but a dielectric's transmittance
(tlm's MTL reading takes glass as clear, :mod:`tlm.scenes.materials`). The PLY file carries
the shading normals too (``nx ny nz``, one per vertex, each vertex one corner), unit
vectors as they are, which tlm reads back to the bit as an OBJ's ``vn`` (a unit normal is
read as written). The scene's lights, camera and resolution are
in neither file.

A ``.yaml`` target writes the scene file that closes the round trip (:func:`scene_yaml`):
``geometry: {mesh: STEM.obj}``, every material under ``materials:`` with its exact values
(which replace the MTL's of the same name on reading, glass's transmittance included),
the quad, point, spot and directional lights (a mesh light is its emitting materials; a
directional light's irradiance: its power follows the scene's bounds; each with its ``name:`` where
it has one, a glTF's light which it was), the camera, the
resolution and the photon count. ``tlm run`` on it renders what the original scene
renders. Floats are written as Python's ``repr``, which reads back to the same bits; a name that tlm's
YAML reads as a number (``1e3``, a float in YAML 1.2) quoted (:func:`tlm.config_words.dump_yaml`).

The OBJ, its MTL library and the scene file are written together, all or none
(:func:`tlm.storage.write_files`): a full disk or a signal leaves an earlier export of the same name as it
was, and no file of the new one.

Each triangle is written with its own three vertices (no welding), so face ``i`` of
the file is triangle id ``i`` of every AOV and BSP leaf, exactly, and the vertex
positions are the ones the renderer uses.

The OBJ, its MTL library and the scene file hold the materials the scene's triangles take
(:func:`used_materials`), no other: a material no triangle takes (a base's, given through ``extends:``, that a
scene file replacing the base's ``geometry:`` leaves unused; a palette entry no part names) is not rendered, and
written it would be the exported file's own, rendered by no triangle and named in no note. So the exported scene
file loads as the scene rendered and exports again to the same files. (A PLY names each material by its index in
the scene, every one: a name that no face takes names nothing on reading.)

Every file written (OBJ, MTL, PLY and scene file) carries, below its first line, the
notices of the mesh files the scene's geometry comes from (:func:`notices`), as comment
lines: a published mesh's licence asks for its attribution to go with every copy (the
Cornell boxes are CC BY 3.0: ``scenes/meshes/COPYRIGHT-cornellbox.txt``). A mesh's notices
are the files beside it whose name begins, in any case, with ``COPYRIGHT``, ``LICENSE`` or
``LICENCE`` (:func:`notice_files`): one whose name goes on to name files there is theirs only
(``COPYRIGHT-<name>.txt`` whose ``<name>`` begins the mesh file's name, letters and digits
compared, any case: ``CornellBox-Water.obj.xz`` and ``COPYRIGHT-cornellbox.txt``; the longest
such), any other is every mesh's there (``copyright.txt``, as McGuire's archives publish it
beside their OBJ files; ``LICENSE``); a symbolic link has those of the file it links to
too. A mesh that tlm exported carries its notices in its own
header, and they are passed on (in the scene file's comments, a character that YAML reads in no file, a BEL
or an ESC, as its escape, ``\\x07``: :func:`_yaml_comment`). A mesh file with none is named in a warning
(``tlm: warning: ...``, a line each): the export carries no licence notice for it.
"""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from tlm.config_words import dump_yaml, listing
from tlm.errors import EnvironmentFailure, InputError, quoted
from tlm.scenes.model import Scene
from tlm.storage import warn, write_atomic, write_files

FORMATS = (".ply", ".obj", ".yaml", ".yml")
_PLY_NORMALS = "property double nx\nproperty double ny\nproperty double nz\n"  # (a PLY's vertex normals)


def check_scene(scene: Scene) -> None:
    """An :class:`InputError` for a scene that no scene file could hold, as the loader refuses such a
    file (:mod:`tlm.scenes.loader`, in its words): triangles not of shape (n, 3, 3), none, or NaN or
    infinite vertices (naming the scene and its first such triangle), and shading normals that are
    not finite. A scene loaded from a file passed these checks; one made or changed in Python (a
    ``dataclasses.replace`` of its triangles) is checked here before it is exported or described."""
    from tlm.scenes.loader import _check_triangles  # (the loader's own check and wording)

    where = f"scene {quoted(scene.name)}"
    try:
        tri = np.asarray(scene.triangles, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("the triangles are not an array of numbers", source=where, key="triangles") from None
    _check_triangles(tri, where, "triangles")
    if scene.normals is not None:
        normals = np.asarray(scene.normals, dtype=np.float64)
        bad = ~np.isfinite(normals.reshape(max(normals.shape[:1], default=1), -1)).all(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(f"the vertex normals of {int(bad.sum())} triangle(s) are not finite (first: triangle "
                             f"{i}, {normals[i].tolist()})", source=where, key="normals")


def export_triangles(scene: Scene, path: Path) -> Scene:
    """Write ``scene`` to ``path`` as its suffix says (the module's docstring) and return it as written (its
    materials those its triangles take but in a PLY: :func:`used_materials`); a scene that no
    file could hold (:func:`check_scene`) or a path that cannot take it is an InputError before
    anything is written."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise InputError(f"unsupported format {quoted(suffix or '(none)')}: use {listing(FORMATS, last='or')}",
                         source=str(path))
    check_scene(scene)
    if suffix != ".ply":  # (a PLY names each material by the scene's index: a name no face takes is read as none)
        scene = used_materials(scene)
    tri = scene.triangles
    n = tri.shape[0]
    verts = tri.reshape(-1, 3)
    faces = np.arange(3 * n, dtype=np.int64).reshape(n, 3)
    ancestor = path.parent  # (a folder not there yet is made, as run's --out makes its own: h474)
    while not ancestor.exists() and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not ancestor.is_dir():  # (a file where a folder on the way should be: the user's path)
        raise InputError(f"folder {quoted(path.parent)} cannot be made: {quoted(ancestor)} is a file, not a folder",
                         source=str(path))
    if path.is_dir():
        raise InputError("is a folder; name a .ply, .obj or .yaml file", source=str(path))
    scene_file = suffix in (".yaml", ".yml")
    if suffix == ".obj" or scene_file:
        _check_library(scene, path.with_suffix(".mtl"))
    if scene_file:
        for other in (path.with_suffix(".obj"), path):
            _check_ours(other, path, "scene file" if other == path else "mesh")
    else:
        _check_ours(path, path, "mesh")
    told, bare = _notices(scene)
    made = _made_folders(path.parent)
    try:
        if suffix == ".ply":
            _write_ply(scene, path, verts, faces, told)
        else:  # (the MTL, the OBJ and the scene file: all of them or none, write_files)
            mesh = path.with_suffix(".obj")
            files = _obj_files(scene, mesh, verts, faces, told)
            write_files([*files, (path, scene_yaml(scene, mesh.name, told))] if scene_file else files)
    except BaseException as e:  # (all or none: the folders made for the files too, on a signal as well)
        _unmade(made)
        if isinstance(e, OSError) and not isinstance(e, EnvironmentFailure):  # (/proc, a special file system)
            raise EnvironmentFailure(f"cannot write it ({e.strerror or e})", source=str(path)) from None
        raise
    from tlm.scenes.meshes import shown_path

    for mesh in bare:  # (a mesh's licence may ask for its notice with every copy: said, not dropped silently)
        warn(f"{path}: the export carries no licence notice for the mesh {shown_path(mesh)}: there is no notice "
             "file of it beside it (COPYRIGHT*, LICENSE*, LICENCE*) and none in its header; if its licence asks for "
             "one with every copy, add it beside the exported files")
    return scene


def _made_folders(folder: Path) -> list[Path]:
    """Make ``folder`` and those above it that are not there yet; the ones made, outermost first (an
    EnvironmentFailure where the machine refuses one: read-only, not permitted)."""
    missing = []
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    made: list[Path] = []
    for one in reversed(missing):
        try:
            one.mkdir()
        except FileExistsError:  # (another process made it meanwhile: not ours to remove)
            continue
        except OSError as e:
            _unmade(made)
            raise EnvironmentFailure(f"cannot make the folder {quoted(one)} ({e.strerror or e})",
                                     source=str(one)) from None
        made.append(one)
    return made


def _unmade(made: list[Path]) -> None:
    """Remove the folders :func:`_made_folders` made (innermost first) where they are still empty: an export
    that wrote nothing leaves nothing."""
    for one in reversed(made):
        try:
            one.rmdir()
        except OSError:
            return


def used_materials(scene: Scene) -> Scene:
    """``scene`` with only the materials its triangles take, in their order, and each triangle's index into them
    (the module's docstring); ``scene`` itself where it takes every one, or where an index names none of them."""
    index = np.asarray(scene.material_index)
    n = len(scene.materials)
    used = np.unique(index)
    if len(used) == n or not len(index) or used[0] < 0 or used[-1] >= n:
        return scene
    new = np.full(n, -1, dtype=np.int32)
    new[used] = np.arange(len(used), dtype=np.int32)
    return replace(scene, materials=tuple(scene.materials[i] for i in used.tolist()), material_index=new[index])


_NOTICE = "Notice of the mesh "  # (the first line of a mesh's notice in a file tlm exports)
_BODY = "  "  # (its other lines start so)


def notices(scene: Scene) -> list[str]:
    """The notices of the mesh files ``scene``'s geometry comes from (the module's
    docstring), as lines to write as comments: for each notice its title line (``Notice of
    the mesh M (its COPYRIGHT-x.txt), to keep with every copy:``) and its text's lines,
    each indented by two spaces (blank lines and a leading ``#`` left out). Empty for a
    scene that is not from a scene file, or whose meshes carry none."""
    return _notices(scene)[0]


def _notices(scene: Scene) -> tuple[list[str], list[Path]]:
    """:func:`notices`, and the mesh files that carry none (each export warns of them)."""
    try:
        files = _mesh_files(Path(scene.source))
    except (InputError, OSError, ValueError):  # (not a scene file: a Scene made in Python)
        return [], []
    out: list[str] = []
    bare: list[Path] = []
    for mesh in files:
        block = _notice_of(mesh)
        if block and not _holds(out, block):
            out += block
        if not block and mesh.is_file() and mesh not in bare:
            bare.append(mesh)
    return out, bare


def _holds(lines: list[str], block: list[str]) -> bool:
    return any(lines[i:i + len(block)] == block for i in range(len(lines) - len(block) + 1))


def _mesh_files(source: Path) -> list[Path]:
    """The mesh files the scene file ``source`` names (its ``extends`` chain followed)."""
    from tlm.scenes.compose import mesh_path
    from tlm.scenes.loader import read_scene_tree

    if not source.is_file():
        return []
    raw, geom_path = read_scene_tree(source, ())
    items = raw.get("geometry")
    items = items if isinstance(items, list) else [items]
    return [mesh_path(item["mesh"], Path(geom_path)) for item in items
            if isinstance(item, dict) and isinstance(item.get("mesh"), str) and item["mesh"]]


def _alnum(text: str) -> str:
    return re.sub(r"[^0-9a-z]", "", text.lower())


_NOTICE_WORDS = ("copyright", "licence", "license")  # (how a notice file's name begins, any case)


def notice_files(mesh: Path) -> list[Path]:
    """The notice files of one mesh file, beside it (the module's docstring): the files whose
    name begins, in any case, with ``COPYRIGHT``, ``LICENSE`` or ``LICENCE``. One that names
    a file there after the word (``COPYRIGHT-cornellbox.txt``: its letters and digits begin
    ``CornellBox-Water.obj.xz``'s) is that file's only (of several, the longest name); the others
    (``copyright.txt``, as McGuire's archives name theirs, ``LICENSE``, ``LICENSE-CC-BY.txt``)
    are every mesh's there, after it, by name. A symbolic link has those beside the file it
    links to too, by that file's name, after its own (``box.obj`` linking to a published
    ``CornellBox-Original.obj``: that file's notice is the link's, a ``LICENSE`` beside the link
    or not)."""
    found = _notice_files_beside(mesh)
    if mesh.is_symlink():
        try:
            target = mesh.resolve(strict=True)
        except (OSError, RuntimeError):  # (a broken link, a loop of links)
            return found
        held = {p.resolve() for p in found}
        found += [p for p in _notice_files_beside(target) if p.resolve() not in held]
    return found


def _notice_files_beside(mesh: Path) -> list[Path]:
    """:func:`notice_files` of ``mesh`` among the files of its own folder."""
    try:
        names = sorted(p.name for p in mesh.parent.iterdir())
    except OSError:
        return []
    beside = [n for n in names if n.lower().startswith(_NOTICE_WORDS) and (mesh.parent / n).is_file()]
    others = [_alnum(n) for n in names if n not in beside]
    own, folder = [], []
    for n in beside:
        rest = _alnum(Path(n).stem[len(next(w for w in _NOTICE_WORDS if n.lower().startswith(w))):])
        if not rest or not any(o.startswith(rest) for o in others):
            folder.append(mesh.parent / n)  # (names no file there: the folder's)
        elif _alnum(mesh.name).startswith(rest):
            own.append(mesh.parent / n)
    return [*sorted(own, key=lambda p: -len(p.name))[:1], *folder]


def _notice_of(mesh: Path) -> list[str]:
    """The notice lines of one mesh file: its notice files' (:func:`notice_files`), else those
    its own header carries when tlm exported it."""
    if not mesh.is_file():
        return []
    out: list[str] = []
    for found in notice_files(mesh):
        try:
            text = found.read_text(encoding="utf-8", errors="replace")
        except OSError:
            continue
        body = [line.strip().removeprefix("#").strip() for line in text.splitlines()]
        body = [f"{_BODY}{line}" for line in body if line]
        changed = f"{_BODY}(Changed: this file holds the mesh's triangles as tlm loads them, not the file itself.)"
        out += [f"{_NOTICE}{mesh.name} (its {found.name}), to keep with every copy:", *body, changed] if body else []
    return out or _notices_in_header(mesh)


def _notices_in_header(mesh: Path) -> list[str]:
    """The notice lines in the header of a mesh file tlm exported (OBJ: ``#`` lines before the
    first statement; PLY: ``comment`` lines before ``end_header``); none in another file."""
    try:
        with open(mesh, "rb") as f:
            head = f.read(1 << 16)
    except OSError:
        return []
    if head.startswith(_MTL_HEAD.encode()):
        prefix, lines = "# ", head.decode("utf-8", "replace").splitlines()
        lines = lines[:next((i for i, line in enumerate(lines) if not line.startswith("#")), len(lines))]
    elif head.startswith(b"ply") and b"\ncomment tlm scene " in head.split(b"end_header", 1)[0]:
        prefix, lines = "comment ", head.split(b"end_header", 1)[0].decode("utf-8", "replace").splitlines()
    else:
        return []
    out, inside = [], False
    for line in lines:
        text = line[len(prefix):] if line.startswith(prefix) else None
        if text is not None and text.startswith(_NOTICE):
            inside = True
        elif text is None or not text.startswith(_BODY):
            inside = False
        if inside:
            out.append(text)
    return out


def _comments(prefix: str, lines: list[str]) -> str:
    """``lines`` as comment lines of a file (``# `` or PLY's ``comment ``), each ending in a newline."""
    return "".join(f"{prefix}{line}\n" for line in lines)


def _write_ply(scene: Scene, path: Path, verts: np.ndarray, faces: np.ndarray,
               told: list[str] | tuple[str, ...] = ()) -> None:
    """The PLY file of the triangles (the module's docstring), written atomically."""
    from tlm.scenes.plyfile import NAME_COMMENT

    n = faces.shape[0]
    names = "".join(f"{NAME_COMMENT}{i} {json.dumps(m.name)}\n" for i, m in enumerate(scene.materials))
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment tlm scene {_one_line(scene.name)}: face i is triangle id i\n{_comments('comment ', list(told))}"
        f"{names}"
        f"element vertex {3 * n}\nproperty double x\nproperty double y\nproperty double z\n"
        f"{_PLY_NORMALS if scene.normals is not None else ''}"
        f"element face {n}\nproperty list uchar int vertex_indices\n"
        "property int material\nend_header\n"
    )
    face_rec = np.zeros(n, dtype=[("k", "u1"), ("v", "<i4", 3), ("m", "<i4")])
    face_rec["k"] = 3
    face_rec["v"] = faces
    face_rec["m"] = scene.material_index
    with write_atomic(path, "wb") as f:
        f.write(header.encode())
        if scene.normals is not None:  # (each vertex is one corner: its normal beside its position)
            verts = np.concatenate([verts, np.asarray(scene.normals, dtype=np.float64).reshape(-1, 3)], axis=1)
        f.write(verts.astype("<f8").tobytes())
        f.write(face_rec.tobytes())


def _obj_files(scene: Scene, path: Path, verts: np.ndarray, faces: np.ndarray,
               told: list[str] | tuple[str, ...] = ()) -> list[tuple[Path, str]]:
    """The OBJ file ``path`` of the triangles and its MTL library beside it (the module's
    docstring), as ``(path, text)``, the library first, for :func:`tlm.storage.write_files`."""
    n = faces.shape[0]
    library = path.with_suffix(".mtl")
    lines = [f"{_MTL_HEAD}{_one_line(scene.name)}: face i is triangle id i", *(f"# {t}" for t in told),
             f"mtllib {library.name}"]
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in verts.tolist()]
    normals = scene.normals
    if normals is not None:  # (per corner, in the vertices' order: corner k's normal is vn k)
        # (as they are: the OBJ reader keeps a unit vn as written, objfile.unit_as_written)
        corners = np.asarray(normals, dtype=np.float64).reshape(-1, 3).tolist()
        lines += [f"vn {x!r} {y!r} {z!r}" for x, y, z in corners]
        face_line = "f {0}//{0} {1}//{1} {2}//{2}".format
    else:
        face_line = "f {} {} {}".format
    part, mat = np.asarray(scene.part), np.asarray(scene.material_index)
    starts = np.flatnonzero(np.r_[True, (part[1:] != part[:-1]) | (mat[1:] != mat[:-1])])
    ends = np.r_[starts[1:], n]
    last_part = None
    for s, e in zip(starts.tolist(), ends.tolist(), strict=True):  # (one o and usemtl per run)
        if part[s] != last_part:
            lines.append(f"o {scene.part_names[part[s]]}")
            last_part = part[s]
        lines.append(f"usemtl {scene.materials[mat[s]].name}")
        lines += [face_line(a + 1, a + 2, a + 3) for a in range(3 * s, 3 * e, 3)]
    return [(library, mtl_text(scene, list(told))), (path, "\n".join(lines) + "\n")]


def _check_library(scene: Scene, library: Path) -> None:
    """An InputError when the OBJ's MTL library cannot be written as tlm reads it back: a
    material name an MTL file cannot hold (a ``#`` starts a comment there; spaces at its
    ends are trimmed), or a file of that name that tlm did not write (a published scene's
    library beside its OBJ), which it would replace."""
    for m in scene.materials:
        if not m.name or "#" in m.name or m.name != m.name.strip() or any(c in m.name for c in "\r\n"):
            raise InputError(f"material {quoted(m.name)} cannot be named in an MTL library (a '#' starts a comment; "
                             "spaces at its ends, or a line break, do not survive): rename it in the scene file",
                             source=str(library.with_suffix(".obj")))
    if library.exists() and not _written_by_tlm(library):
        raise InputError(f"{library.name} beside it is not a library tlm wrote, and the export would replace it: "
                         "name another .obj file", source=str(library.with_suffix(".obj")))


_MTL_HEAD = "# tlm scene "  # (the first line of a library, OBJ or scene file tlm writes)


def _written_by_tlm(path: Path) -> bool:
    """Whether the file starts as every file tlm exports does (a PLY file: its header's
    second comment line, after the format line, ``comment tlm scene ...``)."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 10)
    except OSError:
        return False
    if head.startswith(b"ply"):
        lines = head.split(b"\n")
        return len(lines) > 3 and lines[2].startswith(b"comment tlm scene ") and lines[1].startswith(b"format ")
    return head.startswith(_MTL_HEAD.encode())


def _check_ours(path: Path, target: Path, what: str) -> None:
    """An InputError when ``path``, which exporting ``target`` would replace, exists and
    is not a file tlm wrote (a published scene's OBJ, a user's scene file)."""
    if path.exists() and not _written_by_tlm(path):
        which = "" if path == target else f"{path.name} "  # (the file named: not said twice)
        raise InputError(f"{which}exists and is not a {what} tlm wrote; the export would replace it: "
                         f"name another {target.suffix.lower()} file", source=str(target))


def _one_line(name: str) -> str:
    """A scene's name as a comment line can hold it (its line breaks as spaces)."""
    return " ".join(name.splitlines())


def _floats(values) -> list[float]:
    return [float(x) for x in values]


def scene_yaml(scene: Scene, mesh: str, told: list[str] | None = None) -> str:
    """The scene file of ``scene`` whose geometry is the OBJ ``mesh`` (a name beside it),
    as the module's docstring says; ``told``: the notice lines below its first lines
    (default: :func:`notices` of the scene)."""
    scene = used_materials(scene)
    mats = {}
    for m in scene.materials:
        entry: dict = {"type": m.kind}
        if m.kind == "lambertian":
            entry["albedo"] = _floats(m.albedo)
        elif m.kind == "mirror":
            entry["reflectance"] = _floats(m.reflectance)
        else:
            entry.update(ior=float(m.ior), transmittance=_floats(m.transmittance))
        if m.emits:
            entry["emission"] = _floats(m.emission)
        mats[m.name] = entry
    lights = []
    for light in scene.lights:
        if light.kind == "point":
            lights.append({"type": "point", "position": _floats(light.position), "power": _floats(light.power)})
        elif light.kind == "quad":
            lights.append({"type": "quad", "corner": _floats(light.corner), "edge_u": _floats(light.edge_u),
                           "edge_v": _floats(light.edge_v), "power": _floats(light.power)})
        elif light.kind == "spot":
            lights.append({"type": "spot", "position": _floats(light.position), "direction": _floats(light.direction),
                           "power": _floats(light.power), "inner_cone_angle": float(light.inner_angle),
                           "outer_cone_angle": float(light.outer_angle)})
        elif light.kind == "directional":
            lights.append({"type": "directional", "direction": _floats(light.direction),
                           "irradiance": _floats(light.irradiance)})
        else:  # (a mesh light is its emitting materials)
            continue
        if light.name:  # (a glTF's light's: which it was, FILE KHR_lights_punctual.lights[i] 'NAME' at nodes[n])
            lights[-1] = {"type": light.kind, "name": light.name, **lights[-1]}
    cam = scene.camera
    doc = {
        "name": scene.name,
        "description": str(scene.extra.get("description", "")),
        "geometry": {"mesh": mesh},
        "materials": mats,
        "lights": lights,
        "camera": {"eye": _floats(cam.eye), "target": _floats(cam.target), "up": _floats(cam.up),
                   "vfov": float(cam.vfov)},
        "resolution": [int(cam.width), int(cam.height)],
        "photons": int(scene.photons),
    }
    head = [f"{_MTL_HEAD}{_one_line(scene.name)}: written by tlm scene export, with {_one_line(mesh)} and its MTL "
            "library beside it.",
            "# The materials replace the MTL's of the same name (exactly); mesh lights are the emitting materials.",
            *(f"# {line}" for line in (notices(scene) if told is None else told))]
    return "".join(f"{_yaml_comment(line)}\n" for line in head) + dump_yaml(doc, sort_keys=False,
                                                                             default_flow_style=None, width=120)


# a character YAML reads in no file, not even in a comment: C0 controls but tab, line feed and carriage return,
# DEL, C1 controls but NEL, surrogates, U+FFFE and U+FFFF (PyYAML's Reader.NON_PRINTABLE; libyaml's reader's)
_NOT_YAML = re.compile("[^\t\n\r\x20-\x7e\x85\xa0-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def _yaml_comment(line: str) -> str:
    """A comment line of the scene file as YAML can hold it (h416): each character YAML refuses
    (:data:`_NOT_YAML`: a BEL, an ESC or a NUL in a scene's name or a licence notice) as its Python escape,
    ``\\x07``, ``\\x1b``, ``\\x00`` (the name itself, in ``name:``, keeps them: YAML's own escapes)."""
    return _NOT_YAML.sub(lambda m: ascii(m.group())[1:-1], _one_line(line))  # (a NEL, U+2028: a line break)


def mtl_text(scene: Scene, told: list[str] | None = None) -> str:
    """The scene's materials as an MTL library (the module's docstring); ``told``: the
    notice lines below its first line (default: :func:`notices` of the scene)."""
    def rgb(c) -> str:
        return " ".join(repr(float(x)) for x in c)

    scene = used_materials(scene)
    out = [f"{_MTL_HEAD}{_one_line(scene.name)}: its materials",
           *(f"# {t}" for t in (notices(scene) if told is None else told))]
    for m in scene.materials:
        out.append(f"newmtl {m.name}")
        if m.kind == "lambertian":
            out += [f"Kd {rgb(m.albedo)}", "Ks 0.0 0.0 0.0", "illum 1"]
        elif m.kind == "mirror":
            out += ["Kd 0.0 0.0 0.0", f"Ks {rgb(m.reflectance)}", "illum 3"]
        else:
            out += [f"Ni {float(m.ior)!r}", f"Tf {rgb(m.transmittance)}", "illum 7"]
        if m.emits:
            out.append(f"Ke {rgb(m.emission)}")
    return "\n".join(out) + "\n"
