"""Three modules brought under 700 lines by moving code, the same code, beside them: the tables the
commands print (tlm/cli_tables.py, out of cli.py), the thesis printout's words (tlm/experiments/thesis_text.py,
out of thesis.py) and the report's file checks (tlm/report/checks.py, out of report/collect.py). The old
modules keep every name importable (by its old, private name where it had one) as the same object, and the
moved code does as it did."""

from __future__ import annotations

import json

import pytest

import tlm.cli as cli
import tlm.experiments.thesis as thesis
import tlm.report.collect as collect
from tlm.cli_tables import print_scaling, print_thesis, yaml_text
from tlm.errors import InputError
from tlm.experiments.thesis_text import describe_items, fixed, median_words, slowest_words
from tlm.report.checks import (
    COUNT,
    NUMBER,
    RESULTS_KEYS,
    check,
    counts,
    number,
    read_json,
    read_results,
    read_yaml,
    rows_checked,
    short,
)


def test_the_old_modules_keep_the_moved_names_as_the_same_objects():
    assert (cli._print_thesis, cli._print_scaling, cli._yaml_text) == (print_thesis, print_scaling, yaml_text)
    for obj in (describe_items, fixed, median_words, slowest_words):
        assert getattr(thesis, obj.__name__) is obj, obj.__name__
    for old, obj in (("_check", check), ("_counts", counts), ("_number", number), ("_json", read_json),
                     ("_results", read_results), ("_yaml", read_yaml), ("_rows_checked", rows_checked),
                     ("_short", short)):
        assert getattr(collect, old) is obj, old
    assert (collect.COUNT, collect.NUMBER, collect.RESULTS_KEYS) == (COUNT, NUMBER, RESULTS_KEYS)


def test_the_moved_code_does_as_it_did(tmp_path, capsys):
    assert [yaml_text(v) for v in (None, True, "cornell", [16, 16], 6e8, 0.5)] == [
        "null", "true", "cornell", "[16, 16]", "6.0e+08", "0.5"]
    assert (fixed(0.012344), fixed(12.3456), fixed(21470.4), fixed(0.0)) == ("0.01234", "12.35", "21470", "0")
    summary = {"median_abs_rel_error_held_out": 0.125, "held_out_cells_compared": 6, "scene_modes": 4,
               "slowest_pm_matches": 3}
    assert median_words(summary) == "median |relative error| over the 6 held-out cells: 12.5%"
    assert slowest_words(summary) == "slowest PM as in the thesis in 3 of 4 scene-modes"
    fit = {"scene": "cornell", "mode": "rcast", "scheduler": "static", "target": "throughput", "A": 1.0, "B": 0.5,
           "max_abs_rel_error": 0.01, "slowest": {"max_abs_rel_error": 0.02}, "pipelines": [1, 2, 4]}
    print_scaling({"notes": [], "fits": [fit]}, tmp_path)
    out = capsys.readouterr().out.splitlines()
    assert out[1].startswith("  cornell  rcast   static   throughput A        1  B      0.5") and out[-1] == (
        f"wrote {tmp_path}") and out[1].endswith("(N = 1, 2, 4)")
    bad = tmp_path / "results.json"
    bad.write_text(json.dumps({"scene": {"name": "cornell"}, "timing": {}, "cycles": {"throughput": -1}}))
    with pytest.raises(InputError, match="not negative") as e:
        collect._run(tmp_path, "", "run")  # (the run's results.json, read and checked where collect reads it)
    assert e.value.key == "cycles.throughput" and e.value.source == str(bad)
    (tmp_path / "cut.json").write_text('{"a": 1')
    with pytest.raises(InputError, match="is cut off"):
        read_json(tmp_path / "cut.json")
    with pytest.raises(InputError, match=r"'x' is 'a', not a number \(a row\)"):
        rows_checked(tmp_path / "t.jsonl", [(1, {"x": "a"})], "a row", {"x": NUMBER})
