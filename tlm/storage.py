"""Files and folders that appear whole or not at all: the one place tlm writes atomically.

* :func:`write_atomic` — one file, written beside its destination and renamed onto it;
  :func:`write_file` the same for a ready ``str`` or ``bytes``.
* :func:`atomic_folder` — an output folder (a run, a sweep, a study).
* :func:`write_rows` — the one writer of result rows: ``<name>.jsonl`` and ``<name>.csv``.
* :func:`cache_root` — where the caches live (``$TLM_CACHE``, default ``~/.cache/tlm``).

For a folder, everything is written into a temporary sibling folder, which is renamed onto the
destination only when the block finished; on any error (or Ctrl-C) the temporary
folder is removed and an earlier folder of the same name is left as it was.

An existing destination is replaced only if it is an earlier output of the same kind:
a folder holding the ``marker`` file (``results.json`` for a run folder), or an empty
folder. Anything else — a file, a folder of other things, the current folder or one of
its parents — is refused with an :class:`~tlm.errors.InputError`, so ``--out .`` can
never delete a checkout.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

from tlm.errors import InputError


def check_destination(out: Path, marker: str, key: str = "--out") -> Path:
    """The resolved destination, or an InputError saying why it may not be written."""
    out = Path(out)
    resolved = out.resolve()
    cwd = Path.cwd().resolve()
    if resolved == cwd or resolved in cwd.parents:
        raise InputError(f"{str(out)!r} is the current folder or one of its parents; name a new folder",
                         key=key)
    if resolved.exists():
        if not resolved.is_dir():
            raise InputError(f"{str(out)!r} exists and is not a folder", key=key)
        if any(resolved.iterdir()) and not (resolved / marker).is_file():
            raise InputError(f"{str(out)!r} exists and is not an earlier tlm output (no {marker}); "
                             "refusing to replace it", key=key)
    return resolved


@contextmanager
def atomic_folder(out: Path, marker: str) -> Iterator[Path]:
    """Yield a fresh temporary folder that replaces ``out`` when the block succeeds.

    ``marker`` is the file that marks an earlier output of this kind (it may be
    replaced); the block must write it.
    """
    out = check_destination(out, marker)
    tmp = out.parent / f".{out.name}.tmp-{os.getpid()}"
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
    except OSError as e:
        raise InputError(f"cannot create the output folder ({e.strerror})", source=str(out)) from None
    try:
        yield tmp
        if not (tmp / marker).is_file():
            raise RuntimeError(f"an output folder was written without its {marker}")
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def read_jsonl(path: Path, hint: str = "") -> list[tuple[int, dict]]:
    """The rows of a JSON-lines file the experiments append to, with their line numbers.

    A last line cut off while written (no newline at the end of the file: a process
    killed mid-write) is left out; any other line that is not a JSON object is an
    :class:`InputError` naming the file and the line (``hint`` is added to its message).
    """
    path = Path(path)
    try:
        text = path.read_text()
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
def write_atomic(path: Path, mode: str = "w", **open_kw) -> Iterator[IO]:
    """An open file that replaces ``path`` when the block succeeds.

    The data go to a hidden sibling (``.<name>.tmp<pid>``, so concurrent writers of one
    path never share it) that is renamed onto ``path`` at the end; on any error the
    sibling is removed and ``path`` is left as it was.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, mode, **open_kw) as fh:
            yield fh
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_file(path: Path, data: str | bytes) -> None:
    """``data`` as the whole of ``path``, atomically (:func:`write_atomic`)."""
    with write_atomic(path, "wb" if isinstance(data, bytes) else "w") as fh:
        fh.write(data)


def write_rows(folder: Path, name: str, rows: Iterable[dict], columns: Iterable[str] = ()) -> None:
    """Result rows as ``folder/<name>.jsonl`` (one JSON object a line) and ``<name>.csv``.

    The CSV's columns are ``columns`` first, then every other key of the rows in the
    order it first appears; a list or mapping value is written as JSON in its cell.
    Both files are written atomically.
    """
    rows = list(rows)
    cols = list(columns)
    for r in rows:
        cols.extend(k for k in r if k not in cols)
    folder = Path(folder)
    write_file(folder / f"{name}.jsonl", "".join(json.dumps(r) + "\n" for r in rows))
    with write_atomic(folder / f"{name}.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: json.dumps(v) if isinstance(v, (list, dict)) else v for k, v in r.items()})


def cache_root(kind: str) -> Path:
    """``$TLM_CACHE/<kind>`` (default ``~/.cache/tlm/<kind>``)."""
    return Path(os.environ.get("TLM_CACHE") or Path.home() / ".cache" / "tlm") / kind
