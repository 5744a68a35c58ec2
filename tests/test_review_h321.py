"""h321, a review of d3c7bc5 (``arch.settle_frames``):

1. A stream cut to 5 frames (``settle_frames: 1``) has a window of one steady gap: not steady, and warned of, but
   the warning said its running mean "moved by 0.00%" (a spread below the 1% it warns above) and its estimator
   "the mean gap over the last 1 steady completions". Both now say it is one gap, too few to tell.
2. The advice "raise arch.settle_frames" did nothing where ``arch.frames`` is the bound (the stream runs
   max(arch.frames, arch.settle_frames)): a stream of 16 frames asked at ``settle_frames: 1`` raised to 16 runs the
   same. The run's warning and the scaling fit's note name the bound to pass: above the frames it ran.
3. A ``settle_frames`` that bounds nothing (the stream settled first, below it and the default's; or ``arch.frames``
   bounds it at both) gives the run of the default: a sweep axis over it gave equal points unremarked. The run
   records it as having no effect (``timing_inert``: results.json ``inert``, the sweep's unread factors).
"""

from __future__ import annotations

import dataclasses

import pytest

from tlm.arch.model import simulate
from tlm.arch.steady import steady_throughput
from tlm.experiments.run_warnings import inert_timing_changes, stream_warnings
from tlm.experiments.scaling import unsteady

from .test_dynamic_steady_h292 import refract_frame


@pytest.fixture(scope="module")
def refract():
    return refract_frame()


def _run(refract, **arch):
    """Cornell refract at 32x32, 2 pipelines, ``swap``, dynamic (it settles after 24 frames by default)."""
    cfg, fn, progs = refract
    arch = dataclasses.replace(cfg.arch, scheduler="dynamic", pipelines=2, memory="swap", **arch)
    return simulate(fn, progs, arch), dataclasses.replace(cfg, arch=arch)


def _settle_line(t, cfg) -> str:
    lines = [line for line in stream_warnings(t, cfg) if line.startswith("the stream did not settle")]
    assert len(lines) == 1, lines
    return lines[0]


def test_a_window_of_one_gap_is_not_said_to_have_moved_0_percent(refract):
    t, cfg = _run(refract, frames=5, settle_frames=1)
    est = t.throughput_estimate
    assert est["window"] == [2, 3] and est["steady"] is False and est["spread"] == 0.0
    line = _settle_line(t, cfg)
    assert "too few completions to tell whether it moves" in line and "0.00%" not in line, line
    assert "last 1 steady" not in est["estimator"] and "too few completions" in est["estimator"], est["estimator"]
    _, longer = steady_throughput([100, 130, 160, 200, 230, 260, 290, 297], 2, settling=True)
    assert longer["estimator"].startswith("mean gap over the last 3 steady completions")


def test_the_advice_names_a_bound_that_changes_the_run(refract):
    """16 frames asked at settle_frames 1: the advice is to pass 16 (a settle_frames of 16 runs the same stream)."""
    t, cfg = _run(refract, frames=16, settle_frames=1)
    assert len(t.frames) == 16 and t.throughput_estimate["settled"] is False
    line = _settle_line(t, cfg)
    assert line.endswith("raise arch.settle_frames (the most frames it runs) above 16 to settle it"), line
    same, _ = _run(refract, frames=16, settle_frames=16)
    past, _ = _run(refract, frames=16, settle_frames=17)
    assert len(same.frames) == 16 and len(past.frames) > 16
    note = unsteady({"settled": False, "frames": 16})
    assert note.endswith("(raise arch.settle_frames above 16)"), note


def test_a_bound_that_bounds_nothing_has_no_effect(refract):
    """Settled first (24 frames, below 40 and 64), or arch.frames the bound at both: the default's run, said to have
    no effect; a bound that stopped the stream (1, 16) or the default itself: not."""
    for frames, settle, inert in [
            (5, 40, "the stream ran 24 frames, where it settled: within this bound and the default's (64)"),
            (70, 16, "arch.frames = 70 bounds the stream at this value and the default's"),
            (5, 16, None), (5, 1, None), (5, 64, None)]:
        t, cfg = _run(refract, frames=frames, settle_frames=settle)
        assert inert_timing_changes(t, cfg).get("arch.settle_frames") == inert, (frames, settle)
        said = [line for line in stream_warnings(t, cfg) if line.startswith("arch.settle_frames")]
        assert said == ([f"arch.settle_frames = {settle} has no effect in this run: {inert}"] if inert else [])
        if inert:  # (the run is the default's)
            base, _ = _run(refract, frames=frames)
            assert (len(t.frames), t.cycles, t.events) == (len(base.frames), base.cycles, base.events)
