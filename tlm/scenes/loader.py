"""Scene files: YAML in, a checked :class:`~tlm.scenes.model.Scene` out.

A scene file names its geometry (a built-in builder or a mesh that trimesh loads),
maps the geometry's parts to materials, and lists the lights, the camera, the
resolution and the default photon count. A glTF of the geometry gives its point, spot
and directional lights when the scene file (with its ``extends:``) has no ``lights:`` key,
and its first perspective camera when it has no ``camera:`` key; a line each says which.
The lights are read and built by :mod:`tlm.scenes.lights`. The built-in scenes are the
files in the repository's ``scenes/`` folder (shipped inside the wheel as ``tlm/_scenes``).

Every problem is an :class:`~tlm.errors.InputError` naming the file, the key and the
value: unknown keys (with a "did you mean"), wrong types, unknown materials, NaN or
infinite vertices, an empty mesh, a resolution that cannot fit in memory, a scene (its
transform applied) too large or too small for the float32 ray-triangle test
(:func:`check_float32_range`).
"""

from __future__ import annotations

import errno
import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from tlm.config import builtin_scenes_dir, deep_merge, read_yaml
from tlm.config_paths import scene_file_hint
from tlm.config_read import nameless
from tlm.config_words import listing
from tlm.errors import InputError, did_you_mean, path_shown, quoted
from tlm.mesh_files import mesh_file_format, mesh_file_hint, mesh_file_missing
from tlm.scenes import cache
from tlm.scenes.chain import Files, add_file, blamed, note_given, nulls, parts_removed, stale_parts
from tlm.scenes.chain import origin as _origin
from tlm.scenes.chain import record as _record
from tlm.scenes.float32_range import (  # noqa: F401  (the old names, still importable from here)
    F32_MARGIN,
    F32_MAX,
    F32_TINY,
    SIZE_HI,
    SIZE_LO,
    check_float32_range,
    float32_sizes,
)
from tlm.scenes.lights import mesh_light as mesh_light  # (kept importable from here: tlm.render.checks names it)
from tlm.scenes.lights import scaled_light, scene_lights, typed, with_mesh_light
from tlm.scenes.model import Camera, Geometry, Material, Scene
from tlm.scenes.normals import DEFAULT_CREASE_ANGLE, crease_normals
from tlm.scenes.shapes import machine_memory
from tlm.scenes.validate import MAX_MAGNITUDE
from tlm.scenes.validate import keys as _keys
from tlm.scenes.validate import mapping as _mapping
from tlm.scenes.validate import num as _num
from tlm.scenes.validate import shown as _shown
from tlm.scenes.validate import vec as _vec

SCENE_KEYS = (
    "name", "description", "geometry", "materials", "parts", "default_material",
    "lights", "camera", "resolution", "photons", "transform", "extends", "crease_angle",
)
MATERIAL_KEYS = {
    "lambertian": ("type", "albedo", "emission"),
    "mirror": ("type", "reflectance", "emission"),
    "dielectric": ("type", "ior", "transmittance", "emission"),
}
# the key each material type cannot do without, and what it takes (the others have defaults)
MATERIAL_REQUIRED = {"lambertian": ("albedo", "[r, g, b] in [0, 1]"), "mirror": ("reflectance", "[r, g, b] in [0, 1]"),
                     "dielectric": ("ior", "a number > 0")}
CAMERA_KEYS = ("eye", "target", "up", "vfov")
# the camera's keys without a default, and what they take
CAMERA_REQUIRED = (("eye", "[x, y, z], where the camera is"), ("target", "[x, y, z], the point seen at the image's "
                   "centre"), ("vfov", "the vertical field of view in degrees, in (0, 179]"))
BYTES_PER_PIXEL = 4096  # generous bound on every per-pixel buffer of a run, all passes


def scenes_dir() -> Path:
    """Where the built-in scene files are: inside the wheel, or the repository's
    (:func:`tlm.config.builtin_scenes_dir`, where a config's ``scene`` is read)."""
    return builtin_scenes_dir()


def list_scenes() -> list[str]:
    """The built-in names: every ``.yaml`` under the scenes folder, by its relative path
    without the suffix (``cornell``, ``thesis/ring``, ``examples/mesh_on_floor``)."""
    root = scenes_dir()
    return sorted(
        p.relative_to(root).with_suffix("").as_posix() for p in root.rglob("*.yaml")
        if p.is_file() and not any(q.startswith((".", "_")) for q in p.relative_to(root).parts)
    )


BAD_ON_PURPOSE = "# Bad input"  # how a built-in scene of bad input on purpose begins (a test of an error message)


def listed_scenes() -> list[str]:
    """The built-in names ``tlm scene list`` and a not-found error list: not the scenes of bad
    input on purpose (their first line begins :data:`BAD_ON_PURPOSE`), which are still built-in
    scenes by name."""
    root = scenes_dir()

    def on_purpose(name: str) -> bool:
        try:
            with open(root / f"{name}.yaml", encoding="utf-8") as f:
                return f.readline().startswith(BAD_ON_PURPOSE)
        except (OSError, UnicodeDecodeError):
            return False

    return [n for n in list_scenes() if not on_purpose(n)]


def resolve_scene_path(ref: str | os.PathLike, base: Path | None = None, config_source: str | None = None,
                       key: str = "scene", also: tuple[Path, ...] = ()) -> Path:
    """A built-in name (``cornell``) or a path (a ``str`` or a :class:`~pathlib.Path`): a
    relative path is tried relative to ``base`` (none: the cwd), then to each folder of
    ``also``, then relative to the working folder (a project's config that names its scene
    from the project's root, run from there; a scene file's ``extends`` alike), then among the
    built-in scenes (``thesis/ring.yaml``), as before absolute paths: a project's own
    ``ring.yaml`` is not replaced by the built-in one. A path written as a built-in scene's
    name (``thesis/ring``) is that scene. A file's ``scene`` is made absolute where the config
    is read, looked for in the same order (:func:`tlm.config.scene_from`); a path not found
    names the folders tried, in that order.

    ``config_source`` names the file the reference came from and ``key`` the key that
    gave it (``scene``, a scene file's ``extends``), for error messages; a mesh file given
    by itself (``config_source`` is ``ref``: ``tlm scene show pawn.obj``) is named once,
    without a key it was not given under; one that is in none of the folders looked in is said not
    found first, what its name makes it after (:func:`~tlm.mesh_files.mesh_file_missing`).
    """
    ref = os.fspath(ref) if isinstance(ref, os.PathLike) else ref
    if isinstance(ref, str) and (format_ := mesh_file_format(ref, content=False)) is not None:  # (by its name)
        by_itself = config_source == ref  # (given by itself: `tlm scene show pawn.glb`, load_scene("pawn.glb"))
        folders = _mesh_folders(ref, base, also)
        if folders is not None:  # (not there: said first, as for a scene file; what its name is after; a built-in
            # scene's name with a mesh's suffix, cornell.obj, is asked about as a scene file's name is)
            looked = f" (looked in {', '.join(map(path_shown, folders))})" if folders else ""
            stem = os.path.splitext(ref)[0]
            stem = os.path.splitext(stem)[0] if mesh_file_format(stem, content=False) is not None else stem
            raise InputError(f"{'file' if by_itself else quoted(ref)} not found{looked}; {mesh_file_missing(format_)}"
                             f"{did_you_mean(stem, list_scenes())}",
                             source=ref if by_itself else config_source, key=None if by_itself else key)
        if by_itself:  # (named once)
            raise InputError(mesh_file_hint(ref, format_, ""), source=ref)
        raise InputError(mesh_file_hint(ref, format_, key, base), source=config_source, key=key)
    yaml_file = ref.lower().endswith((".yaml", ".yml"))  # (Scene.YAML too: a file system may keep the case)
    looks_like_path = yaml_file or "/" in ref or os.sep in ref
    if looks_like_path and not yaml_file and (scenes_dir() / f"{ref}.yaml").is_file():
        return scenes_dir() / f"{ref}.yaml"  # a built-in scene of a subfolder: thesis/ring
    if looks_like_path:
        p = Path(ref)
        tried = [] if p.is_absolute() else [Path.cwd() if base is None else Path(base), *map(Path, also)]
        odd = None  # (the first path tried that is there but is no file to read: named if none is found)
        for cand in [p if base is None or p.is_absolute() else Path(base) / p] + [f / p for f in tried[1:]]:
            if cand.is_file():
                return cand
            odd = odd or (cand if os.path.lexists(cand) else None)
        if tried and base is not None and (Path.cwd() / p).is_file():
            return Path.cwd() / p  # (the working folder, before the built-in scenes: a project's own ring.yaml)
        if not p.is_absolute() and (scenes_dir() / p).is_file():
            return scenes_dir() / p  # thesis/ring.yaml
        stem = ref[: -len(p.suffix)] if p.suffix.lower() in (".yaml", ".yml") else ref
        folders = list(dict.fromkeys(os.path.abspath(f) for f in tried))
        cwd = os.path.abspath(Path.cwd())
        if folders and cwd not in folders:
            folders.append(cwd)  # (the working folder, before the built-in scenes)
        looked = f" (looked in {', '.join(map(path_shown, folders))} and among the built-in scenes)" if folders else ""
        if odd is not None:
            named = "" if os.path.abspath(odd) == os.path.abspath(ref) else f": {odd}"
            if config_source == ref and not named:  # (given by itself, `tlm scene show /dev/null`: named once, as
                # the file, without a key it was not given under, as a mesh file given by itself is)
                raise InputError(f"is {_not_a_file(odd)}, not a scene file{_save_it(odd)}", source=ref)
            raise InputError(f"scene file {quoted(ref)}{named} is {_not_a_file(odd)}, not a scene file{_save_it(odd)}",
                             source=config_source, key=key)
        raise InputError(f"scene file {quoted(ref)} not found{looked}{did_you_mean(stem, list_scenes())}"
                         f"{_moved_run(ref, config_source, key)}", source=config_source, key=key)
    builtin = scenes_dir() / f"{ref}.yaml"
    if builtin.is_file():
        return builtin
    folders = [Path.cwd() if base is None else Path(base), *map(Path, also)]  # (a scene file of that name there:
    raise InputError(  # how to give it, h451; a name given by itself, tlm scene show myroom: its path alone, h455)
        f"{quoted(ref)} is not a built-in scene ({', '.join(listed_scenes())}){did_you_mean(ref, listed_scenes())}"
        f"{scene_file_hint(ref, folders, by_itself=config_source == ref)}",
        source=config_source, key=key,
    )


def _moved_run(ref: str, config_source: str | None, key: str) -> str:
    """What to do where a run folder's ``config.resolved.yaml`` names a ``scene`` file by an absolute path not here
    (none where a ``--set scene=`` gave the path on top of it: the file's own ``scene:`` is another)."""
    config, given = str(config_source).split(", with ")[0], str(config_source)
    if key != "scene" or os.path.basename(config) != "config.resolved.yaml" or not os.path.isabs(ref) or (
            config != given and os.path.isfile(config) and dict(read_yaml(Path(config))).get("scene") != ref):
        return ""
    return ("; a run folder's config.resolved.yaml names its scene file by the absolute path it had where the run "
            "was made: was the project moved, or the folder copied from elsewhere? give the file as it is now, "
            "--set scene=PATH")


def _mesh_folders(ref: str, base: Path | None, also: tuple[Path, ...]) -> list[str] | None:
    """None where the mesh file ``ref`` (given where a scene goes) is there, in a folder
    :func:`resolve_scene_path` looks in for a scene file (``base``, else the working folder; each of
    ``also``; the working folder), as anything (a folder, a dangling link: its hint says what it
    is; one of the built-in scenes' own, ``meshes/CornellBox-Original.obj``, too); else the folders looked in
    (none: an absolute ``ref``)."""
    p = Path(ref)
    if p.is_absolute():
        return None if os.path.lexists(p) else []
    folders = list(dict.fromkeys(os.path.abspath(f) for f in (Path.cwd() if base is None else Path(base), *also,
                                                               Path.cwd())))
    return None if any(os.path.lexists(Path(f) / p) for f in (*folders, scenes_dir())) else folders


def _not_a_file(path: Path) -> str:
    """What a path that is there but not a readable file is, in words."""
    if path.is_dir():
        return "a folder"
    if path.is_symlink():
        if _piped(path):  # (/dev/stdin, <(...)'s /dev/fd/63: /proc's link names 'pipe:[N]', which no path is)
            return "a pipe (a file descriptor's name)"
        try:
            path.resolve(strict=True)
        except (RuntimeError, OSError) as exc:  # (a loop: RuntimeError up to Python 3.12, OSError ELOOP after)
            if isinstance(exc, RuntimeError) or getattr(exc, "errno", None) == errno.ELOOP:
                return "a symbolic link that leads round in a loop"
            return f"a symbolic link to {quoted(os.readlink(path))}, which is not there"
    return "a special file (a device, a pipe or a socket)"


def _piped(path: Path) -> bool:
    """Whether ``path`` leads to a pipe or a socket (read once: its text is gone, and a render reads a scene again):
    :func:`tlm.config_read.nameless`, through /proc's descriptor links, which a path's resolve does not follow."""
    return nameless(path) in ("a pipe", "a named FIFO")


def _save_it(path: Path) -> str:
    """What a scene given as a pipe (:func:`_piped`) is to be instead, after its "not a scene file"; else nothing."""
    return (": a scene is read by its file's name (again by a render, its extends: and meshes from its folder): save "
            "it to a file and name that") if path.is_symlink() and _piped(path) else ""


def _material(name: str, raw: Any, src: str) -> Material:
    key = f"materials.{name}"
    raw, kind = typed(raw, src, key, MATERIAL_KEYS)
    need, what = MATERIAL_REQUIRED[kind]  # (missing also where extends: gave the base's material another type)
    if need not in raw:
        raise InputError(f"required for type {kind}: {what}", source=src, key=f"{key}.{need}")
    emission = _vec(raw.get("emission", [0.0, 0.0, 0.0]), src, f"{key}.emission", lo=0.0)
    if kind == "lambertian":
        albedo = _vec(raw.get("albedo"), src, f"{key}.albedo", lo=0.0, hi=1.0)
        return Material(name, kind, albedo=albedo, emission=emission)
    if kind == "mirror":
        refl = _vec(raw.get("reflectance"), src, f"{key}.reflectance", lo=0.0, hi=1.0)
        return Material(name, kind, reflectance=refl, emission=emission)
    ior = _num(raw.get("ior"), src, f"{key}.ior", lo=0.0, lo_exclusive=True)
    trans = _vec(raw.get("transmittance", [1.0, 1.0, 1.0]), src, f"{key}.transmittance", lo=0.0, hi=1.0)
    return Material(name, kind, ior=ior, transmittance=trans, emission=emission)


def _geometry(raw: Any, src: str, path: Path, items: list | None = None) -> Geometry:
    """``geometry:``, one item (builder, mesh or shape) or a list of them, each with an
    optional ``transform`` and ``name`` (:mod:`tlm.scenes.compose`; ``items``: its items' sources)."""
    from tlm.scenes.compose import compose_geometry

    return compose_geometry(raw, src, path, items)


def _check_triangles(tri: np.ndarray, src: str, key: str = "geometry") -> None:
    if tri.ndim != 3 or tri.shape[1:] != (3, 3):
        raise InputError(f"triangles have shape {tri.shape}, expected (n, 3, 3)", source=src, key=key)
    if tri.shape[0] == 0:
        raise InputError("the geometry has no triangles", source=src, key=key)
    bad = ~np.isfinite(tri).all(axis=(1, 2))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{int(bad.sum())} triangle(s) have NaN or infinite vertices (first: triangle {i}, "
            f"{tri[i].tolist()})",
            source=src, key=key,
        )
    far = (np.abs(tri) > MAX_MAGNITUDE).any(axis=(1, 2))
    if far.any():  # (a transform's scale on a mesh's coordinates: each finite, their product not)
        i = int(np.flatnonzero(far)[0])
        raise InputError(f"{int(far.sum())} triangle(s) have a coordinate beyond +-{MAX_MAGNITUDE:g}, the bound "
                         f"that keeps products of the scene's numbers finite in float64 (first: triangle {i}, "
                         f"{tri[i].tolist()})", source=src, key=key)


def check_resolution(width: int, height: int, src: str, key: str = "resolution") -> None:
    if width <= 0 or height <= 0:
        raise InputError(f"[{width}, {height}] must be positive", source=src, key=key)
    need = width * height * BYTES_PER_PIXEL
    total = machine_memory()
    if need > total:
        raise InputError(
            f"[{width}, {height}] needs about {need / 2**30:.0f} GiB, more than this machine's "
            f"{total / 2**30:.0f} GiB",
            source=src, key=key,
        )


def read_scene_tree(path: Path, seen: tuple[Path, ...], given: dict[str, Path] | None = None,
                    origins: dict[str, Path] | None = None, files: list[Path] | None = None) -> tuple[dict, Path]:
    """The scene file's mapping with its ``extends:`` chain merged in, and the file whose
    ``geometry`` it uses (a mesh path is relative to the file that names it). ``given``, where
    passed, gets each ``materials:`` entry's name -> the file of the chain that gave it last (this
    file where it names the entry, else the base's that does): an entry only inherited is not
    this file's to check (:func:`_check_unused`). ``origins``, where passed, gets each key of the
    merged mapping, dotted (``geometry.transform.scale``; a list's is its key's), -> the file of
    the chain that gave it last, for naming that file in an error on it (:func:`tlm.scenes.chain.origin`);
    ``files``, where passed, the files of the chain, base first (:func:`tlm.scenes.chain.stale_parts`).

    ``extends: NAME_OR_PATH`` starts from another scene file; this file's keys replace
    the base's, and mappings (``materials``, ``parts``, ``camera``, a material's fields)
    merge key by key, so ``materials: {glass: {ior: 1.0}}`` changes one number. A material
    given another ``type`` is replaced whole (a mirror takes none of a glass's fields). A
    one-item ``geometry`` that names no ``mesh`` merges into the base's, whose mesh path
    stays relative to the base. A material given as null (``materials: {chrome: null}``) removes the
    base's material of that name (one the base does not give is an error, as is a null in a file that
    extends none), a ``parts:`` entry as null the base's entry; a ``lights:`` list replaces the base's whole.
    """
    src = str(path)
    raw = read_yaml(path)
    if raw is None:  # (as a config file: tlm.config)
        raise InputError("is empty (nothing but comments or blanks) or a bare null: a scene file needs `geometry:` "
                         "at least (docs/scenes.md)", source=src)
    raw = _mapping(raw, src, "")
    if "scene" in raw and "geometry" not in raw and "extends" not in raw:  # (a run config named as a scene)
        raise InputError(f"is a run config (it names `scene: {raw['scene']}`), not a scene file: a config's `scene:` "
                         "names a built-in scene or a scene file (with `geometry:`)", source=src)
    _keys(raw, SCENE_KEYS, src, "")
    own = raw.get("materials")
    if "extends" not in raw:
        for name in nulls(own):  # (nothing to remove: a null here is a mistake, said as such)
            raise InputError("null removes an inherited material, and this file extends no scene (extends:): give the "
                             "material's fields, or leave it out", source=src, key=f"materials.{name}")
        note_given(given, own, path)
        _record(origins, raw, {}, path)
        if files is not None:
            add_file(files, path, raw.get("geometry"), path)
        return raw, path
    ref = raw.pop("extends")
    if not isinstance(ref, str) or not ref:
        raise InputError(f"{quoted(ref)} must be a scene name or a scene file path", source=src, key="extends")
    base_path = resolve_scene_path(ref, path.parent, src, key="extends")
    if base_path.resolve() in seen or base_path.resolve() == path.resolve():
        chain = "".join(f" through {p.name}" for p in seen)
        raise InputError(f"{quoted(ref)} extends itself{chain}", source=src, key="extends")
    base, geom_path = read_scene_tree(base_path, (*seen, path.resolve()), given, origins, files)
    note_given(given, own, path)
    geometry = raw.get("geometry")
    if "geometry" in raw and not (isinstance(geometry, dict) and isinstance(base.get("geometry"), dict)
                                  and "mesh" not in geometry):
        geom_path = path  # (this file names the geometry's mesh, or replaces the geometry)
    mats, base_mats = raw.get("materials"), base.get("materials")
    inherited = list(base_mats) if isinstance(base_mats, dict) else []
    for name in nulls(mats):
        if name not in inherited:
            raise InputError(f"null removes an inherited material, and {base_path} (extends:) gives none named "
                             f"{quoted(name)}{did_you_mean(str(name), [str(k) for k in inherited])}", source=src,
                             key=f"materials.{name}")
    if isinstance(mats, dict) and isinstance(base_mats, dict):
        retyped = {k for k, v in mats.items() if isinstance(v, dict) and "type" in v
                   and isinstance(base_mats.get(k), dict) and base_mats[k].get("type") != v["type"]}
        base = {**base, "materials": {k: v for k, v in base_mats.items() if k not in retyped}}
    merged = deep_merge(base, raw)
    _record(origins, raw, base, path)
    parts_removed(merged, raw, base)
    if files is not None:
        add_file(files, path, merged.get("geometry"), geom_path)
    if nulls(mats):  # (an inherited material given as null: taken out)
        merged["materials"] = {k: v for k, v in merged["materials"].items() if v is not None}
    return merged, geom_path


def load_scene(
    ref: str | os.PathLike, base: Path | None = None, resolution: list[int] | None = None,
    config_source: str | None = None,
) -> Scene:
    """Load a built-in scene by name or a scene file by path (a ``str`` or a :class:`~pathlib.Path`).

    ``resolution`` overrides the scene's; ``config_source`` names the file (or
    ``--set``) that gave ``ref`` and ``resolution``, for error messages.
    """
    path = resolve_scene_path(ref, base, config_source)
    given: dict[str, Path] = {}
    origins: dict[str, Path] = {}
    files = Files()  # (and each one's geometry: stale_parts)
    raw, geom_path = read_scene_tree(path, (), given, origins, files)
    try:
        return _scene(path, raw, geom_path, given, resolution, config_source, origins, files)
    except InputError as e:  # (on a key of an extends: chain: named against the file that gave it)
        if not e.key or e.source not in (str(path), str(geom_path)):
            raise
        named = blamed(e, raw, origins, files, path)  # (None: e names the file that gave its key)
        if named is None:
            raise
        raise named from None


def _scene(path: Path, raw: dict, geom_path: Path, given: dict[str, Path], resolution: list[int] | None,
           config_source: str | None, origins: dict[str, Path], files: list[Path]) -> Scene:
    """:func:`load_scene` of the scene file ``path``, read (:func:`read_scene_tree`) as ``raw`` (``origins``: the
    file of its ``extends:`` chain, ``files``, that gave each key)."""
    src = str(path)
    if "geometry" not in raw:
        raise InputError("missing (builder or mesh)", source=src, key="geometry")
    items: list = []  # (each item's source and part names: what a base's geometry listed again names, stale_parts)
    geom = _geometry(raw["geometry"], str(geom_path), geom_path, items)
    tri = np.asarray(geom.triangles, dtype=np.float64)
    _check_triangles(tri, src)

    inherited = {name: str(f) for name, f in given.items() if f != path}  # (through extends:)
    raw, stale = stale_parts(raw, tuple(geom.part_names), origins, files, src, items,  # (a base's, of parts gone)
                             lambda p, given: _a_file_material(str(p), tuple(geom.materials), given))
    materials, material_index, unused = _assign_materials(raw, geom, src, inherited)
    part = np.asarray(geom.part, dtype=np.int32)

    lights, notes = scene_lights(raw, geom, src, str(_origin(origins, "lights") or path))
    notes = [*stale, *unused, *notes]
    view, camera_notes = _camera(raw, geom, src)

    res = resolution if resolution is not None else raw.get("resolution")
    res_src = (config_source or "(config)") if resolution is not None else src
    if res is None and "resolution" not in raw:
        raise InputError("required: [width, height] in whole pixels (or the config's resolution)", source=src,
                         key="resolution")
    whole = isinstance(res, (list, tuple)) and all(isinstance(x, int) and not isinstance(x, bool) for x in res)
    if not (whole and len(res) == 2):
        raise InputError(f"{res!r} is not [width, height] in whole pixels", source=res_src, key="resolution")
    check_resolution(res[0], res[1], res_src)
    photons = raw.get("photons", 0)
    if not isinstance(photons, int) or isinstance(photons, bool) or photons < 0:
        raise InputError(f"{photons!r} must be a whole number >= 0", source=src, key="photons")

    scale, translate = 1.0, (0.0, 0.0, 0.0)
    if raw.get("transform") is not None:
        tr = _mapping(raw["transform"], src, "transform")
        if "rotate" in tr:
            raise InputError("the scene's transform takes scale and translate; rotate geometry with a "
                             "geometry item's transform (docs/scenes.md)", source=src, key="transform.rotate")
        _keys(tr, ("scale", "translate"), src, "transform")
        scale = _num(tr.get("scale", 1.0), src, "transform.scale", lo=0.0, lo_exclusive=True)
        translate = _vec(tr.get("translate", [0.0, 0.0, 0.0]), src, "transform.translate")
    camera = replace(view, width=res[0], height=res[1])
    notes += camera_notes + _aspect_note(geom, res, "camera" in raw)
    crease = _num(raw.get("crease_angle", DEFAULT_CREASE_ANGLE), src, "crease_angle", lo=0.0, hi=180.0)
    normals = geom.normals
    if normals is not None and not np.isfinite(normals).all():
        raise InputError("the mesh's vertex normals are not finite", source=str(geom_path), key="geometry.mesh")
    if normals is None or "crease_angle" in raw:  # the scene's crease angle overrides the file's normals
        normals = cache.crease_normals(tri, geom.part, crease, crease_normals)
    for key in ("name", "description"):  # (words: `name: [1]` is not the name "[1]")
        if key in raw and not isinstance(raw[key], str):
            raise InputError(f"{_shown(raw[key])} is not text (quote it: {key}: \"...\")", source=src, key=key)
    scene = Scene(
        name=str(raw.get("name", path.stem)),
        triangles=tri,
        material_index=material_index,
        materials=materials,
        part=part,
        part_names=tuple(geom.part_names),
        lights=lights,
        camera=camera,
        photons=photons,
        source=src,
        extra={"description": str(raw.get("description", "")), "crease_angle": crease,
               "normals": "file" if normals is geom.normals else "crease",
               # (a note is a line naming its file as given: its control characters shown as path_shown shows a
               # path's, a tab as \t, where a warning line would make it a space and obey an escape sequence)
               "notes": [path_shown(n) for n in (*geom.notes, *notes)]},
        normals=normals,
    )
    if scale != 1.0 or translate != (0.0, 0.0, 0.0):
        scene = transform_scene(scene, scale, np.asarray(translate))
        _check_triangles(scene.triangles, src, "transform")  # (each number finite, their product not)
    # the final geometry, transform applied
    check_float32_range(scene, src, "transform.scale" if raw.get("transform") is not None else "geometry", scale)
    return with_mesh_light(scene)


def _camera(raw: dict, geom: Geometry, src: str) -> tuple[Camera, list[str]]:
    """The scene's camera (its width and height 0: the resolution gives them): the scene file's
    ``camera:`` when it gives the key, else the first mesh file's perspective camera
    (:attr:`Geometry.imports`, in the geometry's order); and a line per mesh file with a
    perspective camera saying whether it is used."""
    files = [i for i in geom.imports if i.camera is not None]
    if "camera" not in raw and files:
        first = files[0]
        cam = first.camera
        where = first.camera_name
        if not cam.vfov <= 179.0:
            raise InputError(f"{where}: its yfov ({cam.vfov:.4g} degrees) is over tlm's 179 degrees",
                             source=first.source)
        for p in (cam.eye, cam.target, cam.up):
            if not (np.isfinite(p).all() and np.abs(p).max() <= MAX_MAGNITUDE):
                raise InputError(f"{where}: its eye {list(cam.eye)}, view direction or up (with the geometry item's "
                                 f"transform) is not finite or is beyond +-{MAX_MAGNITUDE:g}", source=first.source)
        fwd = np.subtract(cam.target, cam.eye)
        if not (np.linalg.norm(fwd) > 0 and np.linalg.norm(np.cross(fwd, cam.up))
                > 1e-12 * np.linalg.norm(fwd) * np.linalg.norm(cam.up)):
            raise InputError(f"{where}: the geometry item's transform leaves it no view direction or up",
                             source=first.source)
        notes = [f"{first.source}: its camera {where} is the scene's camera (vfov {cam.vfov:.6g} degrees): the "
                 "scene file gives no camera:"]
        notes += [f"{i.source}: its camera {i.camera_name} is not used: the scene's camera is {first.source}'s "
                  f"{first.camera_name}" for i in files[1:] if (i.source, i.camera_name) != (first.source, where)]
        return cam, list(dict.fromkeys(notes))
    if "camera" not in raw:
        raise InputError("missing: give camera: {eye, target, vfov} (no mesh file of the geometry has a perspective "
                         "camera to import)", source=src, key="camera")
    cam_raw = _mapping(raw.get("camera"), src, "camera")
    _keys(cam_raw, CAMERA_KEYS, src, "camera")
    for need, what in CAMERA_REQUIRED:
        if need not in cam_raw:
            raise InputError(f"required: {what}", source=src, key=f"camera.{need}")
    eye = _vec(cam_raw.get("eye"), src, "camera.eye")
    target = _vec(cam_raw.get("target"), src, "camera.target")
    up = _vec(cam_raw.get("up", [0.0, 1.0, 0.0]), src, "camera.up")
    vfov = _num(cam_raw.get("vfov"), src, "camera.vfov", lo=0.0, hi=179.0, lo_exclusive=True)
    fwd = np.subtract(target, eye)
    if not np.linalg.norm(fwd) > 0:
        raise InputError("eye and target coincide", source=src, key="camera")
    if not np.linalg.norm(np.cross(fwd, up)) > 1e-12 * np.linalg.norm(fwd) * np.linalg.norm(up):
        raise InputError(f"up {list(up)} is parallel to the view direction", source=src, key="camera.up")
    notes = [f"{i.source}: its camera {i.camera_name} is not used: the scene file gives camera: (leave camera: out "
             "to import it)" for i in files]
    return Camera(eye, target, up, vfov, 0, 0), list(dict.fromkeys(notes))


def _aspect_note(geom: Geometry, res: list[int], given: bool) -> list[str]:
    """A line when the imported camera's ``aspectRatio`` is not the resolution's."""
    first = next((i for i in geom.imports if i.camera is not None), None)
    if given or first is None or first.aspect is None:
        return []
    ratio = res[0] / res[1]
    if abs(first.aspect - ratio) <= 1e-3 * ratio:
        return []
    return [f"{first.source}: its camera {first.camera_name} has aspectRatio {first.aspect:.6g}, not the "
            f"resolution's {ratio:.6g} ({res[0]}x{res[1]}): the horizontal field of view follows the resolution"]


def _a_file_material(name: str, file_mats: tuple[Material, ...], given: Any = None) -> str:
    """What a ``parts:`` entry that names no part adds where its name is a material of the mesh
    files (``parts: {tallBox: ...}`` on ``CornellBox-Original``, whose ``tallBox`` is a material
    and no part): a material is replaced under ``materials:`` (``given``: the entry's value, a
    material's name whose fields to give there); "" for another name."""
    if not any(name in (m.name, m.alias) for m in file_mats):
        return ""
    how = f"`materials: {{{name}: ...}}` with the fields of {quoted(given)}" if isinstance(given, str) else \
        f"`materials: {{{name}: {{type: ..., ...}}}}`"
    return (f"; {quoted(name)} is a material of the mesh file, not a part: to change the triangles that take it, "
            f"replace it under materials: ({how})")


def _assign_materials(raw: dict, geom: Geometry, src: str, inherited: dict[str, str] | None = None
                      ) -> tuple[tuple[Material, ...], np.ndarray, list[str]]:
    """The scene's materials, each triangle's index into them, and a line per ``materials:``
    entry no triangle can take where the geometry's files name no material, or where the entry
    is only inherited through ``extends:`` (``inherited``: its name -> the file that gave it;
    :func:`_check_unused`).

    A triangle takes, in order of precedence: its part's material under ``parts:``;
    the material the mesh file gives it (a ``materials:`` entry of the same name
    replaces the file's: of the name its file gives it, where two files name one and the
    second's was renamed ``NAME_2``); ``default_material``. The file's materials come
    first, in the file's order, then the scene file's others. A material a file's faces
    name but its libraries do not define (``Material.undefined``) takes the scene file's
    entry of that name, else its faces take ``default_material``, else it is the error.
    """
    materials_raw = _mapping(raw.get("materials") or {}, src, "materials")
    file_mats = tuple(geom.materials)
    if not materials_raw and not file_mats:
        raise InputError("no materials defined (and the geometry's file defines none)", source=src, key="materials")
    # (each entry's origin: the file of the extends: chain that gave it, for results.json's scene.materials)
    yaml_mats = {str(k): replace(_material(str(k), v, src), origin=f"{(inherited or {}).get(str(k), src)}: "
                                 f"materials.{k}") for k, v in materials_raw.items()}
    chosen: list[Material] = []
    remap = np.full(len(file_mats) + 1, -1, dtype=np.int32)  # file material -> scene material (the last: none)
    undefined: dict[int, str] = {}  # scene material -> why its file's faces name it and no library defines it
    for j, m in enumerate(file_mats):
        name = m.name if m.name in yaml_mats else m.alias if m.alias in yaml_mats else None
        pick = yaml_mats[name] if name is not None else m
        if name is not None and any(c is pick for c in chosen):  # (one entry replaces every file's of its name)
            remap[j] = next(i for i, c in enumerate(chosen) if c is pick)
            continue
        remap[j] = len(chosen)
        if name is None and m.undefined:
            undefined[len(chosen)] = m.undefined
        chosen.append(pick)
    materials = tuple(chosen) + tuple(m for m in yaml_mats.values() if not any(c is m for c in chosen))
    names = [m.name for m in materials]
    parts_raw = _mapping(raw.get("parts") or {}, src, "parts")
    default = raw.get("default_material")
    if default is not None and default not in names:
        raise InputError(f"{quoted(default)} is not a material{did_you_mean(str(default), names)}",
                         source=src, key="default_material")
    for p in parts_raw:
        if p not in geom.part_names:
            raise InputError(
                f"the geometry has no part {quoted(p)} (parts: {', '.join(geom.part_names)})"
                f"{_a_file_material(str(p), file_mats, parts_raw[p]) or did_you_mean(str(p), geom.part_names)}",
                source=src, key=f"parts.{p}",
            )
    # per part: the scene file's material, or -1 (the file's material, else the default); a parts: value
    # checked first (a typo there leaves its material unused: the typo is the error, not the entry)
    part_material = np.full(len(geom.part_names), -1, dtype=np.int32)
    for i, p in enumerate(geom.part_names):
        m = parts_raw.get(p)
        if m is None:
            continue
        if m not in names:
            raise InputError(f"{quoted(m)} is not a material{did_you_mean(str(m), names)}",
                             source=src, key=f"parts.{p}")
        part_material[i] = names.index(m)
    unused = _check_unused(yaml_mats, file_mats, parts_raw, default, src, inherited or {})
    part = np.asarray(geom.part, dtype=np.int32)
    material_index = part_material[part]
    if geom.face_material is not None and file_mats:
        face = remap[np.asarray(geom.face_material, dtype=np.int32)]  # (-1, "none", indexes remap's last)
        material_index = np.where(material_index < 0, face, material_index)
    missing = [i for i in undefined if (material_index == i).any()]
    if default is not None and names.index(default) in undefined:
        missing = [names.index(default)]
        default = None
    if missing and default is None:
        raise InputError(f"{undefined[missing[0]]}: give it under materials: in the scene file (or set "
                         "default_material)")
    for i in missing:
        material_index = np.where(material_index == i, -1, material_index)
    unset = material_index < 0
    if unset.any():
        if default is None:
            parts = sorted({geom.part_names[i] for i in np.unique(part[unset])})
            raise InputError(f"part {quoted(parts[0])} has no material and there is no default_material"
                             + (f" ({len(parts)} parts lack one)" if len(parts) > 1 else ""),
                             source=src, key="parts")
        material_index = np.where(unset, names.index(default), material_index).astype(np.int32)
    if undefined:  # (the placeholders, now on no triangle, left out)
        kept = [i for i in range(len(materials)) if i not in undefined]
        new = np.full(len(materials), -1, dtype=np.int32)
        new[kept] = np.arange(len(kept), dtype=np.int32)
        materials, material_index = tuple(materials[i] for i in kept), new[material_index]
    return materials, np.asarray(material_index, dtype=np.int32), unused


def _check_unused(yaml_mats: dict[str, Material], file_mats: tuple[Material, ...], parts_raw: dict,
                  default: Any, src: str, inherited: dict[str, str], shown: int = 12) -> list[str]:
    """The ``materials:`` entries no triangle can take: their name is no mesh file's material (nor
    a renamed one's ``NAME_2`` or first name), no ``parts:`` value and not ``default_material``.
    Where the geometry's files name materials, the first of the scene file's own is an InputError
    (a typo of a file's material name would render the file's material, silently); where they
    name none (builders, shapes: ``materials:`` is the palette ``parts:`` picks from, and an
    entry may be kept for later), and for an entry only inherited through ``extends:``
    (``inherited``: its name -> the file that gave it; this file cannot take it out, and its
    ``parts:`` may have moved a part to a material of its own), a line each, for the scene's notes."""
    file_names = list(dict.fromkeys([m.name for m in file_mats] + [m.alias for m in file_mats if m.alias]))
    used = {*file_names, *(str(v) for v in parts_raw.values()), str(default)}
    unused = [name for name in yaml_mats if name not in used]
    notes = [f"{src}: materials.{name} (given by {inherited[name]}, through extends:): used by no triangle here: "
             "it is not rendered" for name in unused if name in inherited]
    unused = [name for name in unused if name not in inherited]
    if not file_names:
        return notes + [f"{src}: materials.{name}: used by no triangle (no part under parts: names it and it is not "
                        "default_material): it is not rendered" for name in unused]
    if not unused:
        return notes
    name = unused[0]
    listed = listing(file_names, shown)
    close = did_you_mean(name, file_names).strip()[1:-1]  # ("did you mean 'x'?" without its brackets)
    raise InputError(f"used by no triangle (the mesh files' materials: {listed}{'; ' + close if close else ''}): give "
                     "it a mesh file's material's name (to replace that material), or name it under parts: or as "
                     "default_material", source=src, key=f"materials.{name}")


def transform_scene(scene: Scene, scale: float, translate: np.ndarray) -> Scene:
    """Scale about the origin then translate: geometry, lights and camera together.

    Light power is scaled by ``scale**2`` so that radiance, and so the image, does not
    change: a scene scaled by 1e-6 or moved 1e6 away renders the same picture. A light's
    fields its kind does not have stay as they are (:func:`~tlm.scenes.lights.scaled_light`).
    """
    def pt(p):
        return tuple(float(x) for x in np.asarray(p) * scale + translate)

    lights = tuple(scaled_light(lt, scale, translate) for lt in scene.lights if lt.kind != "mesh")
    cam = replace(scene.camera, eye=pt(scene.camera.eye), target=pt(scene.camera.target))
    moved = replace(scene, triangles=scene.triangles * scale + translate, lights=lights, camera=cam)
    return with_mesh_light(moved)
