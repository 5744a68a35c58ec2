"""Sweeps: a base run config copied over a product of factors, one folder per point.

A sweep file (``tlm sweep FILE``)::

    description: FIFO depth against page-miss cost
    base: cornell.yaml            # a run config file (relative to this file) or a mapping
    set: {mode: rcast}            # dotted keys applied to base, for every point
    grid:                         # the full product; the first key varies slowest
      arch.fifo_depth: [1, 16, 256, 1024]
      arch.page_miss_cycles: [0, 12, 48]
    zip:                          # lists of one length, taken together
      seed: [0, 1]
      render.light_samples: [1, 4]

Points are product(grid) x zip: every combination of the grid with every zip column,
zip varying fastest. Any config key may be a factor by its dotted path, and every
point's config goes through the run config's checks before any point runs. Relative
paths in the configs (``scene``, ``arch.programs``) start at the base config's folder
when ``base`` is a file, else at the sweep file's folder.

A point is keyed by the hash of its resolved config, of the content of the files it
names (the scene and its meshes, through the functional key; the programs table) and
of tlm's code, so a rerun (or another sweep into the same folder) skips the points
already done, and recomputes those whose inputs changed. Output folder::

    sweep.yaml               the sweep as resolved: base, set, factors, every point's hash
    sweep.jsonl              one row per point, appended as points finish (a killed sweep
                             keeps them, its last row perhaps cut off); rewritten sorted
                             when the sweep ends
    sweep.csv                the same rows, one column per field, written at the end
    points/<hash>/           config.resolved.yaml, results.json, trace.json (arch.trace);
                             or error.json when the point failed (retried by a rerun)

A point renders nothing that another point rendered: points that differ only in
``arch`` share one functional result (:mod:`tlm.arch.functional`; docs/design.md, "Why
the seam makes sweeps cheap"). One point per functional result goes first; the others
follow once it is cached, so two
workers never render the same frame. Workers: a local process pool, or Dask. A local
worker ends itself when the sweep's process dies (a killed sweep leaves none running);
a worker that dies (a crash, an OOM kill) costs the sweep only the point it ran, if that
point kills its worker again when run alone (:class:`LocalPool`).
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import hashlib
import itertools
import json
import os
import re
import shutil
import sys
import time
import traceback
from collections import deque
from contextlib import ExitStack, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from tlm import storage
from tlm.config import (
    RunConfig,
    check_leaf,
    config_from_dict,
    is_leaf,
    plain,
    read_yaml,
    run_config_field,
    to_dict,
    with_leaves,
)
from tlm.errors import InputError, interrupted_by
from tlm.experiments.executors import InProcess, LocalPool, dask_worker_threads, kernel_threads, open_executor
from tlm.experiments.frames import SUMMARY_KEYS, cached_render, is_cached, render_key
from tlm.experiments.provenance import code_state, versions
from tlm.fingerprint import code_fingerprint
from tlm.storage import atomic_folder, check_destination, claim_folder, warn

_SCALARS = (str, int, float, bool, type(None))
SWEEP_KEYS = ("description", "base", "set", "grid", "zip")
MARKER = "sweep.yaml"  # marks an output folder as a sweep's
POINT_FORMAT = "sweep-point/1"  # the "tlm" field of a point's results.json
FIRST_COLUMNS = ("point", "hash", "status", "error")


# ---------------------------------------------------------------- the sweep file


@dataclass(frozen=True)
class Point:
    """One point: its factor values and its resolved config."""

    index: int
    factors: dict[str, Any]  # dotted key -> value
    config: dict  # to_dict of the resolved RunConfig (its sections shared with other points: read, never written)
    hash: str  # 16 hex digits of sha256 over ``config``, its input files and tlm's code (config_hash)
    functional: str = ""  # the functional key of its frame: points of one key share one render


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

    @property
    def factors(self) -> list[str]:
        return [*self.grid, *self.zip]

    def inert_factors(self) -> list[str]:
        """A warning line per factor that changes nothing in any point
        (:func:`tlm.render.planner.inert_settings`: ``estimate.k`` swept under the m-voxel
        filter, ``photons.count`` in mode rcast): its points would be the same run."""
        lines = []
        for factor in self.factors:
            whys = {i.get(factor) for i in self.inert}
            if self.inert and None not in whys:
                lines.append(f"{self.path}: the factor {factor} changes nothing in any point: "
                             f"{'; '.join(sorted(whys))}")
        return lines

    def identity(self) -> str:
        """16 hex digits naming the sweep's points (their hashes, in order): two sweeps of one
        identity may run into one folder at once, two of others may not (storage.sharing)."""
        return hashlib.sha256("\n".join(p.hash for p in self.points).encode()).hexdigest()[:16]

    def to_dict(self) -> dict:
        return {
            "tlm": "sweep/1", "sweep": str(self.path), "description": self.description,
            "base_file": self.base_file, "base": self.base, "set": self.set, "grid": self.grid, "zip": self.zip,
            "points": [{"point": p.index, "hash": p.hash, "factors": p.factors} for p in self.points],
        }

    def marker(self) -> str:
        """``sweep.yaml``'s text: ``yaml.safe_dump(self.to_dict(), sort_keys=False)``.

        Where every factor value is a plain scalar (a string, number, bool or null: no YAML
        anchors between points), the points' lines are put together from each factor
        value's line and each hash, as that dump writes them, without a dump per point."""
        head = self.to_dict()
        del head["points"]
        lines = {}  # (key, value's id) -> its lines in a point's factors (the values live as long as the points)
        resolver = yaml.resolver.Resolver()  # (a hash that reads as a number is quoted, as the dump quotes it)
        str_tag = "tag:yaml.org,2002:str"
        out = [yaml.safe_dump(head, sort_keys=False), "points:\n"]
        for p in self.points:
            shown = p.hash if resolver.resolve(yaml.ScalarNode, p.hash, (True, False)) == str_tag else f"'{p.hash}'"
            out.append(f"- point: {p.index}\n  hash: {shown}\n  factors:\n")
            for k, v in p.factors.items():
                line = lines.get((k, id(v)))
                if line is None:
                    if type(v) not in _SCALARS:  # (a list or a mapping: the dump's own, anchors and all)
                        return yaml.safe_dump(self.to_dict(), sort_keys=False)
                    text = yaml.safe_dump([{"factors": {k: v}}], sort_keys=False)
                    line = lines[k, id(v)] = text[text.index("\n") + 1:]
                out.append(line)
        return "".join(out)


def config_hash(resolved: dict, inputs: dict[str, str] | None = None) -> str:
    """The point's key: sha256 of the resolved config's canonical JSON, of the fingerprints
    of its input files and of tlm's code, 16 hex digits.

    ``inputs`` (:func:`point_inputs`) holds the content of what the config names by path
    only: the scene and its meshes (through the functional key) and the programs table.
    The files and the code are part of the key so that a rerun after a change to either
    computes its points again instead of reusing results of other inputs or other code.
    """
    # render.threads changes the speed alone (bit-identical results): a point keeps its key
    render = {k: v for k, v in resolved.get("render", {}).items() if k != "threads"}
    body = {"config": {**resolved, "render": render} if "render" in resolved else resolved, "code": code_fingerprint()}
    if inputs is not None:
        body["inputs"] = inputs
    blob = json.dumps(body, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def point_inputs(cfg, folder: Path, source: str, seen: dict | None = None, work: Any = None) -> dict[str, str]:
    """Fingerprints of the files ``cfg`` names: its frame's functional key (the scene's
    content) and the sha256 of the programs table's bytes.

    Loads the scene and the programs table (an InputError names ``source``). ``seen``
    keeps what was loaded, for the next point: points of one sweep share most of them.
    ``work``: what names the config's frame in ``seen``, where the caller has it (any value
    that the resolved config less ``arch`` decides, and that decides it); by default that
    config's JSON.
    """
    from tlm.arch.costs import DEFAULT_PATH
    from tlm.experiments.run import programs_for

    seen = {} if seen is None else seen
    table = cfg.arch.programs
    if ("programs", table) not in seen:
        try:
            programs_for(cfg, folder)
        except InputError as e:  # the table's own message, and which point names it
            raise InputError(str(e), source=source) from None
        path = DEFAULT_PATH if table is None else folder / table  # an absolute table stays itself
        seen["programs", table] = hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]
    if work is None:
        work = json.dumps({k: v for k, v in to_dict(cfg).items() if k != "arch"}, sort_keys=True)
    if ("functional", work) not in seen:
        seen["functional", work] = render_key(cfg, folder, source)
    return {"functional": seen["functional", work], "programs": seen["programs", table]}


def _assign(raw: dict, key: str, value: Any) -> dict:
    """A copy of ``raw`` with the dotted ``key`` set to ``value`` (sections created as needed)."""
    out = dict(raw)
    node = out
    parts = key.split(".")
    for p in parts[:-1]:
        child = node.get(p)
        node[p] = child = dict(child) if isinstance(child, dict) else {}
        node = child
    node[parts[-1]] = value
    return out


def _dotted_keys(section: Any, name: str, src: str, lists: bool) -> dict[str, Any]:
    if section is None:
        return {}
    if not isinstance(section, dict):
        raise InputError(f"must be a mapping of dotted keys, got {section!r}", source=src, key=name)
    for k, v in section.items():
        if not isinstance(k, str) or not k or any(not p for p in k.split(".")):
            raise InputError(f"{k!r} is not a dotted config key", source=src, key=name)
        if lists:
            if not isinstance(v, list):
                raise InputError(f"{v!r} is not a list of values", source=src, key=f"{name}.{k}")
            if not v:
                raise InputError("has no values", source=src, key=f"{name}.{k}")
    return dict(section)


def expand(grid: dict[str, list], zipped: dict[str, list]) -> list[dict[str, Any]]:
    """product(grid) x zip, as {dotted key: value}; the grid's first key varies slowest, zip fastest."""
    columns = list(zip(*zipped.values())) if zipped else [()]
    return [{**dict(zip(grid, combo)), **dict(zip(zipped, col))}
            for combo in itertools.product(*grid.values()) for col in columns]


def _expand_both(grid: dict[str, list], zipped: dict[str, list]) -> tuple[list[dict[str, Any]], list[tuple]]:
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


@dataclass(frozen=True)
class _Field:
    """One top-level field of a point's resolved config (a section, ``scene``, ``mode``, ...)."""

    name: str
    value: Any  # as RunConfig holds it
    resolved: Any  # as to_dict gives it (shared by the points of this value: read, never written)
    full: str  # its canonical JSON (sorted keys, no spaces)
    keyed: str  # '"name":' and its JSON in the point's key (config_hash: render.threads left out)


def _field(name: str, value: Any) -> _Field:
    resolved = to_dict(value)
    full = json.dumps(resolved, sort_keys=True, separators=(",", ":"))
    keyed = full
    if name == "render":
        keyed = json.dumps({k: v for k, v in resolved.items() if k != "threads"}, sort_keys=True,
                           separators=(",", ":"))
    return _Field(name, value, resolved, full, f"{json.dumps(name)}:{keyed}")


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

    def __init__(self, fixed: dict, keys: list[str], values: list[list]):
        self.fixed, self.keys, self.values = fixed, keys, values
        names = [f.name for f in dataclasses.fields(RunConfig)]
        owner = [k.split(".")[0] for k in keys]
        # a key that is no field: every point fails the check (of its first key, point 0 first)
        self.sound = all(o in names for o in owner)
        under = {name: [i for i, o in enumerate(owner) if o == name] for name in names}
        # the fields the factors leave as the base has them; the others' slots (RunConfig's order)
        self.template: dict[str, _Field | None] = {
            name: None if under[name] else _field(name, self._value(name, [])) for name in names}
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
                return _field(name, self._value(name, at, index))
            changes = {}
            for i in at:
                value = self._leaf(i, index[i])
                if value is _REFUSED:
                    return None
                changes[self.keys[i].split(".")[1]] = value
            return _field(name, with_leaves(name, self.base[name], changes))
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
        return {name: _field(name, getattr(cfg, name)) for name in self.template}


_REFUSED = object()


def load_sweep(path: Path) -> Sweep:
    """Read and check a sweep file and every point's config, and load the scenes and programs
    tables the points name (their content is part of the points' keys); InputError names the
    file and key."""
    path = Path(path)
    src = str(path)
    raw = read_yaml(path)
    if not isinstance(raw, dict):
        raise InputError(f"must be a mapping with {', '.join(SWEEP_KEYS)}", source=src)
    for key in raw:
        if key not in SWEEP_KEYS:
            raise InputError(f"unknown key (expected {', '.join(SWEEP_KEYS)})", source=src, key=str(key))
    description = raw.get("description")
    if description is not None and not isinstance(description, str):
        raise InputError(f"{description!r} is not a string", source=src, key="description")
    folder = path.resolve().parent
    base, base_file, base_src = raw.get("base"), None, src
    if isinstance(base, str):
        file = folder / base
        if not file.is_file():
            raise InputError(f"{base!r}: file not found (relative to the sweep file)", source=src, key="base")
        base_file, base_src, folder = base, str(file), file.resolve().parent
        base = read_yaml(file)
    if base is None:
        base = {}
    if not isinstance(base, dict):
        raise InputError("must be a run config mapping or the path of a run config file", source=src, key="base")
    config_from_dict(base, base_src)  # the base alone, so its errors name its own file

    settings = _dotted_keys(raw.get("set"), "set", src, lists=False)
    grid = _dotted_keys(raw.get("grid"), "grid", src, lists=True)
    zipped = _dotted_keys(raw.get("zip"), "zip", src, lists=True)
    if not grid and not zipped:
        raise InputError("needs at least one factor under 'grid' or 'zip'", source=src)
    lengths = {k: len(v) for k, v in zipped.items()}
    if len(set(lengths.values())) > 1:
        raise InputError(f"lists of unequal length ({', '.join(f'{k}: {n}' for k, n in lengths.items())})",
                         source=src, key="zip")
    seen: dict[str, str] = {}
    for name, section in (("set", settings), ("grid", grid), ("zip", zipped)):
        for k in section:
            for other, where in seen.items():
                if k == other or k.startswith(other + ".") or other.startswith(k + "."):
                    raise InputError(f"overlaps {where}.{other}", source=src, key=f"{name}.{k}")
            seen[k] = name

    fixed = dict(base)
    for k, v in settings.items():
        fixed = _assign(fixed, k, v)
    config_from_dict(fixed, f"{src} (base with set)")
    factors_list, indices = _expand_both(grid, zipped)
    checked = _Checked(fixed, [*grid, *zipped], [*grid.values(), *zipped.values()])
    rows = []
    for i, (factors, index) in enumerate(zip(factors_list, indices)):
        fields = checked.point(index)
        if fields is None:  # a value the checks refuse: the point's own check says which, as ever
            point = fixed
            for k, v in factors.items():
                point = _assign(point, k, v)
            shown = ", ".join(f"{k}={v!r}" for k, v in factors.items())
            fields = checked.of(config_from_dict(point, f"{src} (point {i}: {shown})"))
        rows.append((i, factors, fields))
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
    points, seen, known = [], {}, {}
    head = '{"code":' + json.dumps(code_fingerprint()) + ',"config":{'
    order = sorted(checked.template)  # (the key's JSON sorts its keys)
    # the config less arch, as the JSON of its fields: those the factors leave, then the others
    same = tuple(f.full for name, f in checked.template.items() if f is not None and name != "arch")
    other = [name for name, f in checked.template.items() if f is None and name != "arch"]
    for i, factors, fields in rows:
        work = (same, *[fields[name].full for name in other])
        key = (fields["arch"].value.programs, work)  # what point_inputs reads
        if key not in known:
            inputs = point_inputs(_config(fields), folder, f"{src} (point {i})", seen, work)
            known[key] = inputs, json.dumps(inputs, sort_keys=True, separators=(",", ":"))
        inputs, shown = known[key]
        # config_hash(resolved, inputs), its JSON put together from the fields' own
        blob = f'{head}{",".join([fields[name].keyed for name in order])}}},"inputs":{shown}}}'
        points.append(Point(i, factors, {name: f.resolved for name, f in fields.items()},
                            hashlib.sha256(blob.encode()).hexdigest()[:16], inputs["functional"]))
    _one_run_one_row(points, src)
    return Sweep(path, description, base, base_file, settings, grid, zipped, folder, points, inert)


def _one_run_one_row(points: list[Point], src: str) -> None:
    """An InputError when points of other factor values are one run (one key): only
    ``render.threads`` is left out of the key (it changes the speed alone, bit for bit the
    same results), so a sweep over it would run its first value and label the others' rows
    with values never run."""
    first: dict[str, Point] = {}
    for p in points:
        other = first.setdefault(p.hash, p)
        if other is not p and other.factors != p.factors:
            differ = [k for k in p.factors if p.factors[k] != other.factors.get(k)]
            raise InputError(f"points {other.index} and {p.index} differ only in {', '.join(differ)} "
                             f"(render.threads changes no result, only the host's speed), so they would be one run "
                             "with two labels: give render.threads under set:, and time thread counts with "
                             "benchmarks/bench_threads.py", source=src, key=", ".join(differ))


# ---------------------------------------------------------------- one point (runs in a worker)


@dataclass(frozen=True)
class Task:
    """What a worker needs to run one point (plain data: it travels to other processes)."""

    hash: str
    config: dict
    factors: dict[str, Any]
    folder: str  # where relative paths start
    source: str  # the sweep file, for messages
    out: str  # the point's folder
    provenance: dict  # versions and git revision of the submitting host
    threads: int | None = None  # render.threads where the config leaves it null (the worker's
    # share of the CPUs: speed only, so config.resolved.yaml keeps the config as written)


def run_point(task: Task) -> dict:
    """Render (or load) the point's functional result, simulate it, write its folder.

    Returns ``{"status": "ok", "results": ...}``, or ``{"status": "failed", "error":
    ...}`` after writing ``error.json``: an exception never leaves the worker.
    """
    from tlm.arch.model import simulate  # the timing layer is imported where it runs
    from tlm.experiments.run import programs_for, stream_warnings, timing_dict
    from tlm.render.planner import inert_changes

    stage = "functional"
    t0 = time.perf_counter()
    try:
        threads = task.threads if task.threads is not None else dask_worker_threads()
        cfg = config_from_dict(_with_threads(task.config, threads), task.source)
        folder = Path(task.folder)
        got = cached_render(cfg, folder, task.source)
        t1 = time.perf_counter()
        stage = "simulate"
        programs = programs_for(cfg, folder)
        timing = simulate(got.functional, programs, cfg.arch)
        t2 = time.perf_counter()
        stage = "write"
        summary = got.summary
        with atomic_folder(Path(task.out), "results.json") as tmp:
            (tmp / "config.resolved.yaml").write_text(yaml.safe_dump(task.config, sort_keys=False))
            if timing.trace is not None:
                timing.trace.write(tmp / "trace.json", cfg.arch.clock_hz)
            results = {
                "tlm": POINT_FORMAT, "hash": task.hash, "sweep": task.source, "factors": task.factors,
                "seed": cfg.seed, "mode": cfg.mode,
                **{k: summary.get(k) for k in SUMMARY_KEYS},
                # the render's warnings, and this point's own (what it sets and never reads; its stream)
                "warnings": [*(summary.get("warnings") or []), *inert_changes(cfg), *stream_warnings(timing, cfg)],
                "cycles": timing.cycles, "fps": timing.fps,
                "timing": timing_dict(timing, cfg.arch, programs),
                "functional": {"key": got.key, "cached": got.cached, "render_host_seconds": summary["host_seconds"]},
                "host_seconds": {"functional": round(t1 - t0, 6), "simulate": round(t2 - t1, 6)},
                **task.provenance,
            }
            (tmp / "results.json").write_text(json.dumps(results, indent=2) + "\n")
        return {"status": "ok", "results": results}
    except Exception as e:
        if (stop := interrupted_by(e)) is not None:  # Ctrl-C wrapped by a kernel: the sweep stops
            raise stop from e
        error = _error_record(e, stage, traceback.format_exc())
        write_error(task, error)
        return {"status": "failed", "error": error}


def _error_record(e: BaseException, stage: str, tb: str) -> dict:
    return {"type": type(e).__name__, "message": str(e), "stage": stage, "traceback": tb}


def write_error(task: Task, error: dict) -> None:
    """The failed point's folder: ``error.json`` (exception, message, traceback) and its config."""
    with atomic_folder(Path(task.out), "error.json") as tmp:
        (tmp / "config.resolved.yaml").write_text(yaml.safe_dump(task.config, sort_keys=False))
        body = {"hash": task.hash, "factors": task.factors, **error}
        (tmp / "error.json").write_text(json.dumps(body, indent=2) + "\n")


# ---------------------------------------------------------------- rows


def point_row(point: Point, record: dict) -> dict:
    """One tidy flat row: the point, its factors, cycles, fps, utilization, error, host seconds."""
    row: dict[str, Any] = {"point": point.index, "hash": point.hash, "status": record["status"], "error": None}
    row.update(point.factors)
    row["scene"] = point.config["scene"]
    row["mode"] = point.config["mode"]
    if record["status"] != "ok":
        err = record["error"]
        row["error"] = f"{err['type']}: {err['message']}".replace("\n", " ")
        return row
    res = record["results"]
    row.update({f"cycles.{k}": v for k, v in res["cycles"].items()})
    row["fps"] = res["fps"]
    row["simpy_events"] = res["timing"]["simpy_events"]
    # whether cycles.throughput is a steady-state TThru (false: a stream too short for one)
    row["throughput_steady"] = res["timing"].get("throughput_estimate", {}).get("steady")
    row.update(utilization(res["timing"]["units"]))
    err = res.get("error") or {}
    if err.get("available"):
        row["error.rel_mse"] = err.get("rel_mse")
        row["error.rmse"] = err.get("rmse")
    row["functional_cached"] = res["functional"]["cached"]
    row["seconds.functional"] = res["host_seconds"]["functional"]
    row["seconds.simulate"] = res["host_seconds"]["simulate"]
    return row


def utilization(units: dict) -> dict[str, float]:
    """busy / stall / idle fractions of elapsed per PM kind, averaged over the pipelines.

    PMs are the units named ``pipe<p>.<pm>``; memory modules and the crossbar are not PMs.
    """
    kinds: dict[str, list[dict]] = {}
    for scope, b in units.items():
        m = re.fullmatch(r"pipe\d+\.(\w+)", scope)
        if m:
            kinds.setdefault(m[1], []).append(b)
    out = {}
    for what, key in (("busy", "busy"), ("stall", "stalled"), ("idle", "idle")):
        for kind, bs in kinds.items():
            out[f"{what}.{kind}"] = round(sum(b[key] / b["elapsed"] if b["elapsed"] else 0.0 for b in bs)
                                          / len(bs), 6)
    return out


def write_rows(out: Path, rows: list[dict]) -> None:
    """``sweep.jsonl`` and ``sweep.csv``: the rows sorted by point, the union of their columns."""
    storage.write_rows(out, "sweep", sorted(rows, key=lambda r: r["point"]), FIRST_COLUMNS)


# ---------------------------------------------------------------- the sweep


@dataclass
class Outcome:
    """What a sweep did: the rows of its points and the counts of the summary line."""

    rows: list[dict]
    ok: int
    failed: int
    skipped: int
    renders: int  # points whose functional result was rendered, not read from the cache
    seconds: float
    out: Path

    @property
    def table(self):
        """The rows as a pandas DataFrame, one row per point in point order, the columns as in
        ``sweep.csv`` (:data:`FIRST_COLUMNS`, then every other field as it first appears:
        the factors, ``scene``, ``mode``, ``cycles.*``, ``fps``, utilization, host seconds)."""
        import pandas as pd

        rows = sorted(self.rows, key=lambda r: r["point"])
        cols = list(FIRST_COLUMNS)
        for r in rows:
            cols.extend(k for k in r if k not in cols)
        return pd.DataFrame(rows, columns=cols)


def _clean_stale(points_dir: Path) -> None:
    """Remove temporary point folders of sweeps that were killed (their process is gone)."""
    storage.clean_stale(points_dir)


def _done(folder: Path) -> dict | None:
    """A finished point's record from its folder, or None (not run, failed, unreadable, or
    a ``results.json`` that is not this point's: another run written there, an edited file)."""
    try:
        results = json.loads((folder / "results.json").read_text())
    except (OSError, ValueError):
        return None
    if not (isinstance(results, dict) and results.get("tlm") == POINT_FORMAT and results.get("hash") == folder.name
            and all(isinstance(results.get(k), dict) for k in ("cycles", "timing", "functional", "host_seconds"))):
        return None
    return {"status": "ok", "results": results}


def _listed(folder: Path) -> set[str]:
    """The names in ``folder`` (none where it is missing or unreadable)."""
    try:
        return set(os.listdir(folder))
    except OSError:
        return set()


def _with_threads(config: dict, threads: int | None) -> dict:
    """``config`` with ``render.threads`` set to ``threads`` where the config leaves it null."""
    render = config.get("render", {})
    if threads is None or render.get("threads") is not None:
        return config
    return {**config, "render": {**render, "threads": threads}}


def run_sweep(path: Path, out: Path, jobs: int | None = None, dask: str | None = None,
              progress: bool = False) -> Outcome:
    """Run every point of the sweep file ``path`` not already done in ``out``."""
    t_start = time.perf_counter()
    if jobs is None:
        from tlm.kernels.threads import available

        jobs = available()  # (the affinity mask and a container's CPU quota, as render.threads)
    if jobs < 1:
        raise InputError(f"{jobs} must be >= 1", key="--jobs")
    sweep = load_sweep(Path(path))  # loads every distinct programs table and scene
    for line in sweep.inert_factors():
        warn(line)
    fkeys = {p.hash: p.functional for p in sweep.points}
    out = Path(out)
    check_destination(out, MARKER)  # before anything is written: a bad --out fails at once
    points_dir = out / "points"

    by_hash: dict[str, list[Point]] = {}
    for p in sweep.points:
        by_hash.setdefault(p.hash, []).append(p)
    records: dict[str, dict] = {}
    todo: list[str] = []
    present = _listed(points_dir)  # (a point with no folder is not done: no read of it)
    for h in by_hash:
        rec = _done(points_dir / h) if h in present else None
        if rec is not None:
            records[h] = rec
        else:
            todo.append(h)
    skipped = sum(len(by_hash[h]) for h in records)

    provenance = {"versions": versions(), **code_state()}
    # --jobs x render.threads <= the CPUs: a point that leaves render.threads null gets its
    # worker's share of them (its key does not depend on it: config_hash)
    share = kernel_threads(jobs, dask, len(todo))
    tasks = {h: Task(h, by_hash[h][0].config, by_hash[h][0].factors, str(sweep.folder), str(sweep.path),
                     os.path.join(points_dir, h), provenance, threads=share) for h in todo}

    with ExitStack() as held:  # (the folder, held until the last row is written)
        with ExitStack() as stack:
            pool = open_executor(stack, jobs, dask, len(todo)) if todo else None
            # the folder and its marker appear together, before anything else is written in it
            # (and only once the executor opened: a bad --dask leaves nothing): a second sweep
            # into it, started this instant, finds a tlm output, never a half-made folder. A
            # sweep of other points running into it refuses this one (storage.sharing); one of
            # the same points shares it
            marker = sweep.marker()
            made = claim_folder(out, MARKER, marker, existing=False)
            held.enter_context(storage.sharing(out, sweep.identity(), "sweep"))
            if not made:
                storage.write_file(out / MARKER, marker)
            points_dir.mkdir(parents=True, exist_ok=True)
            _clean_stale(points_dir)
            present = _listed(points_dir)
            for h in todo:  # a failed point's folder (or an unreadable one) is run again
                if h in present:  # (another sweep into this folder may be replacing it)
                    shutil.rmtree(points_dir / h, ignore_errors=True)
            if pool is not None:
                # the rows of this sweep's points done already, in place of an earlier sweep's: while
                # it runs (and when it is cut short) the folder's rows are this sweep's only
                write_rows(out, [point_row(p, records[p.hash]) for p in sweep.points if p.hash in records])
                _dispatch(pool, tasks, fkeys, by_hash, records, out, progress, len(sweep.points), skipped)
        if todo:
            _clean_stale(points_dir)  # what workers that died (or were ended) left half written

        rows = [point_row(p, records[p.hash]) for p in sweep.points]
        write_rows(out, rows)
    computed = [r for r in rows if r["hash"] in tasks]
    failed = sum(r["status"] != "ok" for r in computed)
    renders = len({r["hash"] for r in computed if r.get("functional_cached") is False})
    return Outcome(rows, len(computed) - failed, failed, skipped, renders, time.perf_counter() - t_start, out)


def _dispatch(pool: cf.Executor, tasks: dict[str, Task], fkeys: dict[str, str], by_hash: dict[str, list[Point]],
              records: dict[str, dict], out: Path, progress: bool, total: int, skipped: int) -> None:
    """Run the tasks: one per functional key first, the rest of its group once it is cached."""
    from tqdm import tqdm

    groups: dict[str, deque[str]] = {}
    for h in tasks:
        groups.setdefault(fkeys[h], deque()).append(h)
    futures: dict[cf.Future, str] = {}

    def submit(h: str) -> None:
        futures[pool.submit(run_point, tasks[h])] = h

    def release(key: str, everything: bool) -> None:
        queue = groups[key]
        while queue:
            submit(queue.popleft())
            if not everything:
                break

    bar = None
    try:
        for key in groups:
            release(key, everything=is_cached(key))
        bar = tqdm(total=total, initial=skipped, disable=None if progress else True, file=sys.stderr,
                   unit="point", desc="sweep", dynamic_ncols=True)
        failed = 0
        _trim_torn(out / "sweep.jsonl")
        with open(out / "sweep.jsonl", "a") as jsonl:
            while futures:
                if isinstance(pool, (InProcess, LocalPool)):
                    pool.run_next()
                done, _ = cf.wait(list(futures), return_when=cf.FIRST_COMPLETED)
                for f in done:
                    h = futures.pop(f)
                    record = _record(f, tasks[h])
                    records[h] = record
                    for p in by_hash[h]:
                        jsonl.write(json.dumps(point_row(p, record)) + "\n")
                    jsonl.flush()
                    failed += record["status"] != "ok"
                    # the frame is cached unless the point failed while rendering it (or its
                    # worker died): then the next point of the group renders, one at a time
                    rendered = record["status"] == "ok" or record["error"]["stage"] in ("simulate", "write")
                    release(fkeys[h], everything=rendered)
                    bar.update(len(by_hash[h]))
                    if failed:
                        bar.set_postfix(failed=failed)
    except BaseException:
        for f in futures:
            f.cancel()
        if isinstance(pool, LocalPool):  # the workers are killed, not waited for
            _wait_gone(pool.stop())
            _clean_stale(out / "points")
        elif isinstance(pool, InProcess):
            pool.shutdown(wait=False, cancel_futures=True)
        else:
            pool.shutdown(wait=False)
        raise
    finally:
        if bar is not None:
            bar.close()
    pool.shutdown(wait=True)


def _wait_gone(pids: list[int], timeout: float = 2.0) -> None:
    """Wait (a little) until the killed workers ``pids`` are gone, so that their temporary
    folders can be told from a live process's."""
    deadline = time.monotonic() + timeout
    while pids and time.monotonic() < deadline:
        pids = [pid for pid in pids if storage.pid_alive(pid)]
        if pids:
            time.sleep(0.02)


def _trim_torn(path: Path) -> None:
    """Cut off a last row left half written (a sweep killed while writing it), so that the
    rows appended next start on a line of their own."""
    with suppress(FileNotFoundError), open(path, "rb+") as f:
        data = f.read()
        if data and not data.endswith(b"\n"):
            f.truncate(data.rfind(b"\n") + 1)


def _record(f: cf.Future, task: Task) -> dict:
    """The worker's record, or a failed one when the worker itself died or could not be reached."""
    try:
        return f.result()
    except Exception as e:  # a worker process that died, a Dask KilledWorker, an unpicklable result
        if (stop := interrupted_by(e)) is not None:
            raise stop from e
        error = _error_record(e, "worker", "".join(traceback.format_exception(e)))
        with suppress(OSError, InputError):  # the row still says what happened
            write_error(task, error)
        return {"status": "failed", "error": error}
