"""The swap of a writer's finished temporary folder for its destination (out of :mod:`tlm.storage`, which imports
every name from here under its old name: :func:`swap_in` as ``_swap_in``): in one call where the file system can
exchange two paths (:func:`tlm.storage_lock.exchange`), else by two renames, the old folder put back where the new
one cannot follow; a destination that turns out to be a mount point refused (:func:`mounted`).
"""

from __future__ import annotations

import errno
import itertools
import shutil
from contextlib import suppress
from pathlib import Path

from tlm import storage_lock
from tlm.errors import InputError, quoted
from tlm.storage_live import _hold, _release, _writer, sibling_stem


def mounted(out: Path) -> str:
    """The refusal of a destination that is a mount point."""
    return f"{quoted(out)} is a mount point, which cannot be replaced; name a folder inside it"


def swap_in(tmp: Path, out: Path, writer: str | None = None) -> None:
    """Put ``tmp`` in place of ``out``: an old ``out`` swapped for it in one call where the file system
    can (:func:`tlm.storage_lock.exchange`; then removed, at ``tmp``'s name), else moved aside first and
    removed after (the old folder back where ``tmp`` cannot follow or a signal comes between the two);
    retried when another writer put a folder there in between. ``writer``: the :func:`_writer` the names
    of the old folders carry (a new one when not given)."""
    writer = writer or _writer()
    held: list[str] = []
    try:
        swap_tries(tmp, out, writer, held)
    finally:
        for name in held:
            _release(name)


def swap_tries(tmp: Path, out: Path, writer: str, held: list[str]) -> None:
    """:func:`swap_in`'s loop; ``held`` gets the old folders' names it noted as in use."""
    for n in itertools.count():
        try:
            if out.exists() and storage_lock.exchange(tmp, out):
                shutil.rmtree(tmp, ignore_errors=True)  # (the old folder, at the temporary folder's name now)
                return
        except FileNotFoundError:
            pass  # (moved meanwhile: by a writer that renames twice, between its renames: renamed onto below)
        except OSError as e:  # (a mount point is_mount missed: EBUSY)
            if e.errno == errno.EBUSY:
                raise InputError(mounted(out), key="--out") from None
            raise
        old = None
        if out.exists():  # (a file system without the exchange, or another OS: two renames)
            old = out.parent / f".{sibling_stem(out, strict=False)}.old-{writer}-{n}"  # (a long name's: NAME_MAX)
            _hold(old.name)
            held.append(old.name)
            try:
                out.rename(old)
            except FileNotFoundError:
                old = None  # another writer moved it first
            except OSError as e:  # (a mount point is_mount missed: it stays as it is, and so does the output)
                if e.errno == errno.EBUSY:
                    raise InputError(mounted(out), key="--out") from None
                raise
        try:
            tmp.rename(out)
        except OSError as e:
            if e.errno in (errno.ENOTEMPTY, errno.EEXIST) and n < 100:
                if old is not None:
                    shutil.rmtree(old, ignore_errors=True)
                continue  # another writer's folder arrived meanwhile: it is replaced in turn
            if old is not None and not out.exists():
                with suppress(OSError):
                    old.rename(out)  # put the old folder back
            raise
        except BaseException:  # a signal between the two renames: the old folder goes back
            if old is not None and not out.exists():
                with suppress(OSError):
                    old.rename(out)
            raise
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        return
