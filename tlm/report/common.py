"""What every report section shares: the figure and section records, and one plot style.

Figures are drawn with matplotlib's object API (``matplotlib.figure.Figure``, no pyplot state, no display needed), in
matplotlib's default style and tlm's own settings whatever the caller set (:func:`report_style`: ``plt.style.use``,
``rcParams``, a matplotlibrc), theirs back after. The style survives greyscale printing: colours are told apart by
luminance as well as hue, and every series also has its own hatch (bars) or marker and line style (lines).

Every PNG is written by :func:`write_png`, laid out once and drawn once (``Figure.savefig`` alone draws it twice), the
pixels ``savefig`` writes, with one mathtext parser for every figure (a log axis's ``10^2`` parsed once); a name in
it drawn as written (:func:`figure_text`: a folder's ``m$x^2$`` not as a formula, a tab as a space).

The report's figure files are set by :func:`figure_output` (``tlm report --formats --dpi``): the PNG at ``dpi``
(default :data:`DPI`), and where asked a PDF and an SVG beside it, of the same stem. They are saved from the one
laid-out figure (one draw per file, no second layout), so that the three files show one layout. Their text stays text:
the PDF embeds its fonts as TrueType (``pdf.fonttype`` 42; matplotlib's default, Type 3 fonts, is flagged by some
publishers' PDF checks), and the SVG keeps each label a ``<text>`` element (``svg.fonttype`` ``none``), editable and
searchable, in the fonts the figure names (DejaVu Sans, then matplotlib's others, ``sans-serif`` last; a log axis's
powers of ten DejaVu Sans alone): a viewer without DejaVu Sans draws the text in another, of other widths, where glyphs
as paths (``path``) would look the same everywhere but could not be edited. Neither file records the time it was
written, so a report written again from the same inputs writes the same PDF and SVG files, byte for byte.

Every figure's file name is made by :func:`figure_name`: ASCII letters, digits, ``_``, ``-`` and ``.png``'s ``.``,
unquoted in a shell, a URL and LaTeX's ``\\includegraphics``; one name is one figure in a report (of two figures
that would get one name, the later gets a suffix from its key).
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import hashlib
import math
import re
import textwrap
import threading
import unicodedata
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib import ticker
from matplotlib.axis import Axis
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.category import StrCategoryFormatter
from matplotlib.figure import Figure as MplFigure
from matplotlib.mathtext import MathTextParser
from matplotlib.text import Text
from matplotlib.ticker import Formatter, LogLocator

from tlm.config_words import listing
from tlm.errors import LINE_ESCAPES, InputError
from tlm.storage_json import escaped

# Okabe-Ito colours, colour-blind safe; in greyscale orange/sky blue and green/pink look alike: dash, marker, hatch tell
COLOURS = ("#000000", "#E69F00", "#0072B2", "#F0E442", "#D55E00", "#56B4E9", "#009E73", "#CC79A7")
HATCHES = ("", "///", "...", "xxx", "\\\\\\", "+++", "ooo", "---")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
LINESTYLES = ("-", "--", ":", "-.", (0, (5, 1, 1, 1)), (0, (1, 3)), (0, (8, 2)), (0, (3, 1, 1, 1, 1, 1)))
DPI = 110  # the PNG's resolution by default (``tlm report --dpi``)
DPI_MIN, DPI_MAX = 50, 1200  # the resolutions ``--dpi`` accepts
FORMATS = ("png", "pdf", "svg")  # the files a figure can be written as; the PNG always (the page embeds it)
NAME_PART = 60  # a part of a figure's file name (a folder's name, a run's label) keeps this many characters
NAME_MAX = 120  # a figure's file name, suffix and ".png" included, is at most this many characters
NAMED = 8  # a note names up to this many items (runs, points); of more, the first NAMED_SOME and how many more
NAMED_SOME = 4


def some(items: list[str]) -> str:
    """``items`` listed (:func:`~tlm.config_words.listing`): all of up to :data:`NAMED`, ``A1 #4, A1 #5 and
    A1 #6``, else the first :data:`NAMED_SOME` and how many more (a sweep of hundreds of points is not a note of
    hundreds of labels): ``A1 #4, A1 #5, A1 #6, A1 #7 and 192 more``. The note says how many there are in all."""
    return listing(items, NAMED_SOME, whole=NAMED)


def count(n: int, word: str, plural: str | None = None) -> str:
    """``n`` and the word, singular for one: ``1 run``, ``0 runs``, ``2 studies`` (``plural``: not word + ``s``)."""
    return f"{n} {word if n == 1 else plural or word + 's'}"


def colour(i: int) -> str:
    return COLOURS[i % len(COLOURS)]


def hatch(i: int) -> str:
    return HATCHES[i % len(HATCHES)]


def marker(i: int) -> str:
    return MARKERS[i % len(MARKERS)]


def linestyle(i: int):
    return LINESTYLES[i % len(LINESTYLES)]


def line_style(i: int) -> dict:
    """Keyword arguments of ``ax.plot`` for series ``i``: colour, marker, dash differ; yellow's markers edged dark."""
    c, edge = colour(i), "0.15" if colour(i) == COLOURS[3] else colour(i)
    return {"color": c, "marker": marker(i), "linestyle": linestyle(i), "markersize": 5, "markeredgecolor": edge}


def bar_style(i: int) -> dict:
    """Keyword arguments of ``ax.bar`` for series ``i``: colour and hatch differ, black edge."""
    return {"color": colour(i), "hatch": hatch(i), "edgecolor": "black", "linewidth": 0.6}


def legend_below(ax, fontsize: float = 7, ncol: int = 1):
    """The legend of ``ax`` under its tick labels and x label, covering nothing (the layout shrinks the axes)."""
    drop = 1.6 * ax.xaxis.get_major_ticks(1)[0].label1.get_size() + 1.3 * ax.xaxis.label.get_size() + 14  # (points)
    return ax.legend(fontsize=fontsize, ncol=ncol, loc="upper center", bbox_to_anchor=(0.5, 0), borderaxespad=0.0,
                     bbox_transform=matplotlib.transforms.offset_copy(ax.transAxes, ax.figure, y=-drop, units="points"))


def log_ticks(ax, axis: str = "x") -> None:
    """Tick labels of a log ``axis`` that do not run into each other, and at least two of them where
    two fit: no labels on the minor ticks; the major ticks chosen when the figure is drawn, at its
    final size (:class:`LogTicks`), the first of these that leaves room between the labels: the powers
    of ten (every other, every third, ... over many decades), 1, 2 and 5 times them, round steps of the
    range (0.15, 0.2, 0.25, 0.3 over frame times of 0.145 to 0.34 s), 1 to 9 times the powers of ten,
    each only with three ticks or more; else the first with two. Labels are decimals (``0.15``, ``2000``) where every
    tick is from 0.001 to 10^5, else powers of ten (``2×10^6``). Call it once the scale is log."""
    from matplotlib.ticker import NullFormatter

    a = ax.xaxis if axis == "x" else ax.yaxis
    if a.get_scale() == "log":
        a.set_major_locator(LogTicks(axis))
        a.set_major_formatter(LogLabels())
    a.set_minor_formatter(NullFormatter())


LOG_TICKS_MAX = 8  # the most major ticks :func:`log_ticks` puts on an axis
LOG_LABEL_GAP = 0.5  # the room :func:`log_ticks` leaves between two labels, in the labels' font size


def log_labels(ticks) -> list[str]:
    """The labels of a log axis's major ``ticks`` (:func:`log_ticks`): decimals where every tick is from
    0.001 to 10^5 (``0.15``, ``2000``), else mathtext powers of ten (``10^{-4}``, ``2×10^{6}``); each with
    the fewest significant digits (up to 12) that read back as its own tick (``0.2500001``, not ``0.25``
    five times over; ``1.000025×10^{6}``, not ``1.00002×10^{6}``)."""
    values = [float(v) for v in ticks]
    decimal = all(1e-3 <= v < 1e5 for v in values)
    out = []
    for v in values:
        if not (v > 0 and math.isfinite(v)):
            out.append(f"{v:g}")
            continue
        # (decimals: 'g' from 6 digits, which strips trailing zeros and puts no exponent below 10^5)
        texts = (f"{v:.{d}g}" for d in range(6, 13)) if decimal else (f"{v:.{d - 1}e}" for d in range(1, 13))
        text = next((t for t in texts if float(t) == v), f"{v:.12g}" if decimal else f"{v:.11e}")
        if decimal:
            out.append(text)
            continue
        mantissa, e = text.split("e")
        mantissa = mantissa.rstrip("0").rstrip(".") if "." in mantissa else mantissa
        out.append(r"$\mathdefault{" + ("" if mantissa == "1" else f"{mantissa}\\times") + f"10^{{{int(e)}}}" + "}$")
    return out


def _log_candidates(lo: float, hi: float) -> list[list[float]]:
    """The tick sets :class:`LogTicks` tries over ``lo`` to ``hi`` (> 0), in its order: the powers of ten (every one,
    then every 2nd, 3rd, ...), 1-2-5 times them, round linear steps (:class:`~matplotlib.ticker.MaxNLocator`, densest
    first), then 1-9 times the powers of ten; each within the range and at most :data:`LOG_TICKS_MAX` ticks."""
    from matplotlib.ticker import MaxNLocator

    span = (lo * (1 - 1e-9), hi * (1 + 1e-9))

    def inside(values) -> list[float]:
        return sorted({float(v) for v in values if span[0] <= v <= span[1]})

    # (10.0**309 overflows: no tick above the largest power of ten a float holds)
    e0, e1 = math.floor(math.log10(lo)), min(math.ceil(math.log10(hi)), 308)
    out = []
    for stride in (1, 2, 3, 4, 5, 10, 20, 50, 100):
        out.append(inside(10.0**e for e in range(e0, e1 + 1) if e % stride == 0))
    out.append(inside(float(f"{m * 10.0**e:.12g}") for e in range(e0, e1 + 1) for m in (1, 2, 5)))
    for bins in range(LOG_TICKS_MAX - 1, 0, -1):
        try:  # (a range near the largest float has no linear step: its arange fails)
            with np.errstate(all="ignore"):
                ticks = MaxNLocator(nbins=bins, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi)
        except (ValueError, OverflowError):
            continue
        out.append(inside(float(f"{t:.12g}") for t in ticks if t > 0 and math.isfinite(t)))
    out.append(inside(float(f"{m * 10.0**e:.12g}") for e in range(e0, e1 + 1) for m in range(1, 10)))
    return [t for t in out if 0 < len(t) <= LOG_TICKS_MAX]


class LogTicks(LogLocator):
    """The major ticks of a log axis (:func:`log_ticks`), chosen at each draw for the axis's length then: the first of
    :func:`_log_candidates` whose labels (:func:`log_labels`, measured in the tick labels' font) leave
    :data:`LOG_LABEL_GAP` between each two with three ticks or more, else with two, else one that fits; where none
    does (an axis too short for two labels of any set), one tick: the sparsest set's nearest the middle. The choice
    is remembered for the axis's range, length and font (matplotlib asks for the ticks dozens of times a draw)."""

    def __init__(self, axis: str = "x"):
        super().__init__(base=10.0)
        self.which = axis
        self._last: tuple | None = None  # ((range, length, font), ticks) of the latest choice

    def __call__(self):
        lo, hi = self.axis.get_view_interval()
        return self.tick_values(lo, hi)

    def tick_values(self, vmin, vmax):
        lo, hi = sorted((float(vmin), float(vmax)))
        if not (lo > 0 and math.isfinite(hi)) or lo == hi:
            return super().tick_values(vmin, vmax)
        room = self._room()
        key = (lo, hi, room[0], hash(room[1])) if room is not None else None
        if key is not None and self._last is not None and self._last[0] == key:
            return self._last[1].copy()
        sets = _log_candidates(lo, hi)
        fits = [t for t in sets if self._fits(t, lo, hi, room)]
        chosen = None
        for need in (3, 2, 1):
            chosen = next((t for t in fits if len(t) >= need), None)
            if chosen is not None:
                break
        if chosen is None and sets:  # (no set's labels fit: the one tick of the sparsest set nearest the middle)
            middle = math.sqrt(lo) * math.sqrt(hi)
            chosen = [min(min(sets, key=len), key=lambda t: abs(math.log(t / middle)))]
        ticks = np.asarray(chosen if chosen is not None else [], dtype=float)
        if key is not None:
            self._last = (key, ticks.copy())
        return ticks

    def _room(self):
        """The axis's length (points) and its tick labels' font, or None for a locator on no axis."""
        if self.axis is None or self.axis.axes is None:
            return None
        prop = self.axis.majorTicks[0].label1.get_fontproperties()
        box = self.axis.axes.bbox
        return (box.width if self.which == "x" else box.height) * 72.0 / self.axis.figure.dpi, prop

    def _fits(self, ticks: list[float], lo: float, hi: float, room=None) -> bool:
        if len(ticks) < 2 or room is None:
            return True
        length, prop = room
        sizes = [_text_size(text, prop)[0 if self.which == "x" else 1] for text in log_labels(ticks)]
        whole = _ln_ratio(hi, lo)
        at = [length * _ln_ratio(t, lo) / whole for t in ticks]
        gap = LOG_LABEL_GAP * prop.get_size_in_points()
        return all(b - a >= (sa + sb) / 2 + gap for a, b, sa, sb in zip(at, at[1:], sizes, sizes[1:]))


def _ln_ratio(a: float, b: float) -> float:
    """ln(a / b) of two positive floats: the log of their ratio where that is a finite float (right even
    for 1e300 and the next float, whose logs are equal), else the difference of their logs (the ratio of
    1e300 to 1e-301 overflows to inf: :class:`LogTicks` placed its ticks at inf / inf, nan)."""
    r = float(a) / float(b)
    return math.log(r) if 0 < r < math.inf else math.log(a) - math.log(b)


@functools.lru_cache(maxsize=512)
def _text_size(text: str, prop) -> tuple[float, float]:
    """The width and height (points) of a tick label in the font ``prop`` (mathtext where in ``$``)."""
    from matplotlib.textpath import TextToPath

    w, h, _ = TextToPath().get_text_width_height_descent(text, prop, ismath="$" in text)
    return float(w), float(h)


class LogLabels(Formatter):
    """The labels of :class:`LogTicks`'s ticks (:func:`log_labels`, one style for all of them)."""

    def format_ticks(self, values):
        self.set_locs(values)
        return log_labels(values)

    def __call__(self, x, pos=None):
        return log_labels([x])[0] if not len(self.locs) else log_labels([*self.locs, x])[-1]


@dataclass(frozen=True)
class Output:
    """The files each figure of a report is written as: ``formats`` (``png`` first, then any of
    ``pdf`` and ``svg``) and the PNG's ``dpi``."""

    formats: tuple[str, ...] = ("png",)
    dpi: int = DPI

    def extra(self) -> tuple[str, ...]:
        """The formats written beside the PNG."""
        return tuple(f for f in self.formats if f != "png")


def parse_formats(formats: str | Iterable[str] | None) -> tuple[str, ...]:
    """The formats ``formats`` names (names, or one comma-separated string: ``"pdf,svg"``), in the
    order of :data:`FORMATS`, ``png`` first whether named or not (a name given twice is one; None:
    the PNG alone). A ValueError names an empty or unknown format and the allowed ones."""
    names: list[str] = []
    if isinstance(formats, str) and not formats.strip():
        raise ValueError(f"no format named: the formats are {', '.join(FORMATS)}, separated by commas")
    if formats is not None:
        for item in formats.split(",") if isinstance(formats, str) else list(formats):
            name = str(item).strip().lower()
            if not name:
                raise ValueError(f"an empty format in {formats!r}: the formats are {', '.join(FORMATS)}, "
                                 "separated by commas")
            if name not in FORMATS:
                raise ValueError(f"unknown format {str(item).strip()!r}: the formats are {', '.join(FORMATS)}")
            names.append(name)
    return ("png", *(f for f in FORMATS[1:] if f in names))


def parse_dpi(dpi) -> int:
    """``dpi`` (a number, or its text) as a whole number of dots per inch from :data:`DPI_MIN` to
    :data:`DPI_MAX`; None: :data:`DPI`. A ValueError names another value and the range."""
    if dpi is None:
        return DPI
    text = str(dpi).strip()
    try:
        number = float(text)
    except ValueError:
        number = math.nan
    if isinstance(dpi, bool) or not math.isfinite(number) or number != int(number):
        raise ValueError(f"{text!r} is not a whole number of dots per inch (from {DPI_MIN} to {DPI_MAX})")
    if not DPI_MIN <= int(number) <= DPI_MAX:
        raise ValueError(f"{int(number)} dots per inch is out of range: from {DPI_MIN} to {DPI_MAX}")
    return int(number)


def output(formats: str | Iterable[str] | None = None, dpi=None) -> Output:
    """The checked :class:`Output` of ``formats`` (:func:`parse_formats`) and ``dpi`` (:func:`parse_dpi`). A bad value
    is an :class:`InputError` naming the option (``--formats``, ``--dpi``), the value and what is allowed."""
    try:
        chosen = parse_formats(formats)
    except ValueError as e:
        raise InputError(str(e), key="--formats") from None
    try:
        return Output(chosen, parse_dpi(dpi))
    except ValueError as e:
        raise InputError(str(e), key="--dpi") from None


_OUTPUT: contextvars.ContextVar[Output | None] = contextvars.ContextVar("tlm_report_output", default=None)


def current_output() -> Output:
    """The :class:`Output` the figures are written as now (:func:`figure_output`)."""
    return _OUTPUT.get() or Output()


@contextlib.contextmanager
def figure_output(formats: str | Iterable[str] | None = None, dpi=None):
    """Within it, every figure is written as ``formats`` with its PNG at ``dpi`` (:func:`output`,
    checked first: a bad value raises before anything is written); None keeps what is set around it
    (by default the PNG alone at :data:`DPI`)."""
    now = current_output()
    chosen = output(formats if formats is not None else now.formats, dpi if dpi is not None else now.dpi)
    token = _OUTPUT.set(chosen)
    try:
        with report_style():
            yield chosen
    finally:
        _OUTPUT.reset(token)


# the settings a report keeps as the caller set them (by prefix): not how a figure looks (as style.use("default"))
_KEPT_RC = ("backend", "interactive", "toolbar", "timezone", "date.epoch", "figure.max_open_warning",
            "figure.raise_window", "savefig.directory", "tk.window_focus", "docstring.hardcopy", "webagg.")
_STYLED: list = []  # {setting: (the caller's value, the report's)} once per report within report_style now
_STYLING = threading.Lock()


@contextlib.contextmanager
def report_style():
    """Within it (:func:`figure_output`), figures are made, drawn and saved in matplotlib's defaults and
    :data:`VECTOR_RC` whatever the caller set (:data:`_KEPT_RC` aside), the process's (a figure another thread makes
    meanwhile too); the caller's are back at the last end of the reports in its threads, those set meanwhile kept."""
    now = matplotlib.rcParams
    with _STYLING:
        if not _STYLED:
            with warnings.catch_warnings():  # (a deprecated setting's default set without its warning, as rcdefaults)
                warnings.simplefilter("ignore", matplotlib.MatplotlibDeprecationWarning)
                rc = {k: v for k, v in matplotlib.rcParamsDefault.items() if not k.startswith(_KEPT_RC)} | VECTOR_RC
                theirs = {k: dict.get(now, k) for k in rc}
                now.update(rc)
        _STYLED.append(_STYLED[0] if _STYLED else {k: (theirs[k], dict.get(now, k)) for k in rc})
    try:
        yield
    finally:
        with _STYLING:
            if len(_STYLED) == 1:  # (a setting set meanwhile holds another object than the report's: kept)
                dict.update(now, {k: theirs for k, (theirs, ours) in _STYLED[0].items() if dict.get(now, k) is ours})
            _STYLED.pop()


def untangle(fig: MplFigure, texts: list, offsets, hide: bool = False) -> list:
    """Place each annotation of ``texts`` (in order) at the first of ``offsets`` (offset points from its point, the
    first one above or right) where it covers no marker and no label placed before it (its own point's markers
    aside); ``va`` follows the offset's sign (bottom above, top below).

    The figure is laid out first, as :func:`write_png` lays it out (at the PNG's resolution), so that the boxes
    compared are those drawn. Where no offset is free, the label keeps the first offset, or with ``hide`` is hidden;
    the hidden labels are returned."""
    if not texts:
        return []
    fig.set_dpi(current_output().dpi)
    renderer = FigureCanvasAgg(fig).get_renderer()
    _drawable_texts(fig)  # (a surrogate in a label, a title: matplotlib raises as it lays them out)
    engine = fig.get_layout_engine()
    if engine is not None:
        _lay_out(fig, engine)
    points = []  # markers in display coordinates, with their radius in pixels
    px = fig.dpi / 72
    for a in fig.axes:
        for line in a.get_lines():
            if line.get_marker() in (None, "", " ", "None", "none") or not len(line.get_xydata()):
                continue
            r = line.get_markersize() * px / 2 + 1
            points.extend((x, y, r) for x, y in a.transData.transform(line.get_xydata()))
        for coll in a.collections:
            offs = np.asarray(coll.get_offsets())
            sizes = coll.get_sizes()
            if not offs.size or not len(sizes):
                continue
            xy = coll.get_offset_transform().transform(offs)
            for k, (x, y) in enumerate(xy):
                points.append((x, y, np.sqrt(sizes[k % len(sizes)]) * px / 2 + 1))

    def free(box, placed, own) -> bool:  # (its own point's markers may touch it)
        if any(box.x0 - r < x < box.x1 + r and box.y0 - r < y < box.y1 + r and abs(x - own[0]) + abs(y - own[1]) > 1
               for x, y, r in points):
            return False
        return not any(box.overlaps(b) for b in placed)

    def put(t, off) -> None:
        t.set_position(off)
        t.set_va("bottom" if off[1] > 0 else "top" if off[1] < 0 else "center")
        if t.get_ha() != "center":
            t.set_ha("left" if off[0] >= 0 else "right")

    placed, hidden = [], []
    for t in texts:
        own = t.axes.transData.transform(t.xy)
        for off in offsets:
            put(t, off)
            box = t.get_window_extent(renderer)
            if free(box, placed, own):
                break
        else:
            put(t, offsets[0])
            if hide:
                t.set_visible(False)
                hidden.append(t)
                continue
            box = t.get_window_extent(renderer)
        placed.append(box)
    return hidden


def new_figure(width: float = 7.0, height: float = 4.5) -> MplFigure:
    return MplFigure(figsize=(width, height), layout="constrained")


@dataclass
class Figure:
    """One figure of the report: ``file`` (its PNG) is relative to the report folder; a PDF or SVG
    of it, where the report writes them (:func:`figure_output`), is beside it, of the same stem."""

    file: str
    title: str
    caption: str = ""


@dataclass
class Section:
    """A numbered part of the report: figures, optional HTML (tables), or why it is absent.

    ``absent`` is the reason the section has nothing to show for these inputs (the report says so instead of dropping
    the section); ``notes`` are one-line remarks (what was left out of a figure and why). The page shows ``lead`` and
    the first ``shown`` figures; the other figures, the tables (``html``, unless ``html_open``) and the notes are behind
    ``<details>`` so that the page reads in a few screens."""

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


def _lay_out(fig: MplFigure, engine) -> None:
    """Run the figure's layout engine as ``Figure.draw`` runs it (a ValueError ignored), its warning that the axes
    got no room (the figure then left as it is) kept off stderr: a report prints no library warning."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="constrained_layout not applied", category=UserWarning)
        with contextlib.suppress(ValueError):
            engine.execute(fig)


def wrap_title(text: str, width_in: float, fontsize: float = 12.0) -> str:
    """``text`` wrapped to lines that fit ``width_in`` inches at ``fontsize`` points; a title that fits as it is."""
    chars = max(20, int(width_in * 72 / (fontsize * 0.6)))
    return text if len(text) <= chars else textwrap.fill(text, chars, expand_tabs=False)  # (a tab: a space)


# the parser an Agg renderer makes for itself, shared: it keeps the labels it parsed
_MATHTEXT = MathTextParser("path")


# how the vector files keep their text as text (see the module's notes)
VECTOR_RC = {"pdf.fonttype": 42, "svg.fonttype": "none"}


def drawable(text: str) -> str:
    """``text`` with each surrogate as an escape (:func:`tlm.storage_json.escaped`, as a CSV cell's): ``run_\\udcff``,
    a byte not UTF-8, as ``run_\\xff``, text that a font draws and UTF-8 writes (matplotlib refuses a surrogate)."""
    return escaped(text)


# a name's control character in a figure (no glyph): whitespace a space, another \xNN, as escaped_line; \n kept
_FIGURE_ESCAPES = {c: " " if chr(c).isspace() else e for c, e in LINE_ESCAPES.items() if c != 10}


def figure_text(text: str, dollars: bool = False) -> str:
    """``text`` as a figure draws it: :func:`drawable`, then :data:`_FIGURE_ESCAPES`; ``dollars``: ``$`` as ``\\$``."""
    text = drawable(text).translate(_FIGURE_ESCAPES)
    return text.replace("$", r"\$") if dollars else text


class _Drawable(Formatter):
    """An axis's formatter whose labels are drawn as written: ``inner``'s, :func:`figure_text` (``$`` as ``\\$``)."""

    def __init__(self, inner: Formatter):
        self.inner = inner

    def __call__(self, x, pos=None):
        return figure_text(self.inner(x, pos), True)

    def format_ticks(self, values):
        return [figure_text(t, True) for t in self.inner.format_ticks(values)]

    def get_offset(self):
        return figure_text(self.inner.get_offset(), True)

    def set_locs(self, locs):
        self.inner.set_locs(locs)

    def set_axis(self, axis):
        super().set_axis(axis)
        self.inner.set_axis(axis)


# the formatters whose labels can be any text (set_xticks(ticks, labels)'s, a function's, a category): not a number's
_TEXT_FORMATTERS = (ticker.FixedFormatter, ticker.FuncFormatter, ticker.StrMethodFormatter, ticker.FormatStrFormatter,
                    StrCategoryFormatter)


def _drawable_texts(fig: MplFigure) -> None:
    """Every text of ``fig`` (titles, labels, tick labels, legends, notes) drawn as written (:func:`figure_text`): a
    folder's name of bytes not UTF-8 with its bytes escaped (matplotlib raised), ``m$x^2$`` not as a formula."""
    ticks = set()  # (tick labels: drawn as their formatters make them as the figure draws, tlm's 10^{3} mathtext)
    for axis in fig.findobj(Axis):  # (an axes', a secondary axis's; each formatter that can give any text wrapped:
        for minor in (False, True):  # the labels not made here, which cost 12 - 20 ms a log-log figure)
            formatter = axis.get_minor_formatter() if minor else axis.get_major_formatter()
            if isinstance(formatter, _TEXT_FORMATTERS):
                (axis.set_minor_formatter if minor else axis.set_major_formatter)(_Drawable(formatter))
        ticks.update(id(t) for k in (*axis.majorTicks, *axis.minorTicks) for t in (k.label1, k.label2))
        ticks.add(id(axis.offsetText))
    for text in fig.findobj(Text):
        got = text.get_text()
        if isinstance(got, str) and got != (shown := figure_text(got)):
            text.set_text(shown)
        text.set_parse_math(id(text) in ticks)  # (a name's ``$`` drawn as written, not parsed)


def write_png(fig: MplFigure, path: Path) -> None:
    """Write ``fig`` as the PNG ``path`` at the resolution set (:func:`figure_output`, by default :data:`DPI`), laid
    out once and drawn once, and beside it each other format set (``path`` with the suffix ``.pdf``, ``.svg``),
    drawn once each from the same layout.

    The PNG holds the same pixels as ``fig.savefig(path, dpi=dpi)``: the figure's Agg canvas at ``dpi`` is the one
    ``savefig`` would draw on, and its layout engine runs on it as ``savefig`` runs it (in a first draw that outputs
    nothing, which this skips). The engine is then taken off the figure, as ``savefig`` takes it off for its second
    draw, so the PDF and SVG are drawn with the layout the PNG has (an image in them keeps the PNG's resolution)."""
    out = current_output()
    fig.set_dpi(out.dpi)
    canvas = FigureCanvasAgg(fig)
    canvas.get_renderer().mathtext_parser = _MATHTEXT
    _drawable_texts(fig)  # (a surrogate in a label: matplotlib raises)
    engine = fig.get_layout_engine()
    if engine is not None:
        if fig.axes:  # (as Figure.draw runs it, ignoring a ValueError)
            _lay_out(fig, engine)
        fig.set_layout_engine(None)
    path = Path(path)
    fig.savefig(path, dpi=out.dpi)
    for fmt in out.extra():
        # no date in either file, and the SVG's element ids from its name (by default they are random)
        meta = {"CreationDate": None} if fmt == "pdf" else {"Date": None}
        with matplotlib.rc_context({**VECTOR_RC, "svg.hashsalt": path.stem}):
            fig.savefig(path.with_suffix(f".{fmt}"), dpi=out.dpi, format=fmt, metadata=meta)


# the figure names taken in each report folder (its absolute path): name -> the key of the figure that took it
_TAKEN: dict[str, dict[str, str]] = {}


def _name_part(text, limit: int | None = NAME_PART) -> str:
    """``text`` as a part of a file name: accents dropped (é is e), every run of other characters than
    ASCII letters, digits and ``-`` one ``_``, no ``_`` or ``-`` at either end, at most :data:`NAME_PART`
    characters. Text with none of those characters is ``x`` and 8 hex digits of its hash."""
    text = str(text)
    folded = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    part = re.sub(r"[^A-Za-z0-9-]+", "_", folded).strip("_-")[:limit].rstrip("_-")
    if not part and text.strip():
        part = "x" + hashlib.sha1(text.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    return part


_STEM_MAX = NAME_MAX - 4 - 9  # (room for "_" and 8 hex digits, and ".png")
_SETTING = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)+(?=\s*=)")


def short_keys(text: str) -> str:
    """``text`` with each dotted config key before an ``=`` cut to its last part: ``arch.fifo_depth = 16,
    cache.pairs = 1`` is ``fifo_depth = 16, pairs = 1``."""
    return _SETTING.sub(lambda m: m.group(0).rsplit(".", 1)[-1], text)


def _stem(parts: list[str], cut: bool = False) -> str | None:
    """The parts as a file name's stem (:func:`_name_part`, joined by ``_``); None where a part or the
    whole would be cut (unless ``cut``: then cut to fit)."""
    names = [_name_part(p) for p in parts]
    whole = "_".join(n for n in names if n) or "figure"
    if not cut and (len(whole) > _STEM_MAX or any(len(_name_part(p, limit=None)) > NAME_PART for p in parts)):
        return None
    return whole[:_STEM_MAX].rstrip("_-")


def figure_name(out: Path, *parts, key: str | None = None) -> str:
    """The file name of a figure the report writes into the folder ``out``, made from ``parts`` (``"sweep"``, a sweep
    folder's name, a factor; a last part ending in ``.png`` loses it), and taken for the figure ``key`` (what tells
    it from any other: a folder's full path and the factor; by default the parts).

    The name is the parts (:func:`_name_part`, empty ones left out) joined by ``_``, then ``.png``:
    ``sweep_odd_sweep_x_y_2_e_arch_fifo_depth.png`` for ``odd sweep (x&y)#2 é`` and ``arch.fifo_depth``. Where a
    part would be cut (past :data:`NAME_PART`) or the name (past :data:`NAME_MAX`), each dotted setting before an
    ``=`` in the parts keeps its last part (``arch.fifo_depth = 16`` is ``fifo_depth_16``, :func:`short_keys`)
    before anything is cut, so that a combination of factors keeps its values; a name that fits is as it was. It is
    unique within the folder: where a figure of another key took that name (and its file is there), this one gets
    ``_`` and 8 hex digits of its key's hash, so a report written again from the same inputs gives every figure the
    same name. The same key gets the same name again."""
    parts = [str(p) for p in parts]
    if parts and parts[-1].lower().endswith(".png"):
        parts[-1] = parts[-1][:-4]
    key = "\n".join(parts) if key is None else str(key)
    stem = _stem(parts)
    if stem is None:  # (a part or the whole cut: the factors' names shortened first, so their values stay)
        stem = _stem([short_keys(p) for p in parts], cut=True)
    folder = Path(out)
    taken = _TAKEN.setdefault(str(folder.absolute()), {})
    # (surrogatepass: a folder's name of bytes not UTF-8 in the key, os.fsdecode's surrogates, one key still)
    tag = hashlib.sha1(key.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    candidates = [stem, f"{stem}_{tag}", *(f"{stem}_{tag}_{i}" for i in range(2, 1000))]
    for name in (f"{c}.png" for c in candidates):
        other = taken.get(name)
        if other is None or other == key or not (folder / name).exists():  # (a name of an earlier report
            taken[name] = key  # written into this folder, whose file is gone, is free)
            return name
    raise RuntimeError(f"no free file name for the figure {key!r} in {folder}")


def forget_names(out: Path) -> None:
    """Forget the figure names taken in the report folder ``out`` (:func:`figure_name`), once the
    report in it is written: a long session writing many reports keeps no record of them."""
    _TAKEN.pop(str(Path(out).absolute()), None)


@dataclass(frozen=True)
class FigureName:
    """What a figure's file name is made of (:func:`figure_name`): its ``parts`` and its ``key``."""

    parts: tuple
    key: str | None = None


def save(fig: MplFigure, out: Path, name: str | FigureName, title: str, caption: str = "") -> Figure:
    """Write ``fig`` into ``out`` (PNG, and the other formats set: :func:`write_png`) and return its record. Its file
    name is :func:`figure_name` of ``name`` (a file name, or its parts and key); a plain file name's key is ``name``,
    ``title`` and ``caption``: two figures that differ in them are two files."""
    if isinstance(name, FigureName):
        parts, key = tuple(name.parts), name.key
    else:
        parts, key = (name,), None
    if key is None:
        key = "\n".join((*map(str, parts), title, caption))
    file = figure_name(out, *parts, key=key)
    write_png(fig, Path(out) / file)
    return Figure(file, title, caption)
