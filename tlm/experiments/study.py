"""The one study runner, and the shared frame of study files (``tlm thesis``, ``tlm
granularity``, ``tlm error-vs-cost``, ``tlm extreme``, ``tlm scaling``).

:func:`run_study` runs a study's points one after the other into an output folder that
appears whole or not at all, and writes what every study writes the same way: the
rows (:func:`tlm.storage.write_rows`), the resolved config, ``provenance.json`` and any
files of the study's own. A study supplies its points and what one point computes.

A study file is a YAML mapping with a ``base`` run config (a mapping), an optional
``description`` and the study's own keys. :func:`read_study` reads it and checks that
frame, so every study rejects a non-mapping, an unknown key or a bad ``base`` with
the same one-line errors (file and key named, exit status 2 through the CLI);
:func:`read_study_base` reads a study whose ``base`` may also name a run config file or
a built-in run config, as a sweep's may (``tlm granularity``).
Result rows go through :func:`tlm.storage.write_rows`, as every experiment's do.

A study folder lists what the study wrote in it (``.tlm-files``, its top-level names,
and ``report``, which the command writes after it); a rerun into the folder replaces
those and carries everything else (a user's notes, an analysis folder) into the new
output, as a rerun of ``tlm run`` does. A folder written before the list existed is
replaced whole.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import yaml

from tlm.config import (
    SECTIONS,
    apply_overrides,
    file_folder,
    files_from,
    read_set_value,
    read_yaml,
    scene_from,
    sets_scene,
    to_dict,
)
from tlm.config_words import dump_yaml
from tlm.errors import InputError, shell_word
from tlm.experiments.provenance import provenance
from tlm.storage import atomic_folder, check_destination, json_text, write_file, write_rows

# the study file the API runs and the check of its data (tlm.api_common.kind_check: another command's file refused,
# naming that command), while checking() holds them
_CHECK: contextvars.ContextVar[tuple[Path, Callable[[Any, Path], None]] | None] = contextvars.ContextVar(
    "tlm_study_check", default=None)


@contextlib.contextmanager
def checking(path: Path, check: Callable[[Any, Path], None]):
    """A block whose read of the study file ``path`` (:func:`read_study`, :func:`read_study_base`) calls ``check``
    with its data and path before its own checks: on the one read of its text (a pipe's, ``<(...)``, is read once)."""
    token = _CHECK.set((Path(path), check))
    try:
        yield
    finally:
        _CHECK.reset(token)


def _study_frame(path: Path, keys: tuple[str, ...]) -> tuple[dict, str]:
    """``(raw, source)`` of the study file ``path``: a mapping of ``base``, ``keys`` and
    ``description`` (InputError otherwise); inside :func:`checking` of it, its check first."""
    raw = read_yaml(path)
    given = _CHECK.get()
    if given is not None and given[0] == Path(path):
        given[1](raw, Path(path))
    src = str(path)
    allowed = ("base", *keys, "description")
    if not isinstance(raw, dict):
        raise InputError(f"must be a mapping with {', '.join(allowed[:-1])}", source=src)
    for key in raw:
        if key not in allowed:
            raise InputError(f"unknown key (expected {', '.join(allowed)})", source=src, key=str(key))
    return raw, src


def read_study(path: Path, keys: tuple[str, ...], overrides: Iterable[str] = (),
               own_scenes: Callable[[dict], bool] | None = None) -> tuple[dict, dict, str]:
    """``(raw, base, source)`` of the study file ``path`` whose own keys are ``keys``. ``overrides``: the
    ``--set`` strings the base is then given (:func:`with_set`): where one sets ``scene``, the base's scene,
    not the one used, is not warned of (:func:`tlm.config_paths.shadowed_warning`, h451); nor where
    ``own_scenes(raw)`` says that the study file gives each of its cells a scene of its own (h455: an extreme
    study's cases). Give a tuple or a list: an iterator is read here, and the caller's then empty."""
    raw, src = _study_frame(path, keys)
    base = raw.get("base") or {}
    if not isinstance(base, dict):
        raise InputError("must be a run config mapping", source=src, key="base")
    replaced = sets_scene(overrides) or (own_scenes is not None and own_scenes(raw))
    return raw, _files_absolute(base, file_folder(path), not replaced), src  # (a pipe's, <(...): the working folder)


def read_study_base(path: Path, keys: tuple[str, ...], overrides: Iterable[str] = ()
                    ) -> tuple[dict, dict, str, Path]:
    """:func:`read_study` of a study whose ``base`` may also name a run config as a sweep's
    may (:func:`tlm.builtin.read_base`): a file relative to the study file, or a built-in
    run config's name (``base: cornell``). ``(raw, base, the source the base's errors name,
    the folder its relative paths start at)``: a base file's own folder, else the study
    file's. ``overrides``: as :func:`read_study`'s."""
    from tlm.builtin import read_base

    raw, src = _study_frame(path, keys)
    base, base_src, folder = read_base(raw.get("base"), file_folder(path), src, "study file", scene_keys)
    return raw, _files_absolute(base, folder, not sets_scene(overrides)), base_src, folder


def scene_keys(path: Path) -> None:
    """Read the scene file ``path``'s keys and its ``extends:`` chain's (an InputError on a typo), as ``tlm run``
    does before its note on a scene file: :func:`tlm.builtin.read_base`'s check of a scene file given as a base."""
    from tlm.scenes.loader import read_scene_tree

    read_scene_tree(path, ())


def _files_absolute(base: dict, folder: Path, warn: bool = True) -> dict:
    """``base`` with the files it names (``scene``, ``arch.programs``; relative to
    ``folder``) as absolute paths (:func:`tlm.config.files_from`, ``warn`` its): the points'
    ``config.resolved.yaml`` then name those files wherever they are run again."""
    return files_from(base, folder, warn)


def override_key(item: str) -> str:
    """The dotted key the ``--set`` string ``item`` (``dotted.key=value``) sets, as
    :func:`tlm.config.apply_overrides` reads it."""
    return item.partition("=")[0].strip()


def set_leaves(item: str) -> dict[str, Any]:
    """The dotted keys the ``--set`` string ``item`` sets, each with its value: its key, or each key
    under it when its value is a mapping given for a section, which merges into it
    (:func:`tlm.config_words.laid_over`: ``estimate={k: 9}`` sets ``estimate.k`` alone; an empty one
    sets none, the section as it was); a value YAML cannot read (refused elsewhere): its key alone."""
    key, _, text = str(item).partition("=")
    try:
        value = read_set_value(text)  # (as apply_overrides reads it: a byte not UTF-8 kept, scene=dir_\xff/x.yaml)
    except yaml.YAMLError:
        return {key.strip(): None}
    return value_leaves(key.strip(), value)


def value_leaves(key: str, value: Any) -> dict[str, Any]:
    """The dotted keys ``value``, given for the dotted ``key`` (a ``--set``'s, a sweep's ``set:`` entry or
    factor value, a study's points value), sets over the base, each with its value: ``key``, or where
    ``value`` is a mapping given for a section, which merges into it, the keys it names, recursively
    (:func:`set_leaves`)."""
    if isinstance(value, dict) and key in SECTIONS:
        return {k: v for name, child in value.items() for k, v in value_leaves(f"{key}.{name}", child).items()}
    return {key: value}


def with_set(raw: dict, overrides: Iterable[str], folders: Iterable[Path] = (), warn: bool = True) -> dict:
    """The run config mapping ``raw`` with the ``--set`` strings ``overrides`` (``dotted.key=value``,
    values read as YAML) applied as ``tlm run --set`` applies them (:func:`tlm.config.load_config`):
    a relative ``arch.programs`` or ``scene`` file from the working folder, and a ``scene`` file
    that is not there looked for in ``folders`` (the study or sweep file's), each then absolute.
    A string not of that form, or a value YAML cannot read, is an InputError naming ``--set``.
    ``warn``: false where a ``--set scene`` is refused after (the study's or sweep's own scenes give every
    cell's): its bare name is not warned of (:func:`tlm.config_paths.shadowed_warning`) before the error (h455)."""
    overrides = list(overrides)
    if not overrides:
        return raw
    out = apply_overrides(raw, overrides, source="--set", cwd=Path.cwd(), warn=warn)
    if "scene" in out and any(override_key(o) == "scene" for o in overrides):
        out = {**out, "scene": scene_from(out["scene"], list(folders), warn)}
    return out


def refuse_set(overrides: Iterable[str], taken: dict[str, str], source: str | None = None) -> None:
    """An InputError (``FILE: --set ITEM: ...``, ``source`` the file) for the first ``--set``
    string of ``overrides`` that sets a key of ``taken``, or a section above or below one
    (``arch`` and ``arch.fifo_depth``): the keys the study or sweep sets itself, each mapped to
    what sets it and what to do instead (``a factor of the sweep (grid.arch.fifo_depth): change its
    values in the sweep file``); a --set of one would be lost there, or win over the file's values,
    unsaid. A section given as a mapping sets the keys it names (:func:`set_leaves`: it merges into
    the section), so ``arch={pipelines: 2}`` beside a taken ``arch.fifo_depth`` is not refused, but
    ``arch={fifo_depth: 2}`` is, and so is ``arch=null`` (the whole section at its defaults)."""
    for item in overrides:
        key = override_key(item)
        for other, why in taken.items():
            if not any(leaf == other or leaf.startswith(other + ".") or other.startswith(leaf + ".")
                       for leaf in set_leaves(item)):
                continue
            if key == other:
                named = f"{key} is"
            elif other.startswith(key + "."):
                named = f"{key} holds {other},"
            elif key.startswith(other + "."):
                named = f"{key} is in {other},"
            else:
                continue
            raise InputError(f"{named} {why}", source=source, key=f"--set {item.strip()}")


def refuse_own_keys(overrides: Iterable[str], keys: Iterable[str], source: str | None = None,
                    file: str = "study file") -> None:
    """:func:`refuse_set` of the file's own keys (``base``, ``description`` and ``keys``, the study's:
    ``packet_sizes``; ``file``: what the file is, ``sweep file``) given by ``--set``, which sets the
    base's keys, the run config's: each study says it the same way (h416, h423), where the run config's
    check said a plain "unknown key"; a key under base (``base.render.spp=2``) is told the --set
    that sets it (``render.spp=2``; through the API, :func:`tlm.api_common.arguments_text`:
    ``overrides=["render.spp=2"]``)."""
    overrides = list(overrides)
    for item in overrides:
        key, _, value = str(item).partition("=")
        if key.strip().startswith("base.") and key.strip() != "base.":
            raise InputError(f"{key.strip()} is in base, the {file}'s own key, and --set sets what base holds (the "
                             f"run config): --set {shell_word(f'{key.strip()[5:]}={value.strip()}')}", source=source,
                             key=f"--set {item.strip()}")
    refuse_set(overrides, {k: f"the {file}'s own key, and --set sets its base (the run config): change {k} in "
                              f"the {file}" for k in dict.fromkeys(("base", *keys, "description"))}, source)


def run_study(source: str, out: Path, name: str, points: Iterable[Any],
              run_point: Callable[[Any, Path], dict | list[dict] | None], *, columns: Iterable[str] = (),
              marker: str | None = None, config=None, finish: Callable[[list[dict], Path], list[dict]] | None = None,
              files: Callable[[list[dict]], dict[str, Any]] | None = None,
              progress: Callable[[dict], None] | None = None, started: float | None = None,
              overrides: Iterable[str] = ()) -> list[dict]:
    """Run ``points`` into the folder ``out``; the rows written, in the order computed.

    ``run_point(point, folder)`` computes one point (it may write into ``folder``, the
    temporary output folder) and returns its row, a list of rows, or None. ``finish(rows,
    folder)`` may rewrite the rows once every point ran (errors relative to a reference
    point, say). The rows go to ``<name>.jsonl`` and ``<name>.csv`` (``columns`` first);
    ``config`` (a RunConfig) to ``config.resolved.yaml``; ``files(rows)`` names further
    files (``.json`` values are written as JSON, ``.yaml`` as YAML, a str as text); then
    ``provenance.json``. ``marker`` (default ``<name>.jsonl``) marks an earlier output of
    this study, which may be replaced; the destination is checked before any work.
    ``progress(row)`` is called after each row. ``started`` (a ``time.perf_counter()``
    reading) dates the study's start for ``provenance.json`` when its set-up ran before.
    ``overrides``: the ``--set`` strings the study's base was run with, which ``provenance.json``
    records (``overrides``, where any was given).
    """
    start = time.perf_counter() if started is None else started
    marker = marker or f"{name}.jsonl"
    check_destination(out, marker)
    rows: list[dict] = []
    with atomic_folder(out, marker, owned=_owned(Path(out))) as tmp:
        for point in points:
            got = run_point(point, tmp)
            for row in [] if got is None else [got] if isinstance(got, dict) else got:
                rows.append(row)
                if progress is not None:
                    progress(row)
        if finish is not None:
            rows = finish(rows, tmp)
        write_rows(tmp, name, rows, columns)
        if config is not None:
            write_file(tmp / "config.resolved.yaml", dump_yaml(to_dict(config), sort_keys=False))
        for fname, value in (files(rows) if files is not None else {}).items():
            write_file(tmp / fname, _text(fname, value))
        made = provenance(source, time.perf_counter() - start)
        overrides = [str(o) for o in overrides]
        if overrides:  # (the --set strings the study's configs were made with: their values are in its configs)
            made = {"study": made.pop("study"), "overrides": overrides, **made}
        write_file(tmp / "provenance.json", json_text(made, indent=2) + "\n")
        names = sorted({*os.listdir(tmp), MANIFEST, "report"})  # (as bytes: a name as the file system holds it)
        write_file(tmp / MANIFEST, b"".join(os.fsencode(n) + b"\n" for n in names))
    return rows


MANIFEST = ".tlm-files"  # the names a study wrote in its folder (the module's docstring)


def _owned(out: Path) -> set[str] | None:
    """The names an earlier study in ``out`` wrote (its :data:`MANIFEST`), which a rerun
    replaces; None (replace everything) for a folder without one. Its names are read as ``os.listdir`` gives
    them (``os.fsdecode``: UTF-8 ones as such, or as the surrogates of a ``LC_ALL=C`` process), whatever the
    locale's encoding: a non-ASCII name is its file's, never a decoding error that replaces the user's files too."""
    try:
        return {os.fsdecode(n) for n in (out / MANIFEST).read_bytes().splitlines() if n}
    except OSError:
        return None


def _text(name: str, value: Any) -> str:
    if isinstance(value, str):
        return value
    if name.endswith(".yaml"):
        return dump_yaml(value, sort_keys=False)
    return json_text(value, indent=2, default=str) + "\n"  # (strict JSON: a fit's inf or nan as null)
