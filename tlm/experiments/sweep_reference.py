"""A sweep's photon-map references: which of its points are measured against the reference cached now,
the references ``tlm sweep --reference`` computes before the points, and the line on the points left
without an image error.

A point's folder ``points/<hash>/`` is done (:func:`done_record`) only where its photon-map error is
the one the reference cached now gives (:func:`reference_now`): a point measured before its reference
was cached (``tlm reference`` since), or against one computed again since, runs again, its frame read
from the functional cache. :func:`sweep_references` computes and caches, before the points run, each
reference that the points to run need and the cache lacks, or holds one that misses their tolerance (one
per distinct value of the keys a reference reads, :data:`~tlm.experiments.reference.KEY_READS`), as ``tlm
reference`` decides and computes it (a cached one that computing again would not better is kept, and said so;
points that share one but ask for different tolerances or rounds: the strictest, :func:`strictest`).
The sweep holds a copy of each reference its points to run are measured against in its output folder while they
run (:func:`held_root`, :func:`hold_references`, :func:`drop_references`), which they read first: a ``tlm cache
prune`` meanwhile, or a cache that could not take one computed now, costs no point its error; what a killed sweep
left there, every sweep into the folder removes (:func:`clean_held`).
:func:`unmeasured_line` is the sweep's warning on the points that still have no error, with the ``tlm
reference`` command of each reference they need. The sweep that runs the points:
:mod:`tlm.experiments.sweep`.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import suppress
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tlm.errors import InputError
from tlm.experiments.sweep_file import Point
from tlm.experiments.sweep_point import finished

if TYPE_CHECKING:
    from tlm.experiments.reference_cache import ReferenceSettings


def done_record(folder: Path) -> dict | None:
    """A finished point's record from its folder, or None (not :func:`finished`; a photon-map error that is
    not the one the reference cached now gives, :func:`reference_now`)."""
    results = finished(folder)
    if results is None:
        return None
    if reference_now(results.get("error")):  # (measured again: its frame is read from the cache, not rendered)
        return None
    return {"status": "ok", "results": results}


def point_done(folder: Path, point: Point) -> dict | None:
    """The record of ``point`` done in its ``folder`` (:func:`done_record`), or None where it is to run: not
    done, or done without the ``trace.json`` it asks for (:attr:`Point.traces`: a sweep run before without
    ``arch.trace: true``, whose points' hashes hold it as true all the same). A point done with a trace.json it
    no longer asks for is done (the file is kept). What is done, for the sweep, its ``--dry-run`` and
    ``--reference``'s references (:func:`sweep_references`) alike."""
    record = done_record(folder)
    if record is not None and point.traces and not (folder / "trace.json").is_file():
        return None
    return record


def reference_now(error: Any) -> bool:
    """Whether a point's photon-map ``error`` is not the one its reference cached now gives: not measured
    for want of a reference that is cached now (``tlm reference`` since), or measured against another
    reference of its key than the one cached now (computed again since: ``tlm reference --force``, a
    ``reference.max_rounds`` that is not in the key), told by the ``reference_sha256`` it records against
    the sha256 of ``reference.npy`` that the cached reference's ``meta.json`` holds (a point that records
    none, written by an older tlm, too). The point is run again, its frame read from the cache and
    measured now. One measured against a reference that is no longer cached (the cache cleared) keeps
    its error: nothing would measure it now."""
    from tlm.experiments.reference_cache import cache_dir

    if not (isinstance(error, dict) and isinstance(error.get("reference"), str)):
        return False
    meta = cache_dir() / error["reference"] / "meta.json"
    if error.get("available") is False:
        return meta.is_file()
    if error.get("available") is not True:
        return False
    try:
        npy = json.loads(meta.read_text(encoding="utf-8")).get("npy")
    except (OSError, ValueError, AttributeError):  # (none cached now, or a damaged one: its reader says so)
        return False
    sha = npy.get("sha256") if isinstance(npy, dict) else None
    return isinstance(sha, str) and error.get("reference_sha256") != sha


def unmeasured_line(sweep, records: dict[str, dict], out: Path, asked: bool = False) -> list[str]:
    """The line on the sweep's photon-map points that have no image error: no reference cached for
    them (a sweep computes none; ``reference.auto`` is ``tlm run``'s), with how many, and the
    ``tlm reference`` command that computes each reference they need (the base config with the
    ``--set`` strings, and what the sweep's ``set`` and the point's factors give of the keys a
    reference reads, :data:`~tlm.experiments.reference.KEY_READS`; a sweep whose base is a mapping in
    the sweep file, which no command names, by the ``config.resolved.yaml`` of one of the points,
    which holds all of them), and that ``tlm sweep --reference`` computes them (but where it was given,
    ``asked``: a reference it could not compute, which its own warning names);
    none when every photon-map point has one."""
    from tlm.experiments.reference import KEY_READS
    from tlm.experiments.run import reference_command

    missing: dict[str, list[Point]] = {}
    for p in sweep.points:
        rec = records.get(p.hash) or {}
        error = (rec.get("results") or {}).get("error") if rec.get("status") == "ok" else None
        if isinstance(error, dict) and error.get("available") is False:
            missing.setdefault(str(error.get("reference")), []).append(p)
    if not missing:
        return []
    config = _base_config(sweep)
    commands = []
    for points in missing.values():
        # (points of one reference that ask for different stopping rules: the strictest, which meets each one's)
        rule = _strictest_rule([(p.config.get("reference") or {}) for p in points])
        if config is None:  # (its every setting, the --set values and the factors' included)
            resolved = out / "points" / points[0].hash / "config.resolved.yaml"
            own = points[0].config.get("reference") or {}
            commands.append(reference_command(os.path.relpath(resolved), [
                f"reference.{k}={json.dumps(v)}" for k, v in rule.items() if own.get(k) != v]))
            continue
        first = points[0].config
        first = {**first, "reference": {**(first.get("reference") or {}), **rule}} if rule else first
        given = [k for k in (*sweep.set, *points[0].factors)
                 if any(k == r or k.startswith(r + ".") or r.startswith(k + ".") for r in KEY_READS)]
        sets = [*sweep.overrides, *(f"{k}={json.dumps(_dotted(first, k))}" for k in given)]
        commands.append(reference_command(config, sets))
    n = sum(len(ps) for ps in missing.values())
    them = f"{'this reference' if len(commands) == 1 else f'these {len(commands)} references'}"
    which = (f"{n} of {len(sweep.points)} points have" if n > 1 else
             "the 1 point has" if len(sweep.points) == 1 else f"1 of {len(sweep.points)} points has")
    it, its = ("them", "their cached frames") if n > 1 else ("it", "its cached frame")
    why = ("though --reference was given (a line above says why where one could not be computed or cached; a "
           "remote Dask worker reads its own cache)" if asked else "and a sweep computes none (reference.auto is "
           "'tlm run''s)")
    return [f"{which} no photon-map error (error.rmse, error.rel_mse): no reference is cached for {it}, {why}; "
            f"{'; '.join(commands)} computes {them}, and the "
            f"sweep run again into {out} then measures {it} from {its}"
            + ("" if asked else f" ('tlm sweep --reference' computes {them} before the points, and measures {it})")]


@dataclass
class Held:
    """A reference the sweep holds a copy of for its points (:func:`sweep_references` fills them,
    :func:`hold_references` writes them): its ``image`` and ``meta``, the hashes of the sweep's ``points``
    measured against it, and the ``folder`` where it is kept (the cache's, ``<tmp>/tlm-cache-<uid>``'s, or None:
    kept nowhere but by the sweep)."""

    image: Any
    meta: dict
    points: frozenset[str]
    folder: Path | None


def reference_groups(sweep) -> Iterator[tuple[list[Point], Any, Any, str]]:
    """The points of ``sweep`` (a :class:`~tlm.experiments.sweep_file.Sweep`) grouped by what says whether they
    have a photon-map reference and which (``mode``, ``photons.count`` and the keys a reference reads,
    :data:`~tlm.experiments.reference.KEY_READS`), a scene loaded per group: for each group whose points run the
    photon-map pass, its points, the config of its first, the :class:`~tlm.experiments.reference_cache.
    ReferenceSettings` of that config and the reference's key (:func:`sweep_references`, ``tlm sweep --dry-run``)."""
    from tlm.config import config_from_dict
    from tlm.experiments.reference import KEY_READS, reference_key
    from tlm.experiments.reference_cache import ReferenceSettings
    from tlm.render.planner import plan
    from tlm.scenes.loader import load_scene

    groups: dict[str, list[Point]] = {}
    for p in sweep.points:
        reads = [_dotted(p.config, k) for k in ("mode", "photons.count", *KEY_READS)]
        groups.setdefault(json.dumps(reads, sort_keys=True, default=str), []).append(p)
    source = str(sweep.path)
    for group in groups.values():
        cfg = config_from_dict(group[0].config, source)
        scene = load_scene(cfg.scene, sweep.folder, cfg.resolution, source)
        if "pmap" in plan(scene, cfg).run_names:
            settings = ReferenceSettings.from_config(scene, cfg)
            yield group, cfg, settings, reference_key(scene, cfg, settings)


def sweep_references(sweep, points_dir: Path, say: Callable[[str], None] | None = None,
                     progress: bool = False, hold: dict[str, Held] | None = None) -> list[str]:
    """``tlm sweep --reference``: compute and cache each photon-map reference that the sweep's points need,
    before the points run, so that they are measured against it (a point done before without an error, or
    against another reference, is then run again, its frame read from the cache: :func:`reference_now`),
    deciding on a cached one as ``tlm reference`` of a point's config does
    (:func:`~tlm.experiments.reference_cache.verdict`; points of one reference that ask for different
    stopping rules, which its key does not read, by the strictest of them, :func:`strictest`, its lines saying
    so and which of the points' own tolerances it meets): one that meets its points' tolerance is used as it
    is (as ``tlm run`` uses it); one that misses it is computed again (cached where it is better), but one
    that computing again would not better (fewer rounds asked for than it has, or the same rounds
    repeated) is kept, and a line says why. Needed: by a point not done yet in ``points_dir`` (:func:`point_done`,
    as the sweep and its ``--dry-run`` tell it: one done without the trace.json it asks for runs again), or done
    without an error or with one measured against a reference that misses its tolerance
    (:func:`to_measure`); one reference per distinct value of the keys its key reads
    (:data:`~tlm.experiments.reference.KEY_READS`, with the ``mode`` and ``photons.count`` that say whether
    the photon-map pass runs: :func:`~tlm.render.planner.plan`), each computed as ``tlm reference`` of a
    point's config computes it (:func:`~tlm.experiments.reference.make_reference`: its lines to ``say``, one
    per measured cycle as ``tlm reference`` prints them, and its rounds' bar with ``progress``). An
    interrupt stops the sweep before any point runs: the points done before stay, and a rerun reuses the
    references cached. Returns a warning line per reference that could not be computed (its points run all
    the same, without their error, or against the cached one that misses their tolerance), or the one line
    that no point of the sweep runs the photon-map pass. ``hold``: filled with each reference (a :class:`Held`)
    that points to measure are measured against, by key (the one computed now, wherever it was kept, or the cached
    one used or kept), read or computed now, with all the points of its key: the sweep holds a copy of those its
    points to run need for its duration (:func:`hold_references`), so that a ``tlm cache prune`` meanwhile, or a
    cache that could not take one computed now, costs no point its error."""
    from tlm.errors import EnvironmentFailure
    from tlm.experiments.reference import make_reference, repeats_why, rounds_advice
    from tlm.experiments.reference_cache import RULE, cache_dir, describe, load_reference, verdict

    say = say or (lambda line: None)
    present = listed(points_dir)
    source = str(sweep.path)
    pmap = False
    # reference key -> a config of it, the points that need it, those of them not measured yet, and the
    # settings each of them asks for (its stopping rule, RULE, is no part of the key: points of one key may differ)
    needed: dict[str, tuple[Any, list[Point], list[Point], dict[str, ReferenceSettings]]] = {}
    every: dict[str, set[str]] = {}  # reference key -> the hashes of all its points (done or not: Held.points)
    for group, cfg, settings, key in reference_groups(sweep):
        pmap = True
        every.setdefault(key, set()).update(p.hash for p in group)
        measure = {p.hash: to_measure(point_done(points_dir / p.hash, p)) if p.hash in present else "run"
                   for p in group}
        points = [p for p in group if measure[p.hash]]
        if points:
            need = needed.setdefault(key, (cfg, [], [], {}))
            need[1].extend(points)
            need[2].extend(p for p in points if measure[p.hash] != "again")
            need[3].update((p.hash, settings) for p in points)  # (by point: one of a hash listed twice)
    if not pmap:
        return ["--reference: no point of this sweep runs the photon-map pass: no reference to compute"]
    todo = []  # (key, a config of it, how many points need it, the words for them, whether cached, why computed,
    # the settings asked for, each point's own)
    for key, (cfg, points, unmeasured, by_point) in needed.items():
        asked = list(by_point.values())
        settings = strictest(asked)  # (what meets it meets every point's own: the tolerance of each is met)
        cfg = replace(cfg, reference=replace(cfg.reference, **{k: getattr(settings, k) for k in RULE}))
        cached = load_reference(key)
        kind = "compute" if cached is None else verdict(cached[1], settings)
        if cached is not None and hold is not None:  # (the one the points use, unless one is computed now)
            hold[key] = Held(cached[0], cached[1], frozenset(every[key]), cache_dir() / key)
        if kind == "meets" or (kind != "compute" and not unmeasured):  # (points done against the one kept: as
            continue  # they were, said by their warnings)
        n = len({p.hash for p in (points if kind == "compute" else unmeasured)})
        they = f"{n} point{'s' if n != 1 else ''} of the sweep need{'' if n != 1 else 's'}"
        if kind == "compute":
            todo.append((key, cfg, n, they, cached is not None, ("none cached" if cached is None else
                         f"the cached one, {describe(cached[1], settings)}, is computed again")
                         + _asked_line(settings, asked), asked))
            continue
        meta = cached[1]
        why = (f"; reference.max_rounds {settings.max_rounds} asks for fewer rounds than it has" if kind == "fewer"
               else f", {repeats_why(meta, settings)}")
        measured = "they are" if n != 1 else "it is"
        say(f"sweep --reference: reference {key}, which {they}, is cached with {describe(meta, settings)}{why}, so "
            f"it is kept, not computed again, and {measured} measured against it (raise reference.max_rounds above "
            f"{meta.get('rounds')}{rounds_advice(meta.get('relative_standard_error'), meta.get('rounds'), settings)}, "
            "or compute it again with 'tlm reference --force')"
            + _asked_line(settings, asked, "judged") + _judged(meta, asked))
    lines = []
    cached = None  # (the last one read: hold's alone, where it is held, freed once written: hold_references)
    for i, (key, cfg, n, they, had, why, asked) in enumerate(todo, start=1):
        say(f"sweep --reference: computing reference {i} of {len(todo)}, {key}, which {they} ({why})")
        t0 = time.perf_counter()
        try:
            made = make_reference(cfg, sweep.folder, source, say=say, bar=progress, progress=lambda k, c, e: (
                None if math.isnan(e) else say(f"  round {k:3d}  change {c:.4f}  relative standard error {e:.4f}")),
                unkept=hold is not None)  # (one kept nowhere: held by the sweep for its points)
        except (InputError, EnvironmentFailure, OSError, MemoryError) as e:
            line = (f"sweep --reference: the photon-map reference {key} of {n} point{'s' if n != 1 else ''} "
                    f"could not be computed ({type(e).__name__}: {' '.join(str(e).split())}): "
                    + (f"{'they are' if n != 1 else 'it is'} measured against the cached one" if had else
                       f"{'they run' if n != 1 else 'it runs'} without the photon-map error"))
            lines.append(line)
            continue
        if hold is not None and made.image is not None:  # (the cache's now, or the one kept where it could not)
            hold[key] = Held(made.image, made.meta, frozenset(every[key]), made.folder)
        rse = made.meta.get("relative_standard_error")
        state = "converged" if made.meets else "NOT converged (reference.max_rounds reached)"
        say(f"reference {key}: {state} after {made.meta.get('rounds')} rounds (relative standard error "
            f"{'n/a' if rse is None else f'{rse:.4f}'}) in {time.perf_counter() - t0:.1f} s; "
            f"{made.folder or 'kept nowhere but for this sweep'}" + _judged(made.meta, asked))
    return lines


HELD = ".references"  # the output folder's folder of the copies of the references a sweep holds (hold_references)


def clean_held(out: Path) -> None:
    """Remove from the sweep folder ``out`` the copies of references (:func:`hold_references`) that sweeps of this
    machine now gone left (killed: they could not remove their own; ``storage.clean_stale``: another machine's, a
    live process's and this process's other sweeps' are kept), and ``.references`` where that leaves it empty: every
    sweep into the folder does so once it has claimed it, ``--reference`` or not."""
    from tlm import storage

    parent = out / HELD
    storage.clean_stale(parent, "held")
    with suppress(OSError):
        parent.rmdir()


def held_root(out: Path) -> Path:
    """The folder of the copies this sweep holds in its output folder ``out``:
    ``.references/.held.tmp-<host>-<pid>-<n>`` (``storage``'s writer's name: no other sweep's, of another machine
    sharing the folder or of this process, and one :func:`clean_held` never takes for a killed sweep's), noted as in
    use from now until :func:`drop_references`; nothing is written yet (:func:`hold_references`), so that its
    removal can be registered first."""
    from tlm import storage

    root = Path(os.path.abspath(out / HELD)) / f".held.tmp-{storage.new_writer()}"
    storage.hold(root.name)  # (before it exists: no clean_stale of another thread's may take it for a leftover)
    return root


def hold_references(hold: dict[str, Held], root: Path, todo: Iterable[str]) -> tuple[dict[str, str], list[str]]:
    """Write a copy of each reference of ``hold`` (key -> :class:`Held`, :func:`sweep_references`) that a point of
    ``todo`` (the hashes of the points to run) is measured against into ``root`` (:func:`held_root`, in the sweep's
    output folder), which its workers see (a remote Dask worker too: it writes the point folders there), for the
    points to read first (:func:`~tlm.experiments.reference_cache.holding`): a ``tlm cache prune`` meanwhile, or a
    cache that could not take one computed now, costs no point its error. ``hold`` is emptied as it goes (the images
    are not kept in memory for the sweep's duration, nor those no point to run needs). Returns the folders by key and
    a warning line per reference that could not be written, saying what its points read instead."""
    from tlm.errors import EnvironmentFailure
    from tlm.experiments.reference_cache import save_reference

    run = set(todo)
    folders: dict[str, str] = {}
    lines = []
    made = False
    while hold:
        key = next(iter(hold))
        held = hold.pop(key)
        if not held.points & run:  # (its points are all done: nothing reads it)
            continue
        try:
            if not made:
                _make(root)
                made = True
            folders[key] = str(save_reference(key, held.image, held.meta, root, private=False))
        except (EnvironmentFailure, InputError, OSError) as e:
            lines.append(f"sweep --reference: cannot hold a copy of reference {key} in {root} for the sweep's points "
                         f"({' '.join(str(e).split())}): {_read_instead(key, held.folder)}")
        del held  # (its image: freed now)
    return folders, lines


def _make(root: Path) -> None:
    """Make ``root`` (:func:`held_root`) and its ``.references``: again where another sweep's :func:`clean_held` or
    :func:`drop_references` removed the empty ``.references`` between the two (it removes only an empty one)."""
    for tries in range(8):
        try:
            root.mkdir(parents=True, exist_ok=True)
            return
        except FileNotFoundError:
            if tries == 7:
                raise


def _read_instead(key: str, folder: Path | None) -> str:
    """What the points of the reference ``key`` read where the sweep cannot hold a copy of it (kept in ``folder``,
    :class:`Held`)."""
    from tlm.experiments.reference_cache import cache_dir

    cached = cache_dir() / key
    if folder is not None and Path(folder) == cached:
        return "they read it from the cache, where a 'tlm cache prune' meanwhile removes it"
    where = "it is kept nowhere else" if folder is None else f"the cache does not hold it (it is kept in {folder})"
    if (cached / "meta.json").is_file():  # (an older one, which the one computed now could not replace)
        return f"{where}: they are measured against the other one the cache holds"
    return f"{where}: they run without the photon-map error"


def drop_references(root: Path) -> None:
    """Remove the copies :func:`hold_references` wrote (``root``, :func:`held_root`: no longer noted as in use), and
    ``.references`` where that leaves it empty (another sweep's copies in it: left, with it)."""
    import shutil

    from tlm import storage

    shutil.rmtree(root, ignore_errors=True)
    storage.release(root.name)
    with suppress(OSError):
        root.parent.rmdir()


def strictest(asked: list[ReferenceSettings]) -> ReferenceSettings:
    """The settings one reference of a key is computed and judged with for points that ask for different stopping
    rules (:data:`~tlm.experiments.reference_cache.RULE`, no part of the key): the lowest ``tolerance``, the most
    ``min_rounds`` and the most ``max_rounds`` any of them asks for, and the ``spp`` of the first point that asks
    for that tolerance; so a reference that meets them meets each point's own tolerance
    (:func:`~tlm.experiments.reference_cache.meets_tolerance`), and none is computed to fewer rounds than a point
    allows. The first point's settings where all ask alike (as ``tlm reference`` of its config computes it)."""
    from tlm.experiments.reference_cache import RULE

    return replace(asked[0], **_strictest_rule([{k: getattr(s, k) for k in RULE} for s in asked]))


def _strictest_rule(rules: list[dict]) -> dict:
    """Of the stopping rules ``rules`` (mappings of ``tolerance``, ``min_rounds``, ``max_rounds`` and ``spp``, as a
    point's resolved ``reference`` holds them), what :func:`strictest` sets over the first one's: none where they
    are alike (or a point's is not a mapping of numbers)."""
    keys = ("tolerance", "min_rounds", "max_rounds", "spp")
    if all({k: r.get(k) for k in keys} == {k: rules[0].get(k) for k in keys} for r in rules) or not all(
            isinstance(r.get(k), (int, float)) for r in rules for k in keys):
        return {}
    tolerance = min(r["tolerance"] for r in rules)
    return {"tolerance": tolerance, "min_rounds": max(r["min_rounds"] for r in rules),
            "max_rounds": max(r["max_rounds"] for r in rules),
            "spp": next(r["spp"] for r in rules if r["tolerance"] == tolerance)}


def _asked_line(settings: ReferenceSettings, asked: list[ReferenceSettings], how: str = "computed and judged"
                ) -> str:
    """The words on the settings a reference is computed and judged with where its points ask for different
    stopping rules (:func:`strictest`; ``how``: what is done by them); none where they ask alike."""
    if all(s == asked[0] for s in asked):
        return ""
    tolerances = ", ".join(f"{t:g}" for t in sorted({s.tolerance for s in asked}))
    return (f"; its points ask for different stopping rules (tolerance {tolerances}): it is {how} by "
            f"the strictest, tolerance {settings.tolerance:g}, {settings.min_rounds} to {settings.max_rounds} rounds "
            f"in cycles of {settings.spp}")


def _judged(meta: dict, asked: list[ReferenceSettings]) -> str:
    """Where a reference's points ask for different stopping rules: which of their own tolerances it meets, with
    how many points each (each point's error records its own, ``reference_converged``); none where they ask
    alike."""
    from tlm.config_words import listing
    from tlm.experiments.reference_cache import meets_tolerance

    if all(s == asked[0] for s in asked):
        return ""
    counts: dict[bool, dict[float, int]] = {True: {}, False: {}}
    for s in asked:
        told = counts[meets_tolerance(meta, s)]
        told[s.tolerance] = told.get(s.tolerance, 0) + 1
    said = [f"{verb} " + listing(f"{t:g} ({n} point{'s' if n != 1 else ''})" for t, n in sorted(told.items()))
            for verb, told in (("meets", counts[True]), ("does NOT meet", counts[False])) if told]
    return f"; against its points' own tolerances it {', and '.join(said)}"


def to_measure(rec: dict | None) -> str:
    """Whether a point (its :func:`done_record`, None: not done) is to be measured against its reference:
    ``"run"`` (not done), ``"unmeasured"`` (done without a photon-map error: no reference cached when it ran),
    ``"again"`` (done with one measured against a reference that misses its tolerance, ``reference_converged``
    false: measured again where ``--reference`` computes that reference again, :func:`reference_now`), or ``""``
    (no). ``tlm sweep --reference`` and its ``--dry-run`` decide by it."""
    if rec is None:
        return "run"
    error = rec["results"].get("error")
    if not isinstance(error, dict):
        return ""
    if error.get("available") is False:
        return "unmeasured"
    return "again" if error.get("available") is True and error.get("reference_converged") is False else ""


def _dotted(config: dict, dotted: str) -> Any:
    """The value of the dotted key ``dotted`` in a point's resolved ``config``."""
    for part in dotted.split("."):
        config = config.get(part) if isinstance(config, dict) else None
    return config


def _base_config(sweep) -> str | None:
    """The sweep's base config as a command line names it: its file's path from the working folder, a
    built-in one's name; None (``CONFIG``) for a mapping in the sweep file, and for a file read once (a pipe,
    :func:`~tlm.experiments.run.read_once`), which no later command finds: the point's ``config.resolved.yaml``."""
    from tlm.builtin import base_path
    from tlm.experiments.run import read_once

    if sweep.base_file is None:
        return None
    with suppress(InputError, OSError, ValueError):
        file, builtin = base_path(sweep.base_file, sweep.path.resolve().parent, str(sweep.path), "sweep file")
        if not builtin and read_once(str(file)) is not None:
            return None
        return str(file) if builtin else os.path.relpath(file)
    return sweep.base_file


def listed(folder: Path) -> set[str]:
    """The names in ``folder`` (none where it is missing or unreadable)."""
    try:
        return set(os.listdir(folder))
    except OSError:
        return set()
