"""h359: review of e4f30a1 (a static stream of two images runs on until periodic where its asked frames' steady gaps
do not repeat from the first).

``arch.settle_frames`` was said to have no effect on every static stream before e4f30a1 (the planner: the static
tiles ran ``arch.frames`` alone); since, the planner says so only below 3k - 1 frames, and the run's own check
(``timing_inert``) only where a settling stream stopped within both bounds (``frames_cap`` present). A static stream
whose asked gaps repeat runs the frames asked at any bound, without ``frames_cap``, and nothing said the key was
unread: ``tlm run --set arch.settle_frames=16`` of the default Cornell config warned before and not after.
"""

from __future__ import annotations

import dataclasses

import pytest

import tlm
from tlm.experiments.run_warnings import inert_timing_changes, stream_warnings, timing_inert


@pytest.fixture(scope="module")
def pmap16():
    cfg = tlm.load_config("cornell", {"mode": "pmap", "resolution": [16, 16], "render.spp": 1,
                                      "render.light_samples": 1, "photons.count": 4000})
    return tlm.render_image(cfg)


def _run(res, **arch):
    timing = tlm.simulate(res, {"trace": False, **arch})
    cfg = dataclasses.replace(res.cfg, arch=dataclasses.replace(res.cfg.arch, trace=False, **arch))
    return timing, cfg


def test_settle_frames_is_said_unread_where_a_static_streams_gaps_repeat(pmap16):
    """4 pipelines: the 5 frames asked repeat from the first steady gap, so the stream runs them at any bound (the
    same frames and cycles at 1, 16 and 64) and the key is said to have no effect; 3 pipelines run on to 16
    frames (its first gap a transient), which a bound of 8 cuts: read, not said."""
    runs = {s: _run(pmap16, pipelines=4, settle_frames=s) for s in (1, 16, 64)}
    assert {len(t.frames) for t, _ in runs.values()} == {5}
    assert len({(t.cycles["throughput"], t.cycles["latency"]) for t, _ in runs.values()}) == 1
    for s in (1, 16):
        t, cfg = runs[s]
        assert "frames_cap" not in t.throughput_estimate
        assert "repeat from the first" in timing_inert(t, cfg.arch)["arch.settle_frames"]
        assert f"arch.settle_frames = {s} has no effect in this run" in " ".join(stream_warnings(t, cfg))
        assert "arch.settle_frames" in inert_timing_changes(t, cfg)
    t, cfg = runs[64]  # (the default: nothing to say)
    assert "arch.settle_frames" not in inert_timing_changes(t, cfg)
    cut, cfg = _run(pmap16, pipelines=3, settle_frames=8)
    assert len(cut.frames) == 8 and cut.throughput_estimate["frames_cap"] == 8
    assert "arch.settle_frames" not in inert_timing_changes(cut, cfg)
    assert not any("arch.settle_frames = 8 has no effect" in line for line in stream_warnings(cut, cfg))
