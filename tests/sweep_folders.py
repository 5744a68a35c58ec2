"""Sweep folders made by hand for the report's tests: the files and keys the report reads.

A test module builds its own sweep (its grid, rows and results); these write the files every
such folder has, one way: ``sweep.yaml`` (:func:`start`), a point's folder
(:func:`write_point`), ``sweep.jsonl`` (:func:`write_rows`), and the per-PM timing units of
a point's results.json (:func:`busy_units`).
"""

from __future__ import annotations

import json
from pathlib import Path

import yaml

PMS = ("vertex", "traversal", "intersection", "fragment")
UNIT = {"T_norm": 1000, "T_ms": 0, "T_ps": 0, "idle": 0, "elapsed": 1000, "stall": {}, "fractions": {"busy": 1.0}}


def start(root: Path, marker: dict) -> Path:
    """The folder ``root`` (made, with its parents; not there before) and its ``sweep.yaml`` of ``marker``."""
    root.mkdir(parents=True)
    (root / "sweep.yaml").write_text(yaml.safe_dump(marker))
    return root


def busy_units(pipelines: int = 1) -> dict:
    """results.json ``timing.units`` of a point on ``pipelines`` pipelines: every PM of each
    (``pipe<p>.<pm>``) busy all its 1000 cycles."""
    return {f"pipe{p}.{pm}": dict(UNIT) for pm in PMS for p in range(pipelines)}


def write_point(root: Path, name: str, results: dict, config: dict | None = None) -> Path:
    """The point folder ``root/points/<name>``: its results.json and, given ``config``, its config.resolved.yaml."""
    point = root / "points" / name
    point.mkdir(parents=True)
    (point / "results.json").write_text(json.dumps(results))
    if config is not None:
        (point / "config.resolved.yaml").write_text(yaml.safe_dump(config))
    return point


def write_rows(root: Path, rows: list[dict]) -> Path:
    """``root/sweep.jsonl``: one JSON row a point, in order."""
    path = root / "sweep.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return path
