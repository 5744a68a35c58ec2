"""Mesh files told from YAML ones (:func:`mesh_file_format`: by the name's suffix or the file's
first bytes, never by a failed parse), and the one line that says how to use a mesh file given
where a config or a scene file goes (:func:`mesh_file_hint`): read by :func:`tlm.config.read_yaml`
and by the scene loader's path resolution. An OBJ's MTL material library given so is told and
hinted at too: it is read with the OBJ that names it (:func:`mtl_user`), which is what to name."""

from __future__ import annotations

import os
import re

from tlm.config_words import listing
from tlm.errors import quoted

# the mesh files tlm reads (tlm.scenes.meshes.SUPPORTED_EXTENSIONS), each as a message names its format
MESH_FORMATS = {".obj": "an OBJ", ".ply": "a PLY", ".stl": "an STL", ".glb": "a binary glTF (.glb)", ".gltf": "a glTF"}
_MESH_COMPRESSED = (".gz", ".xz", ".bz2")
# a Wavefront material library: no mesh, but given where a scene goes as one is (its OBJ is what to name)
MTL_FORMAT = "a Wavefront MTL material library"
# an MTL's statements (the first words of its lines: the spec's, and the PBR extension's)
_MTL_WORDS = {"newmtl", "ka", "kd", "ks", "ke", "tf", "ni", "ns", "d", "tr", "illum", "sharpness", "bump", "disp",
              "decal", "refl", "norm", "pr", "pm", "ps", "pc", "pcr", "aniso", "anisor"}  # (in lower case; and map_*)
# an OBJ's statements (the first words of its lines)
_OBJ_WORDS = {"v", "vt", "vn", "vp", "f", "l", "p", "o", "g", "s", "mtllib", "usemtl", "cstype", "deg", "curv", "surf"}
# glTF 2.0's top-level properties (a JSON file with others is no glTF)
_GLTF_KEYS = {"asset", "scene", "scenes", "nodes", "meshes", "accessors", "bufferViews", "buffers", "materials",
              "textures", "images", "samplers", "cameras", "skins", "animations", "extensions", "extensionsUsed",
              "extensionsRequired", "extras"}
_GLTF_NOT_LISTS = {"asset", "scene", "extensions", "extras"}  # (every other one is a list; 'scene' an index)
_GLTF_PARSED = 1 << 20  # (bytes: a JSON file up to this size is parsed to tell a glTF; a larger one by its first bytes)
# the names of a file descriptor (``<(...)``'s ``/dev/fd/63``, ``/dev/stdin``, ``/proc/self/fd/0``)
_DESCRIPTOR = re.compile(r"/(?:dev/(?:stdin|fd/[0-9]+)|proc/(?:self|thread-self|[0-9]+)/fd/[0-9]+)")


def descriptor_name(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a file descriptor's name (``/dev/fd/63``, ``/dev/stdin``, ``/proc/self/fd/0``), a name of
    no file of its own: the one rule of :func:`tlm.config_read.nameless` and of a mesh's hint."""
    return _DESCRIPTOR.fullmatch(os.path.abspath(os.fspath(path))) is not None


def _gltf_json(data: bytes, head: bytes, size: int) -> bool:
    """Whether the JSON file of ``size`` bytes whose first are ``data`` (``head``: the first few of them, leading
    blanks left out) is a glTF: an object whose ``asset`` is an object with a ``version``, whose ``meshes`` is a
    list, and whose every key is one of glTF's top-level properties, of its type (``scene``
    an index, ``nodes``, ``buffers``, ... lists). Parsed up to
    :data:`_GLTF_PARSED` bytes (``data`` all of them); a larger file (or one that does not parse: a glTF cut short)
    by its first bytes, ``"asset": {`` holding ``"version"`` and a list of ``meshes``,
    ``nodes``, ``accessors``, ... beside it. A config written as JSON (``{"scene": "cornell",
    "asset": 1}``) is none."""
    import json

    if size <= _GLTF_PARSED and len(data) >= size:
        try:
            parsed = json.loads(data)
        except ValueError:
            parsed = None
        if parsed is not None:
            return (isinstance(parsed, dict) and set(parsed) <= _GLTF_KEYS and isinstance(parsed.get("asset"), dict)
                    and "version" in parsed["asset"] and isinstance(parsed.get("meshes"), list)
                    and all(isinstance(v, list) for k, v in parsed.items() if k not in _GLTF_NOT_LISTS)
                    and (isinstance(parsed.get("scene", 0), int) and not isinstance(parsed.get("scene"), bool)))
    return (re.search(rb'"asset"\s*:\s*\{[^{}]*"version"\s*:', head) is not None
            and re.search(rb'"(scenes|nodes|meshes|accessors|bufferViews|buffers)"\s*:\s*\[', head) is not None)


def mesh_file_format(path: str | os.PathLike, content: bool = True) -> str | None:
    """The format (:data:`MESH_FORMATS`' words: ``"an OBJ"``) of the mesh file ``path``, told
    by its suffix (``pawn.obj``, ``pawn.obj.gz``) or else by its first bytes: a binary glTF's
    ``glTF`` magic, a PLY's ``ply`` and ``format`` lines, an ASCII STL's ``solid`` and ``facet normal``,
    a binary STL's size (80 bytes, a count, 50 bytes a triangle; not for a ``.yaml`` name), an
    OBJ's statements (``v``, ``f``, ``o``, ... and nothing else on its first lines), an MTL
    library's (:data:`MTL_FORMAT`, ``.mtl``: ``newmtl``, ``Kd``, ``illum``, ... and nothing else;
    no mesh, but given where a scene goes as one is, its hint names its OBJ), a glTF
    JSON's ``asset`` object with its ``version``, its ``meshes`` and no key glTF does not have
    (:func:`_gltf_json`; a config written as JSON is none). None for anything else, a file that cannot be read
    included (its read says why): what :func:`tlm.config.read_yaml` refuses by name, never by failing to
    parse it. ``content=False``: by the suffix alone (a name not yet looked for)."""
    name = os.fspath(path).lower()
    stem = name[: -len(os.path.splitext(name)[1])] if name.endswith(_MESH_COMPRESSED) else name
    ext = os.path.splitext(stem)[1]
    if ext in MESH_FORMATS:
        return MESH_FORMATS[ext]
    if ext == ".mtl":
        return MTL_FORMAT
    if not content:
        return None
    try:
        with open(path, "rb") as f:
            data = f.read(_HEAD)
            size = os.fstat(f.fileno()).st_size
            if data.lstrip()[:1] == b"{" and size <= _GLTF_PARSED:  # (a JSON file: a glTF's is told by its parse)
                data += f.read(_GLTF_PARSED + 1 - len(data))
    except OSError:
        return None
    return mesh_bytes_format(data, size, name)


_HEAD = 4096  # (bytes: a file's first, by which its format is told, but a JSON one's parse)


def mesh_bytes_format(data: bytes, size: int | None = None, name: str = "") -> str | None:
    """:func:`mesh_file_format` by content of a file's bytes: ``data``, its first (all of them, up to
    :data:`_GLTF_PARSED`, for a glTF JSON to be parsed; else its first bytes tell it), of ``size`` (none:
    ``len(data)``); ``name``: its name in lower case, where it has one (a ``.yaml`` one is no binary STL).
    What a file read from a pipe, whose bytes are gone once read, is told by (:func:`tlm.config_read.yaml_text`),
    on any system."""
    size = len(data) if size is None else size
    head = data[:_HEAD]
    if head[:4] == b"glTF":
        return MESH_FORMATS[".glb"]
    lines = head.replace(b"\r", b"").split(b"\n")
    if lines[0].strip() == b"ply" and len(lines) > 1 and lines[1].startswith(b"format "):
        return MESH_FORMATS[".ply"]
    if lines[0].split()[:1] == [b"solid"] and b"facet normal" in head:
        return MESH_FORMATS[".stl"]
    if (size >= 84 and size == 84 + 50 * int.from_bytes(head[80:84], "little")
            and not name.endswith((".yaml", ".yml"))):
        return MESH_FORMATS[".stl"]
    words = [ln.split(maxsplit=1)[0] for ln in lines[:-1] if ln.strip() and not ln.lstrip().startswith(b"#")][:40]
    if words and b"v" in words and all(w.decode("latin-1") in _OBJ_WORDS for w in words):
        return MESH_FORMATS[".obj"]
    if words and b"newmtl" in words and all((w := x.decode("latin-1").lower()) in _MTL_WORDS or w.startswith("map_")
                                            for x in words):
        return MTL_FORMAT
    text = head.lstrip()
    if text[:1] == b"{" and _gltf_json(data, text, size):
        return MESH_FORMATS[".gltf"]
    return None


def mesh_file_hint(name: str, format_: str, key: str | None = None, folder: str | os.PathLike | None = None) -> str:
    """What a message about the mesh file ``name`` (of ``format_``, :func:`mesh_file_format`)
    given where a YAML file or a scene is expected says: what it is and how to render it (a
    scene file names it under ``geometry``; ``key``: the key that named it, ``scene`` or
    ``extends``; ``""``: a scene given by itself, on the command line or to ``load_scene``,
    which the message's source names; else a file read as YAML). A file told by its content
    alone is to be renamed first: a mesh file is read by its suffix. ``folder``: the one a relative
    ``name`` is relative to (a scene file's, for its ``extends``; none: the working folder)."""
    if format_ == MTL_FORMAT:
        return _mtl_hint(name, key, folder)
    if key is None and descriptor_name(name):  # (/dev/stdin < pawn.ply: its name is none
        return piped_mesh_hint(format_, "given by a file descriptor's name")  # of its own, as a pipe's is not)
    base, renamed = os.path.basename(name), ""
    if mesh_file_format(base, content=False) is None:
        base = os.path.splitext(base)[0] + next(e for e, f in MESH_FORMATS.items() if f == format_)
        renamed = f"rename it {base} (a mesh file is read by its suffix), "
    scene = (f"`geometry: {{mesh: {base}}}` in a scene file beside it, with `materials:` and `camera:` "
             f"unless the mesh file gives them (docs/scenes.md, \"Geometry\")")
    return _by_key(name, key, f"{format_} mesh file", scene, base, "it", renamed)


def piped_mesh_hint(format_: str, given: str = "given as a pipe") -> str:
    """:func:`mesh_file_hint` of a mesh file of ``format_`` read as YAML where its name is none of its own
    (``given``: a pipe's, ``tlm run <(cat pawn.obj)``; a file descriptor's, ``/dev/stdin < pawn.ply``): to save
    it as a file of a mesh's suffix first."""
    name = "mesh" + next(e for e, f in MESH_FORMATS.items() if f == format_)
    hint = mesh_file_hint(name, format_)  # (as of a file named so: "is an OBJ mesh file, not a YAML file: write ...")
    return hint.replace(f"{format_} mesh file, not a YAML file: ", f"{format_} mesh file {given}, not a YAML file: "
                        f"save it as a file, {name} (a mesh file is read by its suffix), ", 1)


def mesh_file_missing(format_: str) -> str:
    """What a message about a mesh file (of ``format_``, :func:`mesh_file_format` by its name)
    given where a scene goes, and not found, says after the "not found": what its name makes it."""
    if format_ == MTL_FORMAT:
        return (f"by its name {format_}, not a scene: a scene file names the OBJ that reads it under "
                "`geometry:` (docs/scenes.md, \"Geometry\")")
    return f"by its name {format_} mesh file, not a scene: a scene file names it under `geometry:` (docs/scenes.md, " \
           "\"Geometry\")"


def _by_key(name: str, key: str | None, what: str, scene: str, mesh: str, it: str, renamed: str = "") -> str:
    """The hint for a file ``name`` that is ``what``, not a scene, as ``key`` names it (``extends``, a
    config key, ``""``: the command line's scene, None: a file read as YAML): write ``scene`` instead,
    naming ``it`` (``mesh``) under ``geometry:`` (``renamed``: what to rename it first, or nothing)."""
    if key == "extends":
        return (f"{quoted(name)} is {what}, not a scene file to extend: name {it} under `geometry:` instead "
                f"({renamed}`geometry: {{mesh: {mesh}}}`; docs/scenes.md, \"Geometry\")")
    if key == "":
        return f"is {what}, not a scene: {renamed}write {scene}, and name that file in its place"
    if key is not None:
        return (f"{quoted(name)} is {what}, not a scene: {renamed}write {scene}, and name that file instead "
                f"(`{key}: SCENE.yaml`, `--set scene=SCENE.yaml`, `tlm run SCENE.yaml`)")
    return f"is {what}, not a YAML file: {renamed}write {scene}, and run that file (`tlm run SCENE.yaml`)"


def _mtl_hint(name: str, key: str | None, folder: str | os.PathLike | None = None) -> str:
    """:func:`mesh_file_hint` of an MTL material library ``name`` (relative to ``folder``, where
    given): what it is, and the OBJs beside it whose ``mtllib`` names it (:func:`mtl_users`), the
    first to name instead, as :func:`mesh_file_hint` words it for ``key`` (under ``extends``, as the
    scene file that extends it names it); where none names it, it says so (and what an OBJ of its
    stem names instead)."""
    beside = os.path.join(folder, name) if folder is not None else name
    users, other = mtl_users(beside if os.path.exists(beside) else name)  # (else as the working folder finds it)
    obj = users[0] if users else other[0] if other else None
    if users:
        found = f": {listing(users)}, beside it"
    else:  # (the OBJ of its stem, where there is one, is still the one to name: it reads its own mtllib)
        found = f"; no OBJ beside it names it{f': {other[0]}, of its stem, reads {other[1]} instead' if other else ''}"
    what = f"{MTL_FORMAT} (the materials of an OBJ mesh, read with the OBJ{'s' if len(users) > 1 else ''} whose " \
           f"`mtllib` names it{found})"
    mesh = obj or "THE.obj"
    if obj and key == "extends":  # (a path from the scene file that extends the library, as its name is)
        mesh = os.path.join(os.path.dirname(name), obj)
    scene = (f"`geometry: {{mesh: {mesh}}}` in a scene file beside it{'' if obj else ', naming that OBJ'}, with "
             "`camera:` (and `materials:` for any the library lacks; docs/scenes.md, \"Geometry\")")
    return _by_key(name, key, what, scene, mesh, "its OBJ")


def mtl_user(name: str | os.PathLike) -> str | None:
    """The name of an OBJ file beside the MTL library ``name`` whose ``mtllib`` names it
    (:func:`mtl_users`; one of its stem first); None where none does."""
    users = mtl_users(name)[0]
    return users[0] if users else None


_MTLLIB = re.compile(rb"^[ \t]*mtllib[ \t]+([^\r\n]*)", re.MULTILINE)


def mtl_users(name: str | os.PathLike) -> tuple[list[str], tuple[str, str] | None]:
    """The OBJ files beside the MTL library ``name`` (plain or compressed: ``.obj.xz``, ...; up to
    64 looked at, by name) whose ``mtllib`` statements in their first 64 KiB name it, one of its
    stem first (``CornellBox-Sphere.obj``), then by name; and, where none does, an OBJ of its stem
    and what its ``mtllib`` names instead (McGuire's ``CornellBox-Glossy-Floor.obj`` reads
    ``CornellBox-Glossy.mtl``), else None. Only the ``mtllib`` lines are read."""
    path = os.fspath(name)
    folder, base = os.path.dirname(path) or ".", os.path.basename(path)
    stem = base[: -len(os.path.splitext(base)[1])] if base.lower().endswith(_MESH_COMPRESSED) else base
    stem = os.path.splitext(stem)[0]
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return [], None
    objs = [n for n in names if n.lower().endswith((".obj", *(f".obj{z}" for z in _MESH_COMPRESSED)))][:64]
    own = {f"{stem}.obj".lower(), *(f"{stem}.obj{z}".lower() for z in _MESH_COMPRESSED)}
    objs.sort(key=lambda n: n.lower() not in own)
    users, other = [], None
    for n in objs:
        libs = _mtllibs(os.path.join(folder, n))
        if any(_names(base, text) for text in libs):
            users.append(n)
        elif n.lower() in own and other is None:
            other = (n, listing(t.decode("utf-8", "replace").strip() for t in libs) or "no library (no mtllib)")
    return users, (None if users else other)


def _mtllibs(path: str) -> list[bytes]:
    """The texts of the ``mtllib`` statements in the first 64 KiB of the OBJ ``path`` (decompressed
    as its suffix says); none where it cannot be read."""
    import bz2
    import gzip
    import lzma

    opener = {".gz": gzip.open, ".xz": lzma.open, ".bz2": bz2.open}.get(os.path.splitext(path)[1].lower(), open)
    try:
        with opener(path, "rb") as f:
            head = f.read(1 << 16)
    except (OSError, EOFError, lzma.LZMAError):
        return []
    return [m.group(1) for m in _MTLLIB.finditer(head)]


def _names(base: str, mtllib: bytes) -> bool:
    """Whether an ``mtllib`` statement's text names the file ``base`` beside the OBJ: one of its
    names, or its whole text (a name with spaces), written as ``base`` or with ``./`` or ``..``
    that lead back to it (``./box.mtl``, ``.\\box.mtl``)."""
    text = mtllib.decode("utf-8", errors="replace").strip()
    return any(os.path.normpath(w.replace("\\", "/")) == base for w in (*text.split(), text.strip()) if w)
