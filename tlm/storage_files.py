"""Several files written all or none: :func:`write_files`, the body of :func:`tlm.storage.write_files`
(out of :mod:`tlm.storage`, which passes it its own ``write_file`` and ``process_tag``)."""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable, Sequence
from contextlib import suppress
from pathlib import Path

from tlm.errors import EnvironmentFailure
from tlm.storage_errors import write_problem
from tlm.storage_live import sibling_stem

_STAGED = itertools.count()  # (numbers write_files's hidden files in this process)


def write_files(files: Sequence[tuple[Path, str | bytes]], write_file: Callable[[Path, str | bytes], None],
                process_tag: Callable[[], str]) -> None:
    """Each ``(path, data)`` of ``files`` as the whole of ``path``: all of them, or none.

    Each is written to a hidden file of its own beside its path (``.<name>.new<host>-<pid>-<n>``,
    written by :func:`tlm.storage.write_file`), and these are renamed onto the paths, in order, only
    once all are written; an earlier file of a path is moved aside (``.<name>.old<host>-<pid>-<n>``)
    until all are in place. On any error (a full disk), a signal included, the new files are removed
    and every path is left as it was: one renamed already gets its earlier file back, or is removed
    where it had none. A full disk (an OSError of the machine's) is an EnvironmentFailure naming the
    path that did not fit, not its hidden file. ``write_file`` writes one file whole, ``process_tag`` names
    this process (:func:`tlm.storage.write_file`, :func:`tlm.storage.process_tag`)."""
    files = [(Path(p), data) for p, data in files]
    staged: list[tuple[Path, Path, Path]] = []  # (path, its new file, its earlier file's name while aside)
    renaming = -1  # (the index of the path being renamed onto; those before it are in place)
    try:
        for path, data in files:
            tag = f"{process_tag()}-{next(_STAGED)}"
            stem = sibling_stem(path, strict=False)  # (a long name's: within NAME_MAX)
            new, old = path.with_name(f".{stem}.new{tag}"), path.with_name(f".{stem}.old{tag}")
            staged.append((path, new, old))  # (before it exists: a signal after its rename still removes it)
            try:
                write_file(new, data)
            except EnvironmentFailure as e:
                what = write_problem(e.__cause__, path) if isinstance(e.__cause__, OSError) else None
                if what is None:
                    raise
                raise EnvironmentFailure(f"cannot write: {what}", source=str(path)) from e.__cause__
        for i, (path, new, old) in enumerate(staged):
            renaming = i
            with suppress(FileNotFoundError):  # (none before)
                os.rename(path, old)
            os.replace(new, path)
    except BaseException:
        for i, (path, new, old) in reversed(list(enumerate(staged))):
            with suppress(OSError):
                if i <= renaming and os.path.lexists(old):  # (moved aside: back, over the new file if it came)
                    os.replace(old, path)
                elif i <= renaming and not os.path.lexists(new):  # (renamed in where none was before)
                    path.unlink(missing_ok=True)
            with suppress(OSError):
                new.unlink(missing_ok=True)
        raise
    for _path, _new, old in staged:
        with suppress(OSError):
            old.unlink(missing_ok=True)
