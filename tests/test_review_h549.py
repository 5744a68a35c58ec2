"""Review of 71cb21e (h549): tlm.report.numbers on the values a report meets.

1. numpy's numbers (a value read from an array): ``exact``, ``whole`` and ``printed`` of an ``np.float64`` raised
   ValueError (its ``repr`` is ``np.float64(6.41)``); ``np.float32`` and ``np.int64`` were written by ``str``,
   without the rule's separators or trailing zeros (``12345``, ``6.41``).
2. ``sig`` of a number from 2**53 up wrote a float's digits after its rounded ones (``10**30``:
   ``1,000,000,000,000,000,019,884,624,838,656``), and ``whole`` of a huge whole float the same.
3. A value just under 0.001 that rounds to it was written ``1.000e-03`` where 0.001 is ``0.001000``.
4. ``tlm.report.common.legend_below`` raised IndexError on an x axis without ticks (it read the first tick's size).
"""

from __future__ import annotations

import numpy as np
import pytest

from tlm.report.numbers import exact, printed, sig, whole
from tlm.report.tables import fmt


@pytest.mark.parametrize("f", [exact, whole, printed])
def test_a_numpy_float64_is_written_as_its_float(f):
    assert f(np.float64(6.41)) == f(6.41) == "6.41"
    assert f(np.float64(1234.5)) == "1,234.5"


def test_numpy_numbers_follow_the_rule():
    assert fmt(np.float32(6.41)) == fmt(np.float64(6.41)) == "6.410"
    assert fmt(np.int64(11920)) == "11,920"
    assert whole(np.int64(44778358)) == "44,778,358"
    assert exact(np.float32(548.8)) == "548.8"
    assert printed(np.int64(110)) == "110" and printed(np.float64(43.0)) == "43.0"
    assert sig(np.float64(np.nan)) == "nan" and sig(np.bool_(True)) == "True"


def test_a_huge_value_keeps_only_its_rounded_digits():
    assert sig(10**30) == "1,000,000,000,000,000,000,000,000,000,000"
    assert sig(2**70) == "1,181,000,000,000,000,000,000"
    assert sig(1.23456e25) == "12,350,000,000,000,000,000,000,000"
    assert whole(1.23456e25) == exact(1.23456e25) == "1.23456e+25"


def test_the_small_boundary_is_judged_after_rounding():
    assert sig(0.00099996) == sig(0.001) == "0.001000"
    assert sig(0.00099) == "9.900e-04"
    assert [sig(v) for v in (999.95, 9999.7, -1234.5, 0, -0.0)] == ["1,000", "10,000", "-1,234", "0", "0"]


def test_a_legend_goes_below_an_axis_without_ticks():
    # (legend_below sized its drop from the first x tick label: an axis with none raised IndexError)
    from tlm.report.common import legend_below, new_figure

    fig = new_figure(7.0, 3.4)
    ax = fig.subplots()
    ax.plot([0, 1], [0, 1], label="a")
    ax.set_xticks([])
    assert legend_below(ax).get_texts()[0].get_text() == "a"
    assert ax.get_xticks().size == 0
