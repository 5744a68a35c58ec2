"""Strict JSON text and the JSON-lines rows read back (out of :mod:`tlm.storage`, which re-exports them).

* :func:`json_text` — the JSON text of every file tlm writes for its user: strict JSON, a
  number that is not finite (inf, nan) written as null, never as ``Infinity`` or ``NaN``;
  :func:`finite` the value it writes (:func:`tlm.storage.write_rows`'s CSV cells too).
* :func:`read_jsonl` — the rows of a JSON-lines file the experiments append to, a last line cut
  off by a killed process left out.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from tlm.errors import InputError


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
