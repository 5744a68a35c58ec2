"""Which converged reference the cache keeps, its files, and the settings it is judged by.

A reference (:mod:`tlm.experiments.reference`) is computed with :class:`ReferenceSettings`: the
photons and ``k_nearest`` of its key, and its stopping rule (:data:`RULE`). The cache folder
``references/<key>/`` (:func:`cache_dir`) holds one reference per key,
``reference.npy`` and ``meta.json`` (:func:`save_reference`, :func:`load_reference`). A
reference computed now replaces the cached one only where it is better (:func:`better`,
:func:`store_reference`: it meets the tolerance asked for now (:func:`meets_tolerance`: its
error and rounds, not the flag of the run that computed it) and the cached one does not, or
neither does and its relative standard error is lower), or with ``--force``; a cached one
that misses the tolerance is kept without computing where the settings ask for fewer rounds
(:func:`fewer_rounds`) or where computing it would repeat its rounds (:func:`repeats`: the same
stopping rule, :data:`RULE`, or one that stops it at the same round).

A cache that cannot be written (a read-only ``~/.cache``) loses no reference: it is kept in
the temporary folder (:func:`kept_root`, ``<tmp>/tlm-cache-<uid>/references/<key>``). That
folder is made for this user alone, and one made by someone else first (a link, another
user's folder, one others may write) is not written into (:func:`private_folder`).

A reference computed by ``tlm run`` or ``tlm reference`` saves its rounds at the end of its cycles
beside its entry, ``references/<key>.partial.npz`` (:func:`partial_path`;
:mod:`tlm.experiments.reference_resume`), so that one interrupted resumes from there; the file is removed
once the reference is stored, or could not be (:func:`drop_partial`), and ``tlm cache`` lists it as a partial
with its rounds and prunes it as an entry of its own (:func:`tlm.cache_admin.partial_state`).

A sweep (``tlm sweep --reference``) holds its own copy of each reference its points are measured
against, for the sweep's duration (:func:`holding`): a point reads it there first, so that a
``tlm cache prune`` meanwhile, or a cache that could not take a reference the sweep computed,
costs no point its error.
"""

from __future__ import annotations

import contextlib
import contextvars
import json
import math
import os
import stat
import tempfile
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from tlm.cache_admin import partial_info, partial_rounds  # (the one reader of a partial's header, re-exported)
from tlm.caches import cache_problem, cache_root, file_digest
from tlm.config import ReferenceConfig, RunConfig
from tlm.errors import EnvironmentFailure, InputError, shell_word
from tlm.fingerprint import META_SEAL, read_sealed, sealed
from tlm.scenes.model import Scene
from tlm.storage import atomic_folder


@dataclass(frozen=True)
class ReferenceSettings:
    photons: int  # per round
    k_nearest: int = 100
    tolerance: float = 0.02
    min_rounds: int = 4
    max_rounds: int = 128
    spp: int = 4  # rounds of a cycle, one eye ray per pixel each, stratified over the pixel

    @classmethod
    def from_config(cls, scene: Scene, cfg: RunConfig) -> ReferenceSettings:
        r = cfg.reference
        return cls(photons=scene.photons if r.photons is None else r.photons, k_nearest=r.k_nearest,
                   tolerance=r.tolerance, min_rounds=r.min_rounds, max_rounds=r.max_rounds, spp=r.spp)


def cache_dir() -> Path:
    return cache_root("references")


def save_reference(key: str, image: np.ndarray, meta: dict, root: Path | None = None, private: bool = True) -> Path:
    """Write ``reference.npy`` and ``meta.json`` (:data:`META_FORMAT`, sealed with its own digest,
    :func:`~tlm.fingerprint.sealed`) atomically into the cache (or ``root``):
    an :class:`~tlm.errors.EnvironmentFailure` naming why where its folder cannot be written.
    ``private``: a ``root`` is made this user's only first (:func:`private_folder`; not for a
    sweep's own copy in its output folder, :func:`holding`)."""
    folder = cache_dir() if root is None else Path(root)
    final = folder / key
    why = cache_problem(folder)
    if why is not None:
        raise EnvironmentFailure(f"cannot write: {why}", source=str(final))
    if root is not None and private:  # (a folder outside the cache: kept_root()'s, in a temporary folder others write
        # too)
        private_folder(folder, final)
    with atomic_folder(final, "meta.json") as tmp:
        np.save(tmp / "reference.npy", image.astype(np.float32))
        # (its format and, last, its own digest: a value changed in it is a damaged entry, load_reference)
        body = {"key": key, **meta, "npy": file_digest(tmp / "reference.npy"), "format": META_FORMAT}
        (tmp / "meta.json").write_text(json.dumps(sealed(body, META_SEAL), indent=2) + "\n", encoding="utf-8")
    return final


def npy_digest(image: np.ndarray) -> dict:
    """``{"size": bytes, "sha256": hex}`` of the ``reference.npy`` :func:`save_reference` writes of ``image``
    (float32, its shape as given): what its ``meta.json`` holds as ``npy``, without a file. A run whose
    reference the cache could not take records its sha256 all the same (``results.json``
    ``error.reference_sha256``): the reference computed again with the same settings is the same file."""
    import hashlib
    import io

    buf = io.BytesIO()
    np.save(buf, np.asarray(image).astype(np.float32))
    data = buf.getvalue()
    return {"size": len(data), "sha256": hashlib.sha256(data).hexdigest()}


_NUMBER = (int, float)
# what a reference's meta.json holds, by type: what every reader reads (META_FIELDS), and what
# compute_reference writes besides, which the cache's rules read where it is there (META_OPTIONAL)
META_FIELDS = {"rounds": int, "relative_standard_error": (*_NUMBER, type(None))}
META_OPTIONAL = {"photons": int, "k_nearest": int, "tolerance": _NUMBER, "min_rounds": int, "max_rounds": int,
                 "spp": int, "rounds_per_cycle": int, "cycles": int, "standard_error_per_cycle": list,
                 "converged": bool}
META_FORMAT = "reference-meta/2"  # /2: sealed with its own digest (META_SEAL); an entry of neither is an older tlm's


def load_reference(key: str, root: Path | None = None, again: str = "'tlm reference' computes it again"
                   ) -> tuple[np.ndarray, dict] | None:
    """The cached reference ``key`` and its metadata, or None when there is none (``root``:
    another cache's ``references`` folder than :func:`cache_dir`; ``again``: what computes it).

    A damaged one (``meta.json`` unreadable or of another key, without the size and checksum
    of ``reference.npy`` (an older tlm's), without a key of :data:`META_FIELDS`, or with one of
    it or of :data:`META_OPTIONAL` of another type; ``reference.npy`` not the file
    ``meta.json`` describes, or not an image) is reported once as a warning naming the file
    and removed: it is computed again as if it had never been cached. So is one whose ``meta.json``
    is not as its own digest says (:func:`~tlm.fingerprint.read_sealed`: a value changed in it); one
    written before the seals (no digest, no format) is used, said once in a warning.
    """
    if root is None and (own := (_HELD.get() or {}).get(key)) is not None:  # (a sweep's own copy, :func:`holding`)
        found = _read(Path(own), key, again)
        if found is not None:
            return found
    return _read((cache_dir() if root is None else Path(root)) / key, key, again)


def _read(folder: Path, key: str, again: str) -> tuple[np.ndarray, dict] | None:
    """The reference in ``folder`` (:func:`load_reference`), its ``meta.json``'s seal checked."""
    return read_sealed(folder, "reference.npy", key, "reference", again, META_FORMAT,
                       "'tlm reference --force' computes it again, sealed", META_FIELDS, META_OPTIONAL)


# reference key -> the folder of the copy a sweep holds of it (:func:`holding`): this thread's, while a point runs
_HELD: contextvars.ContextVar[Mapping[str, str] | None] = contextvars.ContextVar("tlm_held_references", default=None)


@contextlib.contextmanager
def holding(folders: Mapping[str, str]) -> Iterator[None]:
    """While the block runs (in this thread), :func:`load_reference` of a key of ``folders`` (reference key ->
    the folder of a copy of it, ``<root>/<key>``) reads that copy first, and the cache only where it is not there:
    a sweep's point (:func:`tlm.experiments.sweep_point.run_point`) is measured against the reference the sweep
    computed or chose for it, which the sweep holds for its duration (in its output folder, which its workers
    see: :func:`tlm.experiments.sweep_reference.hold_references`), whatever the cache holds meanwhile (pruned,
    cleared, or one it could not take)."""
    token = _HELD.set({**(_HELD.get() or {}), **folders})
    try:
        yield
    finally:
        _HELD.reset(token)


def meets_tolerance(meta: dict, settings: ReferenceSettings) -> bool:
    """Whether the reference of ``meta`` meets the stopping rule of ``settings`` asked for now,
    the test :func:`compute_reference` stops at: a relative standard error below
    ``settings.tolerance``, measured over at least two cycles, after at least
    ``settings.min_rounds`` rounds. Judged on its error and rounds, not on its ``converged``
    flag, which says whether it met the tolerance of the run that computed it (one that ran to a
    strict tolerance's ``max_rounds`` may meet a looser one asked for now, and one converged at a
    loose tolerance may miss a stricter one). The test of a cached one in ``tlm reference`` and
    ``tlm error-vs-cost`` (:func:`make_reference`, ``study_reference``) and of which of two is
    better (:func:`better`)."""
    err, rounds, cycles = (meta.get(k) for k in ("relative_standard_error", "rounds", "cycles"))
    return (isinstance(err, (int, float)) and math.isfinite(err) and err < settings.tolerance
            and isinstance(rounds, int) and rounds >= settings.min_rounds
            and (not isinstance(cycles, int) or cycles >= 2))


# the stopping rule's settings: a reference computed with the same ones (and the same key) is the same
RULE = ("tolerance", "min_rounds", "max_rounds", "spp")


def cycle_length(settings: ReferenceSettings) -> int:
    """Rounds per cycle: ``spp``, at most half of ``max_rounds`` (two cycles measure a spread)."""
    return max(1, min(settings.spp, settings.max_rounds // 2))


def rounds_advice(rse, rounds, settings) -> str:
    """The clause ``" to about N (...)"`` that follows "raise reference.max_rounds" in a line on a reference
    whose relative standard error ``rse``, after ``rounds`` rounds, misses ``settings.tolerance`` (a
    :class:`ReferenceSettings` or ``cfg.reference``): the standard error falls as 1/sqrt(rounds), so about
    rounds x (rse / tolerance)^2 rounds reach it, rounded up to whole cycles (:func:`cycle_length`); an
    estimate, the rse being measured (h473). Empty where that is no more rounds than ``rounds`` or either is unknown."""
    if (not isinstance(rse, (int, float)) or isinstance(rse, bool) or not math.isfinite(rse) or rse <= 0
            or not isinstance(rounds, int) or rounds < 1 or rse <= settings.tolerance):
        return ""
    need = math.ceil(rounds * (rse / settings.tolerance) ** 2)
    strata = cycle_length(replace(settings, max_rounds=max(need, settings.max_rounds)))
    need = -(-need // strata) * strata
    how = (f"{rounds} rounds x ({rse:.4f} / {settings.tolerance:g})^2 in whole cycles of {strata}: the relative "
           "standard error falls as 1/sqrt(rounds)")
    limit = next(f.metadata["max"] for f in fields(ReferenceConfig) if f.name == "max_rounds")
    if need > limit:  # (a number reference.max_rounds refuses: the tolerance is the one to change)
        return f" (about {need:.3g} rounds would reach the tolerance, {how}; past its limit {limit}: raise " \
               "reference.tolerance instead)"
    return f" to about {need} ({how})" if need > rounds else ""


def repeats(meta: dict, settings: ReferenceSettings) -> bool:
    """Whether computing the cached reference of ``meta``, which does not meet the tolerance of
    ``settings``, again with ``settings`` would only repeat its rounds to the same image: the rounds
    are seeded alike whatever the settings (cycle ``k`` of the same length is the same), so it does
    where its cycles are as long (:func:`cycle_length`), ``settings`` allow as many cycles as it has
    (``reference.max_rounds``) and none, and no cycle before its last meets their stopping rule
    (its ``standard_error_per_cycle``: it would stop there, converged). True too for one computed
    with the same stopping rule (:data:`RULE`, whatever its metadata holds): one that stopped at
    exactly ``reference.max_rounds`` rounds is kept by the next run asking for no more, whatever
    tolerance it asks for (a stricter one, or a ``max_rounds`` that is no whole number of cycles
    more)."""
    if meets_tolerance(meta, settings):
        return False
    if all(meta.get(k) == getattr(settings, k) for k in RULE):
        return True
    strata, cycles, errors = (meta.get(k) for k in ("rounds_per_cycle", "cycles", "standard_error_per_cycle"))
    if not (isinstance(strata, int) and isinstance(cycles, int) and isinstance(errors, list)
            and len(errors) == cycles - 1 and strata == cycle_length(settings)
            and max(2, settings.max_rounds // strata) == cycles):
        return False
    min_cycles = max(2, -(-settings.min_rounds // strata))
    return not any(isinstance(e, (int, float)) and e < settings.tolerance
                   for k, e in enumerate(errors[:-1], start=2) if k >= min_cycles)


def better(new: dict, old: dict, settings: ReferenceSettings) -> bool:
    """Whether the reference of ``meta`` ``new`` is better than ``old`` (of the same key) for
    ``settings``: it meets the tolerance (:func:`meets_tolerance`) and ``old`` does not, or,
    neither meeting it, its relative standard error is lower (or ``old`` has none). Two that
    both meet it: not better (the cached one stays)."""
    a, b = meets_tolerance(new, settings), meets_tolerance(old, settings)
    if a or b:
        return a and not b
    e_new, e_old = new.get("relative_standard_error"), old.get("relative_standard_error")
    return e_old is None or (e_new is not None and e_new < e_old)


def fewer_rounds(meta: dict, settings: ReferenceSettings) -> bool:
    """Whether ``settings`` ask for fewer rounds (``max_rounds``) than the cached reference of
    ``meta``, which does not meet their tolerance, already has: computing it again could only
    give a reference of fewer rounds of the same key (the first cycles of the same seeds where
    the cycles are as long), which is no better, so the cached one is kept."""
    rounds = meta.get("rounds")
    return (not meets_tolerance(meta, settings) and isinstance(rounds, int) and settings.max_rounds < rounds)


def verdict(meta: dict, settings: ReferenceSettings) -> str:
    """What to do with the cached reference of ``meta`` asked for with ``settings``, the one rule of
    ``tlm reference`` and ``tlm error-vs-cost``: ``"meets"`` (use it: :func:`meets_tolerance`),
    ``"fewer"`` (keep it: :func:`fewer_rounds`), ``"repeats"`` (keep it: :func:`repeats`), or
    ``"compute"`` (compute it again, and cache the better one)."""
    if meets_tolerance(meta, settings):
        return "meets"
    if fewer_rounds(meta, settings):
        return "fewer"
    return "repeats" if repeats(meta, settings) else "compute"


def computing_line(key: str, settings: ReferenceSettings, cached_for: str, uncached: str = "it is not cached") -> str:
    """The line said before a reference none cached is computed (the rounds may take minutes);
    ``cached_for``: what it is then cached for, and how to skip it; ``uncached``: what becomes of it
    instead where the cache cannot be written (:func:`~tlm.caches.cache_problem`), said with why."""
    line = (f"computing the photon-map reference {key} (no finished one cached): {settings.photons} photons and "
            f"k = {settings.k_nearest} per round, until the relative standard error is below "
            f"{settings.tolerance} (at most {settings.max_rounds} rounds); ")
    why = cache_problem(cache_dir())
    return line + (f"it is cached for {cached_for}" if why is None else f"the cache cannot take it ({why}): {uncached}")


def describe(meta: dict, settings: ReferenceSettings) -> str:
    """``<rounds> rounds, relative standard error <e>, converged|NOT converged at tolerance <t>``."""
    err = meta.get("relative_standard_error")
    state = "converged" if meets_tolerance(meta, settings) else "NOT converged"
    return (f"{meta.get('rounds')} rounds, relative standard error {'n/a' if err is None else f'{err:.4f}'}, "
            f"{state} at tolerance {settings.tolerance}")


def kept_back(key: str, meta: dict, settings: ReferenceSettings, whose: str = "", force: bool = True) -> str:
    """The line of a cached reference kept without computing it again (:func:`fewer_rounds`);
    ``whose``: whose ``reference.max_rounds`` to raise (``"the base's "``); ``force``: name ``--force``."""
    return (f"reference {key} is cached with {describe(meta, settings)}; reference.max_rounds "
            f"{settings.max_rounds} asks for fewer rounds than it has, so it is kept and not computed again "
            f"(raise {whose}reference.max_rounds above {meta.get('rounds')}"
            + (", or use --force to replace it)" if force else ")"))


@dataclass
class Stored:
    """What :func:`store_reference` did: the reference the cache holds for the key now
    (``image`` (H, W, 3) float32, as ``reference.npy`` holds it; ``meta`` as its ``meta.json`` holds it,
    ``npy`` included; ``folder``), whether that is the one computed now (``replaced``; False: the cached
    one was better and stays) and, then, ``line``: which one the cache holds and why, with both errors, and where
    the one computed now was kept."""

    image: np.ndarray
    meta: dict
    folder: Path
    replaced: bool
    line: str = ""
    same: bool = False  # (not replaced: the cache holds the same reference.npy as the one computed now)


PARTIAL = ".partial.npz"  # references/<key>.partial.npz: the rounds of a reference interrupted
PARTIAL_VERSION = 1  # the layout of a .partial.npz (tlm.experiments.reference_resume)


def partial_path(key: str) -> Path:
    """Where the rounds of a compute of reference ``key`` are saved at the end of its cycles, beside its
    entry (:mod:`tlm.experiments.reference_resume`): ``references/<key>.partial.npz``."""
    return cache_dir() / f"{key}{PARTIAL}"


def drop_partial(key: str, meta: dict) -> None:
    """Remove the saved rounds of a compute of ``key`` (:func:`partial_path`), the reference of ``meta``
    being stored; but for more rounds than its ``rounds`` (in cycles of any length, either engine's): another
    compute's, to a stricter tolerance or of another ``reference.spp``, interrupted, which a later one
    resumes; and for rounds of another layout (``version``: another tlm's, older or newer, which that tlm
    resumes)."""
    path = partial_path(key)
    info = partial_info(path)
    rounds = meta.get("rounds")
    if type(rounds) is int and partial_rounds(info) > rounds:
        return
    if info is not None and type(info.get("version")) is int and info["version"] != PARTIAL_VERSION:
        return
    with contextlib.suppress(OSError):
        path.unlink()


def store_reference(key: str, image: np.ndarray, meta: dict, settings: ReferenceSettings,
                    force: bool = False) -> Stored:
    """Cache the reference ``key`` computed now (``image`` (H, W, 3), ``meta``) where it is
    :func:`better` for ``settings`` than the one cached for the key (read again now: another
    process may have cached one meanwhile), or where none is, or with ``force``; else the
    cached one stays, and the one computed now is kept in :func:`kept_root` (as one the cache
    cannot take; not where the cache is that folder, or where that folder holds a better one)
    or dropped, which ``line`` says; one that is the same file as the cached one (its ``reference.npy``'s
    sha256: computed at once by another process) is dropped, and ``line`` says it is the same (``same``).
    The errors of :func:`save_reference` where the cache cannot take it. Either way the rounds saved of
    the compute, which finished, are removed (:func:`drop_partial`; not where an interrupt stops this: the
    next compute resumes from them)."""
    try:
        stored = _store(key, image, meta, settings, force)
    except (EnvironmentFailure, OSError, InputError):
        drop_partial(key, meta)
        raise
    drop_partial(key, meta)
    return stored


def _store(key: str, image: np.ndarray, meta: dict, settings: ReferenceSettings, force: bool) -> Stored:
    """:func:`store_reference`, but for its saved rounds."""
    held = None if force else load_reference(key, cache_dir())  # (the cache's, not a sweep's own copy: holding)
    if held is None or better(meta, held[1], settings):  # (its meta as meta.json holds it: with the npy's sha256)
        # (the image as reference.npy holds it, float32: what a later run reads back, so measures alike)
        return Stored(image.astype(np.float32), {**meta, "npy": npy_digest(image)}, save_reference(key, image, meta),
                      True)
    digest, npy = npy_digest(image), held[1].get("npy")
    if isinstance(npy, dict) and npy.get("sha256") == digest["sha256"] and npy.get("size") == digest["size"]:
        # (another process computed the same one meanwhile, of the same seeds and settings: nothing to keep)
        return Stored(held[0], held[1], cache_dir() / key, False,
                      f"reference {key}: the cache holds the same reference as the one computed now "
                      f"({describe(held[1], settings)}; reference.npy sha256 {digest['sha256'][:16]}, cached "
                      "meanwhile by another run): the one computed now is dropped", same=True)
    e_new, e_old = meta.get("relative_standard_error"), held[1].get("relative_standard_error")
    why = ("it meets the tolerance" if meets_tolerance(held[1], settings) else
           "the one computed now has no relative standard error" if e_new is None else
           f"its relative standard error is {'lower' if e_old < e_new else 'as low'}")
    line = (f"reference {key}: the cache keeps its reference ({describe(held[1], settings)}), not the one computed "
            f"now ({describe(meta, settings)}): {why}")
    root = kept_root()
    there = root / "references"
    try:
        same = there.resolve() == cache_dir().resolve()
    except OSError:
        same = True
    other = None if same else load_reference(key, there, "it is replaced")
    if same:
        line += "; the one computed now is dropped"
    elif other is not None and not better(meta, other[1], settings):
        line += f"; the one computed now is dropped (one as good is kept in {there / key})"
    else:
        try:
            folder = save_reference(key, image, meta, there)
        except (EnvironmentFailure, OSError, InputError) as e:
            line += f"; the one computed now is dropped (not kept in {root}: {' '.join(str(e).split())})"
        else:
            line += f"; the one computed now is kept in {folder} (TLM_CACHE={shell_word(str(root))} reads it)"
    return Stored(held[0], held[1], cache_dir() / key, False, line)


def kept_root() -> Path:
    """Where ``tlm reference`` keeps a reference its cache cannot take: a cache folder of
    this user's in the temporary folder (``TLM_CACHE`` set to it reads the reference), which
    :func:`save_reference` makes private (:func:`private_folder`)."""
    return Path(tempfile.gettempdir()) / f"tlm-cache-{os.getuid() if hasattr(os, 'getuid') else 'user'}"


def private_folder(folder: Path, final: Path) -> None:
    """Make ``folder`` this user's only before anything is written into it: each of its
    folders below the temporary folder (``folder`` itself where it is not in it) is made with
    mode 0700 where it is absent, and one that exists must be a folder, not a symbolic link,
    owned by this user, that neither its group nor others may write. Another user can make
    ``<tmp>/tlm-cache-<uid>`` first (a folder of theirs, or a link to one) to read or replace
    what tlm keeps there: an :class:`~tlm.errors.EnvironmentFailure` naming ``final``, the
    folder and why, and nothing is written."""
    folder = Path(folder)
    tmp = Path(tempfile.gettempdir())
    chain = [*(p for p in reversed(folder.parents) if tmp in p.parents), folder] if tmp in folder.parents else [folder]
    uid = os.getuid() if hasattr(os, "getuid") else None
    try:
        chain[0].parent.mkdir(parents=True, exist_ok=True)
        for p in chain:
            with contextlib.suppress(FileExistsError):
                os.mkdir(p, 0o700)
            st = os.lstat(p)
            if stat.S_ISLNK(st.st_mode):
                why = f"is a symbolic link (to {os.readlink(p)})"
            elif not stat.S_ISDIR(st.st_mode):
                why = "is not a folder"
            elif uid is not None and st.st_uid != uid:
                why = f"belongs to user {st.st_uid}, not to this user ({uid})"
            elif st.st_mode & 0o022:
                why = f"may be written by its group or others (mode {stat.S_IMODE(st.st_mode):o})"
            else:
                continue
            raise EnvironmentFailure(f"not written: {p} {why}, so another user could read or replace what is kept "
                                     "there; remove it (or 'chmod go-w' a folder of your own), or set TMPDIR to a "
                                     "folder of your own", source=str(final))
    except EnvironmentFailure:
        raise
    except OSError as e:
        raise EnvironmentFailure(f"cannot write: {' '.join(str(e).split())}", source=str(final)) from None
