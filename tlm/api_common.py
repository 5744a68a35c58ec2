"""What tlm/api.py and tlm/api_studies.py share: the experiment file a ``tlm`` command runs
(a path, or a built-in experiment's name) and the folder it writes. :mod:`tlm.api` imports
its studies and reports from :mod:`tlm.api_studies`, which therefore cannot import
:mod:`tlm.api` (a cycle): what both need is here, and :mod:`tlm.api` re-exports
:func:`experiment_path`."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from tlm.errors import InputError


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
    that name; an :class:`InputError` otherwise, and for what is neither a path nor a name."""
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"{path!r} is not an experiment: give an experiment file's path or a built-in "
                         "experiment's name ('tlm config list')", key="path")
    return experiment_path(path, command)
