"""The checks of a sweep's points once expanded (out of :mod:`tlm.experiments.sweep_file`, which imports every
name from here under its old name, :func:`one_run_one_row` as ``_one_run_one_row``): no two points of other
factor values are one run (:func:`one_run_one_row`), nor one result rendered twice (:func:`same_setting`:
``render.batch``, a null ``arch.programs`` beside tlm's own table), and every scene file a point names is found
(:func:`scenes_found`). Each refusal is an :class:`~tlm.errors.InputError` naming the points and the keys. After
the points ran, a null that resolved to another value of its factor (:func:`resolved_nulls`: ``bsp.levels``).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from tlm.config import PATH_KEYS, names_scene_file
from tlm.config_words import value_text
from tlm.errors import InputError
from tlm.experiments.sweep_factors import value_identity


def scenes_found(rows: list, src: str, folders: list[Path], per_point: bool = True) -> None:
    """An InputError naming the point (``per_point``; not for a scene every point has of a ``--set``,
    ``src`` then the file ``with --set``), the scene file and ``folders`` (where it was looked
    for) for the first point whose ``scene`` is a relative path that none of them holds
    (:func:`~tlm.config.scene_from` left it so) and that is no built-in scene
    (``thesis/ring.yaml``)."""
    from tlm.scenes.loader import resolve_scene_path

    done = set()
    for i, _, fields in rows:
        scene = fields["scene"].value
        if scene in done or not names_scene_file(scene) or not scene or Path(scene).is_absolute():
            continue
        resolve_scene_path(scene, folders[0], f"{src} (point {i})" if per_point else src, also=tuple(folders[1:]))
        done.add(scene)


def resolved_value(config: dict, dotted: str) -> Any:
    """The value of the dotted key ``dotted`` in a point's resolved ``config`` (a missing one:
    a fresh object, equal to nothing)."""
    here: Any = config
    for part in dotted.split("."):
        if not isinstance(here, dict) or part not in here:
            return object()
        here = here[part]
    return here


def one_run_one_row(points: list, src: str) -> None:
    """An InputError when points of other factor values are one run (one key): only
    ``render.threads`` is left out of the key (it changes the speed alone, bit for bit the
    same results), so a sweep over it would run its first value and label the others' rows
    with values never run. So is one value written two ways (``1000000000`` and ``1.0e+9`` of
    ``arch.clock_hz``, a float), which :func:`tlm.experiments.sweep_factors.given_once` takes for two, one file named
    two ways (``box.yaml`` and ``./box.yaml``: one absolute path once read), and values that give
    one config (``photons: [{}, null]`` where the base has no ``photons``: its defaults either way). Then
    :func:`same_setting`."""
    first: dict[str, Any] = {}  # (tlm.experiments.sweep_file.Point)
    for p in points:
        other = first.setdefault(p.hash, p)
        if other is p:
            continue
        differ = [k for k in p.factors if value_identity(p.factors[k]) != value_identity(other.factors.get(k))]
        alike = [k for k in differ if p.factors[k] == other.factors.get(k)]
        if alike:  # (1000000000 and 1000000000.0 of a float: one value, written two ways)
            both = (f"{value_text(other.factors[k])} and {value_text(p.factors[k])}" for k in alike)
            raise InputError(f"points {other.index} and {p.index} are one run: " + ", ".join(both)
                             + " are one value, given twice", source=src, key=", ".join(alike))
        files = [k for k in differ
                 if k in ("scene", *PATH_KEYS) and resolved_value(p.config, k) == resolved_value(other.config, k)]
        if files:  # (box.yaml and ./box.yaml, or a path from the sweep file and one from its base: one file)
            both = (f"{value_text(other.factors[k])} and {value_text(p.factors[k])}" for k in files)
            raise InputError(f"points {other.index} and {p.index} are one run: " + ", ".join(both)
                             + " name one file, given twice", source=src, key=", ".join(files))
        if differ and resolved_value(p.config, "render.threads") == resolved_value(other.config, "render.threads"):
            # (not the threads: values that give one config, {} and null of a section the base leaves out)
            both = (f"{k}: {value_text(other.factors.get(k))} and {value_text(p.factors[k])}" for k in differ)
            raise InputError(f"points {other.index} and {p.index} are one run: " + ", ".join(both)
                             + " give the same config (a section's mapping merges into the base's section, and "
                             "null gives it at its defaults): give one of them", source=src, key=", ".join(differ))
        if differ:
            raise InputError(f"points {other.index} and {p.index} differ only in {', '.join(differ)} "
                             f"(render.threads changes no result, only the host's speed), so they would be one run "
                             "with two labels: give render.threads under set:, and time thread counts with "
                             "benchmarks/bench_threads.py", source=src, key=", ".join(differ))
    same_setting(points, src)


# the keys that change the host's speed or memory alone, each with what it changes (their points' work, cycles
# and radiance are bit-identical for every value: tlm.kernels.traverse.closest_hit, tlm.render.batches); the point's
# key leaves out render.threads alone (one_run_one_row's first check), the others are in it, as in the frame's
HOST_ONLY = {"render.threads": "speed", "render.batch": "speed", "render.batch_rays": "memory"}
NULL_PROGRAMS = "arch.programs"  # (null: tlm's own table, tlm.arch.costs.DEFAULT_PATH)
# what no sweep point reads, besides what its run never reads (tlm.render.planner.inert_settings): a sweep writes no
# image (its rows are the work, the cycles, the host's seconds and the radiance's errors), which the exposure scales
NO_IMAGE = {"render.exposure": "a sweep writes no image, and the exposure scales only the pictures tlm run writes "
                               "(not the work, the cycles or the radiance's errors)"}


def same_setting(points: list, src: str) -> None:
    """An InputError where two points differ only in what changes no result: in a key of :data:`HOST_ONLY`
    (``render.batch: [1, 4]``: one result rendered twice, with two labels), or in an ``arch.programs`` given
    null and as the table null resolves to (``tlm/arch/programs.yaml``, by any path); judged only where a
    factor sets one of those keys."""
    from tlm.arch.costs import DEFAULT_PATH
    from tlm.experiments.sweep_factors import keys_given

    watched = {*HOST_ONLY, NULL_PROGRAMS}
    # (the factors of those keys or of their sections, each value once: a sweep of 10^5 points is checked in seconds)
    near = [f for f in (points[0].factors if points else ()) if any(k == f or k.startswith(f + ".") for k in watched)]
    if not any(set(keys_given(f, list({id(p.factors[f]): p.factors[f] for p in points}.values()))) & watched
               for f in near):
        return
    table = os.path.realpath(DEFAULT_PATH)
    first: dict[str, Any] = {}
    for p in points:
        render = {k: v for k, v in (p.config.get("render") or {}).items() if f"render.{k}" not in HOST_ONLY}
        arch = dict(p.config.get("arch") or {})
        arch["programs"] = table if arch.get("programs") is None else os.path.realpath(arch["programs"])
        other = first.setdefault(json.dumps({**p.config, "render": render, "arch": arch}, sort_keys=True,
                                            default=str), p)
        if other is p:
            continue
        differ = [k for k in p.factors if value_identity(p.factors[k]) != value_identity(other.factors.get(k))]
        tables = [k for k in differ if k in ("arch", NULL_PROGRAMS)
                  and resolved_value(p.config, NULL_PROGRAMS) != resolved_value(other.config, NULL_PROGRAMS)]
        if tables:
            both = (f"{k}: {value_text(other.factors[k])} and {value_text(p.factors[k])}" for k in tables)
            null = None in (resolved_value(p.config, NULL_PROGRAMS), resolved_value(other.config, NULL_PROGRAMS))
            said = f" (null is tlm's own, {table})" if null else ""
            raise InputError(f"points {other.index} and {p.index} are one run: " + ", ".join(both) + " give one "
                             f"programs table{said}: give one of them", source=src, key=", ".join(tables))
        keys = [k for k in HOST_ONLY if resolved_value(p.config, k) != resolved_value(other.config, k)]
        if not keys:  # (nothing this check knows of: the run's own)
            continue
        what = " and ".join(sorted({HOST_ONLY[k] for k in keys}))
        raise InputError(f"points {other.index} and {p.index} differ only in {', '.join(differ)} ({', '.join(keys)} "
                         f"{'changes' if len(keys) == 1 else 'change'} no result, only the host's {what}: the work, "
                         "cycles and images are bit-identical for every value), so they would render one result "
                         f"twice, with two labels: give {', '.join(keys)} under set:, and compare values with tlm "
                         f"run --set {keys[0]}=N (results.json's host_seconds; the process's peak memory)",
                         source=src, key=", ".join(differ))


# a factor whose null the run resolves from its scene (the BSP's depth, the photons), which no point's config holds
# before it runs: where results.json records it, and the words of what null is
RESOLVED_NULLS = {"bsp.levels": ("scene.bsp.requested_levels", "floor(ln n) of the scene's {} triangles"),
                  "photons.count": ("scene.photons", "the scene's own count")}


def resolved_nulls(path: Any, factors: list[str], done: list[tuple[Any, dict]], skip: set[str]) -> list[str]:
    """A warning line per factor of :data:`RESOLVED_NULLS` (not in ``skip``) with a point given null and one given
    the value that null resolved to in it (its ``results.json``), the other factors alike: the two are one run,
    run twice (``bsp.levels: [null, 7]`` on cornell's 2604 triangles, floor(ln 2604) = 7), as
    :func:`tlm.experiments.sweep_factors.given_once` refuses a value given twice where it can tell before any
    point runs. ``done``: ``(point, its results)`` of the points that ran and did not fail."""
    lines = []
    for factor in [f for f in factors if f in RESOLVED_NULLS and f not in skip]:
        where, what = RESOLVED_NULLS[factor]
        given: dict[tuple, dict[str, Any]] = {}  # the other factors' values -> this one's value -> its point
        nulls = []
        for point, results in done:
            rest = tuple(value_identity(v) for k, v in point.factors.items() if k != factor)
            value = point.factors.get(factor)
            given.setdefault(rest, {}).setdefault(value_identity(value), point)
            if value is None:
                got = resolved_value(results, where)  # (a missing key: an object, not an int)
                if isinstance(got, int) and not isinstance(got, bool):
                    nulls.append((rest, point, got, ((results.get("scene") or {}).get("triangles"))))
        pairs = [(point, given[rest][value_identity(got)], got, n) for rest, point, got, n in nulls
                 if value_identity(got) in given[rest]]
        if pairs:
            null, other, got, n = pairs[0]
            more = f" (and {len(pairs) - 1} more such pair{'s' if len(pairs) > 2 else ''})" if len(pairs) > 1 else ""
            lines.append(f"{path}: the factor {factor}: null and {value_text(got)} were one setting at points "
                         f"{null.index} and {other.index}{more} (null is {what.format(n)}, {value_text(got)} "
                         "there), so they ran one run twice: give one of them")
    return lines
