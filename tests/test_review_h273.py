"""Review of 7159bde (h273), the log axes' ticks chosen at draw time (report.common LogTicks, LogLabels):
labels of a range narrower than their 6 digits were one text five times over (``0.25`` for 0.2500001 to
0.2500003), or another value (``1.00002×10^6`` for 1000025); an axis reaching past 10^308 raised
OverflowError at the draw; an axis too short for two labels of any tick set got labels on top of each
other; the ticks were chosen anew each of the dozens of times matplotlib asks for them in a draw."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from tlm.report import common


def _figure(size, lo, hi, axis="x", limits=False):
    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    data, other = np.geomspace(lo, hi, 12), np.linspace(0, 1, 12)
    ax.plot(*((data, other) if axis == "x" else (other, data)), "o")
    (ax.set_xscale if axis == "x" else ax.set_yscale)("log")
    if limits:
        (ax.set_xlim if axis == "x" else ax.set_ylim)(lo, hi)
    common.log_ticks(ax, axis)
    return fig, ax


def _labels(fig, ax, axis="x"):
    """(text, tick, window box) of the major labels drawn within the view, in order along the axis."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    a = ax.xaxis if axis == "x" else ax.yaxis
    lo, hi = sorted(a.get_view_interval())
    at = 0 if axis == "x" else 1
    out = [(t.get_text(), t.get_position()[at], t.get_window_extent(renderer)) for t in a.get_majorticklabels()
           if t.get_visible() and t.get_text() and lo * (1 - 1e-9) <= t.get_position()[at] <= hi * (1 + 1e-9)]
    return sorted(out, key=lambda x: x[1])


def _apart(labels, axis="x") -> bool:
    return all((a.x1 <= b.x0) if axis == "x" else (a.y1 <= b.y0) for (_, _, a), (_, _, b) in itertools.pairwise(labels))


def test_labels_of_a_range_narrower_than_six_digits_read_as_their_own_ticks():
    """Frame times equal but for a few units in the 7th digit: the labels were '0.25' five times."""
    for axis in ("x", "y"):
        labels = _labels(*_figure((5.4, 3.1), 0.2500001, 0.2500003, axis), axis)
        texts = [text for text, _, _ in labels]
        assert len(texts) >= 2 and len(set(texts)) == len(texts), texts
        assert all(float(text) == tick for text, tick, _ in labels), labels
        assert _apart(labels, axis), [(t, b.x0, b.x1, b.y0, b.y1) for t, _, b in labels]
    assert common.log_labels([1000025.0, 2e6]) == [r"$\mathdefault{1.000025\times10^{6}}$",
                                                  r"$\mathdefault{2\times10^{6}}$"]  # (was 1.00002: 1000020)
    assert common.log_labels([0.15, 2000.0]) == ["0.15", "2000"]


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # (matplotlib's own, of its scale)
def test_an_axis_up_to_the_largest_float_draws():
    """ceil(log10(1.5e308)) is 309: 10.0**309 raised OverflowError in the draw (and MaxNLocator's arange
    a ValueError near it)."""
    for axis in ("x", "y"):
        labels = _labels(*_figure((5.4, 3.1), 1e300, 1.5e308, axis, limits=True), axis)
        assert len(labels) >= 2 and _apart(labels, axis), [t for t, _, _ in labels]


def test_an_axis_too_short_for_two_labels_of_any_set_gets_one_label_not_three_on_top_of_each_other():
    fig, ax = _figure((2.0, 1.5), 0.011, 0.019)
    labels = _labels(fig, ax)
    assert labels and _apart(labels), [(t, b.x0, b.x1) for t, _, b in labels]


def test_the_ticks_are_chosen_once_per_range_length_and_font_not_at_every_ask(monkeypatch):
    made = []
    real = common._log_candidates
    monkeypatch.setattr(common, "_log_candidates", lambda lo, hi: made.append((lo, hi)) or real(lo, hi))
    fig, ax = _figure((5.4, 3.1), 0.145, 0.34)
    ax.set_yscale("log")
    common.log_ticks(ax, "y")
    fig.canvas.draw()
    assert 0 < len(made) <= 8, len(made)  # (two axes, a few layout passes each; it was 30 and more)
    before = [t.get_text() for t in ax.get_xticklabels()]
    fig.set_size_inches(2.0, 1.5)  # (a shorter axis: chosen again, fewer labels)
    fig.canvas.draw()
    after = [t.get_text() for t in ax.get_xticklabels() if t.get_visible()]
    assert len([t for t in after if t]) < len([t for t in before if t]), (before, after)
