"""h410: review of 6e5d3f3 (h407: ``tlm.granularity``'s sizes line in the API and the report).

A damaged ``granularity_summary.json`` whose ``notes`` held a ``null`` or a number gave the report the notes
``g: None.`` and ``g: 3.``: only its lines of text are said now. The rest pins what the review checked of h407
(each fails on the code before it, which took no ``start=``): a ``start`` that raises stops the study with its
own error and nothing written; ``start`` gets the sizes each once, increasing; over several pipelines the
largest phase is a tile's and every size at or past it is listed.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

import tlm
from tlm.report.collect import read
from tlm.report.tradeoff import tradeoff_section


def _study(tmp_path: Path, sizes: list[int], **arch) -> Path:
    """The committed study at 16x16 (256 eye rays), one frame, at ``sizes``."""
    raw = yaml.safe_load((Path(__file__).parents[1] / "configs" / "tlm_granularity.yaml").read_text())
    raw["base"]["resolution"] = [16, 16]
    raw["base"]["arch"].update(frames=1, **arch)
    raw["packet_sizes"] = sizes
    study = tmp_path / "g.yaml"
    study.write_text(yaml.safe_dump(raw))
    return study


def test_a_damaged_records_notes_that_are_not_text_are_no_lines(tmp_path, cache):
    out = tmp_path / "g"
    tlm.granularity(_study(tmp_path, [64, 256, 1024]), out)
    summary = out / "granularity_summary.json"
    record = json.loads(summary.read_text())
    line = record["notes"][0]
    summary.write_text(json.dumps({**record, "notes": [None, 3, "", line, {"a": 1}]}))
    (tmp_path / "report").mkdir()
    sec = tradeoff_section(read([out]), tmp_path / "report")
    said = [n for n in sec.notes if n.startswith("g: ")]
    assert said == [f"g: {line}."], sec.notes
    assert sec.figures


def test_a_start_that_raises_stops_the_study_with_nothing_written(tmp_path, cache):
    def start(sizes):
        raise RuntimeError("the caller's own")

    out = tmp_path / "g"
    with pytest.raises(RuntimeError, match="the caller's own"):
        tlm.granularity(_study(tmp_path, [64, 256]), out, start=start)
    assert not out.exists()


def test_start_gets_the_sizes_once_each_increasing(tmp_path, cache):
    told: list[list[int]] = []
    rows = tlm.granularity(_study(tmp_path, [256, 64]), tmp_path / "g", start=told.append)
    assert told == [[64, 256]] and [r["packet_size"] for r in rows] == [64, 256]
    assert rows.attrs["notes"] == [] and rows.attrs["one_packet"] == [256]  # (one size alone: no line)


def test_several_pipelines_name_the_largest_tile(tmp_path, cache):
    rows = tlm.granularity(_study(tmp_path, [16, 64, 1024], pipelines=4), tmp_path / "g")
    assert rows.attrs["largest_phase"] == {"phase": "rcast.rays", "items": 64, "unit": "pixels", "tiles": 4}
    assert rows.attrs["one_packet"] == [64, 1024]
    assert rows.attrs["notes"] == [
        "packet sizes 64 and 1024 are at or past the 64 pixels of the frame's largest phase (rcast.rays, in the "
        "largest of its 4 tiles): each phase runs as one packet at each, so their cycles, errors and events are "
        "the same"]
    assert json.loads((tmp_path / "g" / "granularity_summary.json").read_text())["notes"] == rows.attrs["notes"]
