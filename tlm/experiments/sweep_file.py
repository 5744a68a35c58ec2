"""The sweep file (``tlm sweep FILE``, :mod:`tlm.experiments.sweep`): read, expanded into
points and checked, every point's config resolved and keyed.

:func:`load_sweep` checks the file and every point's config before any point runs, and
loads the scenes and programs tables the points name: a point's key (:func:`config_hash`)
is the hash of its resolved config, of the content of the files it names and of tlm's
code. The checks run once per value, not once per point (:class:`_Checked`): a sweep of
10^5 points is checked in seconds (``benchmarks/bench_sweep_validate.py``), with the keys
and messages of the whole-config check. The ``set``, ``grid`` and ``zip`` mappings as written, a
value given twice and the factors' expansion: :mod:`tlm.experiments.sweep_factors`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from tlm.builtin import read_base
from tlm.config import (
    SECTIONS,
    RunConfig,
    check_leaf,
    config_from_dict,
    describe,
    file_folder,
    files_from,
    is_leaf,
    paths_from,
    plain,
    read_yaml,
    run_config_field,
    scene_from,
    sets_scene,
    to_dict,
    with_leaves,
)
from tlm.config_words import Dumper, dump_yaml, sets_nothing, value_text, with_overrides
from tlm.errors import InputError
from tlm.experiments.study import override_key, refuse_own_keys, scene_keys, with_set
from tlm.experiments.sweep_checks import NO_IMAGE as _NO_IMAGE
from tlm.experiments.sweep_checks import one_run_one_row as _one_run_one_row
from tlm.experiments.sweep_checks import resolved_nulls as _resolved_nulls
from tlm.experiments.sweep_checks import resolved_value as _resolved  # noqa: F401  (kept importable from here)
from tlm.experiments.sweep_checks import scenes_found as _scenes_found
from tlm.experiments.sweep_factors import assign as _assign
from tlm.experiments.sweep_factors import dotted_keys as _dotted_keys
from tlm.experiments.sweep_factors import expand as expand
from tlm.experiments.sweep_factors import expand_both as _expand_both
from tlm.experiments.sweep_factors import given_once as _given_once
from tlm.experiments.sweep_factors import keys_given as _keys_given
from tlm.experiments.sweep_factors import value_identity as _same  # noqa: F401  (kept importable from here)
from tlm.experiments.sweep_keys import canonical_json as _json
from tlm.experiments.sweep_keys import from_folder as _from  # noqa: F401  (kept importable from here)
from tlm.experiments.sweep_keys import keyed_field as _keyed
from tlm.experiments.sweep_keys import point_inputs as point_inputs  # (what a test replaces: read here)
from tlm.experiments.sweep_sets import at_default, given_by, named, refuse_factor_sets, said_once, set_leaves
from tlm.fingerprint import code_fingerprint
from tlm.registry import plugins, selected

_SCALARS = (str, int, float, bool, type(None))
SWEEP_KEYS = ("description", "base", "set", "grid", "zip")


@dataclass(frozen=True)
class Point:
    """One point: its factor values and its resolved config."""

    index: int
    factors: dict[str, Any]  # dotted key -> value
    config: dict  # to_dict of the resolved RunConfig (its sections shared with other points: read, never written)
    # 16 hex digits of sha256 over ``config`` (but with arch.trace as true, where no factor gives it: _traced),
    # its input files and tlm's code (config_hash)
    hash: str
    functional: str = ""  # the functional key of its frame: points of one key share one render

    @property
    def traces(self) -> bool:
        """Whether the point keeps the timing model's trace and writes ``trace.json``: its config's
        ``arch.trace``, true only where the sweep asks for it (:func:`_trace_asked`)."""
        return (self.config.get("arch") or {}).get("trace") is True


@dataclass(frozen=True)
class Sweep:
    path: Path
    description: str | None
    base: dict  # the base run config as written (before ``set``)
    base_file: str | None
    set: dict[str, Any]
    grid: dict[str, list]
    zip: dict[str, list]
    folder: Path  # where relative paths in the configs start
    points: list[Point] = field(default_factory=list)
    # per point, the settings it never reads and why (tlm.render.planner.inert_settings of
    # the config load_sweep checked)
    inert: list[dict[str, str]] = field(default_factory=list)
    # the command line's --set strings (tlm sweep --set), applied to the base after ``set``: in every
    # point's config, and so in its hash
    overrides: tuple[str, ...] = ()

    def overridden(self, key: str) -> bool:
        """Whether a ``--set`` of the sweep gave the dotted ``key`` (itself, not a section above it)."""
        return any(override_key(o) == key for o in self.overrides)

    @property
    def factors(self) -> list[str]:
        return [*self.grid, *self.zip]

    def inert_factors(self) -> list[str]:
        """A warning line per factor that changes nothing in any point
        (:func:`tlm.render.planner.inert_settings`: ``estimate.k`` swept under the m-voxel
        filter, ``photons.count`` in mode rcast; ``render.exposure``, as a sweep writes no image:
        :data:`~tlm.experiments.sweep_checks.NO_IMAGE`; a section's factor by the keys its values set, ``render:
        [{exposure: 1}, {exposure: 2}]``): its points would be the same run. Then one per value of a
        factor that sets nothing (a section's mapping that names no key, ``grid: {render: [{}, ...]}``, which
        merges into the base's section: :func:`_keys_given`; null gives the section at its defaults)."""
        lines = []
        for factor in self.factors:
            # (a section's factor, grid: {render: [{exposure: 1}, {exposure: 2}]}: the keys its values set, each)
            keys = _keys_given(factor, {**self.grid, **self.zip}[factor])
            whys = {i.get(k, _NO_IMAGE.get(k)) for i in self.inert for k in keys}  # (and the exposure: no image)
            if self.inert and keys and None not in whys:
                named_keys = "" if keys == [factor] else f" ({', '.join(keys)})"
                lines.append(f"{self.path}: the factor {factor}{named_keys} changes nothing in any point: "
                             f"{said_once(whys)}")
        for where, section in (("grid", self.grid), ("zip", self.zip)):
            for key, values in section.items():
                base = f"its points have the base's {key}"
                lines += [f"{self.path}: {where}.{key}: the value {value_text(v)} "
                          f"{sets_nothing('a value null', base)}" for v in values if not _keys_given(key, [v])]
        return lines

    def set_keys(self) -> dict[str, str]:
        """The keys the sweep's ``--set`` strings set (a section given as a mapping, ``estimate={k: 9}``,
        sets the keys it names, as it merges: :func:`set_leaves`; ``estimate=null`` the section, each key
        of it set before), each with the ``--set`` string that set it last."""
        last: dict[str, str] = {}
        for item in self.overrides:
            for key in set_leaves(item):
                for earlier in [k for k in last if k == key or k.startswith(key + ".")]:
                    del last[earlier]
                last[key] = item.strip()
        return last

    def _inert_whys(self, key: str) -> set[str] | None:
        """Why ``key`` changes nothing, each point's reason (a section, ``estimate`` of ``--set estimate=null``:
        each of its keys'), or None where some point reads it."""
        keys = [k for k, _, _ in describe() if k.startswith(key + ".")] if key in SECTIONS else [key]
        if not self.inert or not all(k in i or k in _NO_IMAGE for i in self.inert for k in keys):
            return None
        return {i.get(k, _NO_IMAGE.get(k)) for i in self.inert for k in keys}

    def inert_sets(self) -> list[str]:
        """A warning line per ``--set`` of the sweep that changes nothing in any point, by the rule of
        :meth:`inert_factors` (:func:`tlm.render.planner.inert_settings`: ``estimate.k`` in mode rcast),
        as ``tlm run --set`` says one its run never reads; a ``--set`` that some points read gets none,
        as a factor does not. A section given as a mapping names the keys no point reads where it sets
        others too (``--set estimate={k: 9, ...}: estimate.k``); one given null, the whole section, is
        said where no point reads any key of it. Then one line per ``--set`` and ``set:`` entry that sets
        nothing: a section's mapping that names no key (``--set render={}``, ``set: {render: {}}``), which
        merges into the base's section (:func:`~tlm.config_words.sets_nothing`; null gives it at its defaults)."""
        whys = {k: self._inert_whys(k) for k in self.set_keys()}
        lines = self._set_lines({k: w for k, w in whys.items() if w is not None}, "changes nothing in any point")
        lines += [f"{self.path}: set.{key}: {value_text(v)} {sets_nothing(f'set.{key}: null')}"
                  for key, v in self.set.items() if not _keys_given(key, [v])]
        empty = dict.fromkeys(o.strip() for o in self.overrides if not set_leaves(o))
        return lines + [f"{self.path}: --set {item} {sets_nothing(f'--set {override_key(item)}=null')}"
                        for item in empty]

    def _set_lines(self, whys: dict[str, set], verb: str) -> list[str]:
        """One line per ``--set`` string of the keys ``whys`` (key -> its points' reasons) that it set last."""
        keys = self.set_keys()
        lines = []
        for item in dict.fromkeys(keys[k] for k in whys):
            mine = [k for k in whys if keys[k] == item]
            named = "" if len(mine) == len(set_leaves(item)) else f": {', '.join(mine)}"
            lines.append(f"{self.path}: --set {item}{named} {verb} (though in every point's config and hash: "
                         f"a rerun into a folder swept without it runs its points again): "
                         f"{said_once(set().union(*(whys[k] for k in mine)))}")
        return lines

    def unread_factors(self, done: list[tuple[Point, dict]]) -> list[str]:
        """A warning line per factor that no point read, judged after the points ran: the
        timing model's keys a point changed from their defaults and never read are in its
        ``results.json`` ``inert`` (:func:`tlm.experiments.run_warnings.inert_timing_changes`:
        ``arch.swap_cycles`` where no PM moved, ``arch.context_switch_cycles`` with one
        image in flight, ...). A factor gets a line when every point in ``done`` (``(point,
        its results)``, the points that ran and did not fail) names it there or holds it at
        its default (a run the others then equal), and one names it at least; not the
        factors :meth:`inert_factors` named before the points ran. Then a line per factor whose null
        resolved to another of its values, the other factors alike (``bsp.levels: [null, 7]`` on
        cornell: :func:`~tlm.experiments.sweep_checks.resolved_nulls`)."""
        if not done:
            return []
        said = {f for f in [*self.factors, *self.set_keys()] if self._inert_whys(f) is not None}
        defaults = to_dict(RunConfig())
        where = "the one point" if len(done) == 1 else f"any of the {len(done)} points"
        lines = []
        sets: dict[str, set] = {}
        for factor in [*self.factors, *self.set_keys()]:
            if factor in said:
                continue
            whys: set[str] = set()
            for point, results in done:
                inert = results.get("inert")
                why = inert.get(factor) if isinstance(inert, dict) else None
                if why is not None:
                    whys.add(str(why))
                elif not at_default(point.config, defaults, factor):
                    whys.clear()
                    break
            if whys and factor in self.factors:
                lines.append(f"{self.path}: the factor {factor} changed nothing in {where}: "
                             f"{said_once(whys)}")
                said.add(factor)
            elif whys:  # (a key of a --set: said as the --set that gave it)
                sets[factor] = whys
        # (then a factor's null and the value it resolved to, bsp.levels: [null, 7] on cornell: one run twice)
        lines += _resolved_nulls(self.path, self.factors, done, said)
        return [*lines, *self._set_lines(sets, f"changed nothing in {where}")]

    def identity(self) -> str:
        """16 hex digits naming the sweep's points (their hashes, in order, and which of them write
        trace.json, :attr:`Point.traces`, which their hashes need not tell: :func:`_traced`): two sweeps of
        one identity may run into one folder at once, two of others may not (tlm.claims.sharing), a sweep
        that asks for ``arch.trace`` and one of the same points that does not among them (each would
        replace the other's points, with or without their trace.json)."""
        return hashlib.sha256("\n".join(p.hash + (" trace" if p.traces else "") for p in self.points
                                        ).encode()).hexdigest()[:16]

    def to_dict(self) -> dict:
        given = {"overrides": list(self.overrides)} if self.overrides else {}  # (tlm sweep --set, as typed)
        return {
            "tlm": "sweep/1", "sweep": str(self.path), "description": self.description,
            "base_file": self.base_file, "base": self.base, "set": self.set, **given, "grid": self.grid,
            "zip": self.zip, "points": [{"point": p.index, "hash": p.hash, "factors": p.factors} for p in self.points],
        }

    def marker(self) -> str:
        """``sweep.yaml``'s text: :func:`~tlm.config_words.dump_yaml` ``(self.to_dict(), sort_keys=False)``
        (``yaml.safe_dump``'s, a string that tlm's reader takes for a number quoted: a description ``'1e3'``).

        Where every factor value is a plain scalar (a string, number, bool or null: no YAML
        anchors between points), the points' lines are put together from each factor
        value's line and each hash, as that dump writes them, without a dump per point."""
        head = self.to_dict()
        del head["points"]
        lines = {}  # (key, value's id) -> its lines in a point's factors (the values live as long as the points)
        resolver = yaml.resolver.Resolver()  # (a hash that reads as a number is quoted, as the dump quotes it:
        resolver.yaml_implicit_resolvers = Dumper.yaml_implicit_resolvers  # tlm's reader's, 1234e5...: a float)
        str_tag = "tag:yaml.org,2002:str"
        out = [dump_yaml(head, sort_keys=False), "points:\n"]
        for p in self.points:
            shown = p.hash if resolver.resolve(yaml.ScalarNode, p.hash, (True, False)) == str_tag else f"'{p.hash}'"
            out.append(f"- point: {p.index}\n  hash: {shown}\n  factors:\n")
            for k, v in p.factors.items():
                line = lines.get((k, id(v)))
                if line is None:
                    if type(v) not in _SCALARS:  # (a list or a mapping: the dump's own, anchors and all)
                        return dump_yaml(self.to_dict(), sort_keys=False)
                    text = dump_yaml([{"factors": {k: v}}], sort_keys=False)
                    line = lines[k, id(v)] = text[text.index("\n") + 1:]
                out.append(line)
        return "".join(out)


def config_hash(resolved: dict, inputs: dict[str, str] | None = None, folder: Path | None = None) -> str:
    """The point's key: sha256 of the resolved config's canonical JSON, of the fingerprints
    of its input files and of tlm's code, 16 hex digits.

    ``inputs`` (:func:`point_inputs`) holds the content of what the config names by path
    only: the scene and its meshes (through the functional key) and the programs table.
    The files and the code are part of the key so that a rerun after a change to either
    computes its points again instead of reusing results of other inputs or other code.
    ``folder``: the sweep file's folder; the files the config names (absolute there:
    :func:`tlm.config.scene_from`) are keyed by their path from it (:func:`_keyed`), so that
    the same project in another folder, moved or copied, has the same keys.
    """
    return _key([_keyed(name, resolved[name], folder) for name in sorted(resolved)],
                None if inputs is None else _json(inputs), _plugins(resolved))


def _plugins(resolved: dict) -> str | None:
    """The JSON of the plug-ins the point's resolved config selects (:func:`tlm.registry.plugins`: a class
    from outside tlm, its code's digest), or None where it selects tlm's own alone."""
    chosen = plugins(resolved)
    return _json(chosen) if chosen else None


def _key(keyed: list[str], inputs: str | None, chosen: str | None = None) -> str:
    """16 hex digits of sha256 over ``{"code": ..., "config": {fields}, "inputs": ..., "plugins": ...}``
    (keys sorted): the fields' :func:`_keyed` texts in the order of their names, the inputs' JSON, and
    ``chosen``, :func:`_plugins`' JSON, only where the point selects a plug-in (the key of a point of
    tlm's own classes alone is the one it had before)."""
    more = "" if inputs is None else f',"inputs":{inputs}'
    more += "" if chosen is None else f',"plugins":{chosen}'
    blob = f'{{"code":{json.dumps(code_fingerprint())},"config":{{{",".join(keyed)}}}{more}}}'
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class _Field:
    """One top-level field of a point's resolved config (a section, ``scene``, ``mode``, ...)."""

    name: str
    value: Any  # as RunConfig holds it
    resolved: Any  # as to_dict gives it (shared by the points of this value: read, never written)
    full: str  # its canonical JSON (sorted keys, no spaces)
    keyed: str  # '"name":' and its JSON in the point's key (config_hash: render.threads left out)


def _field(name: str, value: Any, folder: Path | None = None) -> _Field:
    resolved = to_dict(value)
    return _Field(name, value, resolved, _json(resolved), _keyed(name, resolved, folder))


def _config(fields: dict[str, _Field]) -> RunConfig:
    return RunConfig(**{name: f.value for name, f in fields.items()})


class _Checked:
    """The points' configs checked field by field, each value once.

    A top-level field's raw value (a section, ``scene``, ``seed``, ...) is the base (with
    ``set``) with the factors under that field's key assigned: it depends on those factors'
    values alone, so each combination of them is checked once (:func:`run_config_field`)
    and its JSON made once, not once per point. Where every factor under a section names
    one of its plain fields (``arch.fifo_depth``), each factor value is checked once alone
    (:func:`check_leaf`) and a combination is the base's section with them
    (:func:`with_leaves`, which makes the checks across the section's fields)."""

    def __init__(self, fixed: dict, keys: list[str], values: list[list], folder: Path | None = None):
        self.fixed, self.keys, self.values = fixed, keys, values
        self.folder = folder  # (the sweep file's: the points' keys name files from there, _keyed)
        names = [f.name for f in dataclasses.fields(RunConfig)]
        owner = [k.split(".")[0] for k in keys]
        # a key that is no field: every point fails the check (of its first key, point 0 first)
        self.sound = all(o in names for o in owner)
        under = {name: [i for i, o in enumerate(owner) if o == name] for name in names}
        # the fields the factors leave as the base has them; the others' slots (RunConfig's order)
        self.template: dict[str, _Field | None] = {
            name: None if under[name] else _field(name, self._value(name, []), folder) for name in names}
        self.varying = [(name, under[name], {}) for name in names if under[name]]
        self.leaves = {name: all(is_leaf(keys[i]) for i in at) for name, at, _ in self.varying}
        self.base = {name: self._value(name, []) for name, _, _ in self.varying if self.leaves[name]}
        self.leaf: dict[tuple[int, int], Any] = {}  # (factor, value index) -> its checked value, or _REFUSED

    def _value(self, name: str, at: list[int], index: tuple = ()) -> Any:
        raw = {name: self.fixed[name]} if name in self.fixed else {}
        for i in at:
            raw = _assign(raw, self.keys[i], self.values[i][index[i]])
        return run_config_field(name, plain(raw))

    def _leaf(self, i: int, j: int) -> Any:
        if (i, j) not in self.leaf:
            try:
                self.leaf[i, j] = check_leaf(self.keys[i], plain(self.values[i][j]))
            except Exception:
                self.leaf[i, j] = _REFUSED
        return self.leaf[i, j]

    def _check(self, name: str, at: list[int], index: tuple) -> _Field | None:
        try:
            if not self.leaves[name]:
                return _field(name, self._value(name, at, index), self.folder)
            changes = {}
            for i in at:
                value = self._leaf(i, index[i])
                if value is _REFUSED:
                    return None
                changes[self.keys[i].split(".")[1]] = value
            return _field(name, with_leaves(name, self.base[name], changes), self.folder)
        except Exception:  # (the point's whole check, run again, says what and where)
            return None

    def point(self, index: tuple) -> dict[str, _Field] | None:
        """The point's fields (in RunConfig's order) by the index of each factor's value, or
        None where the checks refuse one (or where a factor's key is no field)."""
        if not self.sound:
            return None
        fields = dict(self.template)
        for name, at, cache in self.varying:
            key = tuple(index[i] for i in at)
            got = cache.get(key, _REFUSED)
            if got is _REFUSED:
                got = cache[key] = self._check(name, at, index)
            if got is None:
                return None
            fields[name] = got
        return fields

    def of(self, cfg: RunConfig) -> dict[str, _Field]:
        return {name: _field(name, getattr(cfg, name), self.folder) for name in self.template}


_REFUSED = object()


def load_sweep(path: Path, overrides: Iterable[str] = (), check: Callable[[Any, Path], None] | None = None
               ) -> Sweep:
    """Read and check a sweep file and every point's config, and load the scenes and programs
    tables the points name (their content is part of the points' keys); InputError names the
    file and key. ``check``: called with the file's data and ``path`` on its one read, before its own checks (the
    API's refusal of a file that is another command's, :func:`tlm.api_common.kind_check`: a pipe's text is read once).

    ``overrides``: ``dotted.key=value`` strings (``tlm sweep --set``), applied to the base after
    the file's ``set`` (a key both give: the --set's value) and before the factors, as ``tlm run
    --set`` applies them (:func:`tlm.experiments.study.with_set`: a relative path from the working
    folder); the points' configs, and so their hashes, hold them. One whose key is a factor's, or a
    section above or below one, is refused (the factor would win unsaid), but a section given as a
    mapping that leaves the factor's key out, which merges into the base's section as ``tlm run --set``
    does (:func:`~tlm.experiments.sweep_sets.refuse_factor_sets`); so is a bad key or value (the error
    names the file ``with --set``, as ``tlm run``'s does). A section given as a mapping under ``set``,
    or as a factor's values, merges into the base's section likewise (:func:`_assign`), and sets the keys
    it names alone (:func:`_keys_given`): ``set``, ``grid`` and ``zip`` overlap, and a ``--set`` a factor,
    by those keys (``set: {render: {spp: 1}}`` beside a factor ``render.light_samples`` is taken).

    A point's ``arch.trace`` (its trace.json) is false unless the sweep writes it (:func:`_trace_asked`);
    its key holds it as true but where a factor gives it (:func:`_traced`)."""
    path = Path(path)
    src = str(path)
    raw = read_yaml(path)
    if check is not None:  # (a run config, a study: the command that runs it, from this one read)
        check(raw, path)
    if not isinstance(raw, dict):
        raise InputError(f"must be a mapping with {', '.join(SWEEP_KEYS)}", source=src)
    for key in raw:
        if key not in SWEEP_KEYS:
            raise InputError(f"unknown key (expected {', '.join(SWEEP_KEYS)})", source=src, key=str(key))
    description = raw.get("description")
    if description is not None and not isinstance(description, str):
        raise InputError(f"{description!r} is not a string", source=src, key="description")
    if raw.get("base") is None:  # (as tlm run refuses an empty config: not the defaults by mistake; h474)
        got = "it is null" if "base" in raw else "none given"
        raise InputError(f"required ({got}): name the run config the points start from, a file (relative to the "
                         "sweep file), a built-in one (base: cornell) or a mapping (base: {scene: cornell}; "
                         "'tlm params' lists the defaults)", source=src, key="base")
    folder = file_folder(path)  # (an anonymous pipe's: the working folder)
    base_file = raw.get("base") if isinstance(raw.get("base"), str) else None
    base, base_src, folder = read_base(raw.get("base"), folder, src, "sweep file", scene_keys)
    try:
        config_from_dict(base, base_src)  # the base alone, so its errors name its own file
    except InputError as e:
        if not isinstance(raw.get("base"), dict):
            raise
        raise e.under("base") from None  # (inline: the key as the sweep file writes it, base.render.spp)

    settings = _dotted_keys(raw.get("set"), "set", src, lists=False)
    grid = _dotted_keys(raw.get("grid"), "grid", src, lists=True)
    zipped = _dotted_keys(raw.get("zip"), "zip", src, lists=True)
    if not grid and not zipped:
        raise InputError("needs at least one factor under 'grid' or 'zip'", source=src)
    lengths = {k: len(v) for k, v in zipped.items()}
    if len(set(lengths.values())) > 1:
        raise InputError(f"lists of unequal length ({', '.join(f'{k}: {n}' for k, n in lengths.items())})",
                         source=src, key="zip")
    seen: dict[str, tuple[str, str]] = {}  # each key set so far (a section's mapping: those it names): by what
    for name, section in (("set", settings), ("grid", grid), ("zip", zipped)):
        for k, v in section.items():
            mine = _keys_given(k, [v] if name == "set" else v)
            for leaf, (other, where) in seen.items():
                if any(m == leaf or m.startswith(leaf + ".") or leaf.startswith(m + ".") for m in mine):
                    raise InputError(f"overlaps {where}.{other}", source=src, key=f"{name}.{k}")
            seen.update(dict.fromkeys(mine, (k, name)))

    # a path the sweep file gives (arch.programs) is relative to the sweep file, the base's to
    # the base config's folder; a scene file it gives is the sweep file's, else the base
    # config's, else a built-in scene, else the working folder's (last). Each is made absolute:
    # one file wherever the sweep runs, on any worker, and in each point's config.resolved.yaml;
    # the points' keys name it by its path from the sweep file's folder (_keyed), not where the
    # project lies
    here = file_folder(path)
    scene_folders = list(dict.fromkeys([here, folder]))

    def moved(k: str, v: Any, warn: bool = True) -> Any:
        return scene_from(v, scene_folders, warn) if k == "scene" else paths_from(k, v, here)

    # (a scene that set, a factor or a --set replaces, used by no point: not warned of, h451)
    overrides = tuple(str(o) for o in overrides)
    replaced = sets_scene(overrides) or sets_scene(f"{k}=" for k in (*settings, *grid, *zipped))
    fixed = files_from(base, folder, not replaced)  # (the base's files: from the base config's folder)
    for k, v in settings.items():
        fixed = _assign(fixed, k, moved(k, v, not sets_scene(overrides)))
    config_from_dict(fixed, f"{src} (base with set)")
    label = with_overrides(src) if overrides else src  # (what a point's error names its config by)
    if overrides:  # (a --set scene beside a scene factor, refused below: not warned of, h455)
        fixed = with_set(fixed, overrides, scene_folders, not sets_scene(f"{k}=" for k in (*grid, *zipped)))
        refuse_own_keys(overrides, SWEEP_KEYS, src, "sweep file")
        # (a factor whose values are a section's mappings sets the keys they name: a --set of another is kept)
        factor_sets = {k: (where, _keys_given(k, values)) for where, section in (("grid", grid), ("zip", zipped))
                       for k, values in section.items()}
        for item in overrides:
            mine = set_leaves(item)
            refuse_factor_sets([item], {k: where for k, (where, keys) in factor_sets.items()
                                        if any(given_by(m, keys) for m in mine)}, src)
        config_from_dict(fixed, label)
    factors_list, indices = _expand_both(grid, zipped)
    factor_keys = [*grid, *zipped]
    checked = _Checked(fixed, factor_keys, [[moved(k, v) for v in values]
                                            for k, values in zip(factor_keys, [*grid.values(), *zipped.values()])],
                       here)
    rows = []
    for i, (factors, index) in enumerate(zip(factors_list, indices)):
        fields = checked.point(index)
        if fields is None:  # a value the checks refuse: the point's own check says which, as ever
            point = fixed
            for k, v in factors.items():
                point = _assign(point, k, moved(k, v))
            shown = ", ".join(f"{k}={value_text(v)}" for k, v in factors.items())  # (as YAML writes them: null)
            try:
                fields = checked.of(config_from_dict(point, f"{src} (point {i}: {shown})"))
            except InputError as e:  # (named by what gave the key: a --set's, not a factor's, says so)
                if not (overrides and given_by(e.key, map(override_key, overrides))
                        and not given_by(e.key, factors)):
                    raise
                raise named(e, f"{label} (point {i}: {shown})") from None
        rows.append((i, factors, fields))
    _given_once(grid, zipped, src)  # (after each value's own check: [32, 32] of resolution is no [w, h] twice)
    from tlm.render.planner import inert_settings

    inert, known = [], {}
    for _, _, fields in rows:
        # (what inert_settings reads: the mode, the photon-map sections, arch.scheduler)
        key = (fields["mode"].full, fields["photons"].full, fields["estimate"].full, fields["reference"].full,
               fields["arch"].value.scheduler)
        if key not in known:
            known[key] = inert_settings(_config(fields))
        inert.append(known[key])
    # every config is checked before any file it names is loaded
    given = (*settings, *factor_keys, *map(override_key, overrides))
    by_set = any(override_key(o) == "scene" for o in overrides)  # (a scene a --set gives: its error says so)
    _scenes_found(rows, label if by_set else src, scene_folders if any(k == "scene" for k in given) else [folder],
                  not by_set)
    points, seen, known = [], {}, {}
    order = sorted(checked.template)  # (the key's JSON sorts its keys)
    asked, by_factor = _trace_asked(base, settings, grid, zipped, overrides)
    traced: dict[int, tuple[dict, str]] = {}  # id of an arch field -> (its config, its keyed text), per trace
    chosen: dict[tuple, str | None] = {}  # the registries' settings (selected) -> the plug-ins' JSON (_plugins)
    # the config less arch, as the JSON of its fields: those the factors leave, then the others
    same = tuple(f.full for name, f in checked.template.items() if f is not None and name != "arch")
    other = [name for name, f in checked.template.items() if f is None and name != "arch"]
    for i, factors, fields in rows:
        work = (same, *[fields[name].full for name in other])
        key = (fields["arch"].value.programs, work)  # what point_inputs reads
        if key not in known:
            inputs = point_inputs(_config(fields), folder, f"{src} (point {i})", seen, work)
            known[key] = inputs, _json(inputs)
        inputs, shown = known[key]
        # (arch.trace: as the sweep asks for it, in the key as true: _traced)
        trace = asked or (bool(by_factor) and any(k in by_factor and TRACE in _keys_given(k, [v])
                                                  for k, v in factors.items()))
        arch = fields["arch"]
        if (id(arch), trace) not in traced:
            traced[id(arch), trace] = _traced(arch, trace, bool(by_factor), here)
        config, keyed = {name: f.resolved for name, f in fields.items()}, traced[id(arch), trace]
        config["arch"] = keyed[0]
        selects = selected(config)  # (what plugins reads of it: estimate.filter, arch.scheduler)
        if selects not in chosen:
            chosen[selects] = _plugins(config)
        # config_hash(resolved, inputs), from the fields' own JSON
        points.append(Point(i, factors, config,
                            _key([keyed[1] if name == "arch" else fields[name].keyed for name in order], shown,
                                 chosen[selects]), inputs["functional"]))
    _one_run_one_row(points, src)
    return Sweep(path, description, base, base_file, settings, grid, zipped, folder, points, inert, overrides)


TRACE = "arch.trace"  # the key whose trace.json a sweep point writes only where the sweep asks for it


def _trace_asked(base: dict, settings: dict, grid: dict, zipped: dict, overrides: Iterable[str]) -> tuple[bool, set]:
    """Whether the sweep writes ``arch.trace`` for every point (in its base, a mapping or the base config file,
    under ``set``, or in a ``--set``), and the factors that may give it (``grid: {arch.trace: [false, true]}``,
    a mapping of the ``arch`` section that names it: :func:`_keys_given`). A point whose ``arch.trace`` none
    of them gives runs with it false (``tlm run``'s default, true, is not a sweep's: a trace of each of its
    points would be most of its output, and ``tlm report`` draws the timeline of two points of a sweep at
    most); one given runs as given."""
    written = [*(k for key, v in base.items() for k in _keys_given(str(key), [v])),
               *(k for key, v in settings.items() for k in _keys_given(key, [v])),
               *(k for item in overrides for k in set_leaves(item))]
    factors = {key for key, values in (*grid.items(), *zipped.items()) if TRACE in _keys_given(key, values)}
    return TRACE in written, factors


def _traced(arch: _Field, trace: bool, by_factor: bool, folder: Path) -> tuple[dict, str]:
    """A point's ``arch`` section with ``arch.trace`` as the sweep asks for it (``trace``: the value it
    resolves to, else false), and its text in the point's key (:func:`_keyed`): with ``arch.trace`` true
    whatever the point runs with, so that asking for a trace, or no longer, keeps the point's key (a point
    done without its trace.json runs again: :func:`tlm.experiments.sweep_reference.point_done`); but where a factor
    gives ``arch.trace`` (``by_factor``), as the point runs, so that its points of either value stay two."""
    resolved = arch.resolved
    value = resolved.get("trace") is True if trace else False
    config = resolved if resolved.get("trace") == value else {**resolved, "trace": value}
    keyed_as = config if by_factor else {**resolved, "trace": True}
    keyed = arch.keyed if keyed_as == resolved else _keyed("arch", keyed_as, folder)
    return config, keyed
