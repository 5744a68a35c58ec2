"""h349: what arch.fifo_depth's run warning claims; h354: a static stream's TThru read before it is periodic.

``arch.fifo_depth`` "has no effect in this run" was said where every coarse packet enters the FIFO alone, while
the packets-of-one estimate (timing.granularity, past packets of one) reads the depth.

h354: the static tiles' completions were taken as periodic from the warm-up, so TThru was the window right after
it. Cornell PMap at 16x16 (4000 photons, one eye ray and light sample a pixel) with 3 pipelines begins with a gap of
6,211,190 before its period of 2 (5,546,150, 5,691,037): 5 frames read 5,878,670, 41 frames 5,632,282, the period's
mean is 5,618,594. A static stream of two images whose asked frames' steady gaps do not repeat from the first now
runs on until they repeat, as the dynamic one does; one whose gaps do runs the frames asked, as before.
"""

from __future__ import annotations

import dataclasses

import pytest

import tlm
from tlm.arch.steady import repeats_from_warmup
from tlm.arch.units import MaxEventsReached
from tlm.experiments.run import frames_said
from tlm.experiments.run_warnings import stream_warnings, timing_inert
from tlm.render.planner import inert_timing_settings


def _sim(res, **arch):
    return tlm.simulate(res, {"trace": False, **arch})


def test_fifo_depth_is_not_called_inert_where_the_estimate_reads_it():
    """Cornell refract 24x24, one image, packets of 64: at depth 1 every coarse packet enters the FIFO alone
    (the run's cycles as at 1024), but the packets-of-one estimate reads the depth: share 0.0417 against
    0.059, and no 'has no effect' line (h425's line, that the cycles are the default's and only the estimate
    reads the depth, is true here)."""
    cfg = tlm.load_config("cornell", {"mode": "refract", "resolution": [24, 24], "render.spp": 1,
                                      "render.light_samples": 1})
    res = tlm.render_image(cfg)
    cfg = res.cfg  # (the run config: tlm.load_config's wraps it)
    arch = {"images_in_flight": 1, "packet_size": 64}
    shallow, deep = (_sim(res, fifo_depth=depth, **arch) for depth in (1, 1024))
    assert shallow.cycles["throughput"] == deep.cycles["throughput"]
    assert shallow.granularity["share"] != deep.granularity["share"]
    a = dataclasses.replace(cfg.arch, fifo_depth=1, trace=False, **arch)
    assert "arch.fifo_depth" not in timing_inert(shallow, a)
    said = [line for line in stream_warnings(shallow, dataclasses.replace(cfg, arch=a)) if "arch.fifo_depth" in line]
    # (h425: the FIFOs' peaks may say the cycles are the default's, but never that the depth is unread)
    assert all("changes no simulated cycle" in line and "only timing.granularity" in line and "reads the depth" in line
               for line in said), said
    # a frame whose phases' rays fit in 1024 entries together, each taking one at least: inert, estimate too
    small = tlm.render_image(tlm.load_config("cornell", {"mode": "rcast", "resolution": [2, 2], "render.spp": 1,
                                                         "render.light_samples": 1}))
    wide, default = (_sim(small, fifo_depth=depth, **arch) for depth in (4096, 1024))
    assert "never fills" in timing_inert(wide, dataclasses.replace(a, fifo_depth=4096))["arch.fifo_depth"]
    assert (wide.cycles, wide.granularity) == (default.cycles, default.granularity)


@pytest.fixture(scope="module")
def pmap16():
    cfg = tlm.load_config("cornell", {"mode": "pmap", "resolution": [16, 16], "render.spp": 1,
                                      "render.light_samples": 1, "photons.count": 4000})
    return tlm.render_image(cfg)


def test_a_static_stream_reads_its_period_at_any_length(pmap16):
    """3 pipelines: the first steady gap is a transient, the period 2 follows; 5 (the default), 13 and 41
    frames read the period's mean (5 and 13 asked run 16: the period held over 12 gaps, the transient's one
    before them; 41 asked hold it already and run 41)."""
    runs = {f: _sim(pmap16, pipelines=3, frames=f) for f in (5, 13, 41)}
    assert {t.cycles["throughput"] for t in runs.values()} == {5618594}
    assert len({t.cycles["latency"] for t in runs.values()}) == 1
    assert [len(t.frames) for t in runs.values()] == [16, 16, 41]
    est = runs[5].throughput_estimate
    assert est["frames"] == 16 and est["frames_cap"] == 64 and est["settled"] and est["period"] == 2
    d = sorted(f["done"] for f in runs[5].frames)
    assert est["window"][0] == 2 and d[2] - d[1] == 6211190  # (the transient's gap left out)


def test_a_static_stream_whose_gaps_repeat_runs_the_frames_asked(pmap16):
    """4 pipelines repeat with a period of 1 from the first steady gap, 8 with one of 2: the frames asked, the
    old window and its TThru, no frames_cap; a period of 2 shows only from 7 frames (four steady gaps), so
    8 pipelines at 5 frames run on (15), to the same TThru."""
    four = _sim(pmap16, pipelines=4)
    assert len(four.frames) == 5 and four.throughput_estimate["window"] == [1, 3]
    assert "frames_cap" not in four.throughput_estimate and "settled" not in four.throughput_estimate
    assert (four.cycles["throughput"], four.cycles["latency"]) == (5839406, 11678812)
    eight = {f: _sim(pmap16, pipelines=8, frames=f) for f in (5, 9)}
    assert [len(t.frames) for t in eight.values()] == [15, 9]
    assert eight[5].cycles["throughput"] == eight[9].cycles["throughput"] == 4791524
    assert eight[5].throughput_estimate["period"] == 2 and "settled" not in eight[9].throughput_estimate


def test_repeats_from_warmup_reads_the_asked_frames_completions_alone():
    """Two images: the steady gaps are those between completions 1 .. frames - 1 (frame f + 2 arrives at
    completion f); a period of 1 from two gaps on, of 2 from four; later completions change nothing."""
    assert repeats_from_warmup([0, 10, 20, 30, 35], 2, 5)  # (gaps 10, 10; the drain's 5 is not one)
    assert not repeats_from_warmup([0, 10, 25, 35, 40], 2, 5)  # (15, 10)
    assert not repeats_from_warmup([0, 10, 25, 35, 45, 55, 65, 75], 2, 5)  # (the run-on's repeats not read)
    assert repeats_from_warmup([0, 10, 20, 25, 35, 40, 45], 2, 7)  # (10, 5, 10, 5)
    assert not repeats_from_warmup([0, 10, 20, 25, 35, 40, 45], 2, 5) and not repeats_from_warmup([0, 5, 9], 2, 4)


def test_settle_frames_bounds_a_static_stream_and_it_warns(pmap16):
    """arch.settle_frames 1: the 5 frames asked alone, not settled, not steady, and the run says so; fewer
    frames than a steady window (3k - 1) run as asked, fill and drain, not steady (as before). The stream's
    bound is read: not said inert, and the progress bar names it."""
    short = _sim(pmap16, pipelines=3, frames=4)
    assert len(short.frames) == 4 and short.throughput_estimate["steady"] is False
    assert "frames_cap" not in short.throughput_estimate
    t = _sim(pmap16, pipelines=3, settle_frames=1)
    est = t.throughput_estimate
    assert len(t.frames) == 5 and est["settled"] is False and not est["steady"] and est["frames_cap"] == 5
    cfg = dataclasses.replace(pmap16.cfg, arch=dataclasses.replace(pmap16.cfg.arch, pipelines=3, settle_frames=1))
    assert any("did not settle within 5 frames" in line for line in stream_warnings(t, cfg))
    assert cfg.arch.scheduler == "static" and "arch.settle_frames" not in inert_timing_settings(cfg)
    assert frames_said(dataclasses.replace(cfg.arch, settle_frames=64)) == "5 frames, to 64 if they do not repeat"
    four = dataclasses.replace(cfg, arch=dataclasses.replace(cfg.arch, frames=4))
    assert "arch.settle_frames" in inert_timing_settings(four) and frames_said(four.arch) == "4 frames"


def test_a_stop_says_a_static_stream_ran_on_only_where_it_did(pmap16):
    """arch.max_events one short of the stream: the 3 pipelines' stream (16 frames, run on) is said to run on past
    the 5 asked; the 4 pipelines' (the 5 asked, its gaps repeat) is not."""
    for pipelines, said in ((3, True), (4, False)):
        full = _sim(pmap16, pipelines=pipelines)
        with pytest.raises(MaxEventsReached) as e:
            _sim(pmap16, pipelines=pipelines, max_events=full.events - 1)
        assert "arch.max_events" in str(e.value)
        assert ("runs on past arch.frames = 5 until its completions repeat" in str(e.value)) == said, str(e.value)
