"""h311: ``arch.settle_frames``, the most frames a settling stream runs, and tlm/api.py's configs moved out.

1. A dynamic stream of two images runs on past ``arch.frames`` until its completions repeat (tlm/arch/steady.py),
   at most 64 frames, a bound no one could change: dynamic sweep points simulated several times longer and their
   traces grew. ``arch.settle_frames`` (default 64, the bound as it was) is now that bound (``max(arch.frames,
   arch.settle_frames)``); ``1`` runs ``arch.frames`` alone. A stream cut that short has too few steady gaps for
   the running mean's spread to say anything: it is not steady (a run warns), and its latency is over the frames
   that arrived after the warm-up (its window has none that arrived in it: a division by zero before).
2. tlm/api.py was one line under 700: ``Config``, ``load_config`` and ``scene_file`` are in tlm/api_config.py now,
   the same objects read from ``tlm.api`` and ``tlm``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import yaml

import tlm
import tlm.api as api
from tlm.arch.model import MaxEventsReached, simulate
from tlm.arch.steady import SETTLE_FRAMES, frames_cap
from tlm.config import ArchConfig, config_from_dict, describe
from tlm.errors import InputError
from tlm.experiments.run_warnings import stream_warnings

from .test_dynamic_steady_h292 import refract_frame

ROOT = Path(__file__).resolve().parents[1]

# Cornell refract at 32x32, dynamic, 5 frames asked, as the code before arch.settle_frames ran it (HEAD 717289d,
# tests/test_dynamic_steady_h292.py's frame): the frames run, TThru, latency and SimPy events
BEFORE = {(2, "swap"): (24, 5361627, 10723255, 15641), (2, "copy"): (22, 5418697, 10837393, 22012),
          (4, "swap"): (64, 2988458, 5977860, 71460)}


@pytest.fixture(scope="module")
def refract():
    return refract_frame()


def _run(refract, **arch):
    cfg, fn, progs = refract
    arch = dataclasses.replace(cfg.arch, scheduler="dynamic", **arch)
    return simulate(fn, progs, arch), dataclasses.replace(cfg, arch=arch)


@pytest.mark.parametrize("frames", [5, 9])
def test_settle_frames_1_runs_the_frames_asked_and_warns(refract, frames):
    """Two pipelines (24 frames to settle by default): exactly arch.frames run, not settled, not steady, and the
    run warns so; the latency is a mean over frames run (5 frames: the one that arrived after the warm-up)."""
    t, cfg = _run(refract, frames=frames, pipelines=2, memory="swap", settle_frames=1)
    est = t.throughput_estimate
    assert len(t.frames) == est["frames"] == est["frames_cap"] == frames
    assert est["settled"] is False and est["steady"] is False
    assert est["latency_frames"] and t.cycles["latency"] > 0 and t.cycles["throughput"] > 0
    lines = stream_warnings(t, cfg)
    assert any(line.startswith(f"the stream did not settle within {frames} frames") for line in lines), lines


@pytest.mark.parametrize(("frames", "settle", "run"), [(5, 16, 16), (5, 10, 10), (20, 16, 20), (5, 40, 24)])
def test_a_small_cap_stops_the_stream_there(refract, frames, settle, run):
    """The stream stops at max(arch.frames, arch.settle_frames) frames, or where it settles first (24 frames)."""
    t, _ = _run(refract, frames=frames, pipelines=2, memory="swap", settle_frames=settle)
    est = t.throughput_estimate
    assert len(t.frames) == run and est["frames_cap"] == max(frames, settle)
    assert est["settled"] is (run == 24)


@pytest.mark.parametrize(("pipelines", "memory"), list(BEFORE))
def test_the_default_leaves_the_cycles_as_they_were(refract, pipelines, memory):
    assert ArchConfig().settle_frames == SETTLE_FRAMES == 64
    for settle in ({}, {"settle_frames": 64}):
        t, _ = _run(refract, frames=5, pipelines=pipelines, memory=memory, **settle)
        got = (len(t.frames), t.cycles["throughput"], t.cycles["latency"], t.events)
        assert got == BEFORE[pipelines, memory]
        assert t.throughput_estimate["frames_cap"] == 64


def test_a_static_stream_runs_the_frames_asked_whatever_the_cap(refract):
    """A static (or one-image) stream is periodic from its warm-up: it runs arch.frames, cap or none."""
    cfg, fn, progs = refract
    for settle in (1, 64):
        t = simulate(fn, progs, dataclasses.replace(cfg.arch, frames=5, pipelines=2, settle_frames=settle))
        assert len(t.frames) == 5 and "frames_cap" not in t.throughput_estimate


def test_a_cap_reached_names_the_run_on_only_where_there_is_one(refract):
    """arch.max_events past the frames asked: the line names the cap (16 frames, arch.settle_frames); at
    settle_frames 1 the stream never runs on, and the line says nothing of it."""
    cfg, fn, progs = refract
    for settle, said in ((16, True), (1, False)):
        arch = dataclasses.replace(cfg.arch, frames=5, pipelines=2, scheduler="dynamic", settle_frames=settle)
        full = simulate(fn, progs, arch)
        with pytest.raises(MaxEventsReached) as e:
            simulate(fn, progs, dataclasses.replace(arch, max_events=full.events - 1))
        text = str(e.value)
        assert ("at most 16 frames, arch.settle_frames" in text) is said and ("runs on past" in text) is said, text


def test_frames_cap():
    assert (frames_cap(5), frames_cap(5, 1), frames_cap(5, 16), frames_cap(100, 16)) == (64, 5, 16, 100)


@pytest.mark.parametrize(("value", "says"), [
    (0, "0 must be >= 1"), (10001, "10001 must be <= 10000"), (True, "true is not an integer"),
    (1.5, "1.5 is not an integer"), (float("nan"), "is not an integer"), ("8", "'8' is not an integer"),
    (None, "is not an integer")])
def test_bad_values_are_refused_naming_the_key(value, says):
    with pytest.raises(InputError) as e:
        config_from_dict({"arch": {"settle_frames": value}}, "test")
    assert e.value.key == "arch.settle_frames" and says in str(e.value) and "\n" not in str(e.value)


def test_the_key_is_a_setting_set_swept_and_recorded(tmp_path, capsys):
    """`tlm params` lists it; --set sets it (and a bad one is one line, exit 2, nothing written); a sweep takes it
    as an axis, each point's config holding its value."""
    from tlm.cli import main
    from tlm.experiments.sweep_file import load_sweep

    assert ("arch.settle_frames", 64) in [(k, d) for k, d, _ in describe()]
    assert api.load_config("cornell", ["arch.settle_frames=16"]).arch.settle_frames == 16
    out = tmp_path / "out"
    assert main(["run", "cornell", "--set", "arch.settle_frames=0", "--out", str(out), "--no-progress"]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert len(err) == 1 and "arch.settle_frames: 0 must be >= 1" in err[0] and not out.exists()
    sweep = tmp_path / "s.yaml"
    sweep.write_text(yaml.safe_dump({"base": {"scene": "cornell", "arch": {"scheduler": "dynamic"}},
                                     "grid": {"arch.settle_frames": [1, 16]}}))
    points = load_sweep(sweep).points
    assert [p.config["arch"]["settle_frames"] for p in points] == [1, 16]


def test_the_configs_moved_out_of_api_are_the_same_objects():
    from tlm import api_config

    for name in ("Config", "load_config", "scene_file", "Overrides"):
        assert getattr(api, name) is getattr(api_config, name), name
    for name in ("Config", "load_config", "scene_file"):
        assert getattr(tlm, name) is getattr(api_config, name), name
    cfg = api_config.load_config({"scene": "cornell"}, {"arch.settle_frames": 8})
    assert isinstance(cfg, api.Config) and cfg.arch.settle_frames == 8 and cfg.overrides == ("arch.settle_frames=8",)
    assert len((ROOT / "tlm" / "api.py").read_text().splitlines()) < 650


def test_a_stream_cut_short_before_it_could_settle_is_not_steady():
    """Five frames of a settling stream (two steady gaps): one running mean, no movement to measure: not steady
    (was: spread 0, steady), its latency over frame 3, the one that arrived after the warm-up and was done before
    the drain (was: no frame, a division by zero in the model)."""
    from tlm.arch.steady import steady_throughput

    value, est = steady_throughput([100, 130, 160, 200, 207], 2, settling=True)
    assert est["settled"] is False and est["steady"] is False and est["spread"] == 0.0
    assert est["window"] == [2, 3] and value == 40 and est["latency_arrivals"] == [3, 4]
    _, longer = steady_throughput([100, 130, 160, 200, 230, 260, 290, 297], 2, settling=True)
    assert longer["steady"] is True and longer["latency_arrivals"][0] == 2 + longer["window"][0]
