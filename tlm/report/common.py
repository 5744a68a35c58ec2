"""What every report section shares: the figure and section records, and one plot style.

Figures are drawn with matplotlib's object API (``matplotlib.figure.Figure``, no
pyplot state, no display needed). The style survives greyscale printing: colours are
told apart by luminance as well as hue, and every series also has its own hatch (bars)
or marker and line style (lines).

Every PNG is written by :func:`write_png`: the layout engine runs once and the figure is
drawn once (``Figure.savefig`` alone draws a laid-out figure twice, once without output to
run the layout), and one mathtext parser serves every figure, so that a tick label parsed
for one figure (``10^2`` on a log axis) is not parsed again for the next (the parser keeps
the last 50). The pixels are those ``savefig`` writes.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure as MplFigure
from matplotlib.mathtext import MathTextParser

# Okabe-Ito colours, ordered so that neighbours differ in luminance (greyscale-safe)
COLOURS = ("#000000", "#E69F00", "#0072B2", "#F0E442", "#D55E00", "#56B4E9", "#009E73", "#CC79A7")
HATCHES = ("", "///", "...", "xxx", "\\\\\\", "+++", "ooo", "---")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
LINESTYLES = ("-", "--", ":", "-.", (0, (5, 1, 1, 1)), (0, (1, 3)), (0, (8, 2)), (0, (3, 1, 1, 1, 1, 1)))
DPI = 110


def colour(i: int) -> str:
    return COLOURS[i % len(COLOURS)]


def hatch(i: int) -> str:
    return HATCHES[i % len(HATCHES)]


def marker(i: int) -> str:
    return MARKERS[i % len(MARKERS)]


def linestyle(i: int):
    return LINESTYLES[i % len(LINESTYLES)]


def line_style(i: int) -> dict:
    """Keyword arguments of ``ax.plot`` for series ``i``: colour, marker and dash differ."""
    return {"color": colour(i), "marker": marker(i), "linestyle": linestyle(i), "markersize": 5}


def bar_style(i: int) -> dict:
    """Keyword arguments of ``ax.bar`` for series ``i``: colour and hatch differ, black edge."""
    return {"color": colour(i), "hatch": hatch(i), "edgecolor": "black", "linewidth": 0.6}


def new_figure(width: float = 7.0, height: float = 4.5) -> MplFigure:
    return MplFigure(figsize=(width, height), layout="constrained")


@dataclass
class Figure:
    """One PNG of the report: ``file`` is relative to the report folder."""

    file: str
    title: str
    caption: str = ""


@dataclass
class Section:
    """A numbered part of the report: figures, optional HTML (tables), or why it is absent.

    ``absent`` is the reason the section has nothing to show for these inputs (the
    report says so instead of dropping the section); ``notes`` are one-line remarks
    (what was left out of a figure and why). The page shows ``lead`` and the first
    ``shown`` figures; the other figures, the tables (``html``, unless ``html_open``)
    and the notes are behind ``<details>`` so that the page reads in a few screens.
    """

    key: str
    title: str
    figures: list[Figure] = field(default_factory=list)
    html: str = ""
    absent: str | None = None
    notes: list[str] = field(default_factory=list)
    lead: str = ""  # what the section found, in words (HTML), shown first
    shown: int = 2  # figures shown open; the rest are behind a <details>
    html_label: str = "Tables"  # the <summary> of the collapsed ``html``
    html_open: bool = False  # ``html`` is short: shown open


# the parser an Agg renderer makes for itself, shared: it keeps the labels it parsed
_MATHTEXT = MathTextParser("path")


def write_png(fig: MplFigure, path: Path) -> None:
    """Write ``fig`` as the PNG ``path`` at :data:`DPI`, laid out once and drawn once.

    The same pixels as ``fig.savefig(path, dpi=DPI)``: the figure's Agg canvas at ``DPI``
    is the one ``savefig`` would draw on, and its layout engine runs on it as ``savefig``
    runs it (in a first draw that outputs nothing, which this skips). The engine is then
    taken off the figure, as ``savefig`` takes it off for its second draw."""
    fig.set_dpi(DPI)
    canvas = FigureCanvasAgg(fig)
    canvas.get_renderer().mathtext_parser = _MATHTEXT
    engine = fig.get_layout_engine()
    if engine is not None:
        if fig.axes:  # (as Figure.draw runs it, ignoring a ValueError)
            with contextlib.suppress(ValueError):
                engine.execute(fig)
        fig.set_layout_engine(None)
    fig.savefig(path, dpi=DPI)


def save(fig: MplFigure, out: Path, name: str, title: str, caption: str = "") -> Figure:
    """Write ``fig`` as ``out/name`` (PNG, :func:`write_png`) and return its record."""
    write_png(fig, Path(out) / name)
    return Figure(name, title, caption)
