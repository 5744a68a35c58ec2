"""What :func:`tlm.config.read_yaml` says of a file it reads that is no YAML file, by the role of a
YAML file read where a config or a scene file goes: a mesh file given through a pipe (``tlm run
<(cat pawn.obj)``), told by its bytes as a mesh file given by its name is (:func:`yaml_text`), and a
file too large to be one (:class:`TooLarge`), whose hint names a scene file's ``geometry`` there only,
not where another reader of :func:`tlm.config.read_text` (an ``arch.programs`` table) read it; and the text of the
bytes such a file holds (:func:`decoded`: UTF-8 whatever the locale, told as a mesh's or not before it is decoded);
what a config given by a name of no file of its own is (:func:`nameless`), and the absolute path a run folder records
of its config file, and the ``--set`` strings of a command it prints, to find them again from another folder
(:func:`config_file`, :func:`rerun_sets`)."""

from __future__ import annotations

import os
import stat
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from tlm.errors import InputError
from tlm.mesh_files import MESH_FORMATS, descriptor_name, mesh_bytes_format, piped_mesh_hint

# what a file too large to be a YAML file tlm reads is where a config or a scene file goes (read_yaml's)
MESH_NAMED = "a mesh is named in a scene file's geometry (docs/scenes.md)"
_PEEKED = 1 << 20  # (bytes of a pipe's text a mesh is told by: a glTF JSON's parse, up to mesh_files' 1 MiB)


class TooLarge(InputError):
    """:func:`tlm.config.read_text`'s file of more than ``MAX_TEXT_BYTES``: its line says the size alone,
    which fits any file read whole (a programs table too); :func:`yaml_text` adds what fits a config's."""


class NotText(InputError):
    """:func:`decoded`'s bytes that are no UTF-8 text (a binary file read where a YAML or a text file goes)."""


def decoded(data: bytes, path: Path) -> str:
    """The text of ``data``, the bytes :func:`tlm.config.read_bytes` read from ``path``, as ``Path.read_text`` gives
    it: UTF-8, whatever the locale's encoding, in universal newlines; bytes that are no UTF-8 a :class:`NotText`
    naming ``path`` and the byte offset in the whole file."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise NotText(f"not a UTF-8 text file (byte 0x{e.object[e.start]:02x} at offset {e.start})",
                      source=str(path)) from None
    return text.replace("\r\n", "\n").replace("\r", "\n")


def yaml_text(path: Path, read: Callable[[Path], bytes]) -> str:
    """The text of ``read(path)``'s bytes (:func:`tlm.config.read_bytes`, one read) where a YAML config or scene file
    goes: a file too large to be one is said with where a mesh goes (:data:`MESH_NAMED`), and one read from a pipe
    or a FIFO (no regular file, whose first bytes :func:`tlm.config.read_yaml` peeks at before) that holds a
    mesh file's bytes is an InputError with the line a mesh file given by its name gets, not its parse's
    (``must be a mapping``, ``not a UTF-8 text file``). The mesh is told by the bytes as read, before they are
    decoded (a binary STL whose bytes are UTF-8 holding ``\\r\\n`` pairs is no STL of its size once its newlines
    are made ``\\n``)."""
    try:
        data = read(path)
    except TooLarge as e:
        raise e.replaced(message=f"{e.message}: {MESH_NAMED}") from None
    if not os.path.isfile(path):
        _refuse_mesh(path, data[:_PEEKED], len(data))
    return decoded(data, path)


def _refuse_mesh(path: Path, head: bytes, size: int) -> None:
    """An InputError where the bytes read from the pipe ``path`` (``head``, the first of ``size``) are a mesh
    file's (:func:`~tlm.mesh_files.mesh_bytes_format`: an MTL library's are left to the YAML parse), saying so as
    :func:`~tlm.mesh_files.mesh_file_hint` says it of a mesh file, and to save it as one first."""
    format_ = mesh_bytes_format(head, size)  # (by the bytes themselves: any system, no file made of them)
    if format_ is None or format_ not in MESH_FORMATS.values():
        return
    hint = piped_mesh_hint(format_)  # (as of a file named mesh.obj, and to save it so first)
    raise InputError(hint, source=str(path))


def nameless(path: str | os.PathLike) -> str | None:
    """What the file ``path`` is where its name is none of its own, or where its text is read once, which a folder
    or a command named after it would not find again: ``"a pipe"`` (``tlm run <(...)``'s ``/dev/fd/63``, a piped
    ``/dev/stdin``: read once, its text gone, in no folder), ``"a named FIFO"`` (``mkfifo c``: a name and a folder
    of its own, which its relative paths start at, :func:`tlm.config.file_folder`, but read once too: ``runs/c``
    would be the folder of every config written to it), ``"a file descriptor's name"`` (a file given as
    ``/dev/stdin < cornell.yaml``: every such config's name is ``stdin``); None for a file of a name of its own, a
    folder, and what is not there."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return None
    if stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode):
        try:  # (a pipe's /dev/fd/63 resolves to /proc/PID/fd/pipe:[N], which is in no folder)
            named = stat.S_ISFIFO(mode) and Path(path).resolve().exists()
        except (OSError, RuntimeError):
            named = False
        return "a named FIFO" if named else "a pipe"
    if stat.S_ISREG(mode) and descriptor_name(path):
        return "a file descriptor's name"
    return None


def config_file(config_path: str | os.PathLike | None, base: str | os.PathLike | None = None) -> str | None:
    """``results.json``'s ``config_file``: the absolute path, links resolved (the file whose folder its relative paths
    start at, :func:`tlm.config.file_folder`), of the config file ``config_path`` names as the run was given it
    (``../exp/a.yaml``: from the working folder of then), which a reader in another folder finds again; None where
    there is none to find again: no file (a mapping's None, a description), a config read once (:func:`nameless`: a
    pipe, a named FIFO, ``/dev/stdin``), whose every setting the run folder's ``config.resolved.yaml`` keeps.
    ``base``: the folder the config was read from (the run's): a relative path that names a file of another folder
    from here (``tlm.api.load_config('a.yaml')``, then ``os.chdir``, then ``tlm.api.run``: another ``a.yaml``, or
    none) is looked for there by its name, else None: never another file than the one the run read."""
    if not config_path:
        return None
    try:
        path = Path(config_path)
        found = path.resolve() if nameless(path) is None and path.is_file() else None
        if base is not None and not path.is_absolute():
            own = Path(base) / path.name  # (where the run read it: its folder, links resolved, tlm.config.file_folder)
            if found is None or (found.parent != Path(base).resolve() and found != own.resolve()):
                found = own.resolve() if own.is_file() and nameless(own) is None else None
        return None if found is None else str(found)
    except (OSError, ValueError, RuntimeError):
        return None


def rerun_sets(overrides: Iterable[str] | None, read: Callable[[str], Any] | None = None) -> list[str]:
    """The ``--set`` strings ``overrides``, given in this working folder, as a command run from another folder takes
    them (``tlm reference``'s, that ``results.json`` records): a relative path given to ``scene`` or to a key of
    ``PATH_KEYS`` absolute, as :func:`tlm.config.apply_overrides` took it (``scene=my.yaml``; not a built-in scene's
    name, ``scene=cornell``); every other as given. Each value read by ``read``, as ``--set`` reads it (the run's
    :func:`tlm.config.read_set_value`, which tlm.config, above this module, has: a byte not UTF-8 in a folder's name,
    ``scene=dir_\\xff/s.yaml``, too; None: plain YAML, :func:`~tlm.config_words.parse_yaml`), the path written back so
    that it reads as itself: in YAML's single quotes where it would read as another value (``/a: b #1/s.yaml``)."""
    from tlm.config_paths import paths_from, scene_from  # (tlm.config, which imports this module, has them)
    from tlm.config_words import parse_yaml

    reader = read or parse_yaml
    out = []
    for item in map(str, overrides or ()):
        key, _, text = item.partition("=")
        key, found = key.strip(), None
        try:
            value = reader(text)
            found = scene_from(value, [Path.cwd()], False) if key == "scene" else paths_from(key, value, Path.cwd())
            if isinstance(found, str) and found != value:
                found = next((t for t in (found, "'" + found.replace("'", "''") + "'")
                              if _reads_as(reader, t, found)), None)
            else:
                found = None
        except Exception:  # (a value the run refused would have stopped it: kept as given)
            found = None
        out.append(f"{key}={found}" if found else item)
    return out


def _reads_as(read: Callable, text: str, value: str) -> bool:
    """Whether ``--set`` reads ``text`` (by ``read``, :func:`tlm.config.read_set_value`) as the string ``value``."""
    try:
        return read(text) == value
    except Exception:  # (YAML's refusal of it)
        return False
