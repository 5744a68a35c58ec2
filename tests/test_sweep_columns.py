"""sweep.csv has an ok point's result columns (``fps``, ``cycles.*``, ...) whatever the points'
outcome: a sweep whose every point failed has them too, its cells empty."""

from __future__ import annotations

import json

import pandas as pd
import pytest
import yaml

from tlm.experiments.sweep import run_sweep

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 32}}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def sweep(tmp_path, name: str, max_events: list[int]):
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.max_events": max_events}}))
    return run_sweep(path, tmp_path / name, jobs=1)


def header(path) -> list[str]:
    return path.read_text().splitlines()[0].split(",")


def test_an_all_failed_sweep_has_the_result_columns(tmp_path):
    # 50 or 60 SimPy events cannot finish a frame: every point fails with MaxEventsReached at simulate time
    failed = sweep(tmp_path, "failed", [50, 60])
    assert (failed.ok, failed.failed) == (0, 2)
    rows = pd.read_csv(tmp_path / "failed" / "sweep.csv", dtype={"hash": str})
    assert {"fps", "cycles.throughput", "cycles.vertex", "busy.fragment", "seconds.simulate"} <= set(rows.columns)
    assert rows["fps"].isna().all() and rows["cycles.throughput"].isna().all()
    assert list(failed.table.columns) == list(rows.columns)
    # the JSONL stays as it was: a failed point's object holds its own fields only
    assert all("fps" not in json.loads(line) for line in (tmp_path / "failed" / "sweep.jsonl").read_text().splitlines())
    # the same columns, in the same order, as a sweep of the same factor whose points ran
    ok = sweep(tmp_path, "ok", [10**8])
    assert ok.ok == 1
    assert header(tmp_path / "failed" / "sweep.csv") == header(tmp_path / "ok" / "sweep.csv")
    from tlm.experiments.sweep_rows import result_columns

    assert set(result_columns()) <= set(ok.rows[0])
