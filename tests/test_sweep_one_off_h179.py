"""A sweep point's one-off host seconds (numba compiling or loading a kernel, first imports),
paid by whichever points a worker ran first: recorded apart (``seconds.one_off``, results.json
``host_seconds.one_off``) and left out of the report's "host s"."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
import yaml

import tlm.experiments.sweep_point as sweep_point
from tlm.experiments.sweep import run_sweep
from tlm.report.collect import read
from tlm.report.sweeps import table

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"light_samples": 1},
        "arch": {"frames": 1, "trace": False, "packet_size": 32}}
COMPILING = 0.05  # seconds the first point's stand-in "kernel" holds numba's compiler lock


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def test_the_first_point_pays_the_one_off_and_host_s_leaves_it_out(tmp_path, monkeypatch):
    from numba.core import event

    real = sweep_point.cached_render
    calls = []

    def compiling_first(*args, **kwargs):  # (the first point's render compiles a kernel, as numba does: its
        calls.append(1)  # global compiler lock's event around it)
        if len(calls) == 1:
            with event.trigger_event("numba:compiler_lock"):
                time.sleep(COMPILING)
        return real(*args, **kwargs)

    monkeypatch.setattr(sweep_point, "cached_render", compiling_first)
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.page_miss_cycles": [0, 12]}}, sort_keys=False))
    out = tmp_path / "o"
    done = run_sweep(path, out, jobs=1)  # (one process: the points one after another)
    rows = sorted((json.loads(line) for line in (out / "sweep.jsonl").read_text().splitlines()),
                  key=lambda r: r["point"])
    assert [r["status"] for r in rows] == ["ok", "ok"]
    assert "seconds.one_off" in list(done.table.columns)
    head = (out / "sweep.csv").read_text().splitlines()[0].split(",")
    assert head.index("seconds.one_off") == head.index("seconds.simulate") + 1
    first, second = rows
    assert first["seconds.one_off"] >= COMPILING  # (the span held the lock at least that long)
    assert first["seconds.one_off"] <= first["seconds.functional"] + first["seconds.simulate"]
    assert 0 <= second["seconds.one_off"] <= second["seconds.functional"] + second["seconds.simulate"]
    res = json.loads((out / "points" / first["hash"] / "results.json").read_text())
    assert res["host_seconds"]["one_off"] == first["seconds.one_off"]
    # the report's points table: host s is the point's seconds less its one-off part, a note says so
    html = table(read([out]).sweeps[0])
    cells = [row.split("</td><td>") for row in html.split("<tr>")[2:]]
    host = {int(c[0].removeprefix("<td>")): float(c[-1].split("</td>")[0]) for c in cells}
    want = round(first["seconds.functional"] + first["seconds.simulate"] + first["seconds.write"]
                 - first["seconds.one_off"], 3)
    assert abs(host[0] - want) <= 0.0011
    assert "less their one-off part, seconds.one_off" in html and "paid by point" in html


def test_a_row_of_an_older_results_json_has_no_one_off(tmp_path: Path):
    from tlm.experiments.sweep_rows import result_columns, result_fields

    res = {"cycles": {"vertex": 1}, "fps": 1.0, "timing": {"simpy_events": 1, "units": {}},
           "functional": {"cached": True}, "host_seconds": {"functional": 2.0, "simulate": 1.0}}
    assert result_fields(res)["seconds.one_off"] is None
    cols = result_columns()
    assert cols[-4:] == ["seconds.functional", "seconds.simulate", "seconds.one_off", "seconds.write"]


def test_the_provenance_host_seconds_do_not_add_the_one_off_part_twice():
    from tlm.report.provenance import _seconds

    # (one_off is a part of functional and simulate, not a stage beside them)
    assert _seconds({"functional": 1.0, "simulate": 0.5, "one_off": 0.4}) == 1.5
    assert _seconds({"functional": 1.0, "simulate": 0.5}) == 1.5
