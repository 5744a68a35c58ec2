"""Where a run's host time went: its stages account for a cold run's compiling (``one_off``), the
render bar's steps are the batches' alone, and the radii record the rule that gave them."""

from __future__ import annotations

import json
import time

import pytest

import tlm.render.batches as batches
from tlm.config import config_from_dict
from tlm.experiments.run import render, run
from tlm.progress import Timer
from tlm.render.pmap import FALLBACK_FRACTION, radii


def _compiling(seconds: float) -> None:
    """What numba compiling a kernel looks like to the one-off clock: its compiler lock's event held."""
    from numba.core import event

    with event.trigger_event("numba:compiler_lock"):
        time.sleep(seconds)


def test_time_booked_apart_leaves_the_stages_it_covers():
    timer = Timer()
    timer.seconds = {"cast": 3.0, "pass_fgather": 5.0, "write": 1.0}
    timer.spans = {"cast": [(0.0, 3.0)], "pass_fgather": [(3.0, 8.0)]}  # ("write": seconds alone, no spans)
    timer.book_apart("one_off", [(2.0, 4.0), (3.5, 6.0), (9.0, 9.5)])  # (overlapping spans counted once)
    assert timer.seconds["cast"] == pytest.approx(2.0)
    assert timer.seconds["pass_fgather"] == pytest.approx(2.0)
    assert timer.seconds["write"] == 1.0
    assert timer.seconds["one_off"] == pytest.approx(4.5)  # (2 .. 6 and 9 .. 9.5: between stages too)
    empty = Timer()
    empty.book_apart("one_off", [])
    assert empty.seconds == {"one_off": 0.0}


def test_a_cold_runs_warm_up_is_its_one_off_stage_and_the_stages_add_up(tmp_path, monkeypatch):
    """A warm-up that compiles for 1.5 s (batches run at once on 2 threads: batches._warm) was in no
    stage: the stages summed to 1.5 s less than the run took, and results.json had no one_off."""
    real = batches._warm

    def cold(frame, traced):
        _compiling(1.5)
        real(frame, traced)

    monkeypatch.setattr(batches, "_warm", cold)
    cfg = config_from_dict({"scene": "cornell", "mode": "rcast", "resolution": [64, 64], "render": {"threads": 2},
                            "arch": {"packet_size": 16}})
    t0 = time.perf_counter()
    results = run(cfg, tmp_path / "run", outputs=())
    wall = time.perf_counter() - t0
    host = results["host_seconds"]
    assert host == json.loads((tmp_path / "run" / "results.json").read_text())["host_seconds"]
    assert host["one_off"] >= 1.5
    assert host["prepare"] < 1.0  # (the warm-up's compiling is one_off's, not its stage's)
    assert sum(host.values()) >= wall - 0.5  # (what is in no stage: the plan, the claim, the folder's move)


def test_the_render_bar_counts_the_batches_steps_not_the_photon_trace(monkeypatch):
    """The photon trace was one step of the render bar, so its rate after the trace (16 s a step on the
    conference room) said minutes were left for the batches' 3 s."""
    made, traced_at = [], []
    real_bar, real_trace = batches.progress_bar, batches.trace_photon_map

    def bar(enabled, **kwargs):
        made.append((kwargs.get("total"), time.perf_counter()))
        return real_bar(enabled, **kwargs)

    def trace(*args, **kwargs):
        out = real_trace(*args, **kwargs)
        traced_at.append(time.perf_counter())
        return out

    monkeypatch.setattr(batches, "progress_bar", bar)
    monkeypatch.setattr(batches, "trace_photon_map", trace)
    res = render(config_from_dict({"scene": "cornell", "mode": "pmap", "resolution": [16, 16],
                                   "photons": {"count": 500}, "render": {"threads": 1}}))
    names = res.plan.run_names
    n = len(batches.batches_for(16 * 16, res.frame.spp, res.cfg.render.batch_rays, 1))
    stepped = [(total, at) for total, at in made if total is not None]
    assert [total for total, _ in stepped] == [n * (1 + len(names))]
    assert traced_at and stepped[0][1] >= traced_at[0]  # (its clock starts after the trace)


def test_an_empty_maps_radius_records_the_fallback_it_used():
    """No caustic photon (nor 2 indirect ones): the radius is the fallback fraction of the diagonal,
    recorded as such, not as the density rule (with its k) that could not measure the map."""
    res = render(config_from_dict({"scene": "cornell", "mode": "pmap", "resolution": [4, 4],
                                   "photons": {"count": 1}}))
    photons = res.photons.photons
    assert photons.caustic_map.n == 0 and photons.indirect_map.n < 2
    got = radii(res.frame, photons)
    diag = res.frame.accel.scale
    assert got["caustic_radius_rule"] == got["radius_rule"] == "fallback"
    assert got["caustic_radius"] == FALLBACK_FRACTION["caustic"] * diag
    assert got["caustic_radius_fraction"] == FALLBACK_FRACTION["caustic"]
    assert got["radius_fraction"] == FALLBACK_FRACTION["indirect"]
    assert "caustic_radius_photons" not in got and "radius_photons" not in got
    assert got["global_radius_rule"] == "fallback" and "global_radius_photons" not in got
