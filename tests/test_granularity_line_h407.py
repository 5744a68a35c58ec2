"""h407: ``tlm granularity``'s line that packet sizes give the same rows (h400) reaches the API and the report,
and its progress lines stay aligned for a packet size of any width.

Since h400 the line (two or more packet sizes at or past the items of the frame's largest phase run every phase
as one packet) was printed under ``tlm granularity``'s table and kept in ``granularity_summary.json``, but
``tlm.granularity`` returned it nowhere (``attrs["notes"]`` was empty) and ``tlm report`` did not say it. The
progress lines put the size in 8 columns: 102400000 pushed its line's columns out of line.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import yaml

import tlm
from tlm.cli import main
from tlm.report.collect import read
from tlm.report.tradeoff import tradeoff_section

SIZES = [64, 256, 1024, 102400000]
SAME = ("packet sizes 256, 1024 and 102400000 are at or past the 256 pixels of the frame's largest phase "
        "(rcast.rays): each phase runs as one packet at each, so their cycles, errors and events are the same")
LARGEST = {"phase": "rcast.rays", "items": 256, "unit": "pixels"}


def _study(tmp_path: Path) -> Path:
    """The committed study at 16x16 (256 eye rays), one frame, packets of 64 to 102400000."""
    raw = yaml.safe_load((Path(__file__).parents[1] / "configs" / "tlm_granularity.yaml").read_text())
    raw["base"]["resolution"] = [16, 16]
    raw["base"]["arch"]["frames"] = 1
    raw["packet_sizes"] = SIZES
    study = tmp_path / "g.yaml"
    study.write_text(yaml.safe_dump(raw))
    return study


def test_the_api_returns_the_line_and_the_sizes(tmp_path, cache):
    told: list[list[int]] = []
    rows = tlm.granularity(_study(tmp_path), tmp_path / "g", start=told.append)
    assert rows.attrs["notes"] == [SAME]
    assert rows.attrs["one_packet"] == [256, 1024, 102400000]
    assert rows.attrs["largest_phase"] == LARGEST
    assert told == [SIZES]  # (once, before the first size, in the order simulated)
    record = json.loads((tmp_path / "g" / "granularity_summary.json").read_text())
    assert record["notes"] == rows.attrs["notes"] and record["one_packet"] == rows.attrs["one_packet"]
    same = {r["packet_size"]: (r["throughput"], r["simpy_events"]) for r in rows}
    assert same[256] == same[1024] == same[102400000] != same[64]


def test_one_size_past_the_largest_phase_is_no_line(tmp_path, cache):
    study = _study(tmp_path)
    raw = yaml.safe_load(study.read_text())
    raw["packet_sizes"] = [16, 64, 1024]
    study.write_text(yaml.safe_dump(raw))
    rows = tlm.granularity(study, tmp_path / "g")
    assert rows.attrs["notes"] == [] and rows.attrs["one_packet"] == [1024]
    assert rows.attrs["largest_phase"] == LARGEST


def test_a_bad_start_is_refused_naming_it(tmp_path, cache):
    try:
        tlm.granularity(_study(tmp_path), tmp_path / "g", start=3)
    except tlm.InputError as e:
        assert "start" in str(e) and "not a function" in str(e), e
    else:
        raise AssertionError("start=3 was taken")
    assert not (tmp_path / "g").exists()


def test_progress_lines_stay_aligned_for_any_size(tmp_path, cache, capsys):
    out = tmp_path / "g"
    assert main(["granularity", str(_study(tmp_path)), "--out", str(out), "--no-report"]) == 0
    printed = capsys.readouterr().out.splitlines()
    progress = [line for line in printed if " M cycles, " in line]
    assert len(progress) == 4 and progress[-1].startswith("  packets of 102400000: throughput "), printed
    for mark in (": throughput", " M cycles, ", " events, ", " s"):
        assert len({line.index(mark) for line in progress}) == 1, (mark, progress)
    table = [line for line in printed if "max |cycle error|" in line]
    assert {line.index(":") for line in table} == {line.index(":") for line in progress}, printed  # (one column)
    assert f"  {SAME}" in printed


def test_the_report_says_the_line_and_older_studies_still_report(tmp_path, cache):
    out = tmp_path / "g"
    tlm.granularity(_study(tmp_path), out)
    label = out.name
    (tmp_path / "report").mkdir()
    sec = tradeoff_section(read([out]), tmp_path / "report")
    assert f"{label}: {SAME}." in sec.notes, sec.notes
    assert sec.figures  # (the line is beside the figure, which is drawn)

    # a study written before h400 (no granularity_summary.json) or before its notes still reports, with no line
    for old in ("none", "no notes"):
        was = tmp_path / f"old {old}" / "g"
        shutil.copytree(out, was)
        summary = was / "granularity_summary.json"
        if old == "none":
            summary.unlink()
        else:
            record = json.loads(summary.read_text())
            summary.write_text(json.dumps({"warnings": record["warnings"]}))
        (tmp_path / f"report {old}").mkdir()
        sec = tradeoff_section(read([was]), tmp_path / f"report {old}")
        assert sec.figures and not any("one packet" in n for n in sec.notes), (old, sec.notes)
