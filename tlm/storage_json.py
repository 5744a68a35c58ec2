"""Strict JSON text, the JSON-lines rows appended and read back (out of :mod:`tlm.storage`, which re-exports them).

* :func:`json_text` — the JSON text of every file tlm writes for its user: strict JSON, a
  number that is not finite (inf, nan) written as null, never as ``Infinity`` or ``NaN``;
  :func:`finite` the value it writes (:func:`tlm.storage.write_rows`'s CSV cells too).
* :func:`read_jsonl` — the rows of a JSON-lines file the experiments append to, a last line cut
  off by a killed process left out; :func:`appending` — such a file appended to, its failures
  naming it (:func:`naming`: a write that names no file, ``os.pwrite`` or a flush, named by its path).
* :func:`escaped` — text with each surrogate as an escape (a byte of a file name not UTF-8, ``\\xff``): what a
  CSV cell, a figure's label or a file's text holds of a path or an error naming one, which UTF-8 writes.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO

from tlm.errors import EnvironmentFailure, InputError, environment_problem, surrogates_escaped


def read_jsonl(path: Path, hint: str = "") -> list[tuple[int, dict]]:
    """The rows of a JSON-lines file the experiments append to, with their line numbers.

    A last line cut off while written (no newline at the end of the file: a process
    killed mid-write) is left out; any other line that is not a JSON object is an
    :class:`InputError` naming the file and the line (``hint`` is added to its message).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")  # (as appending writes it, whatever the locale)
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror or e}", source=str(path)) from None
    lines = text.splitlines()
    rows = []
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
        except ValueError:
            if n == len(lines) and not text.endswith("\n"):
                continue  # the row a killed process was writing
            row = None
        if not isinstance(row, dict):
            raise InputError(f"is not a JSON row{hint}", source=str(path), key=f"line {n}")
        rows.append((n, row))
    return rows


@contextmanager
def naming(path: Path) -> Iterator[None]:
    """Name ``path`` in an OSError of the block: a write to a descriptor (``os.pwrite``), a buffered
    file's flush, its flush at close, name no file. The machine's (a full disk, an I/O error: ENOSPC,
    EIO, EDQUOT, ...) is an EnvironmentFailure, ``PATH: cannot write: no space left on device``, as
    :func:`tlm.storage.write_atomic`'s (one already raised naming a file of ``path`` is named ``path``
    too); any other that names no file gets ``path`` as its filename."""
    try:
        yield
    except OSError as e:
        cause = e.__cause__ if isinstance(e, EnvironmentFailure) and isinstance(e.__cause__, OSError) else e
        what = None if isinstance(cause, EnvironmentFailure) else environment_problem(cause, filename=False)
        if what is not None:
            raise EnvironmentFailure(f"cannot write: {what}", source=str(path)) from cause
        if e.filename is None and not isinstance(e, EnvironmentFailure):
            e.filename = os.fspath(path)
        raise


class _Appended:
    """:func:`appending`'s file: its writes and flushes name the file when they fail (:func:`naming`)."""

    def __init__(self, fh: IO, path: Path):
        self._fh, self._path = fh, path

    def write(self, data):
        with naming(self._path):
            return self._fh.write(data)

    def flush(self) -> None:
        with naming(self._path):
            self._fh.flush()


@contextmanager
def appending(path: Path, mode: str = "a", **open_kw) -> Iterator[_Appended]:
    """``path`` open to append to (rows added as they come, not written whole: ``sweep.jsonl``), whose
    open, writes, flushes and close name ``path`` when they fail (:func:`naming`): a full disk is one
    line naming the file, never a bare ``no space left on device``. Where the block fails, its error
    goes on, not the close's (a flush of what it had not written yet, on a full disk failing too)."""
    path = Path(path)
    if "b" not in mode:  # (UTF-8, whatever the locale's encoding, as write_atomic's)
        open_kw.setdefault("encoding", "utf-8")
    with naming(path):
        fh = open(path, mode, **open_kw)  # noqa: SIM115  (closed below, its failure named)
    try:
        yield _Appended(fh, path)
    except BaseException:
        with suppress(OSError):
            fh.close()
        raise
    with naming(path):
        fh.close()


def json_text(value, **dumps_kw) -> str:
    """``json.dumps(value, **dumps_kw)`` as strict JSON: a float that is not finite (``inf``,
    ``-inf``, ``nan``; a numpy float too) anywhere in ``value``, or returned by ``default``, is
    written as null. Python's ``json`` would write ``Infinity`` or ``NaN``, which JSON does not
    have, and which JavaScript, jq and many other readers refuse. Reading back is unchanged:
    ``json.loads`` reads null as None (and still reads the ``Infinity`` of files written before)."""
    default = dumps_kw.pop("default", None)
    if default is not None:
        dumps_kw["default"] = lambda o: finite(default(o))
    try:
        return json.dumps(value, allow_nan=False, **dumps_kw)
    except ValueError as e:
        if "Out of range float values" not in str(e):
            raise  # (a circular reference)
    return json.dumps(finite(value), allow_nan=False, **dumps_kw)


def escaped(text: str) -> str:
    """``text`` with each surrogate as an escape: a byte that a file name of bytes not UTF-8 holds
    (``os.fsdecode(b"run_\\xff")`` is ``run_\\udcff``) as ``\\xff``, any other lone surrogate as ``\\ud800``:
    text that UTF-8 writes (a surrogate raises UnicodeEncodeError) and a font draws. Text without one is as it
    is. (A JSON or YAML file keeps the surrogate as its own escape instead, ``\\udcff``, read back as the same
    path.) :func:`tlm.errors.surrogates_escaped`, which a ``tlm:`` line on stderr shows too."""
    return surrogates_escaped(text)


def finite(value):
    """``value`` with every float in it that is not finite replaced by None (mappings, lists
    and tuples copied; anything else as it is)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite(v) for v in value]
    return value
