"""Every JSON file tlm writes is strict JSON: a number that is not finite (an fps of no cycles
to time is inf) is written as null, never as ``Infinity`` or ``NaN``, which JSON does not have."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

import tlm.arch.model as model
import tlm.experiments.run as run_mod
from tlm.config import config_from_dict
from tlm.experiments.sweep import run_sweep
from tlm.storage import write_rows

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 32}}


def _refuse(name: str):
    raise ValueError(f"not strict JSON: {name}")


def strict(text: str):
    """``text`` read as strict JSON: ``Infinity``, ``-Infinity`` and ``NaN`` are refused."""
    return json.loads(text, parse_constant=_refuse)


def strict_lines(path: Path) -> list[dict]:
    return [strict(line) for line in path.read_text().splitlines()]


@pytest.fixture
def endless_fps(monkeypatch):
    """The timing model with its fps made infinite (what it gives for a throughput of 0 cycles,
    a frame program with no work, which no rendered frame has: every frame copies its tree and
    vertices, a cycle at least)."""
    real = model.simulate

    def simulate(*args, **kw):
        return dataclasses.replace(real(*args, **kw), fps=math.inf)

    monkeypatch.setattr(model, "simulate", simulate)  # (a sweep point imports it where it runs)
    monkeypatch.setattr(run_mod, "simulate", simulate)


def test_json_text_writes_non_finite_numbers_as_null():
    from tlm.storage import json_text

    value = {"fps": math.inf, "rel_mse": math.nan, "deep": [(-math.inf, 1.5)], "np": np.float64("inf"), "n": 3}
    text = json_text(value, indent=2)
    assert strict(text) == {"fps": None, "rel_mse": None, "deep": [[None, 1.5]], "np": None, "n": 3}
    assert json_text({"x": object()}, default=lambda o: math.nan) == '{"x": null}'
    assert json_text({"a": [1, 2.5]}) == json.dumps({"a": [1, 2.5]})  # finite values: as json.dumps writes them


def test_result_rows_are_strict_json(tmp_path):
    write_rows(tmp_path, "rows", [{"a": math.inf, "b": [math.nan, 1]}, {"a": 2.0}])
    assert strict_lines(tmp_path / "rows.jsonl") == [{"a": None, "b": [None, 1]}, {"a": 2.0}]
    # the CSV says what the JSONL says: an empty cell for null, a list's cell as strict JSON text
    assert (tmp_path / "rows.csv").read_text().splitlines() == ["a,b", ',"[null, 1]"', "2.0,"]


def test_a_run_with_an_infinite_fps_writes_strict_results_json(tmp_path, cache, endless_fps):
    results = run_mod.run(config_from_dict(BASE), tmp_path / "run", outputs=())
    assert results["fps"] == math.inf  # (the returned dict keeps the model's value)
    text = (tmp_path / "run" / "results.json").read_text()
    written = strict(text)
    assert written["fps"] is None and written["cycles"] == results["cycles"]


def test_a_sweep_with_an_infinite_fps_writes_strict_json(tmp_path, cache, endless_fps):
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [16, 64]}}))
    out = tmp_path / "o"
    done = run_sweep(path, out, jobs=1)
    assert done.ok == 2
    rows = strict_lines(out / "sweep.jsonl")
    assert [r["fps"] for r in rows] == [None, None] and all(r["cycles.throughput"] > 0 for r in rows)
    assert pd.read_csv(out / "sweep.csv", dtype={"hash": str})["fps"].isna().all()  # (empty cells, as null)
    for r in rows:
        assert strict((out / "points" / r["hash"] / "results.json").read_text())["fps"] is None
    # a point folder written before (its fps as Infinity) is still read back: the rerun skips it
    # and rewrites the rows as strict JSON
    old = out / "points" / rows[0]["hash"] / "results.json"
    old.write_text(json.dumps({**json.loads(old.read_text()), "fps": math.inf}, indent=2) + "\n")
    assert "Infinity" in old.read_text()
    again = run_sweep(path, out, jobs=1)
    assert (again.ok, again.skipped) == (0, 2)
    assert [r["fps"] for r in strict_lines(out / "sweep.jsonl")] == [None, None]


def test_a_studys_json_files_are_strict_json(tmp_path):
    """A study's further files (a fit that did not converge: inf and nan) and its provenance."""
    from tlm.experiments.study import run_study

    out = tmp_path / "study"
    run_study("s.yaml", out, "rows", [1], lambda p, _: {"p": p},
              files=lambda rows: {"fits.json": {"slope": math.inf, "r2": math.nan, "points": len(rows)}})
    assert strict((out / "fits.json").read_text()) == {"slope": None, "r2": None, "points": 1}
    strict((out / "provenance.json").read_text())


def test_a_timing_trace_is_strict_json(tmp_path):
    """trace.json is read by trace viewers with JavaScript's JSON.parse: no Infinity or NaN."""
    from tlm.arch.units import Trace

    trace = Trace()
    trace.slice("pipe0.traversal", "work", 0, 2, ratio=math.inf, spread=math.nan)
    trace.write(tmp_path / "trace.json", 600e6)
    doc = strict((tmp_path / "trace.json").read_text())
    work = [e for e in doc["traceEvents"] if e["ph"] == "X"]
    assert work[0]["args"]["ratio"] is None and work[0]["args"]["spread"] is None
