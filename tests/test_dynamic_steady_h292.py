"""The dynamic scheduler's TThru does not depend on how many frames are simulated.

With two images in flight the dynamic queue's completions settle into a period only after a
transient of several frames (which pipeline takes which of the low-priority image's tiles
depends on the times the frames before left), so a window right after the warm-up read
TThru 9% high on Cornell refract at 32x32 with one pipeline, 11% with two, and flipped
`memory: copy` against `swap`. The model now runs such a stream on until its completions
repeat (tlm.arch.steady) and measures over whole periods; static tiles stay periodic from
the warm-up on and keep their window.
"""

from __future__ import annotations

import dataclasses
from fractions import Fraction

import pytest

from tlm.arch.costs import load_programs
from tlm.arch.model import simulate
from tlm.arch.steady import SETTLE_FRAMES, STEADY_SPREAD, keep_going, periodic_tail, steady_throughput
from tlm.config import config_from_dict


@pytest.fixture(scope="module")
def refract():
    return refract_frame()


def refract_frame():
    """Cornell refract at 32x32 (configs/cornell.yaml's frame, 4 eye rays and 4 light samples a
    pixel): its config, functional work and programs."""
    from tlm.experiments.run import render

    cfg = config_from_dict({"scene": "cornell", "mode": "refract", "resolution": [32, 32],
                            "render": {"spp": 4, "light_samples": 4}, "arch": {"trace": False}}, "test")
    return cfg, render(cfg).functional(), load_programs()


def _run(refract, **arch):
    cfg, fn, progs = refract
    return simulate(fn, progs, dataclasses.replace(cfg.arch, **arch))


@pytest.mark.parametrize(("pipelines", "scheduler", "memory"), [
    (1, "dynamic", "swap"), (1, "dynamic", "copy"), (2, "dynamic", "swap"), (2, "dynamic", "copy"),
    (2, "static", "swap"), (4, "static", "copy")])
def test_tthru_and_latency_do_not_depend_on_the_stream_length(refract, pipelines, scheduler, memory):
    """5, 9 and 23 frames give the same TThru and latency, all steady (the old window after the
    warm-up read the dynamic scheduler's 5 frames 2-11% high)."""
    runs = [_run(refract, frames=f, pipelines=pipelines, scheduler=scheduler, memory=memory) for f in (5, 9, 23)]
    assert all(t.throughput_estimate["steady"] for t in runs)
    assert len({t.cycles["throughput"] for t in runs}) == 1
    assert len({t.cycles["latency"] for t in runs}) == 1


def test_a_dynamic_stream_runs_on_until_its_completions_repeat(refract):
    """Two pipelines, dynamic: 5 frames asked, 24 run; the gaps repeat with a period of 3 from
    the 11th completion on (confirmed over 12 gaps, more than the 9 before them), and TThru is
    their mean over whole periods (a static stream runs the frames asked)."""
    t = _run(refract, frames=5, pipelines=2, scheduler="dynamic", memory="swap")
    est = t.throughput_estimate
    d = sorted(f["done"] for f in t.frames)
    assert len(t.frames) == est["frames"] > 5
    assert est["settled"] and est["period"] == 3 and len(t.frames) == 24
    a, b = est["window"]
    assert (b - a) % 3 == 0 and b <= len(d) - 2
    assert [d[i + 1] - d[i] for i in range(a, a + 3)] == [d[i + 1] - d[i] for i in range(a + 3, a + 6)]
    assert t.cycles["throughput"] == round(Fraction(d[b] - d[a], b - a))
    assert len(_run(refract, frames=5, pipelines=2, scheduler="static").frames) == 5


def test_copy_against_swap_reads_the_same_at_any_stream_length(refract):
    """Two pipelines, dynamic: the old 5-frame window put `memory: copy` 7% below `swap`, the
    other way round from 11 frames on; now both lengths order them alike."""
    thr = {(f, m): _run(refract, frames=f, pipelines=2, scheduler="dynamic", memory=m).cycles["throughput"]
           for f in (5, 21) for m in ("swap", "copy")}
    assert (thr[5, "copy"] > thr[5, "swap"]) == (thr[21, "copy"] > thr[21, "swap"])
    assert thr[5, "swap"] == thr[21, "swap"] and thr[5, "copy"] == thr[21, "copy"]


@pytest.mark.parametrize("pipelines", [1, 2, 4, 8])
@pytest.mark.parametrize("memory", ["swap", "copy"])
def test_static_completions_repeat_from_the_warm_up(refract, pipelines, memory):
    """What keeps the static window (and every static figure) as it was: with two images in
    flight the static tiles' steady gaps repeat from the first on, with a period of 1 or 2 (17 frames:
    14 steady gaps, enough for periodic_tail's 12)."""
    t = _run(refract, frames=17, pipelines=pipelines, scheduler="static", memory=memory)
    d = sorted(f["done"] for f in t.frames)
    tail = periodic_tail([d[i + 1] - d[i] for i in range(1, len(d) - 2)])
    assert tail is not None and tail[0] == 0 and tail[1] <= 2
    assert len(t.frames) == 17 and "settled" not in t.throughput_estimate


def test_a_stream_that_does_not_settle_within_the_cap_is_not_steady(refract):
    """Four pipelines, dynamic, swap: no period within 64 frames (one of 52 gaps comes after
    some 120). TThru is the mean gap over the later half of the steady gaps; steady where the
    running mean moves by at most STEADY_SPREAD over the window's last half (0.49% here)."""
    t = _run(refract, frames=5, pipelines=4, scheduler="dynamic", memory="swap")
    est = t.throughput_estimate
    d = sorted(f["done"] for f in t.frames)
    assert len(d) == SETTLE_FRAMES and est["settled"] is False
    assert est["steady"] is (est["spread"] <= STEADY_SPREAD)
    a, b = est["window"]
    assert b == len(d) - 2 and a == 1 + (len(d) - 3) // 2
    assert t.cycles["throughput"] == round(Fraction(d[b] - d[a], b - a))
    assert 0 < est["spread"] < 0.01 and est["steady"]


# -- the measure on completion cycles -----------------------------------------------------------

def _stream(gaps, k=2):
    done = [100, 130]  # the warm-up's two completions, then one per gap
    for g in gaps:
        done.append(done[-1] + g)
    return done + [done[-1] + 7]  # the drain


@pytest.mark.parametrize(("gaps", "start", "period"), [
    ([9, 14, 11] + [10] * 12, 3, 1),
    ([50] + [3, 8, 5] * 4, 1, 3),
    ([4, 6] * 6, 0, 2),
    ([1, 2, 3, 4, 5, 6] + [7, 8, 9] * 4, 6, 3),  # (held over 12 gaps, 6 before them)
])
def test_periodic_tail(gaps, start, period):
    assert periodic_tail(gaps) == (start, period)


@pytest.mark.parametrize("gaps", [[5] * 11, [3, 8] * 6 + [4], [1, 2, 3, 4, 5, 6], [],
                                  list(range(13)) + [10] * 12])
def test_no_confirmed_period(gaps):
    """Eleven equal gaps are no period yet (at least twelve), nor is a sequence that breaks at its end, nor
    twelve equal gaps after a transient of 13 (a period held over fewer gaps than came before it)."""
    assert periodic_tail(gaps) is None


def test_a_settling_stream_is_measured_over_whole_periods_after_its_transient():
    done = _stream([50] + [3, 8, 5] * 4)
    value, est = steady_throughput(done, 2, settling=True)
    assert est["steady"] and est["settled"] and est["period"] == 3
    assert est["window"] == [2, 14] and value == round(Fraction(4 * 16, 12))  # 4 periods, 12 gaps: 6 rounds of k = 2
    assert not keep_going(done[:-1], 2)
    assert keep_going(done[:12], 2)
    # the same completions read as a stream periodic from the warm-up: the old window
    assert steady_throughput(done, 2)[1]["window"] == [1, 13]


def test_an_unsettled_stream_is_the_mean_over_its_later_half_and_not_steady():
    gaps = [7, 9, 8, 10, 6, 11, 12, 14]
    done = _stream(gaps)
    value, est = steady_throughput(done, 2, settling=True)
    assert est["steady"] is False and est["settled"] is False
    assert est["window"] == [5, 9] and value == round(Fraction(sum(gaps[4:]), 4))
    # the running mean from the window's middle (completion 7) to its end: 17/2, 29/3, 43/4
    assert est["spread"] == pytest.approx((43 / 4 - 17 / 2) / (43 / 4))
    # a window whose running mean stays within STEADY_SPREAD is steady, though not settled (no warning, no note)
    value, est = steady_throughput(_stream([7, 9, 8, 10, 6, 14, 10, 10]), 2, settling=True)
    assert est["steady"] is True and est["settled"] is False and est["spread"] == pytest.approx(0.0)
