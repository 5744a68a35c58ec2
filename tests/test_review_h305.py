"""Review of 28e342b (the dynamic scheduler's stream runs on past arch.frames until its completions
repeat, tlm/arch/steady.py): a run stopped at ``arch.max_events`` by the frames run past
``arch.frames`` says so, rather than naming a frame the user never asked for."""

from __future__ import annotations

import dataclasses

import pytest

from tlm.arch.costs import load_programs
from tlm.arch.model import MaxEventsReached, simulate
from tlm.arch.steady import SETTLE_FRAMES
from tlm.config import config_from_dict


@pytest.fixture(scope="module")
def frame():
    from tlm.experiments.run import render

    cfg = config_from_dict({"scene": "cornell", "mode": "refract", "resolution": [32, 32],
                            "render": {"spp": 4, "light_samples": 4}, "arch": {"trace": False}}, "test")
    return cfg, render(cfg).functional(), load_programs()


def test_max_events_reached_past_the_frames_asked_says_the_stream_ran_on(frame):
    """Two pipelines, dynamic, 5 frames asked: the stream runs 24 frames until its gaps repeat. A
    cap just under its events stops it at a frame past the 5 asked; the line says the stream runs on
    past arch.frames = 5, at most 64 frames (before: only 'stopped at arch.max_events = N events'); a
    static stream's says nothing of it."""
    cfg, fn, progs = frame
    arch = dataclasses.replace(cfg.arch, frames=5, pipelines=2, scheduler="dynamic")
    full = simulate(fn, progs, arch)
    assert len(full.frames) > 5
    with pytest.raises(MaxEventsReached) as e:
        simulate(fn, progs, dataclasses.replace(arch, max_events=full.events - 1))
    text = str(e.value)
    assert "arch.max_events" in text
    assert f"runs on past arch.frames = 5 until its completions repeat, at most {SETTLE_FRAMES} frames" in text

    # a static stream runs the frames asked: its cap's line says nothing of running on
    static = dataclasses.replace(arch, scheduler="static")
    with pytest.raises(MaxEventsReached) as e:
        simulate(fn, progs, dataclasses.replace(static, max_events=simulate(fn, progs, static).events - 1))
    assert "arch.max_events" in str(e.value) and "runs on past" not in str(e.value)
