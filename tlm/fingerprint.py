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

A class that a registry selects from outside tlm (a plug-in estimator or scheduler) is no part of it: its
own digest, :func:`plugin_digest` (its top-level package's files), joins the keys of what it computes
(:func:`tlm.registry.plugins`).

It also holds a cache entry's own digest, its seal (:func:`sealed`, :func:`seal_problem`): the sha256 of a
reference's or a Mitsuba ground truth's ``meta.json`` (:data:`META_SEAL`), checked as the entry is read
(:func:`read_sealed`), for the two layers that write them (the oracle, the experiments).
"""

from __future__ import annotations

import hashlib
import json
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


# ------------------------------------------------------------------ a plug-in's code (a class from outside tlm)


def plugin_digest(cls: type) -> str:
    """16 hex digits of sha256 over the code of a class a registry selects from outside tlm (a plug-in:
    :func:`tlm.registry.plugins`), which :func:`code_fingerprint` does not read: for each top-level package
    that it or a base class comes from (tlm's own and Python's standard library's left out), the paths and
    bytes of that package's ``.py`` and ``.yaml`` files (:func:`package_files`, as tlm's), or of the one
    module file where it is a module, not a package (``mine.py``, a script's ``__main__``). So an edit of the
    class's module, or of anything of its package it may import, changes it; another package it imports
    (numpy), a data file it reads or a compiled extension does not. A class of no file (typed in an
    interpreter) is keyed by its methods' bytecode and its plain attributes instead. Read when asked, not
    when imported: the registry remembers it per class (:meth:`tlm.registry.Registry.plugin`), so a module
    edited but not imported again keeps its digest."""
    import sys

    h = hashlib.sha256()
    tops = {c.__module__.partition(".")[0] for c in cls.__mro__} - {"tlm", "builtins"}
    for top in sorted(tops - set(sys.stdlib_module_names)):
        h.update(top.encode() + b"\0")
        mod = sys.modules.get(top)
        roots = sorted(getattr(mod, "__path__", None) or [])
        one = None if roots else getattr(mod, "__file__", None)
        files = ([(Path(r), f) for r in roots for f in package_files(Path(r))] if roots
                 else [(Path(one).parent, Path(one))] if one and Path(one).is_file() else [])
        for root, f in files:
            h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
        if not files:  # (no file: the class itself, as the interpreter holds it)
            _bytecode(cls, top, h)
    return h.hexdigest()[:16]


def _bytecode(cls: type, top: str, h) -> None:
    """Feed ``h`` with the methods' bytecode (``marshal``) and the plain attributes (numbers, strings) of
    ``cls`` and its bases of the module ``top``, in a fixed order."""
    import marshal

    for c in cls.__mro__:
        if c.__module__.partition(".")[0] != top:
            continue
        h.update(c.__qualname__.encode() + b"\0")
        for name, value in sorted(vars(c).items()):
            fn = getattr(value, "__func__", getattr(value, "fget", value))
            code = getattr(fn, "__code__", None)
            if code is not None:
                h.update(name.encode() + b"\0" + marshal.dumps(code) + b"\0")
            elif isinstance(value, (bool, int, float, str, bytes, type(None))):
                h.update(name.encode() + b"\0" + repr(value).encode() + b"\0")


# ------------------------------------------------------------------ a cache entry's own digest (its seal)


def sealed(doc: dict, field: str) -> dict:
    """``doc`` (a cache entry's metadata: a reference's or a ground truth's ``meta.json``) with ``field`` the sha256
    of the canonical JSON of the rest of it (its keys sorted, no spaces; a float's repr round-trips), so that a value
    changed in the file (a byte of a count) is told from what was written, as a functional sidecar's own
    ``sidecar_sha256`` is (:func:`tlm.experiments.frames.sealed`, the same digest)."""
    rest = {k: v for k, v in doc.items() if k != field}
    text = json.dumps(rest, sort_keys=True, separators=(",", ":")).encode()
    return {**rest, field: hashlib.sha256(text).hexdigest()}


def seal_problem(doc: dict, field: str) -> str | None:
    """Why ``doc`` (as read) is not what :func:`sealed` wrote (its ``field`` missing, or not the digest of the
    rest of it), or None."""
    held = doc.get(field)
    if not isinstance(held, str):
        return f"it has no {field!r}"
    if sealed(doc, field)[field] != held:
        return f"its content differs from its {field!r}"
    return None


META_SEAL = "meta_sha256"  # a reference's or a ground truth's meta.json: the digest of the rest of it (sealed)
_OLDER: set[str] = set()  # the entries of an older tlm (no seal) said in this process (read_sealed)


def read_sealed(folder: Path, name: str, key: str, what: str, again: str, fmt: str, renew: str,
                fields: dict | None = None, optional: dict | None = None):
    """:func:`tlm.caches.cached_image` of the entry ``folder`` (its image ``name`` and ``meta.json``, of
    :func:`sealed` ``meta.json``: its ``format`` ``fmt`` and its own digest :data:`META_SEAL`), or None.

    Its ``meta.json`` not as its digest says, without it or without its ``format`` (where it has either), or of a
    format that is none of tlm's, is a damaged entry: said once as a warning naming the file, removed (only where
    the folder is still the one read: not one another process put in its place meanwhile), and computed again
    (``what``, ``again``: as :func:`~tlm.caches.cached_image` says it). One of another format of the same name
    (another tlm's) is not read, nor removed: computed again and replaced, quietly, as a functional sidecar of
    another format is. One with neither (written by a tlm before the seals, 2026-12-03) is used as it is (computing
    it again, a reference minutes, a ground truth up to hours, is the user's call: ``renew`` says how) and sealed
    in place as read (:func:`_seal_as_read`: its owner, a cache that can be written), said once, so that later
    runs read it quietly; one that cannot be sealed (another user's, a read-only cache) is said once in this
    process: a value changed in it cannot be told."""
    import os

    from tlm.caches import cached_image, remove_entry
    from tlm.storage import warn

    for _ in range(5):
        try:  # (held open: the folder read is told from one put in its place meanwhile, as cached_image does)
            held = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
        except OSError:
            held = None
        try:
            found = cached_image(folder, name, key, what, again, fields, optional)
            if found is None:
                return None
            kind, why = seal_state(found[1], fmt, what)
            if kind == "older":
                if (now := _seal_as_read(folder, held, found[1], fmt)) is not None:
                    warn(f"{what} cache entry {folder} was written by an older tlm, its meta.json without "
                         f"{META_SEAL!r} (a digest of its own): sealed as read, so a value changed in it from now on "
                         f"is told (one changed before cannot be: {renew})")
                    return found[0], now
                if str(folder) not in _OLDER:
                    _OLDER.add(str(folder))
                    warn(f"{what} cache entry {folder} was written by an older tlm: its meta.json has no "
                         f"{META_SEAL!r} (a digest of its own), so a value changed in it cannot be told; it is used "
                         f"as it is ({renew})")
                return found
            if kind == "other":
                return None  # (another tlm's: computed again and replaced)
            if why is None:
                return found
            try:
                still = held is not None and os.path.samestat(os.stat(folder), os.fstat(held))
            except OSError:
                still = False
            if not still:
                continue  # (replaced while it was read: read the new one)
            left = remove_entry(folder, folder.parent)
        finally:
            if held is not None:
                os.close(held)
        done = "removed" if left is None else f"not removed ({left})"
        warn(f"damaged {what} cache entry {folder / 'meta.json'} ({why}): {done}; {again}")
        return None
    return None


def seal_state(meta: dict, fmt: str, what: str) -> tuple[str | None, str | None]:
    """How :func:`read_sealed` takes the ``meta.json`` ``meta`` of an entry whose writer's format is ``fmt``:
    ``("older", None)``, written before the seals (no ``format``, no :data:`META_SEAL`: used as it is);
    ``("other", None)``, another tlm's format of the same name (computed again, quietly); ``(None, why)``, a
    damaged one (why); ``(None, None)``, sealed and whole. What ``tlm sweep --dry-run`` counts as cached, too."""
    got = meta.get("format")
    if got is None and META_SEAL not in meta:
        return "older", None
    if isinstance(got, str) and got != fmt and got.partition("/")[0] == fmt.partition("/")[0]:
        return "other", None
    return None, (seal_problem(meta, META_SEAL) if got == fmt else f"it has no {'format'!r}" if got is None
                  else f"format {json.dumps(got)[:60]}: not a {what} cache entry's")


def _seal_as_read(folder: Path, held: int | None, meta: dict, fmt: str) -> dict | None:
    """Seal in place the ``meta.json`` of the older entry ``folder`` (no format, no digest) as it was read, ``meta``,
    its image checked against it (:func:`read_sealed`): written whole in its place (:func:`tlm.storage.write_into`,
    under the folder's lock), only where this user owns it, the folder can be written, and the folder and its
    ``meta.json`` are still those read (``held``, the folder's descriptor as it was read): the sealed ``meta``, or
    None where it was left as it is (another user's, a read-only or full cache, replaced meanwhile)."""
    import os

    from tlm.errors import EnvironmentFailure
    from tlm.storage import write_into

    path = folder / "meta.json"
    try:
        if held is None or os.stat(path, follow_symlinks=False).st_uid != os.geteuid() \
                or not os.access(folder, os.W_OK):
            return None
    except OSError:
        return None

    def keep(at: Path) -> bool:  # (the folder read, its meta.json as read: not one put in their place meanwhile)
        try:
            return os.path.samestat(os.stat(at), os.fstat(held)) and json.loads(path.read_bytes()) == meta
        except (OSError, ValueError):
            return False

    now = sealed({**meta, "format": fmt}, META_SEAL)
    try:
        return now if write_into(folder, "meta.json", json.dumps(now, indent=2) + "\n", keep) else None
    except (OSError, EnvironmentFailure):
        return None
