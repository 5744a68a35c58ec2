"""A sweep file's factors as written (:func:`tlm.experiments.sweep_file.load_sweep`): the
``set``, ``grid`` and ``zip`` mappings of dotted keys checked, a value a factor gives twice
refused, the factors expanded into points (the grid's product, the zip's columns), and a
value assigned to a dotted key of a raw config as ``tlm run --set`` merges it. Out of
:mod:`tlm.experiments.sweep_file`, which imports them from here.
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Iterable
from typing import Any

from tlm.config import SECTIONS
from tlm.config_words import laid_over, value_text
from tlm.errors import InputError
from tlm.experiments.study import value_leaves


def assign(raw: dict, key: str, value: Any) -> dict:
    """A copy of ``raw`` with the dotted ``key`` set to ``value`` (sections created as needed); a mapping
    given for a section merges into it, as ``tlm run --set`` merges it (:func:`~tlm.config_words.laid_over`)."""
    out = dict(raw)
    node = out
    parts = key.split(".")
    for p in parts[:-1]:
        child = node.get(p)
        node[p] = child = dict(child) if isinstance(child, dict) else {}
        node = child
    node[parts[-1]] = laid_over(node.get(parts[-1]), value, key, SECTIONS)
    return out


def keys_given(key: str, values: Iterable[Any]) -> list[str]:
    """The dotted keys that ``values``, each given for the dotted ``key`` (a ``set:`` entry's value, a
    factor's list), set over the base: ``key`` itself, or where a value is a mapping given for a section,
    which merges into it (:func:`assign`), the keys it names (``render: {spp: 1}`` sets ``render.spp``
    alone, ``render: {}`` none), as :func:`~tlm.experiments.study.set_leaves` reads a ``--set``'s."""
    out: dict[str, None] = {}
    for v in values:
        out.update(dict.fromkeys(value_leaves(key, v)))
    return list(out)


def dotted_keys(section: Any, name: str, src: str, lists: bool) -> dict[str, Any]:
    if section is None:
        return {}
    if not isinstance(section, dict):
        raise InputError(f"must be a mapping of dotted keys, got {value_text(section)}", source=src, key=name)
    for k, v in section.items():
        if not isinstance(k, str) or not k or any(not p for p in k.split(".")):
            shown = repr(k) if isinstance(k, str) else value_text(k)  # (a YAML key null, true or 1 as written)
            raise InputError(f"{shown} is not a dotted config key", source=src, key=name)
        if lists:
            if not isinstance(v, list):
                raise InputError(f"{value_text(v)} is not a list of values", source=src, key=f"{name}.{k}")
            if not v:
                raise InputError("has no values", source=src, key=f"{name}.{k}")
    return dict(section)


def expand(grid: dict[str, list], zipped: dict[str, list]) -> list[dict[str, Any]]:
    """product(grid) x zip, as {dotted key: value}; the grid's first key varies slowest, zip fastest."""
    return expand_both(grid, zipped)[0]


def expand_both(grid: dict[str, list], zipped: dict[str, list]) -> tuple[list[dict[str, Any]], list[tuple]]:
    """:func:`expand`, and beside each point the index of each factor's value in its list
    (the grid's keys, then the zip's)."""
    columns = list(zip(*zipped.values())) if zipped else [()]
    factors, indices = [], []
    for combo in itertools.product(*(range(len(v)) for v in grid.values())):
        values = {k: grid[k][j] for k, j in zip(grid, combo)}
        for c in range(len(columns)):
            factors.append({**values, **dict(zip(zipped, columns[c]))})
            indices.append(combo + (c,) * len(zipped))
    return factors, indices


def given_once(grid: dict[str, list], zipped: dict[str, list], src: str) -> None:
    """An InputError for a value a grid factor lists twice (``grid.arch.fifo_depth: 1 given
    twice``), or a set of zip values given twice: its points would be one run, run once and
    counted twice (two rows of one hash in ``sweep.csv``, the report's count of runs)."""
    for key, values in grid.items():
        seen: set[str] = set()
        for v in values:
            if value_identity(v) in seen:
                raise InputError(f"{value_text(v)} given twice", source=src, key=f"grid.{key}")
            seen.add(value_identity(v))
    if not zipped:
        return
    first: dict[tuple, int] = {}
    for i, column in enumerate(zip(*zipped.values())):
        j = first.setdefault(tuple(map(value_identity, column)), i)
        if j != i:
            if len(zipped) == 1:
                raise InputError(f"{value_text(column[0])} given twice", source=src, key=f"zip.{next(iter(zipped))}")
            shown = ", ".join(f"{k}={value_text(v)}" for k, v in zip(zipped, column))
            raise InputError(f"{shown} given twice (at {j} and {i})", source=src, key="zip")


def value_identity(value: Any) -> str:
    """What a factor value is, to find one given twice: its type and canonical JSON, so that
    ``1`` and ``1.0`` (or ``true``) are other values here (the point's check may refuse one, or
    find them one run: :func:`~tlm.experiments.sweep_checks.one_run_one_row`)."""
    return f"{type(value).__name__}:{json.dumps(value, sort_keys=True, default=repr)}"
