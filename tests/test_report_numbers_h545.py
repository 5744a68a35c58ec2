"""The report's numbers and HTML as others read them (h545, from probe h544).

1. Table III wrote ours with ``.4g``: TThru ``6.41`` where the sweep table wrote ``6.410``, FPS ``93.6`` beside
   ``93.60``, and ``1.192e+04`` beside ``7460``; the breakdown's legend the same. A table value keeps its
   significant trailing zeros and is written whole, thousands separated, from 1,000 up (``11,920``); the
   thesis's value as the thesis prints it (``43.0``, ``110``, ``0.378``), not padded to four digits.
2. A sweep finding said "at 13 to 13.02 FPS" where the table says 13.00: a range's ends keep their zeros.
3. The provenance wrote a light's power ``1.1e+06 950000 750000`` (``:g``) and a trace's ``44778358 cycles``
   beside ``2,604`` triangles: a recorded value exact and thousands separated, a count too.
4. The tables put a ``<style>`` inside the page's body (not HTML; text extraction showed the CSS): its rules are
   in the head's CSS now.
5. The committed report's link to docs/fidelity.md breaks when plots/ is mailed: the file is named in words
   after the link too.
"""

from __future__ import annotations

import json
import re

import pytest

from tests.test_report_big_sweeps import sweep_folder
from tlm.cli import main
from tlm.report import tables
from tlm.report.collect import read
from tlm.report.html import page
from tlm.report.provenance import _seconds_text, _text
from tlm.report.summary_effects import _fps_range
from tlm.report.tables import fmt, tables_section


def _significant(text: str) -> int:
    """The significant digits of a table's number written with a point (``0.1215``: 4, ``13.00``: 4)."""
    return len(text.replace(",", "").replace(".", "").replace("-", "").lstrip("0"))


def test_a_table_value_keeps_its_trailing_zeros_and_a_big_one_is_written_whole():
    # (the probe's examples: Table III beside the sweep table, and cornell_pmap's TThru beside its TFrag)
    assert [fmt(v) for v in (6.41, 93.6, 20.7, 13.0, 0.3929)] == ["6.410", "93.60", "20.70", "13.00", "0.3929"]
    assert [fmt(v) for v in (11924.3, 7460.2, 102.6, 110.0)] == ["11,920", "7,460", "102.6", "110.0"]
    assert fmt(0.0000123) == "1.230e-05" and fmt(None) == "–" and fmt(0.0) == "0"


def test_a_range_of_frame_rates_keeps_the_zeros_that_part_its_ends():
    assert _fps_range([13.0, 13.02]) == "13.00 to 13.02 FPS"
    assert _fps_range([101.8, 102.0]) == "101.8 to 102.0 FPS"


def test_the_provenance_writes_a_recorded_value_exact_and_thousands_separated():
    assert _text([1100000.0, 950000.0, 750000.0]) == "1,100,000 950,000 750,000"
    assert _text({"corner": [343.0, 548.8, 227.0], "area": 13650.0}) == "corner: 343 548.8 227; area: 13,650"
    assert _text(1224) == "1,224" and _text(0.065) == "0.065" and _text(True) == "True"
    assert _seconds_text(1234.4) == "1,234" and _seconds_text(3.5) == "3.50"


def test_the_tables_have_no_style_in_the_body_and_table_iii_keeps_its_zeros(tmp_path):
    out = tmp_path / "report"
    out.mkdir()
    section = tables_section(read([sweep_folder(tmp_path / "S")]), out)  # (cornell points at 14 and 13 FPS)
    assert "<style" not in section.html
    fps = re.findall(r'data-cell="cornell/rcast/FPS"[^>]*><span class="ours">([^<]*)</span>', section.html)
    assert fps and set(fps) <= {"14.00", "13.00"}, fps
    thesis = re.findall(r'data-cell="cornell/rcast/TThru"[^>]*>.*?<span class="thesis">([^<]*)</span>', section.html)
    assert thesis and set(thesis) == {"43.0"}, thesis  # (Table III's own digits, not 43.00)
    text = page("t", "", [section], out)
    head, _, body = text.partition("</head>")
    assert "<style" not in body and ".tlm-tables caption" in head


def test_the_fidelity_link_names_its_file_in_words_too(tmp_path, monkeypatch):
    doc = tmp_path / "checkout" / "docs" / "fidelity.md"
    doc.parent.mkdir(parents=True)
    doc.write_text("# Fidelity\n\n## By cell\n", encoding="utf-8")
    monkeypatch.setattr(tables, "FIDELITY_DOC", doc)
    (tmp_path / "checkout" / "plots").mkdir()
    line = tables.fidelity_html(tmp_path / "checkout" / "plots")
    assert 'href="../docs/fidelity.md#by-cell"' in line and "</a> in tlm's source" in line, line


@pytest.mark.slow
def test_a_tiny_run_s_report_is_valid_html_with_the_numbers_written_one_way(tmp_path):
    out = tmp_path / "r"
    assert main(["run", "cornell", "--set", "resolution=[16,16]", "--out", str(out), "--formats", "svg",
                 "--no-progress"]) == 0
    text = (out / "report" / "report.html").read_text(encoding="utf-8")
    head, _, body = text.partition("</head>")
    assert "<style" not in body and ".tlm-tables" in head
    cells = dict(re.findall(r'data-cell="cornell/\w+/(\w+)"[^>]*><span class="ours">([^<]*)</span>', body))
    assert set(cells) == {"TVert", "TTrav", "Tisct", "TFrag", "TThru", "FPS"}, cells
    for metric, v in cells.items():  # (four significant digits each, or whole with separators from 1,000 up)
        assert not re.fullmatch(r"\d{4,}", v), (metric, v)
        assert "." not in v or _significant(v) == 4, (metric, v)
        assert "e" not in v, (metric, v)
    results = json.loads((out / "results.json").read_text())
    assert cells["FPS"] == fmt(results["fps"]) and cells["TThru"] == fmt(results["cycles"]["throughput"] / 1e6)
    slices = re.search(r"slices over ([\d,]+) cycles", body).group(1)
    assert int(slices.replace(",", "")) >= 1000 and "," in slices, slices  # (a count, thousands separated)
    svg = (out / "report" / "cycles_00_r_cornell_refract_breakdown.svg").read_text(encoding="utf-8")
    assert f"TThru (frame period): {cells['TThru']}" in svg
    assert "1,100,000 950,000 750,000" in body  # (the light's power as recorded)
