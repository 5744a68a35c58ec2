"""The shared frame of study files (``tlm thesis``, ``tlm granularity``, ``tlm error-vs-cost``).

A study file is a YAML mapping with a ``base`` run config (a mapping), an optional
``description`` and the study's own keys. :func:`read_study` reads it and checks that
frame, so every study rejects a non-mapping, an unknown key or a bad ``base`` with
the same one-line errors (file and key named, exit status 2 through the CLI).
Result rows go through :func:`tlm.storage.write_rows`, as every experiment's do.
"""

from __future__ import annotations

from pathlib import Path

from tlm.config import read_yaml
from tlm.errors import InputError


def read_study(path: Path, keys: tuple[str, ...]) -> tuple[dict, dict, str]:
    """``(raw, base, source)`` of the study file ``path`` whose own keys are ``keys``."""
    raw = read_yaml(path)
    src = str(path)
    allowed = ("base", *keys, "description")
    if not isinstance(raw, dict):
        raise InputError(f"must be a mapping with {', '.join(allowed[:-1])}", source=src)
    for key in raw:
        if key not in allowed:
            raise InputError(f"unknown key (expected {', '.join(allowed)})", source=src, key=str(key))
    base = raw.get("base") or {}
    if not isinstance(base, dict):
        raise InputError("must be a run config mapping", source=src, key="base")
    return raw, base, src
