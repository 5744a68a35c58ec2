"""What the report's sections share (:mod:`tlm.report.common`): a series style that stays
apart in greyscale, the figure and section records, and the PNG a figure is saved as."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure as MplFigure
from matplotlib.mathtext import MathTextParser
from PIL import Image

from tlm.report.common import COLOURS, DPI, Figure, Section, bar_style, colour, line_style, new_figure, save


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


def _busy_figure() -> MplFigure:
    """What the report's figures hold: a log axis (its labels are mathtext), a secondary axis,
    rotated tick labels, a legend outside the axes and a title over the figure."""
    fig = new_figure(6.0, 3.5)
    ax = fig.add_subplot()
    for i in range(3):
        ax.plot([1, 10, 100, 1000], np.array([2.0, 30.0, 500.0, 7000.0]) * (i + 1), label=f"series {i}",
                **line_style(i))
    ax.set(xscale="log", yscale="log", xlabel="frames per second (log scale)", ylabel="millions of cycles")
    ax.set_xticks([1, 10, 100, 1000], ["one", "ten", "a hundred", "a thousand"], rotation=90)
    ax.secondary_xaxis("top", functions=(lambda x: x / 60, lambda x: 60 * x)).set_xlabel("frames per minute")
    fig.legend(loc="outside lower center", ncol=3)
    fig.suptitle("A report figure")
    return fig


def test_a_figure_is_laid_out_and_drawn_once_into_the_pixels_savefig_writes(tmp_path, monkeypatch):
    """savefig draws a figure with a layout engine twice (once with no output, to lay it out):
    the report lays it out and draws it once, into the same PNG bytes savefig writes."""
    _busy_figure().savefig(tmp_path / "savefig.png", dpi=DPI)
    drawn = []
    draw = MplFigure.draw
    monkeypatch.setattr(MplFigure, "draw", lambda fig, renderer: drawn.append(fig) or draw(fig, renderer))
    save(_busy_figure(), tmp_path, "report.png", "t")
    assert len(drawn) == 1
    assert (tmp_path / "report.png").read_bytes() == (tmp_path / "savefig.png").read_bytes()
    with Image.open(tmp_path / "report.png") as im:
        assert im.size == (660, 385)  # 6 x 3.5 inches at 110 DPI


def test_the_figures_share_one_mathtext_parser(tmp_path):
    """A log axis's labels (10^1, 10^2, ...) are mathtext, and parsing one costs more than
    drawing it: a label parsed for one figure is not parsed again for the next."""
    parses = MathTextParser._parse_cached.cache_info
    save(_busy_figure(), tmp_path, "a.png", "t")
    before = parses().misses
    save(_busy_figure(), tmp_path, "b.png", "t")
    assert parses().misses == before
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()
