"""A sweep's rows (:mod:`tlm.experiments.sweep_rows`), made from points and records without
running one: a failed point's row, the columns of ``sweep.csv`` and the files' order."""

from __future__ import annotations

import json

import pandas as pd

from tlm.experiments.sweep_file import Point
from tlm.experiments.sweep_rows import FIRST_COLUMNS, columns, point_row, result_columns, write_rows

CONFIG = {"scene": "cornell", "mode": "rcast"}


def _point(index: int, fifo: int) -> Point:
    return Point(index, {"arch.fifo_depth": fifo}, CONFIG, f"h{index}", "k")


def test_a_failed_points_row_has_its_error_on_one_line_and_the_columns_of_an_ok_one(tmp_path):
    failed = {"status": "failed", "error": {"type": "Deadlock", "message": "pipe0.vertex\nwaits", "stage": "simulate"}}
    rows = [point_row(_point(1, 16), failed), point_row(_point(0, 1), failed)]
    assert rows[1] == {"point": 0, "hash": "h0", "status": "failed", "error": "Deadlock: pipe0.vertex waits",
                       "arch.fifo_depth": 1, "scene": "cornell", "mode": "rcast"}
    cols = columns(rows)
    assert tuple(cols[:4]) == FIRST_COLUMNS and cols[4:7] == ["arch.fifo_depth", "scene", "mode"]
    assert cols[7:] == result_columns() and {"fps", "cycles.throughput", "busy.vertex"} <= set(cols)
    write_rows(tmp_path, rows)
    assert [json.loads(line)["point"] for line in (tmp_path / "sweep.jsonl").read_text().splitlines()] == [0, 1]
    table = pd.read_csv(tmp_path / "sweep.csv", dtype={"hash": str})
    assert list(table.columns) == cols and list(table["point"]) == [0, 1] and table["fps"].isna().all()
