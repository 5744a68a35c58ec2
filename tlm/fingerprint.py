"""The one fingerprint of tlm's code, part of every cache key and every sweep point's hash.

It covers the whole package: every ``.py`` and ``.yaml`` file under ``tlm/``, by path
and content. Any edit of the source therefore invalidates the functional cache, the
references and a sweep's finished points: a cached result is always one that the
code in hand would produce. (A narrower key, over the files one believes matter, is
what let an edit of ``arch/functional.py`` or ``experiments/run.py`` reuse stale
work counts before.)

It is the same for one commit in a checkout and installed from its wheel: the folders the
wheel adds to the package from outside it (pyproject.toml's ``force-include``: the
repository's ``scenes/`` as ``tlm/_scenes`` and ``configs/`` as ``tlm/_configs``), which
a checkout keeps beside ``tlm/``, are not read. Those are data, not code, and every key
that depends on a scene hashes the scene's own content (the functional key, the reference's, the scene cache's entries).
:func:`added` tells them: a top-level folder of the package named in :data:`ADDED`.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

ROOT = Path(__file__).resolve().parent

# the folders pyproject.toml's force-include adds to the wheel's package (data, not code);
# any other folder of the package is code and is hashed, whatever its name
ADDED = ("_scenes", "_configs")
_CODE: str | None = None


def added(root: Path, f: Path) -> bool:
    """Whether ``f`` is in a folder the wheel adds to the package (``_scenes/``): a folder
    directly in ``root`` whose name starts with ``_``."""
    parts = f.relative_to(root).parts
    return len(parts) > 1 and parts[0] in ADDED


def package_files(root: Path = ROOT) -> list[Path]:
    """The files the fingerprint reads, sorted by their path below ``root``: every ``.py``
    and ``.yaml`` but those of ``__pycache__`` and of the folders the wheel adds (:func:`added`)."""
    files = [f for pat in ("*.py", "*.yaml") for f in root.rglob(pat)
             if "__pycache__" not in f.parts and not added(root, f)]
    return sorted(files, key=lambda f: f.relative_to(root).as_posix())


def fingerprint(root: Path = ROOT) -> str:
    """16 hex digits of sha256 over the paths and bytes of :func:`package_files`."""
    h = hashlib.sha256()
    for f in package_files(root):
        h.update(f.relative_to(root).as_posix().encode() + b"\0")
        h.update(f.read_bytes())
        h.update(b"\0")
    return h.hexdigest()[:16]


def code_fingerprint() -> str:
    """:func:`fingerprint` of the installed package, computed once per process."""
    global _CODE
    if _CODE is None:
        _CODE = fingerprint()
    return _CODE


def use_code(code: str) -> None:
    """Take ``code`` as this process's :func:`code_fingerprint` from now on: a sweep's worker adopts the
    sweep's, the code its fork server imported (:func:`tlm.experiments.executors.LocalPool`), rather than
    hash the package files as they are on the disk at its first point. A Dask worker (a remote one, or
    one of the sweep's own ``--dask local`` cluster, a new interpreter) keeps its own, which must equal
    the sweep's (its points are refused otherwise, with why: :mod:`tlm.experiments.sweep_point`)."""
    global _CODE
    _CODE = code
