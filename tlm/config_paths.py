"""The files a run config names, made to name the same files from anywhere: a ``scene`` file
(:func:`scene_from`, looked for as :func:`tlm.scenes.loader.resolve_scene_path` looks) and the
tables of :data:`PATH_KEYS` (:func:`paths_from`), relative to the file that wrote them, made
absolute once where the config is read (:func:`files_from`). Out of :mod:`tlm.config`, which
imports them from here (and names them as its own: ``from tlm.config import scene_from``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

# the dotted keys whose values are file paths, each relative to the file that wrote it (the
# command line's: relative to the working folder); ``scene`` names a file that way too, or a
# built-in scene by name (:func:`scene_from`)
PATH_KEYS = ("arch.programs",)


def builtin_scenes_dir() -> Path:
    """Where the built-in scene files are: inside the wheel (``tlm/_scenes``), or the
    repository's ``scenes/`` (:func:`tlm.scenes.loader.scenes_dir` is this folder)."""
    packaged = Path(__file__).resolve().parent / "_scenes"
    if packaged.is_dir():
        return packaged
    return Path(__file__).resolve().parents[1] / "scenes"


def names_scene_file(value: Any) -> bool:
    """Whether the ``scene`` value ``value`` is written as a path (``box.yaml``, ``a/box``),
    not as a built-in scene's plain name (``cornell``): as :func:`tlm.scenes.loader.resolve_scene_path`
    tells them (``thesis/ring`` is both: a built-in scene of a subfolder, found there)."""
    return isinstance(value, str) and (value.lower().endswith((".yaml", ".yml")) or "/" in value or os.sep in value)


def scene_from(value: Any, folders: list[Path] | tuple[Path, ...]) -> Any:
    """``value``, a ``scene`` given by a file in the first of ``folders`` (the command line:
    the working folder), as the absolute path of the file it names, looked for as
    :func:`tlm.scenes.loader.resolve_scene_path` looks: in each of ``folders`` (each
    absolute) in turn, then in the working folder (a project's config that names its scene
    from the project's root: ``scene: myscenes/box.yaml`` run from there), then among the
    built-in scenes. Read once, where the config is read, so that the
    config names one file wherever it is used again (a worker, a rerun of its
    ``config.resolved.yaml`` from another folder). A built-in scene's name (``cornell``,
    ``thesis/ring``, ``thesis/ring.yaml``), an absolute path, and a path none of them holds
    are returned as they are (:func:`~tlm.scenes.loader.resolve_scene_path` finds the
    built-in one, or says that the file is missing)."""
    if not names_scene_file(value) or not value or Path(value).is_absolute():
        return value
    builtin = builtin_scenes_dir()
    if not value.lower().endswith((".yaml", ".yml")) and (builtin / f"{value}.yaml").is_file():
        return value  # (thesis/ring: the built-in scene first, as the loader takes it)
    for folder in folders:
        target = os.path.abspath(os.path.join(folder, value))
        if os.path.isfile(target):
            return target
    target = os.path.abspath(value)  # (the working folder, before the built-in scenes: a project's own ring.yaml)
    if os.path.isfile(target):
        return target
    return value  # (thesis/ring.yaml: a built-in scene, a name wherever it runs; else the loader says it is missing)


def paths_from(key: str, value: Any, folder: Path, to: Path | None = None) -> Any:
    """``value``, given to the dotted ``key`` (a key of :data:`PATH_KEYS`, or a section
    above one: ``arch: {programs: ...}``) by a file in ``folder`` (the command line: the
    working folder), with each relative path of :data:`PATH_KEYS` in it made to name the
    same file from elsewhere: absolute, or relative to the folder ``to`` when given (where
    the config's other relative paths start). Anything else is returned as it is, a ``key``
    that is no string too (YAML's ``1:``, ``true:``, ``null:``: names no file; the config's
    checks then say it is an unknown key)."""
    if not isinstance(key, str):
        return value
    for path_key in PATH_KEYS:
        if key == path_key:
            if not isinstance(value, str) or not value or Path(value).is_absolute():
                return value
            target = os.path.abspath(os.path.join(folder, value))
            return target if to is None else os.path.relpath(target, to)
        if path_key.startswith(key + ".") and isinstance(value, dict):
            child = path_key[len(key) + 1:].split(".")[0]
            if child in value:
                value = {**value, child: paths_from(f"{key}.{child}", value[child], folder, to)}
    return value


def files_from(raw: dict, folder: Path) -> dict:
    """The run config mapping ``raw``, written by a file in ``folder``, with the files it
    names as absolute paths: ``scene`` (:func:`scene_from`) and the keys of
    :data:`PATH_KEYS` (:func:`paths_from`). Its ``config.resolved.yaml`` then names the same
    files wherever it is run again, and so does a worker of another working folder."""
    out = {k: paths_from(k, v, folder) for k, v in raw.items()}
    if "scene" in out:
        out["scene"] = scene_from(out["scene"], [folder])
    return out
