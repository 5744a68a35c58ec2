"""Materials from mesh files: Wavefront MTL and glTF 2.0, mapped to tlm's three kinds.

tlm renders three kinds of surface (:class:`~tlm.scenes.model.Material`): Lambertian,
perfect mirror and smooth dielectric, any of them emitting. A mesh file's material
models are richer (Phong highlights, metallic-roughness); this module keeps what the
three kinds can show and says how.

**MTL** (:func:`parse_mtl`). Read: ``newmtl``, ``Kd``, ``Ks``, ``Ke``, ``Tf`` (RGB, or one
number for grey), ``Ni``, ``d``, ``Tr`` (= 1 - ``d``; ``d`` wins when both are given),
``illum``, ``Ns``; every other statement (``Ka``, maps, ...) is ignored, and so is a
colour given as ``spectral`` or ``xyz``. Of those, the ones that change how a surface
looks (texture and bump maps: ``map_*``, ``bump``, ``disp``, ``decal``, ``refl``,
``norm``; the PBR extension's ``Pr``, ``Pm``, ``Ps``, ``Pc``, ``Pcr``, ``aniso``,
``anisor``; a colour given as ``spectral`` or ``xyz``) are kept in
:attr:`Material.ignored`, and a run that renders such a material warns of them
(:func:`tlm.render.checks.material_warnings`).

======================================================  ============  ===================================
MTL                                                     tlm kind      parameters
======================================================  ============  ===================================
``illum`` 4, 6, 7 or 9 (glass), or ``d`` < 1            dielectric    ``ior = Ni`` (1.5 without ``Ni``),
(``Tr`` > 0)                                                          ``transmittance = (1, 1, 1)``
``illum`` 3, 5 or 8 (ray-traced reflection), or no      mirror        ``reflectance = Ks`` (clipped to
``illum`` and a dominant ``Ks`` (max Ks > max Kd)                     [0, 1], a note)
anything else (``illum`` 0-2: Phong)                    lambertian    ``albedo = Kd`` (clipped to [0, 1],
                                                                      a note; 0.8 grey without ``Kd``)
``Ke`` > 0, with any of the above                       (same kind)   ``emission = Ke`` (radiance, W/sr/m²)
======================================================  ============  ===================================

Choices, and why:

* A dielectric's transmittance is 1 (clear glass): ``Tf`` is read and checked but not
  used. The published scenes write ``Tf`` for their glass as a Phong-era filter that
  is not the glass's colour: McGuire's ``CornellBox-Sphere`` gives Jensen's clear glass
  sphere (``illum 7``, ``Ni 2.5``) and its water ``Tf 0.1 0.1 0.1``; read literally that
  would be smoked glass passing 10% of the light. A tinted glass is a scene file's
  ``materials:`` override.
* ``illum`` 0-2 is a Phong model whose ``Ks`` is a highlight (``Ns`` 10-200), not a
  mirror: the LBNL conference room gives every material ``Ks 0.2`` beside ``Kd`` as low
  as 0.05, and McGuire's ``CornellBox-Glossy`` ``Ks 0.9`` with ``Ns 40``; those are
  Lambertian with ``Kd``. Only a file that names no ``illum`` lets a dominant ``Ks``
  make a mirror.
* ``Ni`` is used only by dielectrics (exporters write ``Ni`` for every material).

Errors (:class:`~tlm.errors.InputError`, one line naming the MTL file, the line, the
material and the key): a value that is not a number, NaN or infinite; a negative
colour; ``d`` or ``Tr`` outside [0, 1]; ``Ni`` <= 0 on a dielectric; a statement with
too few numbers. Notes (``Geometry.notes``, a line each naming the file and the line): a colour
used that is clipped (``Kd 185 181 173``, 0-255 values, is white), a ``newmtl`` name defined
again (the first definition is used), a material another library of the OBJ defined first, a
statement given again in one material with another value (the last is used, as trimesh's and
tinyobjloader's MTL readers take it: each assignment replaces the one before; the LBNL conference
room's table, ``mesh29_SG``, gives ``Kd 0.286275 0.149020 0.129412`` then ``Kd 1 1 1``, white).

**glTF 2.0** (:func:`gltf_materials`, from the file's JSON, so that extensions count):

==============================================================  ============  =================================
glTF material                                                   tlm kind      parameters
==============================================================  ============  =================================
``KHR_materials_transmission.transmissionFactor`` > 0           dielectric    ``ior`` = ``KHR_materials_ior.ior``
                                                                              (1.5), ``transmittance`` = base colour
``pbrMetallicRoughness.metallicFactor`` >= 0.5 (glTF's          mirror        ``reflectance`` = base colour
default is 1)
otherwise                                                       lambertian    ``albedo`` = base colour
``emissiveFactor`` (times ``KHR_materials_emissive_strength``)  (same kind)   ``emission``
==============================================================  ============  =================================

The base colour is ``baseColorFactor``'s RGB (alpha and textures are ignored). A
material is named by its ``name``, or ``material_<i>`` (its index) without one. What is
ignored and changes the look (every ``*Texture``, an alpha below 1 or an ``alphaMode``
other than ``OPAQUE``, any extension besides the three above, ``doubleSided`` on an
emissive material: tlm's emitters emit from their front only) is kept in
:attr:`Material.ignored`, for the run's warning, as for MTL. ``KHR_materials_pbrSpecularGlossiness``
is not read: as in a glTF reader without it, its material is its fallback
``pbrMetallicRoughness``, and where that gives no ``metallicFactor`` (the default 1) a mirror
(of ``baseColorFactor``, white without one); its ignored entry says so.
"""

from __future__ import annotations

import json
import math
import re
import struct
from pathlib import Path

from tlm.config_words import listing
from tlm.errors import InputError, quoted
from tlm.scenes.model import Material

__all__ = [
    "GLB_MAGIC", "LIBRARY_WINS", "fold_mtl_notes", "glb_chunks", "glb_length_notes", "gltf_json", "gltf_material",
    "gltf_materials", "mtl_material", "mtl_text", "parse_mtl", "write_glb",
]

GLASS_ILLUM = (4, 6, 7, 9)
MIRROR_ILLUM = (3, 5, 8)
DEFAULT_KD = (0.8, 0.8, 0.8)
DEFAULT_IOR = 1.5
GLB_MAGIC = b"glTF"
_COLOURS = ("Kd", "Ks", "Ke", "Tf")
_SCALARS = ("Ni", "d", "Tr", "illum", "Ns")
# statements read past that change a surface's look (the run warns of them: Material.ignored)
_MTL_LOOKS = ("bump", "disp", "decal", "refl", "norm", "Pr", "Pm", "Ps", "Pc", "Pcr", "aniso", "anisor")
_GLTF_READ = ("KHR_materials_emissive_strength", "KHR_materials_transmission", "KHR_materials_ior")
_SPEC_GLOSS = "KHR_materials_pbrSpecularGlossiness"  # (not read: a glTF reader without it reads the fallback)
# (an illum 2 material's Ks that outweighs its Kd: the file's look is glossy, tlm's Lambertian)
HIGHLIGHT = "Ks (an illum 2 glossy highlight stronger than Kd)"
_IGNORED = "ignored"  # (the key of a material's ignored statements among its MTL properties)
_SAID = "said"  # (its statements as the file writes them, by key: [(line, numbers as written, value), ...])


def _clip01(c) -> tuple[float, float, float]:
    return tuple(min(max(float(x), 0.0), 1.0) for x in c)


# ------------------------------------------------------------------ MTL


def _given_again(source: str, name: str, key: str, given: list[tuple[int, str, object]]) -> str:
    """The note on the statement ``key`` of the material ``name`` given more than once with other
    values (``given``: each time's line, numbers as written and value): every line, the last used, and where
    another value is given without editing the (perhaps published) MTL file: a scene file's ``materials:``."""
    times = "twice" if len(given) == 2 else f"{len(given)} times"
    lines = [f"line {line} `{key} {text}`" for line, text, _ in given]
    return (f"{source}: line {given[-1][0]}: material {name!r}: {key} given {times}, {listing(lines)}: "
            f"the last is used, as OBJ readers (trimesh, tinyobjloader) take it (another value: a "
            f"scene file's `materials: {{{name}: ...}}` entry, the MTL file left as it is)")


def mtl_text(data: bytes, source: str, notes: list[str] | None = None) -> str:
    """An MTL file's bytes as text: UTF-8, a byte that is not read as U+FFFD (as an OBJ's
    ``usemtl`` names are read, so that the two still match). ``notes``, where given, gets one line
    for a file with such bytes: the first line that has them, how many do, and what Latin-1 would
    read there (a file saved in Latin-1: ``newmtl Fußboden`` reads ``Fu\ufffdboden``, which a
    scene file's ``materials:`` entry spelled ``Fußboden`` does not name)."""
    data = data.removeprefix(b"\xef\xbb\xbf")  # (a UTF-8 byte order mark, as Notepad saves one: not part of newmtl)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        at = exc.start
    rows = data.split(b"\n")
    bad = sum(1 for row in rows if not row.isascii() and "\ufffd" in row.decode("utf-8", "replace"))
    line = data.count(b"\n", 0, at) + 1
    raw = rows[line - 1].strip()[:80]
    if notes is not None:
        more = f", and {bad - 1} more line{'s' if bad > 2 else ''}" if bad > 1 else ""
        notes.append(f"{source}: line {line}: bytes that are not UTF-8 ({raw.decode('utf-8', 'replace')!r}{more}): "
                     f"read as U+FFFD, so a name there matches no scene file's `materials:` entry spelled otherwise; "
                     f"read as Latin-1 the line is {raw.decode('latin-1')!r} (save the file as UTF-8)")
    return data.decode("utf-8", "replace")


def parse_mtl(text: str, source: str, notes: list[str] | None = None, lines: dict[str, int] | None = None
              ) -> list[Material]:
    """The materials an MTL file defines, in file order (a name defined twice: the
    first definition counts; a statement given twice in one material: the last counts).
    ``source`` names the file in errors. ``notes``, where given, gets a line (file, line, value)
    per definition left out as a repeat of a name, per statement of a material given again with
    another value (every line it is on, as written, and which is used) and per colour clipped into [0, 1]
    (:func:`mtl_material`); ``lines``, where given, each material's name -> the line of its
    ``newmtl``."""
    found: list[tuple[str, int, dict]] = []
    current: dict | None = None
    name = ""
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        words = line.split()
        key = words[0]
        if key == "newmtl":
            name = line[len("newmtl"):].strip()
            current = {}
            found.append((name, number, current))
            continue
        args = words[1:]
        unread = key if key.startswith("map_") or key in _MTL_LOOKS else (
            f"{key} {args[0]}" if key in _COLOURS and args and args[0] in ("spectral", "xyz") else None)
        if current is not None and unread is not None:  # (a colour in spectral or xyz: not read either)
            seen_keys = current.setdefault(_IGNORED, ((), number))[0]
            if unread not in seen_keys:
                current[_IGNORED] = ((*seen_keys, unread), number)
            continue
        if current is None or (key not in _COLOURS and key not in _SCALARS) or unread is not None:
            continue
        if key == "d" and args and args[0] == "-halo":
            args = args[1:]
        where = f"line {number}: material {name!r}: {key}"
        values = []
        for a in args:
            try:
                values.append(float(a))
            except ValueError:
                raise InputError(f"{where}: {a!r} is not a number", source=source) from None
        if not values:
            raise InputError(f"{where}: no value", source=source)
        if not all(math.isfinite(v) for v in values):
            raise InputError(f"{where}: {' '.join(args)} is not finite", source=source)
        if key in _COLOURS:
            if len(values) == 1:
                values = values * 3
            if len(values) < 3:
                raise InputError(f"{where}: needs 3 numbers (r g b) or 1, got {len(values)}", source=source)
            if min(values[:3]) < 0.0:
                raise InputError(f"{where}: {' '.join(args)} has a negative component", source=source)
            value = tuple(values[:3])
        else:
            value = values[0]
            if key in ("d", "Tr") and not 0.0 <= value <= 1.0:
                raise InputError(f"{where}: {args[0]} is outside [0, 1]", source=source)
        # (each statement as the file writes it: one given again with another value is noted; the last wins, as
        # OBJ readers take it)
        current.setdefault(_SAID, {}).setdefault(key, []).append((number, " ".join(args), value))
        current[key] = (value, number)
    seen: dict[str, int] = {}
    out = []
    for name, number, props in found:
        if name in seen:
            if notes is not None:
                notes.append(f"{source}: line {number}: newmtl {name!r} again (first defined at line {seen[name]}): "
                             "this definition is ignored, the first one is used (rename one of them)")
            continue
        seen[name] = number
        if lines is not None:
            lines[name] = number
        said = props.pop(_SAID, {})
        if notes is not None:
            notes += [_given_again(source, name, key, given) for key, given in said.items()
                      if len({value for *_, value in given}) > 1]
        out.append(mtl_material(name, props, source, number, notes))
    return out


_NAME = r"(?P<name>'(?:[^'\\]|\\.)*'|\"(?:[^\"\\]|\\.)*\")"  # (a material's name, as repr writes it)
# the MTL notes one mistake repeated over a file's materials repeats (fold_mtl_notes): kind -> (pattern, what n of
# them are, how the first is said, what the folded line ends with)
_FOLDED = {
    "clipped": (re.compile(rf"^(?P<file>.+?): line (?P<line>\d+): material {_NAME}: (?P<key>Kd|Ks) (?P<said>[^:]*) is "
                           r"over 1: clipped to (?P<what>\w+) (?P<to>\[[^\]]*\])(?P<hint>.*)$"),
                "materials whose {key} is over 1, each clipped to {what} [0, 1]", "{key} {said} -> {to}", "{hint}"),
    "again": (re.compile(rf"^(?P<file>.+?): line (?P<line>\d+): material {_NAME}: (?P<key>\w+) given (?P<said>.*?): "
                         r"the last is used, (?P<hint>.*)$"),
              "statements given again in one material with another value",
              "{key} given {said}",
              ": the last is used, as OBJ readers (trimesh, tinyobjloader) take it (another value: a scene file's "
              "`materials:` entry of each, the MTL file left as it is)"),
    "newmtl": (re.compile(rf"^(?P<file>.+?): line (?P<line>\d+): newmtl {_NAME} again \((?P<said>first defined at "
                          r"line \d+)\): (?P<hint>.*)$"),
               "newmtl names defined again, each later definition ignored", "{said}",
               ": the first definitions are used (rename them)"),
    "library": (re.compile(rf"^(?P<file>.+?): line (?P<line>\d+): newmtl {_NAME} is defined by (?P<key>.+) too "
                           r"\(line (?P<said>\d+)\), which the mtllib names first: (?P<hint>.*)$"),
                "newmtl names that {key} defines too, which the mtllib names first", "{key} line {said}",
                ": the definitions in {key} are used (results.json's scene.materials, `from`, names them), these "
                "are ignored"),
}
# (what an OBJ's MTL notes say of a material a later library defines again: which definition is used and recorded)
LIBRARY_WINS = "that one is used (results.json's scene.materials, `from`, names it), this one is ignored"


def fold_mtl_notes(notes: list[str]) -> list[str]:
    """``notes`` with the MTL notes of one mistake repeated in a file (:func:`parse_mtl`'s: a colour
    clipped, with or without the 0-255 hint; a statement given again; a ``newmtl`` name defined
    again, in the file or by a library the OBJ's ``mtllib`` names before it) folded into one line per
    file and kind, where there are two or more, at the first's place: their count, the first's line,
    material and value, the hint. Every other note is kept as it is. Each note stays in
    ``Geometry.notes`` (``tlm scene show`` lists them all); a run's warnings fold them
    (:func:`tlm.render.checks.file_warnings`)."""
    groups: dict[tuple, list[tuple[int, re.Match]]] = {}
    for i, note in enumerate(notes):
        for kind, (pattern, *_) in _FOLDED.items():
            m = pattern.match(str(note))
            if m is not None:
                hint = m["hint"] if kind == "clipped" else ""
                key = m["key"] if kind in ("clipped", "library") else ""
                groups.setdefault((m["file"], kind, key, hint), []).append((i, m))
                break
    first: dict[int, str] = {}
    dropped: set[int] = set()
    for (file, kind, *_), found in groups.items():
        if len(found) < 2:
            continue
        _, what, said, hint = _FOLDED[kind]
        i, m = found[0]
        fields = {k: v for k, v in m.groupdict().items() if v is not None}
        more = len(found) - 1
        first[i] = (f"{file}: {len(found)} {what.format(**fields)}: the first at line {m['line']}, material "
                    f"{m['name']} ({said.format(**fields)}), and {more} more at line{'s' if more > 1 else ''} "
                    f"{_lines([int(x['line']) for _, x in found[1:]])}{hint.format(**fields)} (`tlm scene show` "
                    "lists each)")
        dropped.update(j for j, _ in found[1:])
    return [first.get(i, str(n)) for i, n in enumerate(notes) if i not in dropped]


def _lines(numbers: list[int], shown: int = 3) -> str:
    """``12, 20, 31, ...``: the first ``shown`` line numbers, and ``...`` where there are more."""
    return ", ".join(map(str, numbers[:shown])) + (", ..." if len(numbers) > shown else "")


def mtl_material(name: str, props: dict, source: str = "", line: int = 0, notes: list[str] | None = None
                 ) -> Material:
    """Map one MTL material (``props``: key -> (value, line number)) to tlm's kinds,
    by the module's table. ``notes``, where given, gets a line when the colour used (``Kd``
    of a Lambertian, ``Ks`` of a mirror) has a component over 1, clipped to 1. An ``illum 2``
    material's ``Ks`` of at least 0.5 and over its ``Kd`` (a glossy highlight, ``CornellBox-Glossy``'s
    sphere: a look tlm does not render) is kept on its ``ignored``, for the run's warning."""

    def get(key, default=None):
        return props[key][0] if key in props else default

    def clipped(key: str, what: str, c) -> tuple[float, float, float]:
        out = _clip01(c)
        if notes is not None and key in props and max(c) > 1.0:
            scaled = " (0-255 values? divide them by 255)" if max(c) > 2.0 and max(c) <= 255.0 else ""
            notes.append(f"{source}: line {props[key][1]}: material {name!r}: {key} {' '.join(f'{x:g}' for x in c)}"
                         f" is over 1: clipped to {what} [{', '.join(f'{x:g}' for x in out)}]{scaled}")
        return out

    kd = get("Kd", DEFAULT_KD)
    ks = get("Ks", (0.0, 0.0, 0.0))
    ke = get("Ke", (0.0, 0.0, 0.0))
    illum = get("illum")
    illum = None if illum is None else int(illum)
    d = get("d")
    if d is None and "Tr" in props:
        d = 1.0 - get("Tr")
    emission = tuple(float(x) for x in ke)
    ignored = get(_IGNORED, ())
    if illum in GLASS_ILLUM or (d is not None and d < 1.0):
        ior = get("Ni", DEFAULT_IOR)
        if not ior > 0.0:
            at = props["Ni"][1]
            raise InputError(f"line {at}: material {name!r}: Ni: {ior:g} is not positive "
                             "(a dielectric's index of refraction)", source=source)
        return Material(name, "dielectric", ior=float(ior), transmittance=(1.0, 1.0, 1.0),
                        emission=emission, ignored=ignored)
    if illum in MIRROR_ILLUM or (illum is None and max(ks) > max(kd) and max(ks) > 0.0):
        return Material(name, "mirror", reflectance=clipped("Ks", "reflectance", ks), emission=emission,
                        ignored=ignored)
    if illum == 2 and max(ks) >= 0.5 and max(ks) > max(kd):
        ignored = (*ignored, HIGHLIGHT)
    return Material(name, "lambertian", albedo=clipped("Kd", "albedo", kd), emission=emission, ignored=ignored)


# ------------------------------------------------------------------ glTF


def _chunks_end(data: bytes) -> int | None:
    """Where a binary glTF file's last chunk ends, walking its chunks from byte 12 by their
    lengths; None where a chunk is cut (its 8-byte head, or its data, runs past the file's end)."""
    end = 12
    while end + 8 <= len(data):
        end += 8 + struct.unpack_from("<I", data, end)[0]
    return end if end == len(data) else None


def _long_header(data: bytes) -> int | None:
    """The length a binary glTF file's 12-byte header gives where it exceeds the file by less than
    a chunk's 8-byte head (no whole chunk can be missing) and the file's chunks are whole, to its
    last byte (:func:`_chunks_end`): a writer that rounded the length up, or a file that lost
    padding past its last chunk; glTF 2.0 wants the header's length to be the file's, and readers
    (trimesh) read such a file by its chunks. None for any other file."""
    if data[:4] != GLB_MAGIC or len(data) < 20:
        return None
    total = struct.unpack_from("<I", data, 8)[0]
    return total if 0 < total - len(data) < 8 and _chunks_end(data) == len(data) else None


def glb_length_notes(data: bytes, source: str = "") -> tuple[str, ...]:
    """The note on a binary glTF file whose header says a few bytes more than the file holds, its
    chunks whole (:func:`_long_header`), which :func:`glb_chunks` reads as it is; () otherwise."""
    total = _long_header(data)
    if total is None:
        return ()
    return (f"{source + ': ' if source else ''}the binary glTF header's length says {total:,} bytes, the file has "
            f"{len(data):,} and its chunks are whole (the last ends at the file's end): read by its chunks, as "
            f"glTF libraries read it; glTF 2.0 wants the header's length to be the file's (fix it: write "
            f"{len(data):,} in bytes 8 to 11, little-endian, or export the file again)",)


_READS_2 = ("tlm reads glTF 2.0 (convert the file to glTF 2.0: gltf-pipeline -i IN.gltf -o OUT.gltf, for one, "
            "upgrades a 1.0 file, a .glb too)")


def glb_chunks(data: bytes, source: str = "") -> tuple[dict, bytes]:
    """The JSON (parsed) and the BIN chunk (b"" if none) of a binary glTF file. A header whose
    length exceeds the file's by less than 8 bytes, the chunks whole, is read all the same
    (:func:`glb_length_notes` says so); a cut chunk is refused as truncated."""
    if data[:4] != GLB_MAGIC:
        raise InputError("not a binary glTF file (no 'glTF' header)", source=source)
    version = struct.unpack_from("<I", data, 4)[0] if len(data) >= 8 else 2
    if version != 2:  # (glTF 1.0's KHR_binary_glTF: one JSON "content" after a 20-byte header, no chunks)
        raise InputError(f"a binary glTF {version}.0 file (its header says version {version}): {_READS_2}",
                         source=source)
    total = struct.unpack_from("<I", data, 8)[0] if len(data) >= 12 else None
    if len(data) < 20 or (total is not None and total > len(data) and _long_header(data) is None):
        said = f"its header says {total:,} bytes" if total is not None else "its header is cut"
        raise InputError(f"the binary glTF file is truncated: {said}, the file has {len(data):,}", source=source)
    length, kind = struct.unpack_from("<II", data, 12)
    if kind != 0x4E4F534A or 20 + length > len(data):  # "JSON"
        raise InputError("the binary glTF file's first chunk is not its JSON", source=source)
    try:
        header = json.loads(data[20:20 + length])
    except ValueError as exc:
        raise InputError(f"the glTF JSON does not parse ({exc})", source=source) from None
    rest = 20 + length
    binary = b""
    if rest + 8 <= len(data):
        blen, bkind = struct.unpack_from("<II", data, rest)
        if bkind == 0x004E4942:  # "BIN\0"
            if rest + 8 + blen > len(data):
                raise InputError(f"the binary glTF file is truncated: its BIN chunk says {blen:,} bytes, the file "
                                 f"holds {len(data) - rest - 8:,} of them", source=source)
            binary = data[rest + 8: rest + 8 + blen]
    return header, binary


def gltf_buffer_sizes(header: dict, path: Path, binary: bytes | None, source: str) -> list[int | None]:
    """The bytes each of a glTF's ``buffers`` holds: a ``.glb``'s first buffer without a
    ``uri`` its BIN chunk (``binary``; None for a ``.gltf``), a ``data:`` URI its decoded
    bytes, a file its size (by its name, else by its name percent-decoded); None where
    there is nothing to measure. A base64 data URI may hold whitespace (line breaks every 76
    characters, as MIME writes it), which is left out, as glTF libraries do. An InputError
    names a buffer whose file is missing or whose data URI is no base64 (any other character
    outside base64's alphabet, or padding wrong)."""
    import base64
    import binascii
    import re
    from urllib.parse import unquote

    buffers = header.get("buffers")
    out: list[int | None] = []
    for i, b in enumerate(buffers if isinstance(buffers, list) else []):
        uri = b.get("uri") if isinstance(b, dict) else None
        if uri is None:
            out.append(len(binary) if binary is not None and i == 0 else None)
        elif not isinstance(uri, str):
            raise InputError(f"buffers[{i}].uri = {quoted(uri)} is not a string", source=source)
        elif uri.startswith("data:"):
            payload = uri.partition(",")[2]
            try:
                out.append(len(base64.b64decode(re.sub(r"\s+", "", payload, flags=re.ASCII), validate=True))
                           if ";base64" in uri.partition(",")[0]
                           else len(unquote(payload).encode("latin-1", "replace")))
            except (binascii.Error, ValueError):
                raise InputError(f"buffers[{i}].uri: its data URI is not valid base64", source=source) from None
        else:
            found = [f for f in (path.parent / uri, path.parent / unquote(uri)) if f.is_file()]
            if not found:
                raise InputError(f"buffers[{i}].uri {quoted(uri)}: no file {path.parent / unquote(uri)}", source=source)
            out.append(found[0].stat().st_size)
    return out


def check_gltf_buffers(header: dict, sizes: list[int | None], source: str) -> tuple[str, ...]:
    """A glTF's buffers and buffer views, before a library reads them (which fails an
    ``assert`` or reads past the end): each buffer's ``byteLength`` is a count of bytes its
    data (``sizes``, :func:`gltf_buffer_sizes`) holds, each buffer view names a buffer and
    lies inside the bytes its data holds. An InputError names the first that does not (a
    file cut short, a view past its buffer's data). A buffer whose ``byteLength`` is less
    than a view of it reaches, where its data holds those bytes, is read as glTF libraries
    read it (the data's bytes, not its ``byteLength``; the spec calls it invalid) and named
    in the lines returned, for ``Geometry.notes``: one per such buffer."""
    def count(x) -> bool:
        return isinstance(x, int) and not isinstance(x, bool) and x >= 0

    buffers = header.get("buffers")
    buffers = [b if isinstance(b, dict) else {} for b in buffers] if isinstance(buffers, list) else []
    lengths: list[int | None] = []
    held: list[int | None] = []
    whats: list[str] = []
    for i, b in enumerate(buffers):
        have = sizes[i] if i < len(sizes) else None
        length = b.get("byteLength", have)  # (left out, as the spec does not allow: what its data holds)
        uri = b.get("uri")
        whats.append(f"its file {quoted(uri)}" if isinstance(uri, str) and not uri.startswith("data:")
                     else "its data URI" if isinstance(uri, str) else "the BIN chunk")
        lengths.append(length)
        held.append(have)
        if length is None:
            continue
        if not count(length):
            raise InputError(f"buffers[{i}].byteLength = {length!r} is not a count of bytes", source=source)
        if have is not None and length > have:
            raise InputError(f"buffers[{i}].byteLength = {length:,} but {whats[i]} holds {have:,} bytes "
                             "(cut short, or not this glTF's)", source=source)
    notes: dict[int, str] = {}
    views = header.get("bufferViews")
    for j, v in enumerate(views if isinstance(views, list) else []):
        v = v if isinstance(v, dict) else {}
        k = v.get("buffer")
        if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < len(buffers):
            raise InputError(f"bufferViews[{j}].buffer = {k!r} names no entry of 'buffers' (it has {len(buffers)})",
                             source=source)
        offset, length = v.get("byteOffset", 0), v.get("byteLength")
        for key, x in (("byteOffset", offset), ("byteLength", length)):
            if not count(x):
                raise InputError(f"bufferViews[{j}].{key} = {x!r} is not a count of bytes", source=source)
        end = held[k] if held[k] is not None else lengths[k]  # (what a library reads: the data's bytes)
        if end is not None and offset + length > end:
            raise InputError(f"bufferViews[{j}] (bytes {offset:,} to {offset + length:,}) runs past the end of "
                             f"buffers[{k}], which holds {end:,}", source=source)
        if lengths[k] is not None and offset + length > lengths[k] and k not in notes:
            notes[k] = (f"{source}: buffers[{k}].byteLength = {lengths[k]:,} is less than bufferViews[{j}] reaches "
                        f"(bytes {offset:,} to {offset + length:,}): read from the {held[k]:,} bytes {whats[k]} "
                        "holds, as glTF libraries read it; the glTF spec wants byteLength to be the buffer's "
                        "length (fix it in the file)")
    return tuple(notes[k] for k in sorted(notes))


def write_glb(header: dict, binary: bytes = b"") -> bytes:
    """A binary glTF file from its JSON and BIN chunk (padded as the format wants)."""
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary = binary + b"\0" * (-len(binary) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text
    if binary:
        chunks += struct.pack("<II", len(binary), 0x004E4942) + binary
    return struct.pack("<4sII", GLB_MAGIC, 2, 12 + len(chunks)) + chunks


def gltf_json(path: Path, data: bytes | None = None) -> dict:
    """The JSON of a ``.gltf`` or ``.glb`` file."""
    path = Path(path)
    data = path.read_bytes() if data is None else data
    if data[:4] == GLB_MAGIC:
        header = glb_chunks(data, str(path))[0]
    else:
        try:
            header = json.loads(data)
        except ValueError as exc:
            raise InputError(f"the glTF JSON does not parse ({exc})", source=str(path)) from None
    if not isinstance(header, dict):  # (the spec's top level is an object: "asset", "meshes", ...)
        raise InputError(f"the glTF JSON is {_json_kind(header)}, not an object (a glTF's top level is an object "
                         "with 'asset', 'meshes', ...)", source=str(path))
    return header


def _json_kind(value) -> str:
    """A JSON value's kind, in words: "a list", "a number", "null", ..."""
    return ("null" if value is None else "a list" if isinstance(value, list) else "a string" if isinstance(value, str)
            else "a boolean" if isinstance(value, bool) else "a number")


# bytes of a glTF accessor's component type, and components of its element type
_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_TYPE_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def check_gltf(header: dict, source: str) -> None:
    """The references of a glTF's JSON, before a library reads it: every mesh, material,
    accessor and buffer view a primitive, node or accessor names exists, an accessor fits
    its buffer view, and there is a mesh. An InputError names the first that does not
    (a library would say "list index out of range" or fail to reshape)."""
    def count(table: str) -> int:
        v = header.get(table)
        return len(v) if isinstance(v, list) else 0

    def ref(where: str, value, table: str) -> None:
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < count(table):
            raise InputError(f"{where} = {value!r} names no entry of {table!r} (it has {count(table)})",
                             source=source)

    def entries(table: str) -> list:
        v = header.get(table)
        return [e if isinstance(e, dict) else {} for e in v] if isinstance(v, list) else []

    asset = header.get("asset")
    version = asset.get("version") if isinstance(asset, dict) else None
    if isinstance(version, (str, int, float)) and not isinstance(version, bool) \
            and str(version).split(".", 1)[0].strip() != "2":
        raise InputError(f"asset.version {version}: {_READS_2}", source=source)
    if not count("meshes"):
        raise InputError("the glTF has no meshes: nothing to render", source=source)
    for i, node in enumerate(entries("nodes")):
        if "mesh" in node:
            ref(f"nodes[{i}].mesh", node["mesh"], "meshes")
    for i, mesh in enumerate(entries("meshes")):
        prims = mesh.get("primitives")
        for j, prim in enumerate(prims if isinstance(prims, list) else []):
            where = f"meshes[{i}].primitives[{j}]"
            prim = prim if isinstance(prim, dict) else {}
            if "material" in prim:
                ref(f"{where}.material", prim["material"], "materials")
            if "indices" in prim:
                ref(f"{where}.indices", prim["indices"], "accessors")
            attrs = prim.get("attributes")
            for name, a in (attrs.items() if isinstance(attrs, dict) else ()):
                ref(f"{where}.attributes.{name}", a, "accessors")
    views = entries("bufferViews")
    for i, acc in enumerate(entries("accessors")):
        for key, table in (("componentType", _COMPONENT_BYTES), ("type", _TYPE_COMPONENTS)):
            value = acc.get(key)
            if isinstance(value, bool) or not isinstance(value, (int, str)) or value not in table:  # (required)
                raise InputError(f"accessors[{i}].{key} = {value!r} is not a glTF accessor {key} (one of "
                                 f"{', '.join(map(str, table))})", source=source)
        if "bufferView" not in acc:
            continue
        ref(f"accessors[{i}].bufferView", acc["bufferView"], "bufferViews")
        size = _COMPONENT_BYTES.get(acc.get("componentType"), 0) * _TYPE_COMPONENTS.get(acc.get("type"), 0)
        n, offset, length = acc.get("count"), acc.get("byteOffset", 0), views[acc["bufferView"]].get("byteLength")
        if size and all(isinstance(x, int) and not isinstance(x, bool) for x in (n, offset, length)):
            need = offset + n * size
            if n < 0 or need > length:
                raise InputError(f"accessors[{i}].count = {n} needs {need:,} bytes of bufferViews"
                                 f"[{acc['bufferView']}], which holds {length:,}", source=source)


def _numbers(value, n: int, where: str, source: str, default) -> tuple[float, ...]:
    if value is None:
        return tuple(default)
    seq = value if isinstance(value, list) else [value]
    try:
        out = tuple(float(x) for x in seq)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {value!r} is not a number", source=source) from None
    if len(out) < n or not all(math.isfinite(x) for x in out):
        raise InputError(f"{where}: {value!r} is not {n} finite number{'s' if n > 1 else ''}",
                         source=source)
    return out


def gltf_material(m: dict, index: int, source: str = "") -> Material:
    """Map one glTF material (its JSON object) to tlm's kinds, by the module's table."""
    if not isinstance(m, dict):
        raise InputError(f"materials[{index}] is not an object", source=source)
    name = str(m.get("name") or f"material_{index}")
    at = f"material {name!r}"
    pbr = m.get("pbrMetallicRoughness") or {}
    ext = m.get("extensions") or {}
    for key, value in (("pbrMetallicRoughness", pbr), ("extensions", ext)):
        if not isinstance(value, dict):
            raise InputError(f"{at}: {key} is not an object", source=source)
    base = _numbers(pbr.get("baseColorFactor"), 3, f"{at}: baseColorFactor", source, (1.0, 1.0, 1.0))[:3]
    metallic = _numbers(pbr.get("metallicFactor"), 1, f"{at}: metallicFactor", source, (1.0,))[0]
    emissive = _numbers(m.get("emissiveFactor"), 3, f"{at}: emissiveFactor", source, (0.0, 0.0, 0.0))[:3]
    strength = _numbers((ext.get("KHR_materials_emissive_strength") or {}).get("emissiveStrength"), 1,
                        f"{at}: emissiveStrength", source, (1.0,))[0]
    transmission = _numbers((ext.get("KHR_materials_transmission") or {}).get("transmissionFactor"), 1,
                            f"{at}: transmissionFactor", source, (0.0,))[0]
    ior = _numbers((ext.get("KHR_materials_ior") or {}).get("ior"), 1, f"{at}: ior", source,
                   (DEFAULT_IOR,))[0]
    for key, vals in (("baseColorFactor", base), ("emissiveFactor", emissive),
                      ("emissiveStrength", (strength,)), ("metallicFactor", (metallic,))):
        if min(vals) < 0.0:
            raise InputError(f"{at}: {key}: {list(vals)} has a negative value", source=source)
    emission = tuple(e * strength for e in emissive)
    ignored = _gltf_ignored(m, pbr, ext, emits=max(emission) > 0.0)
    if transmission > 0.0:
        if not ior > 0.0:
            raise InputError(f"{at}: KHR_materials_ior: ior {ior:g} is not positive", source=source)
        return Material(name, "dielectric", ior=ior, transmittance=_clip01(base), emission=emission,
                        ignored=ignored)
    if metallic >= 0.5:
        return Material(name, "mirror", reflectance=_clip01(base), emission=emission, ignored=ignored)
    return Material(name, "lambertian", albedo=_clip01(base), emission=emission, ignored=ignored)


def _gltf_ignored(m: dict, pbr: dict, ext: dict, emits: bool = False) -> tuple[str, ...]:
    """What of a glTF material changes its look and is not rendered (the module's docstring)."""
    out = [k for k in (*m, *pbr) if k.endswith("Texture")]
    for name, body in ext.items():
        if name == _SPEC_GLOSS and "metallicFactor" not in pbr:  # (what it becomes: glTF's defaults)
            out.append(f"{name} (read as its fallback pbrMetallicRoughness, whose metallicFactor defaults to 1: "
                       "a mirror)")
        elif name not in _GLTF_READ:
            out.append(name)
        elif isinstance(body, dict):
            out += [k for k in body if k.endswith("Texture")]
    factor = pbr.get("baseColorFactor")
    alpha = float(factor[3]) if isinstance(factor, list) and len(factor) > 3 else 1.0
    if alpha < 1.0:
        out.append("alpha")
    if m.get("alphaMode", "OPAQUE") != "OPAQUE":
        out.append("alphaMode")
    if m.get("doubleSided") is True and emits:
        out.append("doubleSided emission")  # (a tlm emitter emits from its front only)
    return tuple(dict.fromkeys(out))


def gltf_materials(header: dict, source: str = "") -> list[Material]:
    """Every material of a glTF file's JSON, by index."""
    mats = header.get("materials") or []
    if not isinstance(mats, list):
        raise InputError("'materials' is not a list", source=source)
    # (each one's origin, for results.json's scene.materials: Material.origin)
    return [gltf_material(m, i, source).with_origin(f"{source} materials[{i}]" if source else "")
            for i, m in enumerate(mats)]
