"""h365: the liveness bound of a stream that may run on grows with the frames it has started.

``model.event_bound`` counted ``frames_cap`` frames (64) for every stream that *may* run on past ``arch.frames``
(``model.settling``: two images, the dynamic queue, or the static tiles at 5 frames or more), though most static
ones run the 5 asked: a stuck model was caught some 10 times later than need be. The run's bound is now that of
the frames its stream has started (``arch.frames`` at least), asked again each time it is reached, so it grows as a
stream that runs on starts more; a progressing run is never stopped by it, however far it runs on.
"""

from __future__ import annotations

import dataclasses

import pytest

from tlm.arch import model
from tlm.arch.model import Deadlock, MaxEventsReached, event_bound, frame_events, settling, simulate

from .test_dynamic_steady_h292 import refract_frame


@pytest.fixture(scope="module")
def refract():
    return refract_frame()


def _arch(refract, **kw):
    cfg, _, _ = refract
    return dataclasses.replace(cfg.arch, **kw)


def test_a_stream_that_runs_the_frames_asked_has_their_bound(refract):
    """Cornell refract 32x32, one pipeline, static, two images: it may run on (settling) but runs the 5 asked;
    its bound is 5 frames' worth, not frames_cap's 64."""
    _, fn, progs = refract
    a = _arch(refract, scheduler="static", pipelines=1, frames=5)
    t = simulate(fn, progs, a)
    assert settling(t.program, a) and len(t.frames) == 5 and "frames_cap" not in t.throughput_estimate
    assert t.event_budget == event_bound(t.program, a, frames=5) == frame_events(t.program) * 5 + 100_000
    assert t.event_budget < event_bound(t.program, a)  # (the most it might have run: 64 frames)
    assert 8 * t.events < t.event_budget


def test_a_stuck_static_stream_is_caught_after_the_frames_asked(refract, monkeypatch):
    """Frames 2 on spin for ever (an event a cycle, never done): the static stream of two images, which may run
    on to 64 frames, stops as a Deadlock at 5 frames' worth of events (packets of 8: the constant a small part),
    not 64 frames' worth, some 9 times more."""
    _, fn, progs = refract
    a = _arch(refract, scheduler="static", pipelines=1, frames=5, packet_size=8)
    real = model._frame_process

    def stuck(m, rec):
        if rec.index >= 2:
            while True:
                yield m.env.timeout(1)
        yield from real(m, rec)

    monkeypatch.setattr(model, "_frame_process", stuck)
    program = model.frame_program(fn, progs, a)
    assert settling(program, a)
    want = event_bound(program, a, frames=5)
    assert 8 * want < event_bound(program, a)  # (what it was caught after before: 64 frames' worth)
    with pytest.raises(Deadlock) as err:
        model.simulate_program(program, a)
    assert type(err.value) is Deadlock
    assert f"({want} events passed, 64 per packet, job and tile of the program: it makes no progress)" in str(
        err.value)


def test_a_stream_that_runs_on_to_64_frames_is_never_stopped_by_it(refract, monkeypatch):
    """Cornell refract 32x32, 4 pipelines, swap, dynamic: 64 frames (it settles after some 120 gaps). With 5
    events per packet, job and tile and no constant, the 5 frames asked's bound is under a ninth of what the run needs,
    and each frame's is just above what a frame takes: the bound grows with the frames started, and the run ends
    as it does under the default bound, to the cycle."""
    _, fn, progs = refract
    a = _arch(refract, scheduler="dynamic", pipelines=4, memory="swap", frames=5)
    full = simulate(fn, progs, a)
    assert len(full.frames) == 64
    assert full.event_budget == event_bound(full.program, a, frames=64)
    monkeypatch.setattr(model, "EVENTS_PER_ITEM", 5)
    monkeypatch.setattr(model, "EVENTS_FLOOR", 0)
    tight = simulate(fn, progs, a)
    assert 9 * event_bound(tight.program, a, frames=5) < tight.events
    assert (tight.cycles, tight.frames, tight.events) == (full.cycles, full.frames, full.events)
    assert tight.event_budget == frame_events(tight.program) * 64 == event_bound(tight.program, a)


def test_a_grown_bound_past_the_config_cap_stops_there_as_the_cap(refract, monkeypatch):
    """The bound starts below arch.max_events and grows past it: the stop there is MaxEventsReached, which
    names the cap and the run on."""
    _, fn, progs = refract
    monkeypatch.setattr(model, "EVENTS_PER_ITEM", 5)
    monkeypatch.setattr(model, "EVENTS_FLOOR", 0)
    a = _arch(refract, scheduler="dynamic", pipelines=4, memory="swap", frames=5, max_events=30_000)
    program = model.frame_program(fn, progs, a)
    assert event_bound(program, a, frames=5) < 30_000
    with pytest.raises(MaxEventsReached, match=r"^stopped at arch\.max_events = 30000 events \(the stream of two "
                                               r"images runs on past arch\.frames = 5"):
        model.simulate_program(program, a)
