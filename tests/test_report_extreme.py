"""The report's section on ``tlm extreme`` folders (:mod:`tlm.report.extreme`): per folder,
how many cases went as expected, the ones that did not named, and a row per case."""

from __future__ import annotations

from pathlib import Path

from tlm.report.collect import Inputs, Study
from tlm.report.extreme import extreme_section


def _row(case, category, passed):
    return {"case": case, "category": category, "expect": "stalls <x>", "measured": "1 & 2", "passed": passed,
            "seconds": 1.234}


def test_each_folder_counts_its_cases_and_names_the_unexpected(tmp_path):
    rows = [_row("zero_photons", "render", True), _row("deep_fifo", "arch", False), _row("one_px", "arch", True)]
    other = Study("thesis", Path("t"), [{"case": "not mine", "passed": False}])
    sec = extreme_section(Inputs([], studies=[Study("extreme", Path("ex1"), rows), other]), tmp_path)
    assert sec.key == "extreme" and sec.absent is None
    html = sec.html
    assert "<h3>ex1</h3><p>3 cases, 2 as expected, <strong>not as expected: deep_fifo</strong>." in html
    assert "not mine" not in html and html.count("<table>") == 1
    cases = [ln for ln in html.splitlines() if ln.startswith("<tr><td")]
    assert [c.split('<td class="l">')[2].split("<")[0] for c in cases] == ["deep_fifo", "one_px", "zero_photons"]
    assert "<strong>NOT as expected</strong>" in cases[0] and "as expected</td><td>1.23</td>" in cases[1]
    assert "stalls &lt;x&gt;" in html and "1 &amp; 2" in html  # escaped
    two = extreme_section(Inputs([], studies=[Study("extreme", Path("a"), rows[2:]),
                                              Study("extreme", Path("b"), rows[:1])]), tmp_path)
    assert two.html.count("<table>") == 2 and "not as expected" not in two.html


def test_without_an_extreme_folder_the_section_says_so(tmp_path):
    sec = extreme_section(Inputs([], studies=[Study("scaling", Path("s"), [])]), tmp_path)
    assert sec.html == "" and "no 'tlm extreme' folder among the inputs" in sec.absent
