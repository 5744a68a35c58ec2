"""Figure layout: whole-number factors get whole-number ticks; log axes label no minor tick
(the probe of the regenerated plots/ found 5.5 BSP levels and overlapping minor labels)."""

from __future__ import annotations

import itertools

import matplotlib.pyplot as plt
import numpy as np

from tests.test_report_sweep_legend import sweep_folder  # (the 24-point sweep folder those tests build)
from tlm.report import common
from tlm.report.collect import read
from tlm.report.sweeps import factor_figure


def test_a_whole_number_factor_is_ticked_in_whole_numbers(tmp_path, monkeypatch):
    """FPS against ``seed`` (0 and 1): the old axis ticked 0.0, 0.2, ..., 1.0."""
    figs = []
    monkeypatch.setattr("tlm.report.sweeps.save", lambda fig, *a, **k: figs.append(fig))
    sw = sweep_folder(tmp_path / "s", lambda p, f, s: 300.0 + p + 7.0 * s)
    factor_figure(read([sw]).sweeps[0], "seed", tmp_path, [])
    ax = figs[0].axes[0]
    lo, hi = ax.get_xlim()
    ticks = [t for t in ax.get_xticks() if lo <= t <= hi]
    assert ticks and all(float(t).is_integer() for t in ticks), ticks


def test_a_log_axis_of_under_two_decades_labels_no_minor_tick_and_no_label_overlaps(tmp_path):
    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    ax.plot(np.geomspace(1.6e3, 4.2e4, 20), np.linspace(0, 1, 20))
    ax.set_xscale("log")
    common.log_ticks(ax, "x")
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    minor = [t.get_text() for t in ax.xaxis.get_minorticklabels() if t.get_visible()]
    assert not any(minor), minor
    boxes = sorted((t.get_window_extent(renderer) for t in ax.xaxis.get_majorticklabels()
                    if t.get_visible() and t.get_text()), key=lambda b: b.x0)
    assert len(boxes) >= 3  # (1, 2 and 5 times the powers of ten: still several labels)
    assert all(a.x1 <= b.x0 for a, b in itertools.pairwise(boxes)), [(b.x0, b.x1) for b in boxes]
    plt.close(fig)


def test_the_summary_tradeoff_figure_labels_no_minor_tick(tmp_path, monkeypatch):
    """summary_tradeoff.png set its own log axes and labelled their minor ticks, which ran into
    each other over a decade and a half of frame times (the regenerated plots/)."""
    from tests.test_report_honest_captions import _evc_rows, capture
    from tlm.report import summary as summary_mod
    from tlm.report.collect import Inputs, Study
    from tlm.report.summary import summary_section

    figs = capture(monkeypatch, summary_mod)
    summary_section(Inputs([], studies=[Study("error-vs-cost", tmp_path / "ec", _evc_rows())]), tmp_path)
    (ax,) = figs[-1].axes
    figs[-1].canvas.draw()
    for axis in (ax.xaxis, ax.yaxis):
        assert not any(t.get_text() for t in axis.get_minorticklabels() if t.get_visible())
