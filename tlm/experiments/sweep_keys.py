"""What a sweep point's key is made of (out of :mod:`tlm.experiments.sweep_file`, which imports every name
from here under its old name and makes the key itself, :func:`tlm.experiments.sweep_file.config_hash`).

* :func:`canonical_json` — the canonical JSON of a value; :func:`keyed_field` — a field of a resolved config as
  the key holds it, its files by their path from the sweep file's folder (:func:`from_folder`).
* :func:`point_inputs` — the fingerprints of the files a point's config names (its scene, its programs table).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

from tlm.config import to_dict
from tlm.errors import InputError
from tlm.experiments.frames import render_key


def canonical_json(value: Any) -> str:
    """Canonical JSON: sorted keys, no spaces."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"))


def keyed_field(name: str, resolved: Any, folder: Path | None = None) -> str:
    """A top-level field of a resolved config as the point's key holds it: ``"name":`` and
    its JSON, less ``render.threads`` (it changes the speed alone, bit-identical results: a
    point keeps its key). Where ``folder`` (the sweep file's) is given, an absolute ``scene``
    file and ``arch.programs`` table are keyed by their path from it (:func:`from_folder`): where
    the project lies is not part of the key, only which of its files a point names (their
    content is, by ``inputs``: :func:`tlm.experiments.sweep_file.config_hash`). Two files of one content that a sweep
    lists stay two points."""
    if name == "render" and isinstance(resolved, dict):
        resolved = {k: v for k, v in resolved.items() if k != "threads"}
    if folder is not None and name == "scene":
        resolved = from_folder(resolved, folder)
    if folder is not None and name == "arch" and isinstance(resolved, dict) and "programs" in resolved:
        resolved = {**resolved, "programs": from_folder(resolved["programs"], folder)}
    return f"{json.dumps(name)}:{canonical_json(resolved)}"


def from_folder(value: Any, folder: Path) -> Any:
    """An absolute path ``value`` as its path from ``folder`` (posix: ``../scenes/box.yaml``);
    anything else (a built-in scene's name, none) as it is."""
    if not isinstance(value, str) or not os.path.isabs(value):
        return value
    try:
        return Path(os.path.relpath(value, folder)).as_posix()
    except ValueError:  # (another drive: no path from there)
        return value


def point_inputs(cfg, folder: Path, source: str, seen: dict | None = None, work: Any = None) -> dict[str, str]:
    """Fingerprints of the files ``cfg`` names: its frame's functional key (the scene's
    content) and the sha256 of the programs table's bytes.

    Loads the scene and the programs table (an InputError names ``source``). ``seen``
    keeps what was loaded, for the next point: points of one sweep share most of them.
    ``work``: what names the config's frame in ``seen``, where the caller has it (any value
    that the resolved config less ``arch`` decides, and that decides it); by default that
    config's JSON.
    """
    from tlm.arch.costs import DEFAULT_PATH
    from tlm.experiments.run import programs_for

    seen = {} if seen is None else seen
    table = cfg.arch.programs
    if ("programs", table) not in seen:
        try:
            programs_for(cfg, folder)
        except InputError as e:  # the table's own message, and which point names it
            raise InputError(str(e), source=source) from None
        path = DEFAULT_PATH if table is None else folder / table  # an absolute table stays itself
        if not Path(path).is_file():  # (a pipe's, <(...): read once here, its points run in processes of their own)
            raise InputError("is no file but a pipe or a device, which each point of a sweep reads again in its own "
                             "process: save the table to a file and name that", source=str(path),
                             key="arch.programs")
        seen["programs", table] = hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]
    if work is None:
        work = json.dumps({k: v for k, v in to_dict(cfg).items() if k != "arch"}, sort_keys=True)
    if ("functional", work) not in seen:
        seen["functional", work] = render_key(cfg, folder, source)
    return {"functional": seen["functional", work], "programs": seen["programs", table]}
