"""What the report's sections share (:mod:`tlm.report.common`): a series style that stays
apart in greyscale, the figure and section records, and the PNG a figure is saved as."""

from __future__ import annotations

from PIL import Image

from tlm.report.common import COLOURS, Figure, Section, bar_style, colour, line_style, new_figure, save


def test_each_of_eight_series_differs_in_colour_marker_dash_and_hatch():
    lines = [line_style(i) for i in range(8)]
    bars = [bar_style(i) for i in range(8)]
    for key in ("color", "marker", "linestyle"):
        assert len({repr(s[key]) for s in lines}) == 8, key
    assert len({s["hatch"] for s in bars}) == 8 and {s["edgecolor"] for s in bars} == {"black"}
    assert line_style(9) == line_style(1) and bar_style(8) == bar_style(0)  # the ninth series cycles
    assert colour(3) == COLOURS[3] == bars[3]["color"] == lines[3]["color"]


def test_save_writes_the_png_and_returns_its_record(tmp_path):
    fig = new_figure(2.0, 1.5)
    ax = fig.add_subplot()
    for i in range(2):
        ax.plot([0, 1], [i, i + 1], **line_style(i))
    rec = save(fig, tmp_path, "f.png", "A title", "a caption")
    assert rec == Figure("f.png", "A title", "a caption")
    with Image.open(tmp_path / "f.png") as im:
        assert im.format == "PNG" and im.size == (220, 165)  # figsize x DPI


def test_a_section_starts_empty_with_two_figures_shown():
    s = Section("k", "T")
    assert (s.figures, s.html, s.absent, s.notes, s.lead, s.shown, s.html_open) == ([], "", None, [], "", 2, False)
    s.notes.append("x")
    assert Section("k", "T").notes == []  # no list shared between sections
