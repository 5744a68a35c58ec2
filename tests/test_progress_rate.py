"""The sweep bar's rate and time left (``progress_bar(eta_after=...)``: ``Bar.recent_rate``),
on a fake clock: steps of equal length give the true time left after each (a step that ends
in the last half of the time counts there only for its part in that half, not whole)."""

from __future__ import annotations

import io

import pytest

from tlm import progress


def _bar(total: int, initial: int = 0, eta_after: float = progress.SWEEP_ETA_AFTER):
    clock = [0.0]
    bar = progress._bar_class()(total=total, initial=initial, eta_after=eta_after, unit="point",
                                file=io.StringIO(), disable=False, mininterval=0)
    bar._time = lambda: clock[0]
    bar.start_t = bar.last_print_t = 0.0
    return bar, clock


def _left(bar, now: float) -> float | None:
    rate = bar.recent_rate(now - bar.start_t)
    return None if rate is None else (bar.total - bar.n) / rate


@pytest.mark.parametrize("total, initial", [(6, 0), (20, 0), (100, 30)])
def test_equal_steps_show_the_true_time_left_after_each(total, initial):
    bar, clock = _bar(total, initial)
    first = max(1, -(-(total - initial) // 10))  # (eta_after: a tenth of the steps to run, at least one)
    for k in range(1, total - initial):
        clock[0] = float(k)
        bar.update(1)
        left = total - initial - k
        for after in (0.0, 0.01, 0.5, 0.99):  # (a redraw just after the step, or while the next one runs)
            got = _left(bar, k + after)
            if k < first:
                assert got is None
            else:
                assert got == pytest.approx(left, abs=1e-9), (k, after)
    bar.close()


def test_a_first_point_of_8_6_s_shows_the_time_left_at_its_rate():
    # (the probe's sweep of 6 points: after an 8.6 s first point the bar read 1/6 [00:08<00:21, 4.30s/point])
    bar, clock = _bar(6)
    clock[0] = 8.6
    bar.update(1)
    assert "1/6 [00:08<00:43,  8.60s/point]" in str(bar), str(bar)
    bar.close()


def test_a_slow_first_step_counts_only_its_part_in_the_last_half():
    bar, clock = _bar(100)
    clock[0] = 40.0  # one step of 40 s, then nine of 1 s each
    bar.update(1)
    for k in range(1, 10):
        clock[0] = 40.0 + k
        bar.update(1)
    # at 49 s the last half began at 24.5 s: 15.5 s of the first step's 40 (0.3875 of it) and nine steps
    rate = bar.recent_rate(49.0)
    assert rate == pytest.approx((9 + 15.5 / 40) / 24.5)
    # the first step drops out as the bar goes on: at 80 s (half from 40 s) the 1 s steps alone
    for k in range(10, 41):
        clock[0] = 40.0 + k
        bar.update(1)
    assert bar.recent_rate(80.0) == pytest.approx(1.0)
    bar.close()


def test_a_stall_lowers_the_rate_and_then_shows_no_time_left():
    bar, clock = _bar(50)
    for k in range(1, 11):  # ten steps of 1 s
        clock[0] = float(k)
        bar.update(1)
    assert bar.recent_rate(10.9) == pytest.approx(1.0)  # (the next step still within its second)
    # 5 s since the last step: the step running now adds less than one step to the half
    # (7.5 s from 7.5 s): 2.5 steps + 1 over 7.5 s
    assert bar.recent_rate(15.0) == pytest.approx(3.5 / 7.5)
    assert bar.recent_rate(21.0) is None  # no step ended in the last half (from 10.5 s)
    clock[0] = 21.0
    assert "10/50 [00:21<?, " in str(bar)
    bar.close()
