"""Review h459 of the session's change: what an interrupted sweep's line counts of the rows an earlier run kept
(:func:`tlm.experiments.sweep_rows.rows_kept`, h450/h457)."""

from __future__ import annotations

import json

from tlm.experiments.sweep_rows import rows_kept


def _jsonl(out, rows, tail: str = "") -> None:
    out.mkdir()
    (out / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows) + tail, encoding="utf-8")


def test_a_point_rerun_and_appended_again_is_one_row_its_last(tmp_path):
    # a failed point's row, then its rerun's (appended by a rerun killed before it rewrote the file sorted): the
    # folder keeps 2 points, neither failed; it counted 3 rows, 1 failed, '3 of 2 points' where the sweep had 2
    out = tmp_path / "s"
    _jsonl(out, [{"hash": "a", "status": "failed"}, {"hash": "b", "status": "ok"}, {"hash": "a", "status": "ok"}])
    kept = rows_kept(out, ["a", "b"])
    assert sorted(r["hash"] for r in kept) == ["a", "b"]
    assert [r["status"] for r in kept if r["hash"] == "a"] == ["ok"]


def test_a_row_whose_hash_is_no_string_is_left_out_not_an_error(tmp_path):
    # (a hand-edited or damaged row: its list 'hash' raised TypeError, unhashable, in place of the interrupt's line)
    out = tmp_path / "s"
    _jsonl(out, [{"hash": ["a"], "status": "ok"}, {"hash": {"x": 1}}, {"hash": "b", "status": "ok"}],
           tail='{"hash": "a", "status": "ok"}')  # (a last line cut off: left out, as before)
    assert [r["hash"] for r in rows_kept(out, ["a", "b"])] == ["b"]
