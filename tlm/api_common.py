"""What tlm/api.py and tlm/api_studies.py share: the experiment file a ``tlm`` command runs
(a path, or a built-in experiment's name) and the folder it writes. :mod:`tlm.api` imports
its studies and reports from :mod:`tlm.api_studies`, which therefore cannot import
:mod:`tlm.api` (a cycle): what both need is here, and :mod:`tlm.api` re-exports
:func:`experiment_path`."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from tlm.errors import InputError, did_you_mean


def experiment_path(ref: str | Path, command: str = "run") -> Path:
    """The experiment file that ``tlm COMMAND REF`` runs: ``ref`` when it exists, else the
    built-in experiment named ``ref``; an :class:`InputError` otherwise (a path that does
    not exist names the built-in experiment of its file name, which is not taken in its
    place; a name that is none lists them)."""
    from tlm.builtin import experiment_path as find
    from tlm.scenes.loader import list_scenes  # (what tlm.api.list_scenes returns)

    return find(os.fspath(ref), command, list_scenes())


def folder(out: Any, key: str = "out") -> Path:
    """``out`` as the path of a folder to write; an InputError for what is not a path."""
    if not isinstance(out, (str, os.PathLike)):
        raise InputError(f"{out!r} is not a folder's path: name the folder to write", key=key)
    return Path(out)


def experiment_file(path: str | Path, command: str) -> Path:
    """The experiment file a study function was given, as ``tlm COMMAND PATH`` takes it
    (:func:`experiment_path`): ``path`` where it exists, else the built-in experiment of
    that name; an :class:`InputError` otherwise, for what is neither a path nor a name, and
    for a file whose keys say it is another command's (:func:`refuse_other_kind`)."""
    from tlm.config import read_yaml

    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"{path!r} is not an experiment: give an experiment file's path or a built-in "
                         "experiment's name ('tlm config list')", key="path")
    found = experiment_path(path, command)
    if found.is_file():  # (a folder, or a file that cannot be read: the study's own loading says so)
        refuse_other_kind(read_yaml(found), found, command)
    return found


# what each kind of file is (file_kind), and what each command takes, in the messages
KIND_NAMES = {"run": "a run config", "scene": "a scene file", "sweep": "a sweep file",
              "thesis": "a thesis study file", "extreme": "an extreme-cases study file",
              "granularity": "a granularity study file", "error-vs-cost": "an error-vs-cost study file"}
# the kinds each command takes (a command not named: its own kind)
COMMAND_KINDS = {"run": ("run", "scene"), "reference": ("run", "scene"), "calibrate": ("thesis",)}


def file_kind(raw: Any) -> tuple[str, list[str]] | None:
    """What the keys of an experiment file (its data ``raw``) say clearly it is, and the keys
    that say so: a study or a sweep (its own keys, :data:`tlm.builtin.EXPERIMENT_COMMANDS`:
    the command that takes it; with no key of a run config or a scene file beside them, and
    with ``base`` or a key that is no near miss of a run config's: ``modes`` alone is a run
    config's typo of ``mode``), ``run`` (a run config: ``scene``, or run config keys alone) or
    ``scene`` (a scene file: ``geometry`` or ``extends``, no ``scene``). None when they do
    not say (what the loading then reports)."""
    import dataclasses

    from tlm.builtin import EXPERIMENT_COMMANDS
    from tlm.config import RunConfig
    from tlm.scenes.loader import SCENE_KEYS

    if not isinstance(raw, dict) or not raw:
        return None
    keys = [str(k) for k in raw]
    fields = [f.name for f in dataclasses.fields(RunConfig)]
    own = [k for k, _ in EXPERIMENT_COMMANDS if k in keys]
    others = [k for k in keys if k in fields or (k in SCENE_KEYS and k != "description")]
    if own:
        if others or not ("base" in keys or any(not did_you_mean(k, fields) for k in own)):
            return None
        return dict(EXPERIMENT_COMMANDS)[own[0]], own
    if "base" in keys:
        return None  # (a study or a sweep of no factor: its own loading names what it lacks)
    if "scene" in keys:
        return "run", ["scene"]
    if "geometry" in keys or "extends" in keys:
        return "scene", [k for k in ("geometry", "extends") if k in keys]
    if all(k in fields for k in keys):
        return "run", keys
    return None


def refuse_other_kind(raw: Any, path: Path, command: str) -> None:
    """An :class:`InputError` naming the command to use when the keys of the file ``path``
    (its data ``raw``) say clearly it is for another command than ``tlm COMMAND``
    (:func:`file_kind`): ``tlm run thesis``, ``tlm sweep cornell``. A built-in experiment is
    named by its name, as ``tlm config list -l`` names it."""
    from tlm.builtin import configs_dir, list_experiments

    found = file_kind(raw)
    takes = COMMAND_KINDS.get(command, (command,))
    if found is None or found[0] in takes:
        return
    kind, keys = found
    ref = str(path)
    try:
        if Path(path).resolve().parent == configs_dir().resolve() and Path(path).stem in list_experiments():
            ref = Path(path).stem
    except OSError:
        pass
    wanted = " or ".join(KIND_NAMES[k] for k in takes if k in KIND_NAMES) or f"a file for 'tlm {command}'"
    use = {"run": f"run it with tlm run {ref}",
           "scene": f"render it with tlm run {ref} (its default settings), or name it in a run config's `scene:`"
           }.get(kind, f"run it with tlm {kind} {ref}")
    if command == "calibrate" and kind != "thesis":
        wanted += " (tlm calibrate fits the programs to a thesis study's scenes)"
    raise InputError(f"{KIND_NAMES[kind]} (it has {', '.join(f'{k}:' for k in keys)}), not {wanted}: {use}",
                     source=str(path))
