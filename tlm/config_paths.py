"""The files a run config names, made to name the same files from anywhere: a ``scene`` file
(:func:`scene_from`, looked for as :func:`tlm.scenes.loader.resolve_scene_path` looks) and the
tables of :data:`PATH_KEYS` (:func:`paths_from`), relative to the file that wrote them, made
absolute once where the config is read (:func:`files_from`). Out of :mod:`tlm.config`, which
imports them from here (and names them as its own: ``from tlm.config import scene_from``).
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

from tlm import storage
from tlm.errors import path_shown, quoted

# the dotted keys whose values are file paths, each relative to the file that wrote it (the
# command line's: relative to the working folder); ``scene`` names a file that way too, or a
# built-in scene by name (:func:`scene_from`)
PATH_KEYS = ("arch.programs",)
# a scene file's top-level keys that no run config has (of tlm.scenes.loader.SCENE_KEYS, which this layer
# does not import; tlm.cli's _SCENE_ONLY alike): what tells a scene file from a run config of one name
# (configs/room.yaml, beside configs/cornell.yaml, runs the built-in scene room: no scene of its own)
SCENE_ONLY_KEYS = frozenset(("camera", "lights", "materials", "parts", "default_material", "geometry",
                             "transform", "crease_angle", "extends"))
_TOP_KEY = re.compile(r"^[\"']?([A-Za-z_][\w-]*)[\"']?[ \t]*:", re.M)  # (a block mapping's key at column 0)
# (a flow mapping's key, ``{scene: room, mode: rcast}``: a file of no block key read by its flow keys, h455)
_FLOW_KEY = re.compile(r"[{,][ \t\r\n]*[\"']?([A-Za-z_][\w-]*)[\"']?[ \t]*:")


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


def scene_from(value: Any, folders: list[Path] | tuple[Path, ...], warn: bool = True) -> Any:
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
    built-in one, or says that the file is missing). ``warn``: false where a value given after this one
    replaces it (an override of ``scene``: :func:`sets_scene`), so that :func:`shadowed_warning` says nothing
    of a scene not used (h451)."""
    if warn and isinstance(value, str) and value:
        shadowed_warning(value, folders)
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


def shadowed_warning(value: str, folders: list[Path] | tuple[Path, ...]) -> None:
    """Say once (a line of :func:`tlm.storage.warn`, not said again while :data:`tlm.storage.SAID`
    holds one of ``value``) where the ``scene`` value ``value`` names a built-in scene (``room``,
    ``thesis/ring``), which the loader takes, while a scene file of that name (``room.yaml``,
    ``thesis/ring.yml``) is in one of ``folders`` or in the working folder, looked for as
    :func:`scene_from` looks for a file: a user who meant the file gets the built-in scene, unsaid
    before (h435). Which one is taken is not changed; the line says how to give the file
    (``scene=./room.yaml``, or its path from the config's folder: :func:`_given_as`). A run config of that
    name (``configs/room.yaml``: no key of :data:`SCENE_ONLY_KEYS`) and the built-in scene's own file (run from
    ``scenes/``) are no such file."""
    if value.lower().endswith((".yaml", ".yml")) or Path(value).is_absolute():
        return  # (a file's name: the folders before the built-in scenes, as scene_from looks)
    builtin = builtin_scenes_dir() / f"{value}.yaml"
    if not builtin.is_file():
        return
    said = f"scene {quoted(value)} is the built-in scene of that name"
    if any(line.startswith(said) for line in storage.SAID):
        return  # (once: --set scene= is looked at from the working folder, then from the config's)
    found = _file_named(value, folders, builtin)
    if found is not None:
        target, name = found
        storage.warn(f"{said}, not the file {path_shown(_shown(target))}: to run the file, give it as a path, "
                     f"scene={path_shown(_given_as(target, name, folders))}")


def sets_scene(overrides: Any) -> bool:
    """Whether one of the ``dotted.key=value`` strings ``overrides`` sets ``scene`` (``scene=...``, or
    ``scene.file=...``, which makes it a mapping), its key read as :func:`tlm.config.apply_overrides` reads it:
    a ``scene`` given before them (a config's, a study's base's) is then not the one used, and is not warned of
    (:func:`shadowed_warning`, h451)."""
    return any(str(item).partition("=")[0].strip().split(".")[0] == "scene" for item in overrides)


def scene_file_hint(value: str, folders: list[Path] | tuple[Path, ...], by_itself: bool = False) -> str:
    """For the error of the ``scene`` value ``value`` that is no built-in scene's name (``myroom``): where a scene
    file of that name (``myroom.yaml``) is in one of ``folders`` or in the working folder, looked for as
    :func:`shadowed_warning` looks, the clause that names it and how to give it (``scene=./myroom.yaml``, h451);
    else nothing. ``by_itself``: ``value`` was given as a scene by itself, not as a config's ``scene``
    (``tlm scene show myroom``, ``tlm.load_scene("myroom")``): the path alone (``./myroom.yaml``, h455)."""
    found = scene_file_named(value, folders)
    if found is None:
        return ""
    shown, given = found
    how = f"give it as a path, {given}" if by_itself else f"to run it, give it as a path, scene={given}"
    return f"; a scene file of that name lies at {shown}: {how}"


def scene_file_named(value: Any, folders: list[Path] | tuple[Path, ...]) -> tuple[str, str] | None:
    """``(the file as a line names it, the path that gives it)`` of the scene file that :func:`scene_file_hint`
    names for ``value`` (``("cfg/myroom.yaml", "./myroom.yaml")``); None where there is none."""
    if not isinstance(value, str) or not value or names_scene_file(value):
        return None
    found = _file_named(value, folders)
    if found is None:
        return None
    target, name = found
    return path_shown(_shown(target)), path_shown(_given_as(target, name, folders))


def _file_named(value: str, folders: list[Path] | tuple[Path, ...], builtin: Path | None = None
                ) -> tuple[str, str] | None:
    """``(absolute path, name)`` of the first scene file named ``value`` with ``.yaml`` or ``.yml``
    (``room.yaml``) in one of ``folders`` or in the working folder, other than ``builtin`` (the built-in
    scene's own file, run from ``scenes/``); a run config of that name (:func:`_scene_file`) is none."""
    for folder in dict.fromkeys([*map(os.fspath, folders), os.getcwd()]):
        for suffix in (".yaml", ".yml"):
            target = os.path.abspath(os.path.join(folder, value + suffix))
            if (os.path.isfile(target) and (builtin is None or not _same_file(target, builtin))
                    and _scene_file(target)):
                return target, value + suffix
    return None


def _shown(target: str) -> str:
    """The absolute path ``target`` as a message names it: from the working folder where it lies under it."""
    shown = os.path.relpath(target)
    return target if shown.startswith("..") else shown


def _given_as(target: str, name: str, folders: list[Path] | tuple[Path, ...]) -> str:
    """The ``scene`` path for :func:`shadowed_warning`'s line that names the file ``target`` (found as ``name``,
    ``room.yaml``, in one of ``folders`` or the working folder) whichever way it is read: as a config's ``scene:``
    (looked for in ``folders``, then the working folder) and as ``--set scene=`` (the working folder first, then
    beside the config). ``./room.yaml`` where it does; else the file's path from the first of ``folders`` or
    from the working folder (``../room.yaml``, ``cfg/room.yaml``) or its whole path, the shortest that does. A
    run config ``configs/room.yaml`` beside ``configs/cornell.yaml`` made ``./room.yaml`` that config (h438)."""
    cwd = os.getcwd()
    orders = ([*map(os.fspath, folders), cwd], [cwd, *map(os.fspath, folders)])

    def found(given: str, order: list[str]) -> str | None:
        return next((t for t in (os.path.abspath(os.path.join(f, given)) for f in order) if os.path.isfile(t)), None)

    def names_it(given: str) -> bool:
        return all(_same_file(t, Path(target)) for t in (found(given, order) or "" for order in orders))

    if names_it(f"./{name}"):
        return f"./{name}"
    paths = (os.path.relpath(target, start) for start in (*map(os.fspath, folders[:1]), cwd))
    named = [p for p in (p if os.sep in p else f"./{p}" for p in paths) if names_it(p)]
    return min([*named, target], key=len)  # (a path climbing to / from both: the whole path, shorter, h460)


def _same_file(a: str, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _scene_file(path: str) -> bool:
    """Whether the YAML file ``path`` may be a scene file: it names a key of :data:`SCENE_ONLY_KEYS` at its
    top level (a flow mapping's: anywhere in it), or no key (a file not read); not a run config (``scene: room``,
    ``"scene": room``, ``{scene: room}``)."""
    try:
        with open(path, "rb") as f:
            text = f.read(1 << 20).decode("utf-8", "replace")
    except OSError:
        return True
    keys = set(_TOP_KEY.findall(text)) or set(_FLOW_KEY.findall(text))  # (a key quoted, "scene":, or of a flow
    return not keys or bool(keys & SCENE_ONLY_KEYS)  # mapping, {scene: room}, too: a run config so written, h455)


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


def files_from(raw: dict, folder: Path, warn: bool = True) -> dict:
    """The run config mapping ``raw``, written by a file in ``folder``, with the files it
    names as absolute paths: ``scene`` (:func:`scene_from`) and the keys of
    :data:`PATH_KEYS` (:func:`paths_from`). Its ``config.resolved.yaml`` then names the same
    files wherever it is run again, and so does a worker of another working folder. ``warn``:
    false where its ``scene`` is replaced after (:func:`scene_from`'s)."""
    out = {k: paths_from(k, v, folder) for k, v in raw.items()}
    if "scene" in out:
        out["scene"] = scene_from(out["scene"], [folder], warn)
    return out
