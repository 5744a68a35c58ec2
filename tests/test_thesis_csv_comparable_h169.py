"""`tlm thesis`'s CSV says which cells are not comparable with the thesis, where their error is.

A cell whose resolved config is not the thesis's (a ``--set bsp.levels=3``, a FIFO depth, a
smaller resolution) was named *not comparable* in thesis_summary.json, the printed line and
the report, but its rows of ``thesis_comparison.csv`` (the documented machine-readable
output) showed its ``rel_error`` as a comparable cell's, with no column saying otherwise: a
script reading the CSV compared it silently. Now every row has ``comparable`` (false for
such a cell, empty where the thesis has no value) and ``not_comparable`` (how, in the
summary's words), after the old columns, which stay where they were; the JSONL likewise.
The summary's ``not_comparable`` is keyed as the CSV's ``scene`` column names the scene
(``ring``), and its ``scenes`` maps that name to the printed one (``thesis/ring``).
"""

from __future__ import annotations

import csv
import json

import yaml

import tlm.experiments.thesis as thesis_mod
from tlm.builtin import configs_dir
from tlm.cli import main
from tlm.report.collect import read
from tlm.report.tables import collect_sources

OLD_COLUMNS = ["scene", "mode", "metric", "thesis", "ours", "rel_error", "calibrated"]
TINY = {"seed": 0, "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "packet_size": 64, "trace": False}}


def _csv(path):
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        return reader.fieldnames, list(reader)


def test_a_cell_not_comparable_says_so_in_each_csv_and_jsonl_row(tmp_path, cache, capsys):
    """On the old code the CSV had no such column: its rows read as a comparable cell's."""
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump({"base": TINY, "scenes": ["thesis/ring"], "modes": ["rcast"]}))
    out = tmp_path / "out"
    assert main(["thesis", str(study), "--out", str(out), "--no-progress", "--no-report",
                 "--set", "bsp.levels=3"]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "thesis_summary.json").read_text())
    why = summary["not_comparable"]["ring"]
    assert "16×16 pixels (thesis 320×240)" in why and "bsp.levels 3 (thesis: floor(ln n))" in why
    header, rows = _csv(out / "thesis_comparison.csv")
    assert header == [*OLD_COLUMNS, "comparable", "not_comparable"]  # (the old columns where they were)
    assert [r["metric"] for r in rows] == list(thesis_mod.METRICS)
    for r in rows:
        assert r["comparable"] == "False" and r["not_comparable"] == "; ".join(why), r
        assert r["rel_error"] != ""  # (kept: the column says how to read it)
        assert r["scene"] in summary["not_comparable"]  # (one key for the scene in the CSV and the summary)
    jsonl = [json.loads(line) for line in (out / "thesis_comparison.jsonl").read_text().splitlines()]
    assert [(j["comparable"], j["not_comparable"]) for j in jsonl] == [(False, "; ".join(why))] * len(rows)
    # the summary names the CSV's scene as the printed lines do
    assert summary["scenes"] == {"ring": "thesis/ring"}
    assert f"not comparable with the thesis: {summary['scenes']['ring']} is " in printed
    # tlm report reads the table with its new columns, and still judges the scene not comparable
    inputs = read([out])
    (st,) = inputs.of_kind("thesis")
    assert [r["comparable"] for r in st.rows] == [False] * len(rows)
    (src,) = collect_sources(inputs, [])["ring"]
    assert src.not_comparable == why


def test_a_cell_at_the_thesis_setting_is_comparable_in_the_csv(tmp_path, cache):
    """The thesis's ring, ray casting, at the committed configs/thesis.yaml's setting (a few seconds)."""
    study = tmp_path / "study.yaml"
    raw = yaml.safe_load((configs_dir() / "thesis.yaml").read_text())
    study.write_text(yaml.safe_dump({**raw, "scenes": ["thesis/ring"], "modes": ["rcast"]}))
    out = tmp_path / "out"
    assert main(["thesis", str(study), "--out", str(out), "--no-progress", "--no-report"]) == 0
    summary = json.loads((out / "thesis_summary.json").read_text())
    assert summary["not_comparable"] == {} and summary["median_abs_rel_error_held_out"] is not None
    header, rows = _csv(out / "thesis_comparison.csv")
    assert header == [*OLD_COLUMNS, "comparable", "not_comparable"]
    assert [(r["comparable"], r["not_comparable"]) for r in rows] == [("True", "")] * len(thesis_mod.METRICS)


def test_a_row_without_a_thesis_value_is_neither_comparable_nor_not():
    """A scene with no thesis table: both columns empty, as its rel_error is (nothing compared)."""
    ours = dict.fromkeys(thesis_mod.METRICS, 1.0)
    rows = thesis_mod.comparison_rows("box", "rcast", ours) + thesis_mod.comparison_rows("ring", "rcast", ours)
    got = thesis_mod.with_comparable(rows, {"ring": ["32×32 pixels (thesis 320×240)", "bsp.levels 3 (thesis: 9)"]})
    assert {(r["scene"], r["comparable"], r["not_comparable"]) for r in got} == {
        ("box", None, None), ("ring", False, "32×32 pixels (thesis 320×240); bsp.levels 3 (thesis: 9)")}
    fine = thesis_mod.with_comparable(rows[6:], {})
    assert all(r["comparable"] is True and r["not_comparable"] is None for r in fine)
    assert [{k: r[k] for k in OLD_COLUMNS} for r in got] == rows  # (the old columns as they were)
