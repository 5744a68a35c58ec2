"""Which file of a scene file's ``extends:`` chain gave each key of the merged mapping
(:func:`~tlm.scenes.loader.read_scene_tree`), so that an error on a key names the file that
gave it: a base's bad value is the base's, a key this file gives (a one-item ``geometry:``
merged into the base's) this file's."""

from __future__ import annotations

import re
from pathlib import Path


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
