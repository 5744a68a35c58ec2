"""The checks of a sweep's points once expanded (out of :mod:`tlm.experiments.sweep_file`, which imports every
name from here under its old name, :func:`one_run_one_row` as ``_one_run_one_row``): no two points of other
factor values are one run (:func:`one_run_one_row`), and every scene file a point names is found
(:func:`scenes_found`). Each refusal is an :class:`~tlm.errors.InputError` naming the points and the keys.
"""

from __future__ import annotations

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
    one config (``photons: [{}, null]`` where the base has no ``photons``: its defaults either way)."""
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
