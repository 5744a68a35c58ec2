"""h364: ``tlm granularity``'s rows say the frames each packet size simulated, and its seconds and events per
frame, and a line under its table says where the sizes ran different frame counts.

Since e4f30a1 a static stream of two images whose steady gaps do not repeat among the frames asked runs on until
they do (tlm/arch/steady.py, ``arch.settle_frames``), at one packet size and not at another: Cornell PMap at 16x16
(4000 photons, one eye ray and light sample a pixel) with 2 pipelines runs the 5 frames asked at packets of 64 and
256, 16 at 4096 (tests/test_static_steady_h349.py's frame). ``simulate_seconds`` and ``simpy_events`` are totals
over those frames, so the rows' totals are not comparable; their ``*_per_frame`` columns are, and the report draws
and words the host time per frame there.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.cli_tables import granularity_frames_line
from tlm.experiments.granularity import COLUMNS, frames_differ
from tlm.report.collect import Inputs, Study
from tlm.report.summary import study_findings
from tlm.report.tradeoff import granularity_per_frame, granularity_points

BASE = {"scene": "cornell", "mode": "pmap", "resolution": [16, 16], "render": {"spp": 1, "light_samples": 1},
        "photons": {"count": 4000}, "arch": {"pipelines": 2}}
OLD = ("packet_size", "vertex", "traversal", "intersection", "fragment", "throughput", "latency",
       "rel_error_vertex", "rel_error_traversal", "rel_error_intersection", "rel_error_fragment",
       "rel_error_throughput", "rel_error_latency", "max_abs_rel_error", "granularity_share", "simulate_seconds",
       "simpy_events", "reference")


def test_the_rows_say_their_frames_and_the_table_says_they_differ(tmp_path, cache, capsys):
    """2 pipelines: packets of 64 and 256 run the 5 frames asked, 4096 runs on to 16; the CSV's and the JSONL's
    rows say so, with the seconds and events per frame, the old columns in their places, and the printed table
    a line under it naming which sizes ran how many and what to compare."""
    study = tmp_path / "g.yaml"
    study.write_text(json.dumps({"base": BASE, "packet_sizes": [64, 256, 4096]}))
    out = tmp_path / "g"
    assert main(["granularity", str(study), "--out", str(out), "--no-report"]) == 0
    printed = capsys.readouterr().out
    assert COLUMNS[:len(OLD)] == OLD  # (users' scripts read them: appended, not moved)
    with open(out / "granularity.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == COLUMNS
    assert [(int(r["packet_size"]), int(r["frames"])) for r in rows] == [(64, 5), (256, 5), (4096, 16)]
    jsonl = [json.loads(line) for line in (out / "granularity.jsonl").read_text().splitlines()]
    assert [r["frames"] for r in jsonl] == [5, 5, 16]
    for r in jsonl:
        assert r["simpy_events_per_frame"] == round(r["simpy_events"] / r["frames"], 1)
        assert r["simulate_seconds_per_frame"] == pytest.approx(r["simulate_seconds"] / r["frames"], abs=1e-4)
    assert frames_differ(jsonl) == {5: [64, 256], 16: [4096]}
    assert "packets of     4096: max |cycle error| 7.013% against packets of 64, " in printed
    assert ", 16 frames (" in printed and " s a frame)" in printed
    line = ("  the rows ran different frame counts: 5 at packets of 64, 256; 16 at packets of 4096 (where the "
            "stream's completions did not repeat within arch.frames it ran on until they did, at most "
            "arch.settle_frames: tlm/arch/steady.py); simulate_seconds and simpy_events are totals over a row's "
            "frames: compare them per frame (simulate_seconds_per_frame, simpy_events_per_frame in granularity.csv)")
    lines = printed.splitlines()
    assert lines[lines.index(line) + 1] == f"wrote {out}/granularity.csv"  # (under the table)
    assert lines[lines.index(line) - 1].startswith("  packets of     4096: max |cycle error|")


def _rows(frames):
    """Three sizes: the whole simulation's seconds rise with the frames run, per frame they fall."""
    secs = (2.0, 0.5, 0.8)
    return [{"packet_size": n, "max_abs_rel_error": e, "simulate_seconds": s, "frames": f,
             "simulate_seconds_per_frame": round(s / f, 6), "simpy_events": 1000, "simpy_events_per_frame":
                 round(1000 / f, 1)}
            for n, e, s, f in zip((1, 64, 256), (0.0, 0.004, 0.05), secs, frames, strict=True)]


def test_the_line_is_said_only_where_the_frames_differ():
    assert granularity_frames_line(_rows((5, 5, 5))) == ""
    assert granularity_frames_line(_rows((16, 5, 16))).startswith(
        "  the rows ran different frame counts: 5 at packets of 64; 16 at packets of 1, 256 (")
    assert frames_differ(_rows((5, 5, 5))) == {}
    old = [{k: v for k, v in r.items() if "frame" not in k} for r in _rows((16, 5, 16))]
    assert frames_differ(old) == {}  # (a study written before the frames column: as before)


def test_the_report_compares_host_seconds_per_frame_where_the_frames_differ():
    """The figure's and the summary's seconds: per frame where the sizes ran different frame counts (and said
    so), the whole simulation's where they ran the same, or the rows predate the frames column."""
    uneven = Study("granularity", Path("g"), _rows((16, 5, 16)))
    _size, secs, _err = granularity_points(uneven)
    assert list(secs) == [0.125, 0.1, 0.05]
    assert "ran different frame counts (5 at packets of 64; 16 at the others: " in granularity_per_frame(uneven)
    (text,) = study_findings(Inputs([], studies=[uneven]))
    assert "packets of 64 stay within 1% of the cycles of packets of 1 (error 0.40%), in 0.1 s of simulation a " \
           "frame against 0.125 s" in text
    assert "; the packet sizes ran different frame counts (5 at packets of 64; 16 at the others: " in text
    even = Study("granularity", Path("g"), _rows((5, 5, 5)))
    assert list(granularity_points(even)[1]) == [2.0, 0.5, 0.8] and granularity_per_frame(even) == ""
    (text,) = study_findings(Inputs([], studies=[even]))
    assert "in 0.5 s of simulation against 2 s" in text and "frame" not in text
