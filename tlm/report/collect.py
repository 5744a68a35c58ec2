"""The report's inputs: every tlm output folder it is given, read once.

``tlm report`` accepts any folder a tlm command writes, and a folder of such folders
(one level down, e.g. ``runs/``):

=================  ==========================================  ================================
kind               written by                                  recognised by
=================  ==========================================  ================================
run                ``tlm run``                                 ``results.json`` (results/1)
sweep              ``tlm sweep``                               ``sweep.yaml`` and ``points/``
thesis             ``tlm thesis``                              ``thesis_comparison.csv``
error-vs-cost      ``tlm error-vs-cost``                       ``rows.jsonl`` + ``reference.json``
granularity        ``tlm granularity``                         ``granularity.jsonl``
scaling            ``tlm scaling``                             ``eq52.json``
extreme            ``tlm extreme``                             ``extreme.jsonl``
=================  ==========================================  ================================

Every run folder found (a run, a thesis cell ``<scene>/<mode>``, a sweep point) becomes
a :class:`Run`; the study tables are kept as rows.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from tlm.errors import InputError
from tlm.storage import read_jsonl


@dataclass
class Run:
    """One simulated frame stream: a run folder, a thesis cell or a sweep point."""

    path: Path
    label: str  # short and unique in the report, e.g. "cornell/pmap" or "scaling_ring #3"
    kind: str  # "run", "thesis" or "sweep-point"
    results: dict  # results.json
    config: dict  # config.resolved.yaml
    factors: dict[str, Any] = field(default_factory=dict)  # a sweep point's factor values

    @property
    def scene(self) -> str:
        return str(self.results["scene"]["name"])

    @property
    def mode(self) -> str:
        return str(self.results.get("mode") or self.config.get("mode"))

    @property
    def trace(self) -> Path | None:
        p = self.path / "trace.json"
        return p if p.is_file() else None

    @property
    def images(self) -> Path | None:
        p = self.path / "images"
        return p if p.is_dir() else None

    @property
    def radiance(self) -> Path | None:
        p = self.path / "radiance"
        return p if p.is_dir() else None


@dataclass
class Sweep:
    path: Path
    spec: dict  # sweep.yaml
    rows: list[dict]  # sweep.jsonl: the rows of the points sweep.yaml lists
    runs: list[Run]  # its finished points, in point order

    @property
    def planned(self) -> int:
        """The points sweep.yaml lists (the rows, for a sweep.yaml that lists none)."""
        return len(self.spec.get("points") or []) or len(self.rows)

    @property
    def unfinished(self) -> str:
        """"" for a sweep with a row for every point; else what the report says of the
        points without one (an interrupted sweep, or one still running)."""
        missing = self.planned - len(self.rows)
        return (f"; {missing} of its {self.planned} points not run yet (the sweep was interrupted or is still "
                f"running: the same 'tlm sweep' command finishes it)") if missing > 0 else ""


@dataclass
class Study:
    """A study's result table: ``kind`` is thesis, error-vs-cost, granularity or scaling."""

    kind: str
    path: Path
    rows: list[dict]
    meta: dict = field(default_factory=dict)  # summary / reference / fits


@dataclass
class Inputs:
    dirs: list[Path]
    runs: list[Run] = field(default_factory=list)  # every run, sweep points included
    sweeps: list[Sweep] = field(default_factory=list)
    studies: list[Study] = field(default_factory=list)
    # sweeps read for the scaling section only: the ones a scaling study among the inputs
    # fitted (its idle fractions per PM are drawn; not fitted again, not shown as sweeps)
    scaling_sweeps: list[Sweep] = field(default_factory=list)
    scaling_missing: list[str] = field(default_factory=list)  # sweeps a scaling study recorded, now gone

    def of_kind(self, kind: str) -> list[Study]:
        return [s for s in self.studies if s.kind == kind]


def _json(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise InputError(f"cannot read: {e}", source=str(path)) from None


def _jsonl(path: Path) -> list[dict]:
    """The rows (a last row cut off by a killed process left out; any other bad row refused)."""
    return [row for _, row in read_jsonl(path)]


def _yaml(path: Path) -> Any:
    try:
        return yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise InputError(f"cannot read: {str(e).splitlines()[0]}", source=str(path)) from None


def _run(folder: Path, label: str, kind: str) -> Run:
    results = _json(folder / "results.json")
    if not isinstance(results, dict) or "timing" not in results or "scene" not in results:
        raise InputError("is not a tlm results file (no 'timing' or 'scene')", source=str(folder / "results.json"))
    cfg_path = folder / "config.resolved.yaml"
    config = _yaml(cfg_path) if cfg_path.is_file() else {}
    return Run(folder, label, kind, results, config or {})


def kind_of(folder: Path) -> str | None:
    """Which tlm command wrote ``folder`` (None: none of them)."""
    if (folder / "sweep.yaml").is_file() and ((folder / "points").is_dir() or (folder / "sweep.jsonl").is_file()):
        return "sweep"  # (a sweep *file* named sweep.yaml beside other things is not one)
    if (folder / "thesis_comparison.csv").is_file():
        return "thesis"
    if (folder / "eq52.json").is_file():
        return "scaling"
    if (folder / "extreme.jsonl").is_file():
        return "extreme"  # its cases/<name>/ run folders are not read as runs
    if (folder / "granularity.jsonl").is_file():
        return "granularity"
    if (folder / "rows.jsonl").is_file() and (folder / "reference.json").is_file():
        return "error-vs-cost"
    if (folder / "results.json").is_file():
        return "run"
    return None


def _csv_rows(path: Path) -> list[dict]:
    def value(v: str):
        if v == "":
            return None
        if v in ("True", "False"):
            return v == "True"
        try:
            return float(v)
        except ValueError:
            return v

    with open(path, newline="") as f:
        return [{k: value(v) for k, v in row.items()} for row in csv.DictReader(f)]


def read(dirs: list[Path]) -> Inputs:
    """Read every folder of ``dirs`` (or, for a folder of folders, each tlm folder in it)."""
    inputs = Inputs([Path(d) for d in dirs])
    folders: list[tuple[Path, str]] = []
    for d in inputs.dirs:
        if not d.is_dir():
            raise InputError("is not a folder", source=str(d))
        k = kind_of(d)
        if k is not None:
            folders.append((d, k))
            continue
        inner = [(c, kind_of(c)) for c in sorted(d.iterdir()) if c.is_dir() and not c.name.startswith(".")]
        inner = [(c, k) for c, k in inner if k is not None]
        if not inner:
            raise InputError("holds no tlm output (a run, sweep, thesis, error-vs-cost, granularity, "
                             "scaling or extreme folder)", source=str(d))
        folders.extend(inner)
    labels: set[str] = set()

    def unique(label: str) -> str:
        out, i = label, 2
        while out in labels:
            out, i = f"{label} ({i})", i + 1
        labels.add(out)
        return out

    for folder, kind in folders:
        if kind == "run":
            run = _run(folder, "", "run")
            run.label = unique(f"{folder.name}: {run.scene}/{run.mode}")
            inputs.runs.append(run)
        elif kind == "thesis":
            rows = _csv_rows(folder / "thesis_comparison.csv")
            summary_path = folder / "thesis_summary.json"
            summary = _json(summary_path) if summary_path.is_file() else {}
            inputs.studies.append(Study("thesis", folder, rows, summary))
            for cell in sorted(folder.glob("*/*/results.json")):
                run = _run(cell.parent, "", "thesis")
                run.label = unique(f"{run.scene}/{run.mode}")
                inputs.runs.append(run)
        elif kind == "sweep":
            spec = _yaml(folder / "sweep.yaml") or {}
            rows = _jsonl(folder / "sweep.jsonl") if (folder / "sweep.jsonl").is_file() else []
            planned = {str(p.get("hash")) for p in spec.get("points") or [] if isinstance(p, dict)}
            if planned:  # (rows of an earlier sweep into the folder, left by a rerun cut short: not this one's)
                rows = [r for r in rows if str(r.get("hash")) in planned]
            runs = []
            for row in sorted(rows, key=lambda r: r.get("point", 0)):
                point = folder / "points" / str(row.get("hash"))
                if row.get("status") != "ok" or not (point / "results.json").is_file():
                    continue
                run = _run(point, "", "sweep-point")
                run.factors = dict(run.results.get("factors") or {})
                run.label = unique(f"{folder.name} #{row.get('point')}")
                runs.append(run)
            inputs.sweeps.append(Sweep(folder, spec, rows, runs))
            inputs.runs.extend(runs)
        else:
            _study(inputs, folder, kind)
    return inputs


def _study(inputs: Inputs, folder: Path, kind: str) -> None:
    if kind == "scaling":
        rows = _csv_rows(folder / "eq52.csv") if (folder / "eq52.csv").is_file() else []
        inputs.studies.append(Study("scaling", folder, rows, _json(folder / "eq52.json")))
    elif kind == "granularity":
        inputs.studies.append(Study("granularity", folder, _jsonl(folder / "granularity.jsonl")))
    elif kind == "extreme":
        inputs.studies.append(Study("extreme", folder, _jsonl(folder / "extreme.jsonl")))
    elif kind == "error-vs-cost":
        inputs.studies.append(Study("error-vs-cost", folder, _jsonl(folder / "rows.jsonl"),
                                    {"reference": _json(folder / "reference.json")}))
    study = inputs.studies[-1]
    for name, key, load in (("config.resolved.yaml", "config", _yaml), ("provenance.json", "provenance", _json)):
        if (folder / name).is_file():
            study.meta[key] = load(folder / name)
