"""Which file of a scene file's ``extends:`` chain gave each key of the merged mapping
(:func:`~tlm.scenes.loader.read_scene_tree`), so that an error on a key names the file that
gave it: a base's bad value is the base's, a key this file gives (a one-item ``geometry:``
merged into the base's) this file's, a part with no material the file's that gave the geometry
(:func:`blamed`); and what becomes of the entries that a base's ``parts:`` (a null
taking one out, :func:`parts_removed`) or ``materials:`` (:func:`nulls`, :func:`note_given`) gave."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from tlm.config_words import listing
from tlm.errors import InputError, did_you_mean, quoted


class Files(list):
    """The files of an ``extends:`` chain, base first (:func:`~tlm.scenes.loader.read_scene_tree`), and
    ``geometries``: each one's ``geometry:`` value, merged, and the file its mesh paths are relative to."""

    def __init__(self) -> None:
        super().__init__()
        self.geometries: dict[Path, tuple[Any, Path]] = {}


def add_file(files: list[Path], path: Path, geometry: Any, geom_path: Path) -> None:
    """``path`` appended to ``files``; for :class:`Files`, its ``geometry`` and ``geom_path`` kept."""
    files.append(path)
    if isinstance(files, Files):
        files.geometries[path] = (geometry, geom_path)


def record(origins: dict[str, Path] | None, raw: dict, base: dict, path: Path, prefix: str = "") -> None:
    """``origins`` (:func:`~tlm.scenes.loader.read_scene_tree`): each key ``raw`` gives -> ``path``;
    a key whose value replaces the base's (not a mapping merged into the base's mapping) takes the
    base's keys below it out."""
    if origins is None:
        return
    for k, v in raw.items():
        key = f"{prefix}{k}"
        merges = isinstance(v, dict) and isinstance(base.get(k), dict)
        if not merges and key in origins:  # (a key given before: those below it are the value replaced)
            for below in [o for o in origins if o.startswith((f"{key}.", f"{key}["))]:
                del origins[below]
        origins[key] = path
        if isinstance(v, dict):
            record(origins, v, base[k] if merges else {}, path, f"{key}.")


def origin(origins: dict[str, Path], key: str) -> Path | None:
    """The file of an ``extends:`` chain that gave ``key`` (an error's: ``geometry.params.glass_seg``,
    ``lights[0].power``), from ``origins`` (:func:`~tlm.scenes.loader.read_scene_tree`): the file
    that gave the longest part of it given; for a mapping, the one file that gave all of it, else
    None (merged from several files, or given by none)."""
    parts = re.split(r"(?=[.\[])", key)
    for n in range(len(parts), 0, -1):
        at = "".join(parts[:n])
        if at in origins:
            files = {origins[at], *(f for o, f in origins.items() if o.startswith((f"{at}.", f"{at}[")))}
            return origins[at] if len(files) == 1 else None
    return None


def blamed(e: InputError, raw: dict, origins: dict[str, Path], files: list[Path], path: Path) -> InputError | None:
    """``e``, an error of :func:`~tlm.scenes.loader.load_scene` of the scene file ``path`` (merged: ``raw``) on a key,
    as it names the file of the ``extends:`` chain ``files`` that gave that key (:func:`origin`); None where that is
    ``e``'s. A part with no material (key ``parts``, ``raw``'s ``parts:`` a mapping, or none) is the last file's that
    gave the geometry's parts (:func:`_parts_by`) unless a later file gave a ``parts:`` entry: the fix is there (a
    ``parts:`` entry, ``default_material``), and an earlier file's ``parts:``, given for the geometry it replaced, is
    named as such."""
    where, message = origin(origins, str(e.key)) or path, e.message
    if e.key == "parts" and isinstance(raw.get("parts") or {}, dict):
        at = {f: i for i, f in enumerate(files)}
        by = _parts_by(origins, at)
        givers = {origins[k] for k in origins if k == "parts" or k.startswith(("parts.", "parts["))}
        if by >= 0 and all(at.get(f, len(files)) <= by for f in givers):
            where = files[by]
            earlier = [str(f) for f in files[:by] if f in givers]
            if earlier:
                message += (f"; the parts: given by {listing(earlier)} (through extends:) is for the geometry "
                            "this file's geometry: replaces: give them materials under parts: or set default_material")
    if str(where) == e.source and message == e.message:
        return None
    return e.replaced(source=str(where), message=message)


def parts_removed(merged: dict, raw: dict, base: dict) -> None:
    """``parts: {X: null}`` in a file whose base (``base``, merged) gives ``parts.X``: the entry
    taken out of ``merged`` (:func:`~tlm.scenes.loader.read_scene_tree`), so that it is no more
    checked: the part, where the geometry has it, takes the mesh file's material or
    ``default_material``; where the file's geometry has no such part, nothing is said of it."""
    own, inherited, out = raw.get("parts"), base.get("parts"), merged.get("parts")
    if isinstance(own, dict) and isinstance(inherited, dict) and isinstance(out, dict):
        merged["parts"] = {k: v for k, v in out.items() if not (k in own and own[k] is None and k in inherited)}


def stale_parts(raw: dict, part_names: tuple[str, ...], origins: dict[str, Path], files: list[Path],
                src: str, items: list | None = None, hint: Any = None) -> tuple[dict, list[str]]:
    """``raw`` without the ``parts:`` entries a base of the ``extends:`` chain ``files`` (base first)
    gave for a part that the geometry, replaced or changed by a later file of the chain (more than a
    ``transform``: :func:`_parts_by`), no longer has (a file extending ``examples/mesh_on_floor``
    without its pawns), and a note each naming the base file and the part. An entry for a part the
    geometry lacks that the file giving the geometry (or a later one) gave is left: the error it is
    names that file and key. So is a base's entry that names no part of the geometry it was given for
    (a typo), as far as the part names of the geometries from that file on (``files`` a :class:`Files`: each
    file's ``geometry:``) are known without building them (:func:`~tlm.scenes.compose.listed_part_names`, from
    ``items``, the items of the geometry built): an InputError naming that file and key, with ``hint(part,
    value)``'s words where they say more than a near name (the loader's: the name is a material of the mesh
    files), as the base alone says it."""
    parts = raw.get("parts")
    at = {f: i for i, f in enumerate(files)}
    geometry_by = _parts_by(origins, at)
    if not isinstance(parts, dict) or geometry_by < 0:
        return raw, []
    given_by = {k: origins.get(f"parts.{k}") for k in parts if k not in part_names}
    stale = {k: by for k, by in given_by.items() if at.get(by, geometry_by) < geometry_by}
    for k, by in stale.items():
        _typo(k, by, files[at[by]:geometry_by], getattr(files, "geometries", None), items,
              hint(k, parts[k]) if hint is not None else "")
    notes = [f"{src}: parts.{k} (given by {by}, through extends:): the geometry here has no part {quoted(k)}: the "
             f"entry is not used (`parts: {{{k}: null}}` leaves it out without this note)" for k, by in stale.items()]
    return {**raw, "parts": {k: v for k, v in parts.items() if k not in stale}}, notes


def _typo(part: str, by: Path, since: list[Path], geometries: dict[Path, tuple[Any, Path]] | None,
          items: list | None, hint: str = "") -> None:
    """An InputError naming the file ``by`` and its ``parts.PART`` where ``part`` is a part of no geometry of the
    files ``since`` (``by`` and those after it before the file that gave the geometry), each known (their part names:
    :func:`~tlm.scenes.compose.listed_part_names`): a typo, as ``by`` alone says it; where one is not known, the
    entry may have been for a part of it: nothing."""
    from tlm.scenes.compose import listed_part_names

    if geometries is None or items is None:
        return
    known = []
    for f in since:
        geometry, geom_path = geometries.get(f, (None, f))
        names = None if geometry is None else listed_part_names(geometry, geom_path, items)
        if names is None or part in names:
            return
        known.append(names)
    names = known[0]
    raise InputError(f"the geometry has no part {quoted(part)} (parts: {', '.join(names)})"
                     f"{hint or did_you_mean(str(part), names)}",
                     source=str(by), key=f"parts.{part}")


def _parts_by(origins: dict[str, Path], at: dict[Path, int]) -> int:
    """The place in the chain (``at``) of the last file that gave the geometry's parts: that gave ``geometry:``,
    but not a one-item ``geometry`` that only merges a ``transform`` into the base's (a scale keeps the part
    names: a base's entry for a part its own geometry lacks stays the base's error); -1 where none."""
    below = [k for k in origins if k.startswith(("geometry.", "geometry["))]
    if not below:  # (a list, or a value not a mapping: the file that gave it)
        return at.get(origins.get("geometry"), -1)
    return max((at.get(origins[k], -1) for k in below
                if k != "geometry.transform" and not k.startswith("geometry.transform.")), default=-1)


def nulls(materials: Any) -> list:
    """The names a scene file's ``materials:`` mapping gives as null (each removes the base's material)."""
    return [k for k, v in materials.items() if v is None] if isinstance(materials, dict) else []


def note_given(given: dict[str, Path] | None, materials: Any, path: Path) -> None:
    """``given`` (:func:`~tlm.scenes.loader.read_scene_tree`): each material ``materials`` gives -> ``path``."""
    if given is not None and isinstance(materials, dict):
        given.update(dict.fromkeys((str(k) for k, v in materials.items() if v is not None), path))
