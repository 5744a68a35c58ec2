"""A failed sweep point's line is of a bounded size: its row's ``error`` (the sweep's failure
line on stdout, ``sweep.csv``, ``sweep.jsonl``) keeps the message's first parts and says how many
more the point's ``error.json`` holds. A deadlock at 64 pipelines names every blocked unit, and
its whole message, some 10 KB, was each of them."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import yaml

from tlm.errors import ERROR_CHARS, error_line
from tlm.experiments.sweep import run_sweep

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 1, "trace": False, "pipelines": 64, "max_events": 2000}}
BOUND = ERROR_CHARS + 120  # (the line's tail: how many more, and where the whole message is)


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def test_a_deadlocked_point_fails_on_a_short_line_and_keeps_its_whole_message(tmp_path):
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [1]}}))
    done = run_sweep(path, tmp_path / "o", jobs=1)
    assert (done.ok, done.failed) == (0, 1)
    row = done.rows[0]
    line = row["error"]
    assert line.startswith("MaxEventsReached: ") and "waits for" in line
    assert len(line) <= BOUND, len(line)  # (was some 10,000 characters)
    assert f"more (the whole message: points/{row['hash']}/error.json)" in line
    with open(tmp_path / "o" / "sweep.csv", newline="") as f:
        (written,) = csv.DictReader(f)
    assert written["error"] == line
    whole = json.loads((tmp_path / "o" / "points" / row["hash"] / "error.json").read_text())["message"]
    assert len(whole) > 5 * BOUND and whole.count("waits for") > line.count("waits for")
    assert line.split("; ... and ")[0].removeprefix("MaxEventsReached: ") in whole
    rest = int(line.split("; ... and ")[1].split(" ")[0])
    assert line.count("; ") - 1 + rest == whole.count("; ")  # (every part either shown or counted)


def test_an_error_line_is_one_line_of_a_bounded_size():
    assert error_line("a\nb", "w") == "a b"
    assert error_line("x" * 10, "w", limit=10) == "x" * 10
    assert error_line("x" * 30, "w", limit=10) == "x" * 10 + "... and 20 more characters (the whole message: w)"
    assert error_line("; ".join(["abcd"] * 10), "w", limit=12) == "abcd; abcd; ... and 8 more (the whole message: w)"


def test_a_deadlocked_run_says_it_on_a_short_line_and_keeps_its_whole_message(tmp_path, capsys):
    """``tlm run`` of the same frame: one line on stderr of a bounded size (it was the whole
    message, some 10 KB), naming the file that holds the whole message; nothing written."""
    from tlm.cli import main

    path = tmp_path / "run.yaml"
    path.write_text(yaml.safe_dump(BASE))
    assert main(["run", str(path), "--out", str(tmp_path / "r"), "--no-progress", "--no-reference"]) == 1
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("tlm: stopped at arch.max_events = 2000 events")
    assert "raise it if the run is only long" in err  # (the advice is kept: it comes before the list)
    assert len(err) <= BOUND + 200, len(err)  # (the file's path is long)
    kept = err.rsplit("(the whole message: ", 1)[1].rstrip(")")
    whole = Path(kept).read_text()
    assert whole.count("waits for") > err.count("waits for") and len(whole) > 5 * BOUND
    assert not (tmp_path / "r").exists()


def test_a_deadlocked_step_of_tlm_plots_is_said_on_a_short_line(tmp_path, capsys):
    """``tlm plots``' step runner says a step's deadlock as the step's own command does: bounded."""
    from tlm.cli import main

    configs = tmp_path / "configs"
    configs.mkdir()
    (configs / "cornell_pmap.yaml").write_text(yaml.safe_dump(BASE))
    argv = ["plots", "--configs", str(configs), "--runs", str(tmp_path / "runs"), "--out", str(tmp_path / "plots"),
            "--only", "cornell_pmap"]
    assert main(argv) == 2  # (the step failed, 1, and then no step's folder is left for the report: 2)
    lines = [ln for ln in capsys.readouterr().err.splitlines() if "arch.max_events" in ln]
    assert lines and all(len(ln) <= BOUND + 200 for ln in lines), [len(ln) for ln in lines]
    assert "raise it if the run is only long" in lines[0]
